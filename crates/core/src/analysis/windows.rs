//! Rolling windows on the sample clock: per-channel buffers fed by [`SampleBlock`]s, cut into
//! windows of `window_s` every `hop_s` (1 s / 0.5 s by default). Gaps on the sample clock
//! shorter than a window are filled with NaN (so the window is flagged, not silently
//! shifted); longer gaps restart the windowing. A sample clock that jumps backwards (a looping
//! replay, a restarted device) is folded onto a monotonic pipeline clock. A series of periodic
//! captures ([`Windower::capture_series`]) is the exception: there a forward jump is the time
//! between two captures, not lost samples, so it starts a new capture (windows never straddle
//! two captures) and is counted in `captures`, never in `samples_lost` or `gaps`.
//!
//! An analog tacho is turned into edge times as blocks arrive (a streaming Schmitt trigger),
//! so every window sees tacho edges on the pipeline clock, whatever form the tacho came in.
//! A window is handed out as soon as its own last sample has arrived, whatever its speed
//! source: a fixed, stored or estimated speed needs nothing else, and a tacho's speed is
//! taken from the edges known by the window's last sample (from one window before its start)
//! and extrapolated past the last of them (an analog edge is known once the sample that
//! confirms it has arrived; an edge delivered by the source, once the sample it falls in
//! has). So no window waits for signal past its end, and its edges, hence its speed and
//! features, do not depend on how the samples were cut into blocks: a whole recording and a
//! live stream give the same windows. What extrapolating costs against the speed from every
//! edge is measured in `tests/fast/features_identity.rs` (docs/benchmarks.md, "Latency").
//!
//! The buffers are allocated once (window + largest block) and slid with `copy_within`.

use crate::dsp::speed_config::SpeedConfig;
use crate::dsp::tacho::EdgeDetector;
use crate::recording::SampleBlock;
use std::collections::VecDeque;

/// Window length and hop in samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowSpec {
    pub sample_rate: f64,
    pub len: usize,
    pub hop: usize,
}

impl WindowSpec {
    pub fn new(sample_rate: f64, window_s: f64, hop_s: f64) -> anyhow::Result<Self> {
        let len = (window_s * sample_rate).round() as usize;
        let hop = (hop_s * sample_rate).round() as usize;
        if len < 16 || hop == 0 || hop > len {
            anyhow::bail!(
                "features.window_s = {window_s} and hop_s = {hop_s} at {sample_rate} Hz give {len} and {hop} samples; need a window of at least 16 samples and 0 < hop <= window"
            );
        }
        Ok(WindowSpec {
            sample_rate,
            len,
            hop,
        })
    }
}

/// Counters of the windower (reported in the status topic).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct WindowStats {
    pub samples_in: u64,
    /// Samples missing on the sample clock (filled with NaN or skipped).
    pub samples_lost: u64,
    pub gaps: u64,
    /// Windowing restarted (gap longer than a window, or the clock went backwards).
    pub restarts: u64,
    pub windows: u64,
    /// Captures started, in a series of periodic captures (0 for a continuous stream).
    #[serde(default)]
    pub captures: u64,
}

/// A complete window, borrowed from the buffers.
#[derive(Debug)]
pub struct WindowView<'a> {
    /// First sample of the window on the (monotonic) pipeline clock.
    pub first_sample: u64,
    /// Window start and end, s on the pipeline clock.
    pub t_start: f64,
    pub t_end: f64,
    /// One slice per source channel (rig acceleration channel order), `len` samples each.
    pub channels: Vec<&'a [f32]>,
    /// Tacho edges held by the windower: (time in s on the pipeline clock, pipeline-clock
    /// sample from which the edge is known). Read them with [`WindowView::edges`].
    pub edge_buffer: &'a VecDeque<(f64, u64)>,
    /// Edges known from this pipeline-clock sample on are not used (the window's end).
    pub edges_until: u64,
    /// Edges before this time (s) belong to earlier windows.
    pub edges_from: f64,
    /// Samples inside this window that were lost on the sample clock (NaN-filled).
    pub lost_samples: u32,
    /// Samples past the window's end that had arrived when it was handed out: the part of
    /// the block completing it that lies after its end (set by the source's block size, not
    /// by the analysis, which waits for none).
    pub after_end: u64,
}

impl WindowView<'_> {
    /// Tacho edge times (s, pipeline clock) from one window before the start, known by the
    /// window's last sample.
    pub fn edges(&self) -> impl Iterator<Item = f64> + '_ {
        let (from, end) = (self.edges_from, self.edges_until);
        self.edge_buffer
            .iter()
            .filter(move |&&(t, known)| t >= from && known < end)
            .map(|&(t, _)| t)
    }
}

