//! What reading a recording could not deliver ([`Losses`]): gaps on the sample clock (blocks
//! the writer never wrote, or data in a damaged stretch of the file that was skipped), the
//! damaged stretches themselves (where in the file, and why), and a tail cut off. Each comes
//! with samples and seconds, for the stderr line ([`Losses::line`]), the `import`/`replay`
//! summaries and their JSON.

use serde::{Deserialize, Serialize};

/// Why samples are missing between two readable blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GapCause {
    /// A damaged stretch of the file was skipped here.
    Damaged,
    /// The file is intact but holds no blocks here: the writer never wrote them (a recorder
    /// that fell behind and dropped blocks, a source that lost samples).
    NotRecorded,
}

impl GapCause {
    /// Words for logs.
    pub fn text(&self) -> &'static str {
        match self {
            GapCause::Damaged => "a damaged stretch of the file skipped",
            GapCause::NotRecorded => "not in the file: its writer never wrote them",
        }
    }
}

/// Samples missing on the sample clock between two readable blocks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gap {
    /// First missing sample (index since the recording start) and when it was, s.
    pub first_sample: u64,
    pub at_s: f64,
    pub samples: u64,
    pub seconds: f64,
    pub cause: GapCause,
}

/// A stretch of the file that could not be read and was skipped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Damage {
    /// Byte offset in the file and length of the stretch.
    pub at_byte: u64,
    pub bytes: u64,
    /// What was wrong ("chunk CRC mismatch", "record length runs past the end", ...).
    pub what: String,
}

/// The file ends before its end record: cut short (copied while written, a writer killed
/// before it could close the file, a disk that filled up) or damaged up to its end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truncation {
    /// Where the unreadable rest starts and the file's size, bytes.
    pub at_byte: u64,
    pub file_bytes: u64,
    /// Samples readable before it (per channel) and their duration, s.
    pub readable_samples: u64,
    pub readable_s: f64,
    /// Samples known to be lost after them (from the time span the cut chunk's header
    /// declares), when the header is legible: the loss is at least this.
    pub lost_samples_at_least: u64,
    pub lost_s_at_least: f64,
    pub what: String,
}

/// Everything a reader could not deliver.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Losses {
    pub gaps: Vec<Gap>,
    pub damaged: Vec<Damage>,
    pub truncated: Option<Truncation>,
    /// Samples (per channel) dropped because not every channel had them (channels ending at
    /// different samples, a block missing on one channel only).
    #[serde(default)]
    pub unmatched_samples: u64,
}

/// [`Losses`] with their totals and the one-line summary, as reported in the `import` and
/// `replay` summaries (text and JSON) and the daemon's status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LossReport {
    /// Samples per channel and seconds known to be lost.
    pub samples_lost: u64,
    pub seconds_lost: f64,
    /// [`Losses::line`].
    pub summary: String,
    #[serde(flatten)]
    pub losses: Losses,
}

impl Losses {
    /// The report of these losses at `sample_rate`.
    pub fn report(&self, sample_rate: f64) -> LossReport {
        LossReport {
            samples_lost: self.samples_lost(),
            seconds_lost: self.seconds_lost(sample_rate),
            summary: self.line(sample_rate),
            losses: self.clone(),
        }
    }

    /// Nothing was lost.
    pub fn is_empty(&self) -> bool {
        self.gaps.is_empty()
            && self.damaged.is_empty()
            && self.truncated.is_none()
            && self.unmatched_samples == 0
    }

    /// Samples per channel lost in gaps (on the sample clock).
    pub fn gap_samples(&self) -> u64 {
        self.gaps.iter().map(|g| g.samples).sum()
    }

    /// Samples per channel known to be lost: gaps, the known part of a cut tail, and samples
    /// dropped because not every channel had them.
    pub fn samples_lost(&self) -> u64 {
        self.gap_samples()
            + self
                .truncated
                .as_ref()
                .map_or(0, |t| t.lost_samples_at_least)
            + self.unmatched_samples
    }

    /// [`Losses::samples_lost`] in seconds at `sample_rate`.
    pub fn seconds_lost(&self, sample_rate: f64) -> f64 {
        self.samples_lost() as f64 / sample_rate
    }

