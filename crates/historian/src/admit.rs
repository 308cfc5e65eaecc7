//! Admission: what the historian checks of every parsed message before it may reach the
//! database, because any publisher on the mesh (a rogue one, or a daemon whose clock jumped)
//! can send anything. A message speaks only for the point of the key it arrived on
//! (`<prefix>/<machine>/<asset>/<point>/health|status`: machine, asset and point must be the
//! key's); names are plain key chunks (non-empty, at most [`MAX_NAME`] bytes, no `/ * $ # ?`,
//! no white space or control characters, not starting with `@`), so every stored point is a
//! valid Zenoh key and a name in SQL is always a bound parameter; a window may not end (nor be
//! published) more than `[intake] max_future_s` after the historian's clock, which also bounds
//! the partitions it creates; `seq` is at most [`MAX_SEQ_RATE`] per second of the run (plus
//! one) and fits the database's `int8`. Whatever fails is refused with the reason counted
//! ([`Refusal`], the historian status `received.refused`) and logged.

use super::row::WindowRow;
use super::writer::StatusRow;

/// Longest machine, asset or point name, bytes.
pub const MAX_NAME: usize = 128;
/// Windows per second of a run no daemon exceeds (2 per second is usual): `seq` beyond
/// `1 + MAX_SEQ_RATE x end_s` is not a window count.
pub const MAX_SEQ_RATE: u64 = 1000;

/// Why a message was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// Machine, asset or point differ from the key the message arrived on.
    Key,
    /// A name that is no plain key chunk.
    Name,
    /// Dated beyond now + the allowed clock skew.
    Future,
    /// A `seq` no daemon can have reached.
    Seq,
    /// Larger than `[intake] max_message_kb`.
    TooLarge,
}

impl Refusal {
    pub fn as_str(self) -> &'static str {
        match self {
            Refusal::Key => "key",
            Refusal::Name => "name",
            Refusal::Future => "future",
            Refusal::Seq => "seq",
            Refusal::TooLarge => "too_large",
        }
    }
}

/// A refusal and what exactly was wrong.
pub type Refused = (Refusal, String);

/// The admission rules of one historian.
#[derive(Debug, Clone)]
pub struct Rules {
    /// The key prefix (`rigmon`).
    pub prefix: String,
    /// Allowed clock skew into the future, ns.
    pub max_future_ns: u64,
}

/// A machine, asset or point name usable as one Zenoh key chunk; the error says why not.
pub fn check_name(what: &str, name: &str) -> Result<(), String> {
    let why = if name.is_empty() {
        "is empty"
    } else if name.len() > MAX_NAME {
        "is longer than 128 bytes"
    } else if name.starts_with('@') {
        "starts with @"
    } else if name.contains(['/', '*', '$', '#', '?']) {
        "contains / * $ # or ?"
    } else if name.chars().any(|c| c.is_whitespace() || c.is_control()) {
        "contains white space or control characters"
    } else {
        return Ok(());
    };
    Err(format!("{what} {:?} {why}", shorten(name)))
}

/// A name for a log line: at most 64 characters, escaped by `{:?}` at the caller.
fn shorten(s: &str) -> String {
    if s.chars().count() <= 64 {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(64).collect::<String>())
    }
}

/// `<prefix>/<machine>/<asset>/<point>/<suffix>` as its three names.
pub fn key_point<'a>(prefix: &str, key: &'a str, suffix: &str) -> Option<[&'a str; 3]> {
    let rest = key.strip_prefix(prefix)?.strip_prefix('/')?;
    let rest = rest.strip_suffix(suffix)?.strip_suffix('/')?;
    let mut parts = rest.split('/');
    let p = [parts.next()?, parts.next()?, parts.next()?];
    parts.next().is_none().then_some(p)
}

