//! A recording made of periodic captures (snapshots: 0.1 s every 10 s, say) held whole: its
//! samples are the captures one after the other, and its metadata says where each capture
//! starts in them and on the sample clock (the capture's time since the first capture, in
//! samples). Analysis feeds each capture at its own time, so the time between captures is a
//! gap on the clock, never lost samples, and no window straddles two captures.

use super::Recording;
use std::collections::BTreeMap;

/// Metadata key: the interval between captures, s, and the mark of a capture series.
pub const META_CAPTURE_INTERVAL: &str = "capture_interval_s";
/// Metadata key: where each capture starts, `index:clock` pairs separated by spaces.
pub const META_CAPTURE_STARTS: &str = "capture_starts";

/// Where one capture starts: sample index in the channel vectors, and sample-clock index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CaptureStart {
    pub index: u64,
    pub clock: u64,
}

/// A stretch of a capture-series recording: samples `[start, end)` of the channels, the first
/// of them at `clock` on the sample clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CaptureSpan {
    pub start: usize,
    pub end: usize,
    pub clock: u64,
}

/// Whether metadata marks a series of captures.
pub fn is_capture_series(metadata: &BTreeMap<String, String>) -> bool {
    metadata.contains_key(META_CAPTURE_INTERVAL)
}

/// Write where each capture starts into the metadata.
pub fn write_starts(metadata: &mut BTreeMap<String, String>, starts: &[CaptureStart]) {
    let text: Vec<String> = starts
        .iter()
        .map(|s| format!("{}:{}", s.index, s.clock))
        .collect();
    metadata.insert(META_CAPTURE_STARTS.into(), text.join(" "));
}

/// The captures of a recording as spans on its sample clock: one span from 0 for a
/// continuous recording. Starts that do not rise, or lie past the samples, are an error
/// naming the pair.
pub fn spans(rec: &Recording) -> Result<Vec<CaptureSpan>, String> {
    let n = rec.len();
    let Some(text) = rec.metadata.get(META_CAPTURE_STARTS) else {
        return Ok(vec![CaptureSpan {
            start: 0,
            end: n,
            clock: 0,
        }]);
    };
    let mut starts = Vec::new();
    for (k, pair) in text.split_whitespace().enumerate() {
        let parsed = pair
            .split_once(':')
            .and_then(|(i, c)| Some((i.parse::<u64>().ok()?, c.parse::<u64>().ok()?)));
        let Some((index, clock)) = parsed else {
            return Err(format!(
                "metadata {META_CAPTURE_STARTS}: entry {k} ({pair:?}) is not index:clock"
            ));
        };
        if let Some(&(i0, c0)) = starts.last() {
            if index <= i0 || clock < c0 + (index - i0) {
                return Err(format!(
                    "metadata {META_CAPTURE_STARTS}: capture {k} ({pair:?}) does not start after capture {} ends",
                    k - 1
                ));
            }
        }
        if index as usize >= n {
            return Err(format!(
                "metadata {META_CAPTURE_STARTS}: capture {k} starts at sample {index}, past the {n} samples"
            ));
        }
        starts.push((index, clock));
    }
    let mut out = Vec::with_capacity(starts.len());
    for (k, &(index, clock)) in starts.iter().enumerate() {
        let end = starts.get(k + 1).map_or(n, |s| s.0 as usize);
        out.push(CaptureSpan {
            start: index as usize,
            end,
            clock,
        });
    }
    if out.first().is_some_and(|s| s.start != 0) {
        return Err(format!(
            "metadata {META_CAPTURE_STARTS}: the first capture starts at sample {}, not 0",
            out[0].start
        ));
    }
    Ok(out)
}

/// The time line a cut's times are on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timeline {
    /// The capture clock: time since the first capture, gaps between captures included (a
    /// manifest row's `start_s`/`end_s`).
    Clock,
    /// The signal: the captures' samples one after the other, gaps left out (seconds of
    /// signal, as `Recording::duration_s` counts them).
    Signal,
}

/// Keep the captures that start in `[t0, t0 + seconds)` of a capture-series recording (times
/// on its clock: since the first capture), the first kept at time 0. Returns false (and
/// leaves the recording alone) when it is not a capture series.
pub fn cut(rec: &mut Recording, t0: f64, seconds: f64) -> bool {
    cut_on(rec, t0, seconds, Timeline::Clock)
}

/// [`cut`] with the times on `timeline`.
pub fn cut_on(rec: &mut Recording, t0: f64, seconds: f64, timeline: Timeline) -> bool {
    if !is_capture_series(&rec.metadata) {
        return false;
    }
    let Ok(all) = spans(rec) else {
        return false;
    };
    let fs = rec.sample_rate;
    let t1 = t0 + seconds;
    let kept: Vec<CaptureSpan> = all
        .into_iter()
        .filter(|s| {
            let at = match timeline {
                Timeline::Clock => s.clock,
                Timeline::Signal => s.start as u64,
            };
            let t = at as f64 / fs;
            t >= t0 && t < t1
        })
        .collect();
    for c in &mut rec.channels {
        let mut samples = Vec::with_capacity(kept.iter().map(|s| s.end - s.start).sum());
        for s in &kept {
            samples.extend_from_slice(&c.samples[s.start..s.end]);
        }
        c.samples = samples;
    }
    let origin = kept.first().map_or(0, |s| s.clock);
    let mut index = 0;
    let starts: Vec<CaptureStart> = kept
        .iter()
        .map(|s| {
            let start = CaptureStart {
                index,
                clock: s.clock - origin,
            };
            index += (s.end - s.start) as u64;
            start
        })
        .collect();
    write_starts(&mut rec.metadata, &starts);
    true
}

