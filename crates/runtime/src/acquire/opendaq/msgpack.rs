//! A small, bounded MessagePack reader: the openDAQ LT streaming protocol encodes its meta
//! information in MessagePack (`Metainfo_Type` = 2). Decodes into [`serde_json::Value`] so the
//! rest of the source reads meta information like JSON.
//!
//! Format: the MessagePack specification (msgpack/msgpack `spec.md`): big-endian, fixint /
//! fixmap / fixarray / fixstr, nil, bool, bin, ext, float 32/64, (u)int 8-64, str 8/16/32,
//! array 16/32, map 16/32. Binary and extension values become `null`; map keys that are not
//! strings are written as their JSON text. Nesting is limited to [`MAX_DEPTH`], and a
//! container can never claim more elements than bytes are left, so no input allocates more
//! than a few times its own length.

use serde_json::{Map, Number, Value};

/// Deepest nesting accepted (openDAQ meta information nests about 5 deep).
pub const MAX_DEPTH: usize = 32;

/// What was wrong with a MessagePack document, and at which byte.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MsgpackError {
    #[error("MessagePack ends early at byte {0}")]
    Truncated(usize),
    #[error("MessagePack byte 0x{byte:02x} at offset {at} is not a valid type marker")]
    BadMarker { byte: u8, at: usize },
    #[error("MessagePack nests deeper than {MAX_DEPTH} at byte {0}")]
    TooDeep(usize),
    #[error("MessagePack string at byte {0} is not UTF-8")]
    NotUtf8(usize),
    #[error("MessagePack has {0} bytes after the value")]
    Trailing(usize),
}

/// Decode one MessagePack value that fills `bytes` exactly.
pub fn decode(bytes: &[u8]) -> Result<Value, MsgpackError> {
    let mut r = Reader { b: bytes, at: 0 };
    let v = r.value(0)?;
    if r.at != bytes.len() {
        return Err(MsgpackError::Trailing(bytes.len() - r.at));
    }
    Ok(v)
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], MsgpackError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or(MsgpackError::Truncated(self.at))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn uint(&mut self, n: usize) -> Result<u64, MsgpackError> {
        Ok(self
            .take(n)?
            .iter()
            .fold(0u64, |acc, &x| (acc << 8) | x as u64))
    }

    fn int(&mut self, n: usize) -> Result<i64, MsgpackError> {
        let u = self.uint(n)?;
        let shift = 64 - 8 * n as u32;
        Ok(((u << shift) as i64) >> shift)
    }

    fn string(&mut self, n: usize) -> Result<String, MsgpackError> {
        let at = self.at;
        let s = self.take(n)?;
        std::str::from_utf8(s)
            .map(str::to_owned)
            .map_err(|_| MsgpackError::NotUtf8(at))
    }

    /// A container length: every element takes at least one byte, so a length larger than
    /// what is left is truncated input (and never allocated).
    fn count(&mut self, n: usize, per_element: usize) -> Result<usize, MsgpackError> {
        let at = self.at;
        let c = self.uint(n)? as usize;
        if c.saturating_mul(per_element) > self.b.len() - self.at {
            return Err(MsgpackError::Truncated(at));
        }
        Ok(c)
    }

    fn array(&mut self, n: usize, depth: usize) -> Result<Value, MsgpackError> {
        let mut v = Vec::with_capacity(n);
        for _ in 0..n {
            v.push(self.value(depth + 1)?);
        }
        Ok(Value::Array(v))
    }

    fn map(&mut self, n: usize, depth: usize) -> Result<Value, MsgpackError> {
        let mut m = Map::new();
        for _ in 0..n {
            let k = match self.value(depth + 1)? {
                Value::String(s) => s,
                other => other.to_string(),
            };
            let v = self.value(depth + 1)?;
            m.insert(k, v);
        }
        Ok(Value::Object(m))
    }

    fn value(&mut self, depth: usize) -> Result<Value, MsgpackError> {
        if depth > MAX_DEPTH {
            return Err(MsgpackError::TooDeep(self.at));
        }
        let at = self.at;
        let m = self.take(1)?[0];
        Ok(match m {
            0x00..=0x7f => Value::from(m as u64),
            0x80..=0x8f => {
                let n = self.count_fixed((m & 0x0f) as usize, 2)?;
                self.map(n, depth)?
            }
            0x90..=0x9f => {
                let n = self.count_fixed((m & 0x0f) as usize, 1)?;
                self.array(n, depth)?
            }
            0xa0..=0xbf => Value::String(self.string((m & 0x1f) as usize)?),
            0xc0 => Value::Null,
            0xc2 => Value::Bool(false),
            0xc3 => Value::Bool(true),
            0xc4..=0xc6 => {
                let n = self.uint(1 << (m - 0xc4))? as usize;
                self.take(n)?;
                Value::Null
            }
            0xc7..=0xc9 => {
                let n = self.uint(1 << (m - 0xc7))? as usize;
                self.take(1)?; // ext type
                self.take(n)?;
                Value::Null
            }
            0xca => float(f32::from_bits(self.uint(4)? as u32) as f64),
            0xcb => float(f64::from_bits(self.uint(8)?)),
            0xcc..=0xcf => Value::from(self.uint(1 << (m - 0xcc))?),
            0xd0..=0xd3 => Value::from(self.int(1 << (m - 0xd0))?),
            0xd4..=0xd8 => {
                self.take(1 + (1 << (m - 0xd4)))?;
                Value::Null
            }
            0xd9..=0xdb => {
                let n = self.uint(1 << (m - 0xd9))? as usize;
                Value::String(self.string(n)?)
            }
            0xdc | 0xdd => {
                let n = self.count(if m == 0xdc { 2 } else { 4 }, 1)?;
                self.array(n, depth)?
            }
            0xde | 0xdf => {
                let n = self.count(if m == 0xde { 2 } else { 4 }, 2)?;
                self.map(n, depth)?
            }
            0xe0..=0xff => Value::from(m as i8 as i64),
            0xc1 => return Err(MsgpackError::BadMarker { byte: m, at }),
        })
    }

    fn count_fixed(&mut self, n: usize, per_element: usize) -> Result<usize, MsgpackError> {
        if n * per_element > self.b.len() - self.at {
            return Err(MsgpackError::Truncated(self.at));
        }
        Ok(n)
    }
}

