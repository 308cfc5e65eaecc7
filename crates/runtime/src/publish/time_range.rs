//! The `_time=[..]` selector parameter, as zenoh's storages read it: `[t1..t2]` with `[`/`]`
//! for inclusive and `]`/`[` for exclusive bounds, either bound empty for "unbounded", each
//! time an RFC 3339 instant (`2026-11-26T03:00:00Z`) or `now()` / `now(-24h)` (units `ms`,
//! `s`, `m`, `h`, `d`, `w`). Used by the daemon's recent-history queryable and by the
//! historian's history queryable; `rigmon history` writes it.

use anyhow::{anyhow, bail, Result};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// The selector parameter name.
pub const PARAMETER: &str = "_time";

/// A time range in ns since the Unix epoch; `None` bounds are open.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TimeRange {
    /// First instant included.
    pub from_ns: Option<u64>,
    /// First instant excluded.
    pub until_ns: Option<u64>,
}

impl TimeRange {
    /// Parse `[t1..t2]` (evaluating `now()` against `now_ns`).
    pub fn parse(text: &str, now_ns: u64) -> Result<Self> {
        let t = text.trim();
        let hint = "write it like [now(-24h)..] or [2026-11-26T00:00:00Z..2026-11-27T00:00:00Z[";
        let (open, rest) = t.split_at(t.chars().next().map_or(0, char::len_utf8));
        let (body, close) = rest.split_at(rest.len().saturating_sub(1));
        let start_inclusive = match open {
            "[" => true,
            "]" => false,
            _ => bail!("_time={t:?}: must start with [ or ]; {hint}"),
        };
        let end_inclusive = match close {
            "]" => true,
            "[" => false,
            _ => bail!("_time={t:?}: must end with ] or [; {hint}"),
        };
        let Some((a, b)) = body.split_once("..") else {
            bail!("_time={t:?}: no `..` between the bounds; {hint}");
        };
        let bound = |s: &str| -> Result<Option<u64>> {
            let s = s.trim();
            if s.is_empty() {
                Ok(None)
            } else {
                parse_instant(s, now_ns)
                    .map(Some)
                    .map_err(|e| anyhow!("_time={t:?}: {e}; {hint}"))
            }
        };
        let (from, until) = (bound(a)?, bound(b)?);
        let range = TimeRange {
            from_ns: from.map(|v| if start_inclusive { v } else { v + 1 }),
            until_ns: until.map(|v| if end_inclusive { v + 1 } else { v }),
        };
        if let (Some(f), Some(u)) = (range.from_ns, range.until_ns) {
            if u <= f {
                bail!("_time={t:?}: the range is empty (its end is not after its start)");
            }
        }
        Ok(range)
    }

    /// True when `t_ns` lies inside.
    pub fn contains(&self, t_ns: u64) -> bool {
        self.from_ns.is_none_or(|f| t_ns >= f) && self.until_ns.is_none_or(|u| t_ns < u)
    }

    /// The selector value: `[from..until[` with RFC 3339 instants (µs).
    pub fn to_selector_value(self) -> String {
        let fmt = |ns: Option<u64>| {
            ns.map(|v| humantime::format_rfc3339_micros(UNIX_EPOCH + Duration::from_nanos(v)))
                .map(|d| d.to_string())
                .unwrap_or_default()
        };
        format!("[{}..{}[", fmt(self.from_ns), fmt(self.until_ns))
    }
}

/// One bound: `now()`, `now(-2h)`, `now(+30s)` or an RFC 3339 instant.
fn parse_instant(s: &str, now_ns: u64) -> Result<u64> {
    if let Some(inner) = s.strip_prefix("now(").and_then(|r| r.strip_suffix(')')) {
        let inner = inner.trim();
        if inner.is_empty() {
            return Ok(now_ns);
        }
        let (sign, d) = match inner.as_bytes()[0] {
            b'-' => (-1i128, &inner[1..]),
            b'+' => (1, &inner[1..]),
            _ => (1, inner),
        };
        let dur = parse_duration(d)?;
        let v = now_ns as i128 + sign * dur.as_nanos() as i128;
        return u64::try_from(v.max(0)).map_err(|_| anyhow!("{s}: out of range"));
    }
    let t = humantime::parse_rfc3339_weak(s)
        .map_err(|e| anyhow!("{s:?} is neither now(..) nor an RFC 3339 time ({e})"))?;
    Ok(t.duration_since(UNIX_EPOCH)
        .map_err(|_| anyhow!("{s}: before 1970"))?
        .as_nanos() as u64)
}

/// A duration as zenoh and people write it: `24h`, `30m`, `1.5s`, `7d`, `2w`, `500ms`, or
/// anything `humantime` reads (`1h 30m`).
pub fn parse_duration(s: &str) -> Result<Duration> {
    let s = s.trim();
    let split = s
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(s.len());
    let (num, unit) = s.split_at(split);
    if let Ok(v) = num.parse::<f64>() {
        let unit_s = match unit.trim() {
            "ms" => Some(1e-3),
            "s" | "" => Some(1.0),
            "m" => Some(60.0),
            "h" => Some(3600.0),
            "d" => Some(86_400.0),
            "w" => Some(604_800.0),
            _ => None,
        };
        if let Some(u) = unit_s {
            if v.is_finite() && v >= 0.0 {
                return Ok(Duration::from_secs_f64(v * u));
            }
        }
    }
    humantime::parse_duration(s)
        .map_err(|e| anyhow!("{s:?} is not a duration like 24h, 30m, 7d ({e})"))
}

/// Wall-clock now, ns since the Unix epoch.
pub fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOW: u64 = 1_800_000_000_000_000_000;

    #[test]
    fn relative_and_absolute_bounds() {
        let r = TimeRange::parse("[now(-24h)..]", NOW).unwrap();
        assert_eq!(r.from_ns, Some(NOW - 86_400 * 1_000_000_000));
        assert_eq!(r.until_ns, None);
        let r = TimeRange::parse("[2026-11-26T00:00:00Z..2026-11-27T00:00:00Z[", NOW).unwrap();
        assert_eq!(r.until_ns.unwrap() - r.from_ns.unwrap(), 86_400_000_000_000);
        assert!(r.contains(r.from_ns.unwrap()) && !r.contains(r.until_ns.unwrap()));
        let back = TimeRange::parse(&r.to_selector_value(), NOW).unwrap();
        assert_eq!(back, r);
        let incl = TimeRange::parse("]..now()]", NOW).unwrap();
        assert!(incl.contains(NOW) && !incl.contains(NOW + 1) && incl.from_ns.is_none());
    }

    #[test]
    fn bad_ranges_say_how_to_write_them() {
        for bad in [
            "now(-1h)..",
            "[yesterday..]",
            "[now(-1h)now()]",
            "[now()..now(-1h)]",
        ] {
            let e = TimeRange::parse(bad, NOW).unwrap_err().to_string();
            assert!(
                e.contains("_time=") && e.contains("[now(-24h)..]") || e.contains("empty"),
                "{e}"
            );
        }
        assert_eq!(parse_duration("90m").unwrap(), Duration::from_secs(5400));
        assert_eq!(parse_duration("1h 30m").unwrap(), Duration::from_secs(5400));
        assert!(parse_duration("soon")
            .unwrap_err()
            .to_string()
            .contains("24h"));
    }
}