    /// Record a gap of `samples` before sample `first + samples`.
    pub fn add_gap(&mut self, first: u64, samples: u64, sample_rate: f64, cause: GapCause) {
        if samples == 0 {
            return;
        }
        // Two gaps with no samples between them are one stretch of missing samples.
        if let Some(g) = self.gaps.last_mut() {
            if g.first_sample + g.samples == first {
                g.samples += samples;
                g.seconds = g.samples as f64 / sample_rate;
                if cause == GapCause::Damaged {
                    g.cause = GapCause::Damaged;
                }
                return;
            }
        }
        self.gaps.push(Gap {
            first_sample: first,
            at_s: first as f64 / sample_rate,
            samples,
            seconds: samples as f64 / sample_rate,
            cause,
        });
    }

    /// One line for stderr and the provenance: what was lost, where, and how much.
    pub fn line(&self, sample_rate: f64) -> String {
        let mut parts = Vec::new();
        let gap_s: f64 = self.gaps.iter().map(|g| g.seconds).sum();
        if !self.damaged.is_empty() {
            let first = &self.damaged[0];
            parts.push(format!(
                "{} damaged stretch(es) skipped (first at byte {}: {})",
                self.damaged.len(),
                first.at_byte,
                first.what
            ));
        }
        if !self.gaps.is_empty() {
            let listed: Vec<String> = self
                .gaps
                .iter()
                .take(3)
                .map(|g| {
                    format!(
                        "{:.3} s at {:.3} s{}",
                        g.seconds,
                        g.at_s,
                        match g.cause {
                            GapCause::Damaged => " (damaged)",
                            GapCause::NotRecorded => " (not recorded)",
                        }
                    )
                })
                .collect();
            parts.push(format!(
                "{} gap(s) on the sample clock, {:.3} s ({} samples) lost: {}{}",
                self.gaps.len(),
                gap_s,
                self.gap_samples(),
                listed.join(", "),
                if self.gaps.len() > 3 { ", ..." } else { "" }
            ));
        }
        if let Some(t) = &self.truncated {
            let lost = if t.lost_samples_at_least > 0 {
                format!(
                    "at least {:.3} s ({} samples) lost after it",
                    t.lost_s_at_least, t.lost_samples_at_least
                )
            } else {
                "what followed is unknown".to_string()
            };
            parts.push(format!(
                "cut short at byte {} of {} ({}): readable up to {:.3} s, {lost}",
                t.at_byte, t.file_bytes, t.what, t.readable_s
            ));
        }
        if self.unmatched_samples > 0 {
            parts.push(format!(
                "{} samples ({:.3} s) dropped because not every channel had them",
                self.unmatched_samples,
                self.unmatched_samples as f64 / sample_rate
            ));
        }
        format!(
            "{}; {:.3} s ({} samples per channel) known lost",
            parts.join("; "),
            self.seconds_lost(sample_rate),
            self.samples_lost()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_names_each_loss_with_seconds_and_samples() {
        let mut l = Losses::default();
        assert!(l.is_empty());
        l.add_gap(32_000, 16_000, 10_000.0, GapCause::Damaged);
        l.damaged.push(Damage {
            at_byte: 300_000,
            bytes: 266_000,
            what: "chunk CRC mismatch".into(),
        });
        l.truncated = Some(Truncation {
            at_byte: 600_000,
            file_bytes: 610_000,
            readable_samples: 64_000,
            readable_s: 6.4,
            lost_samples_at_least: 15_000,
            lost_s_at_least: 1.5,
            what: "a chunk cut short".into(),
        });
        assert_eq!(l.samples_lost(), 31_000);
        let line = l.line(10_000.0);
        for want in [
            "byte 300000: chunk CRC mismatch",
            "1.600 s (16000 samples) lost: 1.600 s at 3.200 s (damaged)",
            "cut short at byte 600000 of 610000",
            "at least 1.500 s (15000 samples)",
            "3.100 s (31000 samples per channel) known lost",
        ] {
            assert!(line.contains(want), "{want:?} not in {line}");
        }
    }
}
