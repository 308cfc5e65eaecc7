//! Acceleration units: one table of the accepted spellings (matched ignoring case, spaces and
//! a superscript two), the factor to m/s^2 of each, and a channel's unit as the rig file wrote
//! it with the acceleration unit parsed once when the file is read.
//!
//! File formats keep the spelling they had: a [`ChannelUnit`] serializes to the text it was
//! read from (rig TOML, MCAP channel metadata, WAV/CSV sidecars), an [`AccelUnit`] to its
//! canonical spelling.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::str::FromStr;

/// Standard gravity, m/s^2 (the `g` of accelerometer data sheets).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// A unit of acceleration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AccelUnit {
    /// m/s^2.
    MetrePerSecondSquared,
    /// mm/s^2.
    MillimetrePerSecondSquared,
    /// Standard gravity, g (9.80665 m/s^2).
    StandardGravity,
}

/// Every accepted spelling, normalised (lower case, no spaces, `²` read as `2`), and its unit.
/// The first spelling of each unit is its canonical one.
const SPELLINGS: [(&str, AccelUnit); 9] = [
    ("m/s^2", AccelUnit::MetrePerSecondSquared),
    ("m/s2", AccelUnit::MetrePerSecondSquared),
    ("m*s^-2", AccelUnit::MetrePerSecondSquared),
    ("ms^-2", AccelUnit::MetrePerSecondSquared),
    ("mm/s^2", AccelUnit::MillimetrePerSecondSquared),
    ("mm/s2", AccelUnit::MillimetrePerSecondSquared),
    ("g", AccelUnit::StandardGravity),
    ("g0", AccelUnit::StandardGravity),
    ("gn", AccelUnit::StandardGravity),
];

impl AccelUnit {
    pub const ALL: [AccelUnit; 3] = [
        AccelUnit::MetrePerSecondSquared,
        AccelUnit::MillimetrePerSecondSquared,
        AccelUnit::StandardGravity,
    ];

    /// The unit a spelling names (any case, spaces ignored, `m/s²` as `m/s2`); None for a
    /// spelling that is not an acceleration unit.
    pub fn parse(text: &str) -> Option<AccelUnit> {
        let norm: String = text
            .chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| {
                if c == '²' {
                    '2'
                } else {
                    c.to_ascii_lowercase()
                }
            })
            .collect();
        SPELLINGS
            .iter()
            .find(|(s, _)| *s == norm)
            .map(|&(_, unit)| unit)
    }

    /// The canonical spelling (`m/s^2`, `mm/s^2`, `g`).
    pub fn as_str(self) -> &'static str {
        SPELLINGS
            .iter()
            .find(|(_, u)| *u == self)
            .map(|(s, _)| *s)
            .expect("every unit has a spelling")
    }

    /// Multiply a value in this unit by this to get m/s^2.
    pub fn factor_to_m_s2(self) -> f64 {
        match self {
            AccelUnit::MetrePerSecondSquared => 1.0,
            AccelUnit::MillimetrePerSecondSquared => 1e-3,
            AccelUnit::StandardGravity => STANDARD_GRAVITY,
        }
    }

    /// The accepted spellings, for error messages: `m/s^2, m/s2, ..., gn (any case; m/s² too)`.
    pub fn accepted() -> String {
        let list: Vec<&str> = SPELLINGS.iter().map(|(s, _)| *s).collect();
        format!("{} (any case; m/s² too)", list.join(", "))
    }
}

impl fmt::Display for AccelUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for AccelUnit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        AccelUnit::parse(s).ok_or_else(|| {
            format!(
                "{s:?} is not an acceleration unit; use one of {}",
                AccelUnit::accepted()
            )
        })
    }
}

impl Serialize for AccelUnit {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for AccelUnit {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// A channel's engineering unit as written (`g`, `m/s^2`, `V` for a tacho), with the
/// acceleration unit it names parsed once. Which channels must name one is the rig file's to
/// say (its acceleration channels); a tacho's `V` is kept as text.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default)]
pub struct ChannelUnit {
    text: String,
    accel: Option<AccelUnit>,
}

impl ChannelUnit {
    pub fn new(text: impl Into<String>) -> ChannelUnit {
        let text = text.into();
        ChannelUnit {
            accel: AccelUnit::parse(&text),
            text,
        }
    }