fn float(x: f64) -> Value {
    Number::from_f64(x).map_or(Value::Null, Value::Number)
}

/// Encode a JSON value as MessagePack (for tests, fake servers and the fuzz corpus; the
/// source itself only reads). Integers use the smallest form, floats are float64.
pub fn encode(v: &Value) -> Vec<u8> {
    let mut out = Vec::new();
    encode_into(v, &mut out);
    out
}

fn encode_len(out: &mut Vec<u8>, n: usize, fix: u8, fix_max: usize, m16: u8, m32: u8) {
    if n <= fix_max {
        out.push(fix | n as u8);
    } else if n <= u16::MAX as usize {
        out.push(m16);
        out.extend_from_slice(&(n as u16).to_be_bytes());
    } else {
        out.push(m32);
        out.extend_from_slice(&(n as u32).to_be_bytes());
    }
}

fn encode_into(v: &Value, out: &mut Vec<u8>) {
    match v {
        Value::Null => out.push(0xc0),
        Value::Bool(b) => out.push(if *b { 0xc3 } else { 0xc2 }),
        Value::Number(n) => {
            if let Some(u) = n.as_u64() {
                if u < 0x80 {
                    out.push(u as u8);
                } else {
                    out.push(0xcf);
                    out.extend_from_slice(&u.to_be_bytes());
                }
            } else if let Some(i) = n.as_i64() {
                if i >= -32 {
                    out.push(i as i8 as u8);
                } else {
                    out.push(0xd3);
                    out.extend_from_slice(&i.to_be_bytes());
                }
            } else {
                out.push(0xcb);
                out.extend_from_slice(&n.as_f64().unwrap_or(0.0).to_be_bytes());
            }
        }
        Value::String(s) => {
            if s.len() < 32 {
                out.push(0xa0 | s.len() as u8);
            } else if s.len() <= u8::MAX as usize {
                out.push(0xd9);
                out.push(s.len() as u8);
            } else {
                encode_len(out, s.len(), 0, 0, 0xda, 0xdb);
            }
            out.extend_from_slice(s.as_bytes());
        }
        Value::Array(a) => {
            encode_len(out, a.len(), 0x90, 15, 0xdc, 0xdd);
            a.iter().for_each(|x| encode_into(x, out));
        }
        Value::Object(m) => {
            encode_len(out, m.len(), 0x80, 15, 0xde, 0xdf);
            for (k, x) in m {
                encode_into(&Value::String(k.clone()), out);
                encode_into(x, out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn round_trips_what_opendaq_sends() {
        let v = json!({
            "method": "signal",
            "params": {
                "definition": {"dataType": "int64", "linear": {"delta": 1000},
                    "resolution": {"num": 1, "denom": 1_000_000}, "rule": "linear",
                    "range": {"low": -10.0, "high": 10.5}},
                "valueIndex": 0, "neg": -5, "big": -100_000, "long": "x".repeat(300),
                "list": (0..20).collect::<Vec<_>>(),
            }
        });
        assert_eq!(decode(&encode(&v)).unwrap(), v);
    }

    #[test]
    fn reads_the_compact_forms_of_other_encoders() {
        // {"a": 1} with a uint8, int16 and float32 inside an array: [0xcc 200, 0xd1 -300, f32 1.5]
        let b = [
            0x81, 0xa1, b'a', 0x93, 0xcc, 200, 0xd1, 0xfe, 0xd4, 0xca, 0x3f, 0xc0, 0, 0,
        ];
        assert_eq!(
            decode(&b).unwrap(),
            serde_json::json!({"a": [200, -300, 1.5]})
        );
    }

    #[test]
    fn damaged_input_is_an_error_not_a_panic_or_a_big_allocation() {
        assert_eq!(
            decode(&[0xc1]),
            Err(MsgpackError::BadMarker { byte: 0xc1, at: 0 })
        );
        assert!(matches!(
            decode(&[0xdd, 0xff, 0xff, 0xff, 0xff]),
            Err(MsgpackError::Truncated(_))
        ));
        assert!(matches!(
            decode(&[0xa5, b'a']),
            Err(MsgpackError::Truncated(_))
        ));
        assert!(matches!(
            decode(&[0x91; 100]),
            Err(MsgpackError::TooDeep(_))
        ));
        assert_eq!(decode(&[0xc0, 0xc0]), Err(MsgpackError::Trailing(1)));
        assert!(matches!(
            decode(&[0xa2, 0xff, 0xfe]),
            Err(MsgpackError::NotUtf8(_))
        ));
    }
}
