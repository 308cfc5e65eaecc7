//! The quality flags of a health message (`quality.flags`): why a window's data cannot be
//! trusted (`nan`, `dropout`, `clipping`, `flat`, `no_speed`, `tacho_lost`, ...) or an
//! advisory finding (`dc_offset`, `speed_ambiguous`, `missing_tacho_pulses`). The names are
//! the message's, the historian's and the verdict's `unknown_reason` detail.

use serde::{Deserialize, Serialize};
use std::fmt;

/// One quality flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QualityFlag {
    /// Non-finite samples (NaN/Inf) in the window.
    Nan,
    /// Samples lost on the sample clock, or a channel that stopped moving inside a signal.
    Dropout,
    /// A channel's peaks sit flat at its extreme value.
    Clipping,
    /// A channel with no signal at all.
    Flat,
    /// No speed for the window.
    NoSpeed,
    /// The feature pipeline failed on the window.
    FeaturesFailed,
    /// The classifier failed on the window's features.
    InferenceFailed,
    /// Tacho pulses stopped inside the window.
    TachoLost,
    /// A speed the recipe cannot resolve, or outside the configured range.
    SpeedOutOfRange,
    /// The speed read from the vibration is not known well enough.
    SpeedUncertain,
    /// Half or twice the speed explains the spectrum nearly as well (advisory).
    SpeedAmbiguous,
    /// A channel's mean exceeds its AC RMS (advisory).
    DcOffset,
    /// Tacho pulses were missing and inserted (advisory).
    MissingTachoPulses,
}

impl QualityFlag {
    pub const ALL: [QualityFlag; 13] = [
        QualityFlag::Nan,
        QualityFlag::Dropout,
        QualityFlag::Clipping,
        QualityFlag::Flat,
        QualityFlag::NoSpeed,
        QualityFlag::FeaturesFailed,
        QualityFlag::InferenceFailed,
        QualityFlag::TachoLost,
        QualityFlag::SpeedOutOfRange,
        QualityFlag::SpeedUncertain,
        QualityFlag::SpeedAmbiguous,
        QualityFlag::DcOffset,
        QualityFlag::MissingTachoPulses,
    ];

    /// The flag's name (serde name).
    pub const fn as_str(self) -> &'static str {
        match self {
            QualityFlag::Nan => "nan",
            QualityFlag::Dropout => "dropout",
            QualityFlag::Clipping => "clipping",
            QualityFlag::Flat => "flat",
            QualityFlag::NoSpeed => "no_speed",
            QualityFlag::FeaturesFailed => "features_failed",
            QualityFlag::InferenceFailed => "inference_failed",
            QualityFlag::TachoLost => "tacho_lost",
            QualityFlag::SpeedOutOfRange => "speed_out_of_range",
            QualityFlag::SpeedUncertain => "speed_uncertain",
            QualityFlag::SpeedAmbiguous => "speed_ambiguous",
            QualityFlag::DcOffset => "dc_offset",
            QualityFlag::MissingTachoPulses => "missing_tacho_pulses",
        }
    }

    /// The flag a name means; None for another name.
    pub fn parse(name: &str) -> Option<QualityFlag> {
        QualityFlag::ALL.into_iter().find(|f| f.as_str() == name)
    }
}

impl fmt::Display for QualityFlag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_the_serde_names_and_parse_back() {
        for f in QualityFlag::ALL {
            let json = serde_json::to_string(&f).unwrap();
            assert_eq!(json, format!("\"{}\"", f.as_str()));
            assert_eq!(serde_json::from_str::<QualityFlag>(&json).unwrap(), f);
            assert_eq!(QualityFlag::parse(f.as_str()), Some(f));
        }
        let names: std::collections::BTreeSet<_> =
            QualityFlag::ALL.iter().map(|f| f.as_str()).collect();
        assert_eq!(names.len(), QualityFlag::ALL.len());
        assert_eq!(QualityFlag::parse("clipped"), None);
    }
}