/// Pipeline-clock sample from which an edge delivered by the source (time `t` s) is known:
/// the sample it falls in.
fn known_at(t: f64, fs: f64) -> u64 {
    (t * fs).floor().max(0.0) as u64
}

/// Per-channel sliding buffers.
#[derive(Debug)]
pub struct Windower {
    spec: WindowSpec,
    bufs: Vec<Vec<f32>>,
    /// Analog tacho switching levels (threshold, hysteresis), when the rig has one.
    tacho_levels: Option<(f64, f64)>,
    /// Edge detector for the analog tacho and the pipeline-clock sample it started at.
    detector: Option<(EdgeDetector, u64)>,
    new_edges: Vec<(f64, u64)>,
    edges: VecDeque<(f64, u64)>,
    /// Pipeline-clock index of `bufs[_][0]`.
    start: u64,
    /// Pipeline-clock index of the next expected sample (None before the first block).
    next: Option<u64>,
    /// Added to the source's sample index to get the pipeline clock.
    offset: i128,
    /// NaN-filled ranges (pipeline clock, [from, to)) still inside the buffers.
    holes: VecDeque<(u64, u64)>,
    stats: WindowStats,
    /// The stream is a series of captures: a forward jump starts the next capture.
    captures: bool,
}

impl Windower {
    /// `tacho_levels` = (threshold, hysteresis) of an analog tacho; blocks that carry analog
    /// tacho samples then have their edges detected here (blocks' own edge lists are used
    /// otherwise).
    pub fn new(spec: WindowSpec, n_channels: usize, tacho_levels: Option<(f64, f64)>) -> Self {
        let cap = spec.len * 2;
        Windower {
            spec,
            bufs: (0..n_channels).map(|_| Vec::with_capacity(cap)).collect(),
            tacho_levels,
            detector: None,
            new_edges: Vec::with_capacity(64),
            edges: VecDeque::with_capacity(256),
            start: 0,
            next: None,
            offset: 0,
            holes: VecDeque::new(),
            stats: WindowStats::default(),
            captures: false,
        }
    }

    /// Read the stream as a series of periodic captures: a forward jump of the sample clock
    /// is the time between two captures (a new capture, windowing restarted, nothing lost).
    pub fn capture_series(mut self) -> Self {
        self.captures = true;
        self
    }

    /// The windower a rig asks for: windows and hop from `[features]`, the analog tacho's
    /// switching levels when `[speed]` takes speed from one.
    pub fn for_rig(
        speed: &SpeedConfig,
        features: &crate::dsp::FeatureSettings,
        sample_rate: f64,
        n_channels: usize,
    ) -> anyhow::Result<Self> {
        let spec = WindowSpec::new(sample_rate, features.window_s, features.hop_s)?;
        Ok(Windower::new(spec, n_channels, speed.tacho_levels()))
    }

    pub fn spec(&self) -> WindowSpec {
        self.spec
    }

    pub fn stats(&self) -> WindowStats {
        self.stats
    }

    /// Pipeline-clock index of the next expected sample.
    pub fn next_sample(&self) -> Option<u64> {
        self.next
    }

