//! The machine conditions a classifier names: `healthy` and the bearing fault families
//! (`outer_race`, `inner_race`, `ball`). Their names are the labels of `labels.csv`, of a
//! model's metadata, of health messages and of the historian; a model may carry other labels
//! too (a dataset's own), so label lists stay strings and this type names the known ones.

use serde::{Deserialize, Serialize};
use std::fmt;

/// A known machine condition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Condition {
    Healthy,
    OuterRace,
    InnerRace,
    Ball,
}

impl Condition {
    /// Every condition, in the order models, reports and the historian list them.
    pub const ALL: [Condition; 4] = [
        Condition::Healthy,
        Condition::OuterRace,
        Condition::InnerRace,
        Condition::Ball,
    ];
    /// The bearing fault families.
    pub const FAULTS: [Condition; 3] =
        [Condition::OuterRace, Condition::InnerRace, Condition::Ball];
    /// [`Condition::ALL`]'s names.
    pub const NAMES: [&'static str; 4] = [
        Condition::Healthy.as_str(),
        Condition::OuterRace.as_str(),
        Condition::InnerRace.as_str(),
        Condition::Ball.as_str(),
    ];
    /// [`Condition::FAULTS`]' names.
    pub const FAULT_NAMES: [&'static str; 3] = [
        Condition::OuterRace.as_str(),
        Condition::InnerRace.as_str(),
        Condition::Ball.as_str(),
    ];

    /// The label (serde name).
    pub const fn as_str(self) -> &'static str {
        match self {
            Condition::Healthy => "healthy",
            Condition::OuterRace => "outer_race",
            Condition::InnerRace => "inner_race",
            Condition::Ball => "ball",
        }
    }

    /// The condition a label names (exact, as written in files); None for other labels.
    pub fn parse(label: &str) -> Option<Condition> {
        Condition::ALL.into_iter().find(|c| c.as_str() == label)
    }

    /// The condition a person's spelling names: the label, or a short form the simulator's
    /// and calibration's `--fault`/label lists have always taken (`outer`, `or`, `orf`;
    /// `inner`, `ir`, `irf`; `b`, `re`; `none` for healthy), in any case; None otherwise.
    pub fn from_spelling(text: &str) -> Option<Condition> {
        Some(match text.trim().to_ascii_lowercase().as_str() {
            "healthy" | "none" => Condition::Healthy,
            "outer_race" | "outer" | "or" | "orf" => Condition::OuterRace,
            "inner_race" | "inner" | "ir" | "irf" => Condition::InnerRace,
            "ball" | "b" | "re" => Condition::Ball,
            _ => return None,
        })
    }

    /// The bearing faults of a list such as `outer_race+inner_race` or `healthy` (`,` or `+`
    /// between names, each as [`Condition::from_spelling`] takes it; healthy adds none; a
    /// fault named twice counts once), in the order given: the first is the dominant one.
    pub fn parse_faults(text: &str) -> anyhow::Result<Vec<Condition>> {
        let mut out = Vec::new();
        for part in text
            .split([',', '+'])
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            match Condition::from_spelling(part) {
                Some(Condition::Healthy) => {}
                Some(c) if !out.contains(&c) => out.push(c),
                Some(_) => {}
                None => anyhow::bail!(
                    "unknown fault {part:?}: use healthy, outer_race, inner_race, ball (comma-separated for compound faults)"
                ),
            }
        }
        Ok(out)
    }

    /// True for the label `healthy`.
    pub fn is_healthy(label: &str) -> bool {
        label == Condition::Healthy.as_str()
    }

    /// Where this condition stands in a label list (a model's, a confusion matrix's).
    pub fn index_in<S: AsRef<str>>(self, labels: &[S]) -> Option<usize> {
        labels.iter().position(|l| l.as_ref() == self.as_str())
    }
}

impl fmt::Display for Condition {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl PartialEq<str> for Condition {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}

impl PartialEq<Condition> for &str {
    fn eq(&self, other: &Condition) -> bool {
        *self == other.as_str()
    }
}

impl PartialEq<Condition> for String {
    fn eq(&self, other: &Condition) -> bool {
        self == other.as_str()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_through_serde_and_parse() {
        assert_eq!(
            Condition::NAMES,
            ["healthy", "outer_race", "inner_race", "ball"]
        );
        assert_eq!(Condition::FAULT_NAMES, ["outer_race", "inner_race", "ball"]);
        for c in Condition::ALL {
            assert_eq!(Condition::parse(c.as_str()), Some(c));
            let json = serde_json::to_string(&c).unwrap();
            assert_eq!(json, format!("\"{c}\""));
            assert_eq!(serde_json::from_str::<Condition>(&json).unwrap(), c);
        }
        assert_eq!(Condition::parse("Healthy"), None);
        assert_eq!(Condition::parse("misalignment"), None);
    }

    #[test]
    fn a_fault_list_takes_the_short_spellings_and_drops_healthy() {
        use Condition::*;
        assert_eq!(
            Condition::parse_faults("OR+irf, b").unwrap(),
            [OuterRace, InnerRace, Ball]
        );
        assert_eq!(
            Condition::parse_faults("inner,inner_race").unwrap(),
            [InnerRace]
        );
        assert!(Condition::parse_faults("healthy").unwrap().is_empty());
        assert!(Condition::parse_faults("none").unwrap().is_empty());
        let e = Condition::parse_faults("or+crack").unwrap_err().to_string();
        assert!(e.contains("\"crack\"") && e.contains("outer_race"), "{e}");
    }

    #[test]
    fn healthy_is_found_in_a_label_list() {
        let labels: Vec<String> = ["outer_race", "healthy"].map(String::from).to_vec();
        assert_eq!(Condition::Healthy.index_in(&labels), Some(1));
        assert_eq!(Condition::Ball.index_in(&labels), None);
        assert!(Condition::is_healthy("healthy") && !Condition::is_healthy("ball"));
        let ball = String::from("ball");
        assert!("healthy" == Condition::Healthy && ball == Condition::Ball);
    }
}