fn same_point(rules: &Rules, key: &str, suffix: &str, names: [&str; 3]) -> Result<(), Refused> {
    for (what, n) in ["machine", "asset", "point"].into_iter().zip(names) {
        check_name(what, n).map_err(|e| (Refusal::Name, e))?;
    }
    match key_point(&rules.prefix, key, suffix) {
        Some(k) if k == names => Ok(()),
        _ => Err((
            Refusal::Key,
            format!(
                "it says it is {:?} but arrived on {key}; a publisher speaks only for the point of its key ({}/<machine>/<asset>/<point>/{suffix})",
                shorten(&names.join("/")),
                rules.prefix
            ),
        )),
    }
}

fn not_future(rules: &Rules, what: &str, ns: u64, now_ns: u64) -> Result<(), Refused> {
    let limit = now_ns.saturating_add(rules.max_future_ns);
    if ns > limit {
        let ahead = (ns - now_ns) as f64 / 1e9;
        return Err((
            Refusal::Future,
            format!(
                "its {what} is {ahead:.0} s ahead of this historian's clock (at most [intake] max_future_s = {:.0} s); is the daemon's clock right?",
                rules.max_future_ns as f64 / 1e9
            ),
        ));
    }
    Ok(())
}

/// Admit one health window that arrived on `key`.
pub fn window(rules: &Rules, key: &str, r: &WindowRow, now_ns: u64) -> Result<(), Refused> {
    let p = &r.point;
    same_point(
        rules,
        key,
        "health",
        [p.machine.as_str(), p.asset.as_str(), p.point.as_str()],
    )?;
    not_future(rules, "window end", r.end_ns, now_ns)?;
    not_future(rules, "publish time", r.publish_ns, now_ns)?;
    let run_ms = r.end_ns.saturating_sub(r.run_start_ns) / 1_000_000;
    let most = (run_ms.saturating_mul(MAX_SEQ_RATE) / 1000)
        .saturating_add(1)
        .min(i64::MAX as u64);
    if r.seq > most {
        return Err((
            Refusal::Seq,
            format!(
                "seq {} where a run {:.1} s old has at most {most} windows ({MAX_SEQ_RATE} per second)",
                r.seq,
                run_ms as f64 / 1e3
            ),
        ));
    }
    Ok(())
}