    /// Add a block. Returns the number of samples found missing before it.
    pub fn push(&mut self, block: &SampleBlock) -> u64 {
        let n = block.len();
        if block.channels.len() != self.bufs.len() {
            // A source that changes its channel count mid-stream is a bug upstream; keep the
            // channels we know and NaN-fill the rest rather than crash the daemon.
            tracing::warn!(
                "block with {} channels, expected {}",
                block.channels.len(),
                self.bufs.len()
            );
        }
        let mut lost = 0;
        let pos = (block.first_sample as i128 + self.offset).max(0) as u64;
        let pos = match self.next {
            None => self.start_capture(pos),
            Some(next) if pos == next => pos,
            // The next capture: no window may hold samples of two captures.
            Some(next) if self.captures && pos > next => self.start_capture(pos),
            Some(next) if pos > next && pos - next < self.spec.len as u64 => {
                // Short gap: NaN-fill so the affected windows carry a dropout flag.
                let gap = pos - next;
                lost = gap;
                self.stats.gaps += 1;
                for b in &mut self.bufs {
                    b.resize(b.len() + gap as usize, f32::NAN);
                }
                // The edge detector's clock must skip the gap too.
                self.detector = None;
                self.holes.push_back((next, pos));
                pos
            }
            Some(next) => {
                // Long gap or clock going backwards: restart on the monotonic pipeline clock.
                if pos > next {
                    lost = pos - next;
                    self.stats.gaps += 1;
                } else {
                    // Backwards: continue the pipeline clock one hop after the last sample.
                    self.offset += next as i128 - pos as i128;
                }
                self.stats.restarts += 1;
                self.clear();
                let pos = (block.first_sample as i128 + self.offset) as u64;
                self.start = pos;
                pos
            }
        };
        self.stats.samples_lost += lost;
        self.stats.samples_in += n as u64;
        for (i, b) in self.bufs.iter_mut().enumerate() {
            match block.channels.get(i) {
                Some(c) if c.len() == n => b.extend_from_slice(c),
                _ => b.resize(b.len() + n, f32::NAN),
            }
        }
        let fs = self.spec.sample_rate;
        match (self.tacho_levels, &block.tacho_analog) {
            (Some((thr, hyst)), Some(a)) if a.len() == n => {
                let (det, origin) = self
                    .detector
                    .get_or_insert_with(|| (EdgeDetector::new(thr, hyst, fs), pos));
                self.new_edges.clear();
                det.push_indexed(a, &mut self.new_edges);
                let (origin, shift) = (*origin, *origin as f64 / fs);
                self.edges
                    .extend(self.new_edges.iter().map(|&(e, k)| (e + shift, origin + k)));
            }
            _ => {
                let shift = self.offset as f64 / fs;
                self.edges.extend(block.tacho_edges.iter().map(|&e| {
                    let t = e + shift;
                    (t, known_at(t, fs))
                }));
            }
        }
        self.next = Some(pos + n as u64);
        lost
    }

    /// Start windowing afresh at `pos`: the first block, or the next capture of a series.
    fn start_capture(&mut self, pos: u64) -> u64 {
        self.stats.captures += u64::from(self.captures);
        self.clear();
        self.start = pos;
        pos
    }

    fn clear(&mut self) {
        for b in &mut self.bufs {
            b.clear();
        }
        self.detector = None;
        self.edges.clear();
        self.holes.clear();
    }

