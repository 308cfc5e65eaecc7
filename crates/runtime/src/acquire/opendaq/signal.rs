//! What an openDAQ LT streaming `signal` meta information says about a signal: its data
//! type, rule (explicit values, or an implicit linear domain such as time), tick resolution,
//! unit, post-scaling and which domain signal gives its time stamps.
//!
//! Source: openDAQ Stream Protocol Specification 1.3.0 (openDAQ/streaming-protocol-lt,
//! `docs/openDAQ-streaming.md`), sections "Signal Description", "Signal Definition Object",
//! "Rules" and "Data Types"; `docs/openDAQ-signal-definition-examples.md` for time signals.

use serde_json::Value;

/// A base data type of a signal member (spec section "Base Data Types"). Structs, complex
/// numbers, bit fields, 128-bit integers and signals with dimensions are not read by rigmon.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DataType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl DataType {
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "int8" => DataType::I8,
            "uint8" => DataType::U8,
            "int16" => DataType::I16,
            "uint16" => DataType::U16,
            "int32" => DataType::I32,
            "uint32" => DataType::U32,
            "int64" => DataType::I64,
            "uint64" => DataType::U64,
            "real32" => DataType::F32,
            "real64" => DataType::F64,
            _ => return None,
        })
    }

    /// Bytes per value on the wire.
    pub fn size(self) -> usize {
        match self {
            DataType::I8 | DataType::U8 => 1,
            DataType::I16 | DataType::U16 => 2,
            DataType::I32 | DataType::U32 | DataType::F32 => 4,
            DataType::I64 | DataType::U64 | DataType::F64 => 8,
        }
    }

    /// One value from exactly `self.size()` little-endian bytes (signal data is sent in the
    /// device's byte order; every openDAQ device and this client are little-endian).
    pub fn read_f64(self, b: &[u8]) -> f64 {
        let mut a = [0u8; 8];
        a[..b.len().min(8)].copy_from_slice(&b[..b.len().min(8)]);
        match self {
            DataType::I8 => a[0] as i8 as f64,
            DataType::U8 => a[0] as f64,
            DataType::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            DataType::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            DataType::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            DataType::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            DataType::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            DataType::I64 => i64::from_le_bytes(a) as f64,
            DataType::U64 => u64::from_le_bytes(a) as f64,
            DataType::F64 => f64::from_le_bytes(a),
        }
    }

    /// An integer tick value (domain signals), exact for 64-bit integers.
    pub fn read_ticks(self, b: &[u8]) -> Option<i128> {
        let mut a = [0u8; 8];
        a[..b.len().min(8)].copy_from_slice(&b[..b.len().min(8)]);
        Some(match self {
            DataType::I64 => i64::from_le_bytes(a) as i128,
            DataType::U64 => u64::from_le_bytes(a) as i128,
            DataType::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i128,
            DataType::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as i128,
            _ => return None,
        })
    }
}

/// How a signal's values are produced (spec section "Rules").
#[derive(Debug, Clone, PartialEq)]
pub enum Rule {
    /// Every value is sent.
    Explicit,
    /// Implicit: value = start + delta x (index - start index); a new start arrives as
    /// signal data (index, value) on resynchronisation.
    Linear { delta: i64 },
    /// Implicit constant or another rule rigmon does not use.
    Other(String),
}

/// A described signal.
#[derive(Debug, Clone, PartialEq)]
pub struct SignalDescription {
    /// Member name (`definition.name`).
    pub name: String,
    /// `None` when the type is one rigmon cannot read (named in `type_name`).
    pub data_type: Option<DataType>,
    pub type_name: String,
    pub rule: Rule,
    /// Tick size in seconds for time signals (`resolution.num / resolution.denom`).
    pub resolution: Option<(u64, u64)>,
    /// Unit symbol (`unit.displayName`), e.g. "V", "s".
    pub unit: Option<String>,
    /// Unit quantity, e.g. "voltage", "time".
    pub quantity: Option<String>,
    /// `postScaling`: value = scale x raw + offset.
    pub scale: f64,
    pub offset: f64,
    /// `tableId`: signals of one table share a domain.
    pub table_id: Option<String>,
    /// The `relatedSignals` entry of type `domain`, else the table id (openDAQ servers name
    /// the table after its domain signal).
    pub domain_id: Option<String>,
    /// Table index of this signal's first value (`valueIndex`, default 0).
    pub value_index: u64,
    /// The member has `dimensions` (vectors, spectra): not a sampled waveform.
    pub has_dimensions: bool,
}