/// Admit one daemon status that arrived on `key`.
pub fn status(rules: &Rules, key: &str, s: &StatusRow, now_ns: u64) -> Result<(), Refused> {
    let names: Vec<&str> = s.key.splitn(3, '/').collect();
    let names = [
        names.first().copied().unwrap_or(""),
        names.get(1).copied().unwrap_or(""),
        names.get(2).copied().unwrap_or(""),
    ];
    same_point(rules, key, "status", names)?;
    not_future(rules, "time", super::row::ns_of(s.time), now_ns)
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOW: u64 = 1_800_000_000_000_000_000;

    fn rules() -> Rules {
        Rules {
            prefix: "rigmon".into(),
            max_future_ns: 300_000_000_000,
        }
    }

    /// A window of `rig` ending at `end_ns`, `end_s` into its run, numbered `seq`.
    fn window_of(rig: &str, seq: u64, end_ns: u64, end_s: f64) -> WindowRow {
        let m = serde_json::json!({
            "schema": "rigmon.health", "schema_version": 1,
            "rig": rig, "asset": "shaft", "point": "nde", "seq": seq,
            "window": {"start_s": end_s - 1.0, "end_s": end_s, "start_ns": end_ns - 1_000_000_000, "end_ns": end_ns},
            "publish_time_ns": end_ns, "rpm": 588.0, "speed_source": "tacho",
            "quality": {"ok": true, "flags": [], "clipped_samples": 0, "nan_samples": 0,
                        "dropout_samples": 0, "flat_channels": [], "missing_tacho_pulses": 0},
            "probabilities": {"healthy": 0.1, "outer_race": 0.9},
            "window_state": "outer_race", "unknown_reason": null, "state": "outer_race",
            "state_since_s": 1e300, "state_changed": false, "confidence": 0.9, "novelty": 0.2,
            "novelty_threshold": 1.0,
            "fault_bands": {"channel": "vertical", "orders": {}, "bpfo": [], "bpfi": [], "two_bsf": [], "floor": 0.0},
            "velocity_rms_mm_s": null, "iso_zone": null,
            "model": {"id": "m", "sha256": "ab", "labels": ["healthy", "outer_race"]},
            "calibration_id": null, "software_version": "0.1.0"
        });
        WindowRow::parse(m.to_string().as_bytes(), "lab").unwrap()
    }

    const KEY: &str = "rigmon/c3-ok/shaft/nde/health";

    /// Issue 38, F11: the machine was taken from the payload, so any publisher could speak
    /// for any machine. F1/F12: a window dated 2400 became the point's state now and made a
    /// partition. F2: seq 2^64-1 was taken as is.
    #[test]
    fn a_window_must_match_its_key_be_no_later_than_now_and_have_a_possible_seq() {
        let r = rules();
        let ok = window_of("c3-ok", 7, NOW - 1_000_000_000, 10.0);
        window(&r, KEY, &ok, NOW).unwrap();
        assert_eq!(
            ok.state_since, ok.time,
            "state_since 1e300 s saturates at the window end"
        );
        // another machine's key (F11)
        let (why, text) = window(&r, "rigmon/c3/any/point/health", &ok, NOW).unwrap_err();
        assert_eq!(why, Refusal::Key);
        assert!(
            text.contains("c3-ok/shaft/nde") && text.contains("rigmon/c3/any/point/health"),
            "{text}"
        );
        // a name that is no key chunk, whatever the key (F3)
        let bad = window_of("c3*bad", 1, NOW, 1.0);
        assert_eq!(window(&r, KEY, &bad, NOW).unwrap_err().0, Refusal::Name);
        // the year 2400 (F1, F12), and 301 s ahead; 299 s ahead is a skew allowed
        let y2400 = (430.0 * 365.25 * 86400e9) as u64;
        let (why, text) = window(&r, KEY, &window_of("c3-ok", 4, y2400, 4.0), NOW).unwrap_err();
        assert_eq!(why, Refusal::Future);
        assert!(text.contains("max_future_s = 300"), "{text}");
        let ahead = |s: u64| window_of("c3-ok", 4, NOW + s * 1_000_000_000, 4.0);
        assert_eq!(
            window(&r, KEY, &ahead(301), NOW).unwrap_err().0,
            Refusal::Future
        );
        window(&r, KEY, &ahead(299), NOW).unwrap();
        // seq 2^64-1 three seconds into a run (F2); 1000 windows per second is the most
        let forged = window_of("c3-ok", u64::MAX, NOW, 3.5);
        let (why, text) = window(&r, KEY, &forged, NOW).unwrap_err();
        assert_eq!(why, Refusal::Seq);
        assert!(text.contains("at most 3501"), "{text}");
        window(&r, KEY, &window_of("c3-ok", 3501, NOW, 3.5), NOW).unwrap();
        let far = window_of("c3-ok", u64::MAX, NOW, 1e12);
        assert_eq!(
            window(&r, KEY, &far, NOW).unwrap_err().0,
            Refusal::Seq,
            "beyond int8"
        );
    }

    #[test]
    fn names_are_plain_key_chunks() {
        for good in ["lut-rig", "c3-ok", "pump_7.de", "Ölpumpe"] {
            check_name("machine", good).unwrap();
        }
        for bad in [
            "",
            "c3*bad",
            "a$b",
            "a#b",
            "a?b",
            "a/b",
            "@h",
            "a b",
            "a\u{1b}[31m",
        ] {
            let e = check_name("machine", bad).unwrap_err();
            assert!(e.starts_with("machine "), "{e}");
        }
        assert!(check_name("point", &"x".repeat(129)).is_err());
        assert_eq!(
            key_point("rigmon", "rigmon/m/a/p/health", "health"),
            Some(["m", "a", "p"])
        );
        assert_eq!(key_point("rigmon", "rigmon/m/a/p/x/health", "health"), None);
        assert_eq!(key_point("rigmon", "other/m/a/p/health", "health"), None);
        assert_eq!(key_point("rigmon", "rigmon/m/a/p/status", "health"), None);
    }
}