    /// The unit as written.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// The acceleration unit it names (None for `V` and other non-acceleration units).
    pub fn accel(&self) -> Option<AccelUnit> {
        self.accel
    }
}

impl fmt::Display for ChannelUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

impl From<&str> for ChannelUnit {
    fn from(s: &str) -> Self {
        ChannelUnit::new(s)
    }
}

impl From<String> for ChannelUnit {
    fn from(s: String) -> Self {
        ChannelUnit::new(s)
    }
}

impl From<AccelUnit> for ChannelUnit {
    fn from(u: AccelUnit) -> Self {
        ChannelUnit::new(u.as_str())
    }
}

impl PartialEq<str> for ChannelUnit {
    fn eq(&self, other: &str) -> bool {
        self.text == other
    }
}

impl PartialEq<&str> for ChannelUnit {
    fn eq(&self, other: &&str) -> bool {
        self.text == *other
    }
}

impl Serialize for ChannelUnit {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.text)
    }
}

impl<'de> Deserialize<'de> for ChannelUnit {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d).map(ChannelUnit::new)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_spelling_parses_in_any_case() {
        for (s, unit) in SPELLINGS {
            assert_eq!(AccelUnit::parse(s), Some(unit), "{s}");
            assert_eq!(AccelUnit::parse(&s.to_ascii_uppercase()), Some(unit), "{s}");
            assert_eq!(AccelUnit::parse(&format!(" {s} ")), Some(unit), "{s}");
        }
        assert_eq!(AccelUnit::parse("G"), Some(AccelUnit::StandardGravity));
        assert_eq!(
            AccelUnit::parse("m/s²"),
            Some(AccelUnit::MetrePerSecondSquared)
        );
        assert_eq!(
            AccelUnit::parse("mm/s²"),
            Some(AccelUnit::MillimetrePerSecondSquared)
        );
        assert_eq!(
            AccelUnit::parse("m s^-2"),
            Some(AccelUnit::MetrePerSecondSquared)
        );
        for bad in ["", "V", "furlong", "m/s", "mm/s", "gg", "m/s^3"] {
            assert_eq!(AccelUnit::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn factors_and_canonical_spellings() {
        let f = |u: AccelUnit| u.factor_to_m_s2();
        assert_eq!(f(AccelUnit::MetrePerSecondSquared), 1.0);
        assert_eq!(f(AccelUnit::MillimetrePerSecondSquared), 1e-3);
        assert_eq!(f(AccelUnit::StandardGravity), 9.80665);
        let names: Vec<String> = AccelUnit::ALL.iter().map(|u| u.to_string()).collect();
        assert_eq!(names, ["m/s^2", "mm/s^2", "g"]);
        for u in AccelUnit::ALL {
            assert_eq!(AccelUnit::parse(u.as_str()), Some(u));
        }
    }

    #[test]
    fn a_wrong_spelling_says_what_is_accepted() {
        let e = "furlong".parse::<AccelUnit>().unwrap_err();
        assert!(
            e.contains("\"furlong\"") && e.contains("m/s^2") && e.contains("gn"),
            "{e}"
        );
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Channel {
        unit: ChannelUnit,
        accel: Option<AccelUnit>,
    }

    #[test]
    fn serde_keeps_the_written_spelling() {
        for text in ["G", "m/s2", "mm/s^2", "V", "m/s²"] {
            let toml_text = format!("unit = {text:?}\naccel = \"M/S2\"\n");
            let c: Channel = toml::from_str(&toml_text).unwrap();
            assert_eq!(c.unit.as_str(), text);
            assert_eq!(c.unit.accel(), AccelUnit::parse(text));
            assert_eq!(c.accel, Some(AccelUnit::MetrePerSecondSquared));
            let back = toml::to_string(&c).unwrap();
            assert_eq!(back, format!("unit = {text:?}\naccel = \"m/s^2\"\n"));
            let json = serde_json::to_string(&c.unit).unwrap();
            assert_eq!(json, format!("{text:?}"));
        }
        let e = toml::from_str::<Channel>("unit = \"g\"\naccel = \"furlong\"\n").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }
}