    /// The next complete window, if the buffers hold one. Call [`Windower::advance`] after
    /// using it.
    pub fn window(&self) -> Option<WindowView<'_>> {
        let len = self.spec.len;
        let held = self.bufs.first().map_or(0, |b| b.len());
        if held < len {
            return None;
        }
        let end = self.start + len as u64;
        let lost: u64 = self
            .holes
            .iter()
            .map(|&(a, b)| b.min(end).saturating_sub(a.max(self.start)))
            .sum();
        let fs = self.spec.sample_rate;
        Some(WindowView {
            first_sample: self.start,
            t_start: self.start as f64 / fs,
            t_end: end as f64 / fs,
            channels: self.bufs.iter().map(|b| &b[..len]).collect(),
            edge_buffer: &self.edges,
            edges_until: end,
            edges_from: self.edges_from(self.start),
            lost_samples: lost as u32,
            after_end: (held - len) as u64,
        })
    }

    /// Slide by one hop (after a window was taken).
    pub fn advance(&mut self) {
        let hop = self.spec.hop;
        for b in self.bufs.iter_mut() {
            let n = b.len();
            if n >= hop {
                b.copy_within(hop.., 0);
                b.truncate(n - hop);
            } else {
                b.clear();
            }
        }
        self.start += hop as u64;
        self.stats.windows += 1;
        while self.holes.front().is_some_and(|&(_, b)| b <= self.start) {
            self.holes.pop_front();
        }
        // Keep one window of edges before the start for speed at the window's beginning.
        let keep_from = self.edges_from(self.start);
        while self.edges.front().is_some_and(|&(e, _)| e < keep_from) {
            self.edges.pop_front();
        }
    }

    /// Edges a window starting at `start` uses begin one window before it (s).
    fn edges_from(&self, start: u64) -> f64 {
        let fs = self.spec.sample_rate;
        start as f64 / fs - self.spec.len as f64 / fs
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(first: u64, n: usize, value: f32) -> SampleBlock {
        SampleBlock {
            first_sample: first,
            sample_rate: 100.0,
            channels: vec![
                vec![value; n],
                (0..n).map(|i| (first + i as u64) as f32).collect(),
            ],
            tacho_analog: None,
            tacho_edges: vec![first as f64 / 100.0],
        }
    }

    #[test]
    fn windows_every_hop_handed_out_with_the_block_that_completes_them() {
        let spec = WindowSpec::new(100.0, 1.0, 0.5).unwrap();
        let mut w = Windower::new(spec, 2, None);
        let mut starts = Vec::new();
        for k in 0..10 {
            w.push(&block(k * 30, 30, 1.0));
            let arrived = (k + 1) * 30;
            while let Some(v) = w.window() {
                assert_eq!(
                    v.channels[1][0], v.first_sample as f32,
                    "window content follows the clock"
                );
                assert_eq!(v.channels[1].len(), 100);
                // Handed out with the first block that reached its end, not one later.
                let end = v.first_sample + 100;
                assert_eq!(v.after_end, arrived - end, "window at {}", v.first_sample);
                assert!(v.after_end < 30, "window at {}", v.first_sample);
                starts.push(v.first_sample);
                w.advance();
            }
        }
        assert_eq!(starts, [0, 50, 100, 150, 200]);
        assert_eq!(w.stats().samples_lost, 0);
    }

    #[test]
    fn no_speed_source_makes_a_window_wait_past_its_end() {
        use crate::dsp::FeatureSettings;
        let features = FeatureSettings {
            window_s: 1.0,
            hop_s: 0.5,
            ..FeatureSettings::default()
        };
        let speeds = [
            r#"source = "tacho"
channel = "tacho""#,
            r#"source = "edges""#,
            r#"source = "fixed"
rpm = 600.0"#,
            r#"source = "recording""#,
            r#"source = "estimate""#,
        ];
        for text in speeds {
            let speed: SpeedConfig = toml::from_str(text).unwrap();
            let mut w = Windower::for_rig(&speed, &features, 100.0, 2).unwrap();
            // Blocks of one hop, with an analog tacho and delivered edges: each block ending
            // on a window's end hands that window out at once, with nothing past its end.
            let mut got = Vec::new();
            for k in 0..8u64 {
                let mut b = block(k * 50, 50, 1.0);
                b.tacho_analog = Some((0..50).map(|i| [0.0, 5.0][i % 10 / 5]).collect());
                w.push(&b);
                while let Some(v) = w.window() {
                    got.push((k, v.first_sample, v.after_end));
                    w.advance();
                }
            }
            let want: Vec<(u64, u64, u64)> = (1..8).map(|k| (k, (k - 1) * 50, 0)).collect();
            assert_eq!(got, want, "{text}");
        }
    }

    #[test]
    fn short_gap_is_nan_filled_and_counted() {
        let spec = WindowSpec::new(100.0, 1.0, 0.5).unwrap();
        let mut w = Windower::new(spec, 2, None);
        w.push(&block(0, 60, 1.0));
        assert_eq!(w.push(&block(70, 60, 1.0)), 10);
        let v = w.window().unwrap();
        assert_eq!(v.lost_samples, 10);
        assert!(v.channels[0][60..70].iter().all(|x| x.is_nan()));
        assert_eq!(v.channels[1][70], 70.0);
        w.advance();
        let v = w.window();
        assert!(v.is_none(), "only 130 samples so far");
        w.push(&block(130, 40, 1.0));
        let v = w.window().unwrap();
        assert_eq!((v.first_sample, v.lost_samples), (50, 10));
        w.advance();
        w.push(&block(170, 100, 1.0));
        let v = w.window().unwrap();
        assert_eq!((v.first_sample, v.lost_samples), (100, 0));
    }

    #[test]
    fn long_gap_and_backwards_clock_restart() {
        let spec = WindowSpec::new(100.0, 1.0, 0.5).unwrap();
        let mut w = Windower::new(spec, 2, None);
        w.push(&block(0, 80, 1.0));
        assert_eq!(w.push(&block(500, 100, 2.0)), 420);
        let v = w.window().unwrap();
        assert_eq!(v.first_sample, 500);
        assert_eq!(v.lost_samples, 0);
        assert!(v.channels[0].iter().all(|&x| x == 2.0));
        w.advance();
        // A looping replay starts again at sample 0: the pipeline clock keeps going.
        w.push(&block(0, 100, 3.0));
        let v = w.window().unwrap();
        assert_eq!(v.first_sample, 600);
        let e: Vec<f64> = v.edges().collect();
        assert!(
            (e[0] - 6.0).abs() < 1e-9,
            "edges follow the folded clock: {e:?}"
        );
        assert_eq!(w.stats().restarts, 2);
    }

    #[test]
    fn captures_restart_the_windows_and_lose_nothing() {
        let spec = WindowSpec::new(100.0, 0.5, 0.25).unwrap();
        let mut w = Windower::new(spec, 2, None).capture_series();
        w.push(&block(0, 80, 1.0));
        let mut firsts = Vec::new();
        while let Some(v) = w.window() {
            firsts.push(v.first_sample);
            w.advance();
        }
        // 10 s later, the next capture: a short jump would be NaN-filled in a stream.
        assert_eq!(w.push(&block(1000, 80, 2.0)), 0);
        while let Some(v) = w.window() {
            assert!(
                v.channels[0].iter().all(|&x| x == 2.0),
                "straddles two captures"
            );
            assert_eq!(v.lost_samples, 0);
            firsts.push(v.first_sample);
            w.advance();
        }
        // And a capture 70 samples after the last one ended: shorter than a window.
        w.push(&block(1150, 80, 3.0));
        while let Some(v) = w.window() {
            assert!(
                v.channels[0].iter().all(|&x| x == 3.0),
                "straddles two captures"
            );
            firsts.push(v.first_sample);
            w.advance();
        }
        assert_eq!(firsts, vec![0, 25, 1000, 1025, 1150, 1175]);
        let s = w.stats();
        assert_eq!((s.samples_lost, s.gaps, s.captures), (0, 0, 3));
    }

    #[test]
    fn analog_tacho_edges_land_on_the_pipeline_clock() {
        let spec = WindowSpec::new(100.0, 1.0, 0.5).unwrap();
        let mut w = Windower::new(spec, 2, Some((2.5, 0.5)));
        for k in 0..4u64 {
            let mut b = block(k * 50, 50, 1.0);
            b.tacho_edges.clear();
            // A pulse every 25 samples, rising at sample 10 of each pulse period.
            b.tacho_analog = Some(
                (0..50)
                    .map(|i| {
                        if (k * 50 + i) % 25 >= 10 && (k * 50 + i) % 25 < 15 {
                            5.0
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            );
            w.push(&b);
        }
        let v = w.window().unwrap();
        let e: Vec<f64> = v.edges().collect();
        // Only the edges known by the window's last sample (100 samples = 4 pulses), although
        // the buffers already hold 200 samples.
        assert_eq!(e.len(), 4, "{e:?}");
        // Crossing of 2.5 V between samples 9 (0 V) and 10 (5 V): 9.5 samples.
        assert!(
            (e[0] - 0.095).abs() < 1e-9 && (e[1] - 0.345).abs() < 1e-9,
            "{e:?}"
        );
    }

    /// Every window's tacho edges, with an analog tacho cut into blocks of `n` samples.
    fn window_edges(n: usize) -> Vec<(u64, Vec<f64>)> {
        let spec = WindowSpec::new(100.0, 1.0, 0.5).unwrap();
        let mut w = Windower::new(spec, 1, Some((2.5, 0.5)));
        // a pulse every 13 samples, rising over samples 4..6
        let tacho: Vec<f32> = (0..400)
            .map(|i| [0.0, 0.0, 0.0, 0.0, 2.0, 4.0, 5.0, 5.0][(i % 13).min(7)])
            .collect();
        let mut out = Vec::new();
        let mut drain = |w: &mut Windower| {
            while let Some(v) = w.window() {
                out.push((v.first_sample, v.edges().collect::<Vec<f64>>()));
                w.advance();
            }
        };
        for (k, a) in tacho.chunks(n).enumerate() {
            w.push(&SampleBlock {
                first_sample: (k * n) as u64,
                sample_rate: 100.0,
                channels: vec![vec![1.0; a.len()]],
                tacho_analog: Some(a.to_vec()),
                tacho_edges: Vec::new(),
            });
            drain(&mut w);
        }
        out
    }

    #[test]
    fn window_edges_end_with_the_window_whatever_the_blocks() {
        let whole = window_edges(400);
        assert_eq!(whole.len(), 7);
        for n in [1, 7, 50, 64, 150] {
            assert_eq!(window_edges(n), whole, "blocks of {n}");
        }
        // The window [100, 200) sees the edges from sample 0 confirmed by its last sample:
        // each crosses 2.5 V at 13 k + 4.25 and is confirmed (>= 3 V) at 13 k + 5, so the
        // crossing at 199.25, confirmed at 200, belongs to the next window.
        let (first, e) = &whole[2];
        assert_eq!(*first, 100);
        let want: Vec<f64> = (0..20)
            .filter(|k| 13 * k + 5 < 200)
            .map(|k| ((13 * k) as f64 + 4.25) / 100.0)
            .collect();
        assert_eq!(e.len(), want.len(), "{e:?}");
        assert_eq!(want.len(), 15);
        for (a, b) in e.iter().zip(&want) {
            assert!((a - b).abs() < 1e-9, "{e:?} vs {want:?}");
        }
    }
}