impl SignalDescription {
    /// Read the `params` of a `signal` meta information. The error says which field was
    /// missing or unusable.
    pub fn from_params(params: &Value) -> Result<Self, String> {
        let def = params
            .get("definition")
            .filter(|d| d.is_object())
            .ok_or("signal meta information has no `definition` object")?;
        let type_name = def
            .get("dataType")
            .and_then(Value::as_str)
            .ok_or("signal definition has no `dataType`")?
            .to_string();
        let rule = match def.get("rule").and_then(Value::as_str) {
            Some("explicit") | None => Rule::Explicit,
            Some("linear") => {
                let d = def
                    .get("linear")
                    .and_then(|l| l.get("delta"))
                    .ok_or("linear rule without `linear.delta`")?;
                let delta = d
                    .as_i64()
                    .or_else(|| d.as_f64().filter(|f| f.fract() == 0.0).map(|f| f as i64))
                    .filter(|&x| x > 0)
                    .ok_or_else(|| format!("linear delta {d} is not a positive integer"))?;
                Rule::Linear { delta }
            }
            Some(other) => Rule::Other(other.to_string()),
        };
        let resolution = def.get("resolution").and_then(|r| {
            let num = r.get("num")?.as_u64()?;
            let denom = r.get("denom")?.as_u64()?;
            (num > 0 && denom > 0).then_some((num, denom))
        });
        let unit = def.get("unit");
        let text = |v: Option<&Value>, k: &str| {
            v.and_then(|u| u.get(k))
                .and_then(Value::as_str)
                .map(str::to_string)
        };
        let post = def.get("postScaling");
        let num = |k: &str, d: f64| {
            post.and_then(|p| p.get(k))
                .and_then(Value::as_f64)
                .filter(|x| x.is_finite())
                .unwrap_or(d)
        };
        let table_id = params
            .get("tableId")
            .and_then(Value::as_str)
            .map(str::to_string);
        let domain_id = params
            .get("relatedSignals")
            .and_then(Value::as_array)
            .and_then(|a| {
                a.iter().find_map(|r| {
                    (r.get("type")?.as_str()? == "domain")
                        .then(|| r.get("signalId")?.as_str().map(str::to_string))?
                })
            })
            .or_else(|| table_id.clone());
        Ok(SignalDescription {
            name: def
                .get("name")
                .and_then(Value::as_str)
                .unwrap_or("")
                .to_string(),
            data_type: DataType::parse(&type_name),
            type_name,
            rule,
            resolution,
            unit: text(unit, "displayName"),
            quantity: text(unit, "quantity"),
            scale: num("scale", 1.0),
            offset: num("offset", 0.0),
            table_id,
            domain_id,
            value_index: params
                .get("valueIndex")
                .and_then(Value::as_u64)
                .unwrap_or(0),
            has_dimensions: def
                .get("dimensions")
                .and_then(Value::as_array)
                .is_some_and(|a| !a.is_empty()),
        })
    }

    /// A time domain: linear rule with a tick resolution. Returns (delta in ticks, ticks per
    /// second as num/denom).
    pub fn linear_time(&self) -> Option<(i64, (u64, u64))> {
        match (&self.rule, self.resolution) {
            (Rule::Linear { delta }, Some(res)) => Some((*delta, res)),
            _ => None,
        }
    }

    /// Sample rate of a linear time domain, Hz.
    pub fn sample_rate(&self) -> Option<f64> {
        let (delta, (num, denom)) = self.linear_time()?;
        Some(denom as f64 / (num as f64 * delta as f64))
    }

    /// An explicit scalar signal rigmon can read as a waveform.
    pub fn is_waveform(&self) -> bool {
        self.rule == Rule::Explicit && self.data_type.is_some() && !self.has_dimensions
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn reads_the_reference_device_s_time_and_value_signals() {
        // As the openDAQ 3.40 reference device sends them (captured on loopback).
        let time = SignalDescription::from_params(&json!({"definition": {"dataType": "int64",
            "linear": {"delta": 1000}, "name": "Time AI 1",
            "resolution": {"denom": 1_000_000, "num": 1}, "rule": "linear",
            "unit": {"displayName": "s", "quantity": "time", "unitId": -1}},
            "tableId": "/RefDev0/IO/AI/RefCh0/Sig/AI0Time", "valueIndex": 0}))
        .unwrap();
        assert_eq!(time.sample_rate(), Some(1000.0));
        assert_eq!(time.quantity.as_deref(), Some("time"));
        let ai = SignalDescription::from_params(&json!({"definition": {"dataType": "real64",
            "name": "AI 1", "range": {"high": 10.0, "low": -10.0}, "rule": "explicit",
            "unit": {"displayName": "V", "quantity": "voltage", "unitId": -1}},
            "tableId": "/RefDev0/IO/AI/RefCh0/Sig/AI0Time", "valueIndex": 0}))
        .unwrap();
        assert!(ai.is_waveform());
        assert_eq!(ai.unit.as_deref(), Some("V"));
        assert_eq!(
            ai.domain_id.as_deref(),
            Some("/RefDev0/IO/AI/RefCh0/Sig/AI0Time")
        );
        assert_eq!(DataType::F64.read_f64(&2.5f64.to_le_bytes()), 2.5);
        assert_eq!(DataType::I16.read_f64(&(-3i16).to_le_bytes()), -3.0);
    }

    #[test]
    fn related_domain_wins_over_table_and_bad_deltas_are_named() {
        let s = SignalDescription::from_params(&json!({"definition": {"dataType": "int16",
            "rule": "explicit", "postScaling": {"scale": 0.5, "offset": 1.0}},
            "tableId": "t", "relatedSignals": [{"type": "domain", "signalId": "time"}]}))
        .unwrap();
        assert_eq!(
            (s.domain_id.as_deref(), s.scale, s.offset),
            (Some("time"), 0.5, 1.0)
        );
        let e = SignalDescription::from_params(&json!({"definition": {"dataType": "int64",
            "rule": "linear", "linear": {"delta": -2}}}))
        .unwrap_err();
        assert!(e.contains("-2"), "{e}");
        assert!(SignalDescription::from_params(&json!({"x": 1})).is_err());
    }
}
