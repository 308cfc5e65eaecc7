//! The components of the calibration error (`env`, `peaks`, ... `impacts`): one typed name
//! each, in report order. `calibrate::error` computes them into an `ErrorParts` indexed by
//! this type, so a component cannot be misspelt; the names are the reports' and the JSON's.

use serde::{Serialize, Serializer};
use std::fmt;

/// One component of the calibration error (`calibrate::error` defines each); its name is
/// the one of reports, JSON and the catalog.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ErrorComponent {
    Env,
    Peaks,
    Ratios,
    Lines,
    Orders,
    Harmonics,
    Bands,
    Modes,
    Floor,
    Speed,
    Fractional,
    HalfOrders,
    Impacts,
}

impl ErrorComponent {
    /// Every component, in report order.
    pub const ALL: [ErrorComponent; 13] = [
        ErrorComponent::Env,
        ErrorComponent::Peaks,
        ErrorComponent::Ratios,
        ErrorComponent::Lines,
        ErrorComponent::Orders,
        ErrorComponent::Harmonics,
        ErrorComponent::Bands,
        ErrorComponent::Modes,
        ErrorComponent::Floor,
        ErrorComponent::Speed,
        ErrorComponent::Fractional,
        ErrorComponent::HalfOrders,
        ErrorComponent::Impacts,
    ];

    /// The component's name in reports and JSON.
    pub const fn name(self) -> &'static str {
        match self {
            ErrorComponent::Env => "env",
            ErrorComponent::Peaks => "peaks",
            ErrorComponent::Ratios => "ratios",
            ErrorComponent::Lines => "lines",
            ErrorComponent::Orders => "orders",
            ErrorComponent::Harmonics => "harmonics",
            ErrorComponent::Bands => "bands",
            ErrorComponent::Modes => "modes",
            ErrorComponent::Floor => "floor",
            ErrorComponent::Speed => "speed",
            ErrorComponent::Fractional => "fractional",
            ErrorComponent::HalfOrders => "half_orders",
            ErrorComponent::Impacts => "impacts",
        }
    }

    /// The component a name means; None for another name.
    pub fn parse(name: &str) -> Option<ErrorComponent> {
        ErrorComponent::ALL.into_iter().find(|c| c.name() == name)
    }
}

impl fmt::Display for ErrorComponent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for ErrorComponent {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_in_report_order() {
        let names: Vec<&str> = ErrorComponent::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(
            names,
            [
                "env",
                "peaks",
                "ratios",
                "lines",
                "orders",
                "harmonics",
                "bands",
                "modes",
                "floor",
                "speed",
                "fractional",
                "half_orders",
                "impacts"
            ]
        );
        for (k, c) in ErrorComponent::ALL.into_iter().enumerate() {
            assert_eq!(
                c as usize, k,
                "ALL is in declaration order (the parts' index)"
            );
            assert_eq!(ErrorComponent::parse(c.name()), Some(c));
            assert_eq!(serde_json::to_string(&c).unwrap(), format!("\"{c}\""));
        }
        assert_eq!(ErrorComponent::parse("half-orders"), None);
    }
}