/// Each capture of a capture-series recording as a recording of its own (no capture
/// metadata left; an analog tacho cut with it); None when it is not a capture series.
pub fn pieces(rec: &Recording) -> Option<Vec<Recording>> {
    if !is_capture_series(&rec.metadata) {
        return None;
    }
    let all = spans(rec).ok()?;
    let mut metadata = rec.metadata.clone();
    metadata.remove(META_CAPTURE_INTERVAL);
    metadata.remove(META_CAPTURE_STARTS);
    let step_ns = 1e9 / rec.sample_rate;
    let piece = |s: &CaptureSpan| Recording {
        sample_rate: rec.sample_rate,
        start_time_ns: rec.start_time_ns + (s.clock as f64 * step_ns) as u64,
        channels: rec
            .channels
            .iter()
            .map(|c| super::Channel {
                name: c.name.clone(),
                axis: c.axis.clone(),
                unit: c.unit.clone(),
                samples: c.samples[s.start..s.end].to_vec(),
            })
            .collect(),
        tacho: match &rec.tacho {
            Some(super::Tacho::Analog { samples, unit }) => Some(super::Tacho::Analog {
                samples: samples[s.start.min(samples.len())..s.end.min(samples.len())].to_vec(),
                unit: unit.clone(),
            }),
            _ => None,
        },
        rpm: rec.rpm,
        nominal_rpm: rec.nominal_rpm.clone(),
        provenance: rec.provenance.clone(),
        metadata: metadata.clone(),
    };
    Some(all.iter().map(piece).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::{Channel, Provenance};

    fn rec(n: usize) -> Recording {
        Recording {
            sample_rate: 100.0,
            start_time_ns: 0,
            channels: vec![Channel {
                name: "x".into(),
                axis: "vertical".into(),
                unit: "g".into(),
                samples: vec![0.0; n],
            }],
            tacho: None,
            rpm: None,
            nominal_rpm: None,
            provenance: Provenance::default(),
            metadata: BTreeMap::new(),
        }
    }

    #[test]
    fn starts_round_trip_and_bad_ones_are_named() {
        let mut r = rec(30);
        assert_eq!(spans(&r).unwrap().len(), 1);
        let starts = [
            CaptureStart { index: 0, clock: 0 },
            CaptureStart {
                index: 10,
                clock: 1000,
            },
            CaptureStart {
                index: 20,
                clock: 2000,
            },
        ];
        write_starts(&mut r.metadata, &starts);
        let s = spans(&r).unwrap();
        assert_eq!(
            s.iter()
                .map(|s| (s.start, s.end, s.clock))
                .collect::<Vec<_>>(),
            vec![(0, 10, 0), (10, 20, 1000), (20, 30, 2000)]
        );
        r.metadata
            .insert(META_CAPTURE_STARTS.into(), "0:0 10:5".into());
        assert!(spans(&r).unwrap_err().contains("capture 1"));
        r.metadata
            .insert(META_CAPTURE_STARTS.into(), "0:0 40:900".into());
        assert!(spans(&r).unwrap_err().contains("past the 30 samples"));
    }

    /// Samples 0..30 as three captures of 10 samples at 0, 10 and 20 s on the clock.
    fn make_series(r: &mut Recording) {
        r.metadata.insert(META_CAPTURE_INTERVAL.into(), "10".into());
        let starts: Vec<CaptureStart> = (0..3)
            .map(|k| CaptureStart {
                index: 10 * k,
                clock: 1000 * k,
            })
            .collect();
        write_starts(&mut r.metadata, &starts);
    }

    #[test]
    fn a_cut_keeps_the_captures_starting_inside_it() {
        let mut r = rec(30);
        r.channels[0].samples = (0..30).map(|i| i as f32).collect();
        assert!(!cut(&mut r.clone(), 0.0, 1.0), "not a series: left alone");
        make_series(&mut r);
        // Captures at 0, 10 and 20 s: [5 s, 25 s) keeps the last two.
        assert!(cut(&mut r, 5.0, 20.0));
        assert_eq!(r.channels[0].samples[0], 10.0);
        assert_eq!(r.len(), 20);
        let s = spans(&r).unwrap();
        assert_eq!(
            s.iter()
                .map(|s| (s.start, s.end, s.clock))
                .collect::<Vec<_>>(),
            vec![(0, 10, 0), (10, 20, 1000)]
        );
    }

    #[test]
    fn a_cut_on_the_signal_counts_samples_and_pieces_are_the_captures() {
        let mut r = rec(30);
        r.channels[0].samples = (0..30).map(|i| i as f32).collect();
        assert!(pieces(&r).is_none(), "not a series");
        make_series(&mut r);
        // 0.3 s of signal (100 Hz): the second half of it, [0.15 s, 0.3 s), holds the capture
        // that starts at sample 20 only; on the clock that span holds none.
        let mut on_clock = r.clone();
        assert!(cut_on(&mut on_clock, 0.15, 0.15, Timeline::Clock));
        assert_eq!(on_clock.len(), 0);
        let mut on_signal = r.clone();
        assert!(cut_on(&mut on_signal, 0.15, 0.15, Timeline::Signal));
        assert_eq!(on_signal.channels[0].samples[0], 20.0);
        assert_eq!(on_signal.len(), 10);
        let p = pieces(&r).unwrap();
        assert_eq!(p.len(), 3);
        assert_eq!(
            p[1].channels[0].samples,
            (10..20).map(|i| i as f32).collect::<Vec<_>>()
        );
        assert!(!is_capture_series(&p[1].metadata));
        assert_eq!(
            p[2].start_time_ns, 20_000_000_000,
            "the capture's time on the clock"
        );
    }
}
