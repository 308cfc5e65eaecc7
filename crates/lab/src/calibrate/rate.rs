//! The rate a measured recording is analysed at: the simulator's output rate for the rig
//! ([`crate::sim::sample_rate`]), the rate the classifier's training data is simulated at and
//! so the signal calibration must match. A recording sampled faster is brought down to it
//! once, right after it is loaded and cut, before any view is computed or any twin simulated:
//! its analog tacho is first turned into edge times at the recorded rate
//! ([`analog_tacho_to_edges`], so the speed track and its mean stay the same), then every
//! channel is resampled, band-limited ([`Resampler`]). A recording at or below that rate is
//! left as it is, bit for bit.

use crate::analysis::speed_source::analog_tacho_to_edges;
use crate::config::RigConfig;
use crate::dsp::resample::Resampler;
use crate::recording::Recording;
use crate::sim::{rig_simulation, sample_rate};
use anyhow::{Context, Result};

/// The rate measured recordings of this rig are analysed at, Hz: the simulator's output rate.
pub fn analysis_rate(rig: &RigConfig) -> Result<f64> {
    Ok(sample_rate(&rig.acquisition, rig_simulation(rig)?))
}

/// Bring `rec` down to [`analysis_rate`] if it was recorded faster; returns the rate it was
/// recorded at.
pub fn to_analysis_rate(rec: &mut Recording, rig: &RigConfig) -> Result<f64> {
    let recorded = rec.sample_rate;
    let target = analysis_rate(rig)?;
    if recorded <= target {
        return Ok(recorded);
    }
    let what = rec.provenance.source_path.clone();
    analog_tacho_to_edges(rec, rig).with_context(|| format!("speed reference of {what}"))?;
    let mut r = Resampler::new(rec.len(), recorded, target).with_context(|| {
        format!("{what}: resampling from {recorded} Hz to the rig's simulation rate {target} Hz")
    })?;
    for c in &mut rec.channels {
        c.samples = r.process(&c.samples).with_context(|| {
            format!(
                "{what}: channel {:?} from {recorded} Hz to the rig's simulation rate {target} Hz",
                c.name
            )
        })?;
    }
    rec.sample_rate = r.rate_out();
    rec.provenance.notes.push(format!(
        "resampled from {recorded} Hz to {} Hz (the rig's simulation rate) for calibration",
        r.rate_out()
    ));
    Ok(recorded)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::{Channel, Provenance, Tacho};

    fn rig(speed: &str) -> RigConfig {
        let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
            .join("config/lut-rig.toml");
        let text = std::fs::read_to_string(path).unwrap();
        // the LUT rig simulates at 10 kHz; its [speed] section replaced by `speed`
        let start = text.find("[speed]").unwrap();
        let end = start + text[start..].find("\n[features]").unwrap();
        RigConfig::parse(&format!("{}{speed}\n{}", &text[..start], &text[end..])).unwrap()
    }

    /// `seconds` at `fs` of a 150 Hz and a 7 kHz sine on every channel the rig names, and a
    /// 0-5 V tacho with one pulse per revolution at 1234 rpm.
    fn recording(rig: &RigConfig, fs: f64, seconds: f64) -> Recording {
        let n = (seconds * fs) as usize;
        let x: Vec<f32> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                ((std::f64::consts::TAU * 150.0 * t).sin()
                    + 0.5 * (std::f64::consts::TAU * 7000.0 * t).sin()) as f32
            })
            .collect();
        let rev = 60.0 / 1234.0;
        let tacho: Vec<f32> = (0..n)
            .map(|i| {
                let ph = (i as f64 / fs + 0.013) / rev;
                if ph - ph.floor() < 0.1 {
                    5.0
                } else {
                    0.0
                }
            })
            .collect();
        Recording {
            sample_rate: fs,
            start_time_ns: 0,
            channels: rig
                .acceleration_channels()
                .map(|c| Channel {
                    name: c.name.clone(),
                    axis: c.axis.clone(),
                    unit: c.unit.to_string(),
                    samples: x.clone(),
                })
                .collect(),
            tacho: Some(Tacho::Analog {
                samples: tacho,
                unit: "V".into(),
            }),
            rpm: None,
            nominal_rpm: None,
            provenance: Provenance {
                source_path: "test.wav".into(),
                ..Provenance::default()
            },
            metadata: Default::default(),
        }
    }

    const TACHO: &str = "[speed]\nsource = \"tacho\"\nchannel = \"tacho\"\npulses_per_rev = 1\nthreshold = 2.5\nhysteresis = 0.5\n";

    #[test]
    fn a_faster_recording_is_analysed_at_the_simulation_rate_with_the_same_speed() {
        let rig = rig(TACHO);
        assert_eq!(analysis_rate(&rig).unwrap(), 10_000.0);
        let mut rec = recording(&rig, 48_000.0, 2.0);
        let mean_rpm = |rec: &Recording| {
            crate::analysis::whole_recording(rec, &rig)
                .unwrap()
                .mean_rpm(0.0, rec.duration_s())
        };
        let rpm_before = mean_rpm(&rec);
        let edges = match &rec.tacho {
            Some(Tacho::Analog { samples, .. }) => {
                crate::dsp::tacho::detect_edges(samples, 48_000.0, 2.5, 0.5)
            }
            _ => unreachable!(),
        };
        assert_eq!(to_analysis_rate(&mut rec, &rig).unwrap(), 48_000.0);
        assert_eq!(rec.sample_rate, 10_000.0);
        assert_eq!(rec.len(), 20_000);
        assert!((rec.duration_s() - 2.0).abs() < 1e-12);
        // the tacho became the edges detected at 48 kHz: same track, same mean speed
        assert_eq!(rec.tacho, Some(Tacho::Edges { times_s: edges }));
        let rpm_after = mean_rpm(&rec);
        assert_eq!(rpm_after, rpm_before);
        assert!((rpm_after - 1234.0).abs() < 0.5, "{rpm_after}");
        // 150 Hz kept, 7 kHz (above the new Nyquist) gone, on every channel
        for c in &rec.channels {
            let ms = c.samples.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / 20_000.0;
            let rms = ms.sqrt();
            assert!((rms - 0.5f64.sqrt()).abs() < 0.005, "{}: rms {rms}", c.name);
        }
        assert!(rec.provenance.notes.iter().any(|n| n.contains("48000 Hz")));
    }

    #[test]
    fn a_recording_at_or_below_the_simulation_rate_is_left_untouched() {
        let rig = rig(TACHO);
        for fs in [10_000.0, 8_000.0] {
            let rec = recording(&rig, fs, 1.0);
            let mut same = rec.clone();
            assert_eq!(to_analysis_rate(&mut same, &rig).unwrap(), fs);
            assert_eq!(same, rec, "{fs} Hz");
        }
    }

    #[test]
    fn a_tacho_the_speed_source_does_not_read_is_dropped_when_it_has_no_levels() {
        // fixed speed: a flat tacho is irrelevant and goes; the rig reading it is an error
        let fixed = rig("[speed]\nsource = \"fixed\"\nrpm = 1234.0\n");
        let mut rec = recording(&fixed, 48_000.0, 1.0);
        rec.tacho = Some(Tacho::Analog {
            samples: vec![1.0; 48_000],
            unit: "V".into(),
        });
        to_analysis_rate(&mut rec, &fixed).unwrap();
        assert_eq!(rec.tacho, None);
        let stored = rig("[speed]\nsource = \"recording\"\n");
        let mut rec = recording(&stored, 48_000.0, 1.0);
        rec.tacho = Some(Tacho::Analog {
            samples: vec![1.0; 48_000],
            unit: "V".into(),
        });
        let e = format!("{:#}", to_analysis_rate(&mut rec, &stored).unwrap_err());
        assert!(
            e.contains("test.wav") && e.contains("no usable levels"),
            "{e}"
        );
    }
}
