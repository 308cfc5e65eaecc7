//! The time of each capture in a series: from the captures' own clock (FEMTO's files start with
//! hour, minute, second, microsecond), where a step from one capture to the next is a plausible
//! multiple of the interval; else (the clock jumped, as Bearing1_1's does by hours at files
//! 2120-2122) one interval after the previous capture, with a warning naming the files. Without
//! a clock, capture k is at k x interval.

/// Seconds in a day: a clock that steps back by about this much passed midnight.
const DAY_S: f64 = 86_400.0;
/// A clock step is the clock's own when it lies between half an interval and this many
/// intervals (a few captures missing); anything else is a jump.
const MOST_INTERVALS: f64 = 10.0;

/// Capture times, s since the first capture, and where the clock jumped.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureTimes {
    pub times_s: Vec<f64>,
    pub interval_s: f64,
    /// Captures (indices) placed one interval after the previous one because the clock jumped,
    /// with the clock step it showed, s.
    pub jumps: Vec<(usize, f64)>,
    /// Where the interval came from ("acquisition.capture_interval_s", "the median step of
    /// the capture clock").
    pub interval_from: String,
}

/// Time of day, s, from hour, minute, second and microsecond.
pub fn time_of_day(h: f64, m: f64, s: f64, us: f64) -> f64 {
    h * 3600.0 + m * 60.0 + s + us * 1e-6
}

/// "15:32:49.066"
pub fn clock_text(t: f64) -> String {
    let t = t.rem_euclid(DAY_S);
    let (h, rest) = ((t / 3600.0).floor(), t % 3600.0);
    let (m, s) = ((rest / 60.0).floor(), rest % 60.0);
    format!("{h:02}:{m:02}:{s:06.3}")
}

/// One step of a time-of-day clock, midnight passed counted forward.
fn step(from: f64, to: f64) -> f64 {
    let d = to - from;
    if d < 0.0 {
        d + DAY_S
    } else {
        d
    }
}

/// The median step of the clock, s, among steps in (0, 1 h]: the interval it shows.
fn median_step(clock: &[f64]) -> Option<f64> {
    let mut steps: Vec<f64> = clock
        .windows(2)
        .map(|w| step(w[0], w[1]))
        .filter(|&d| d > 0.0 && d <= 3600.0)
        .collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    // Whole milliseconds: the clock's last digits jitter.
    Some((steps[steps.len() / 2] * 1e3).round() / 1e3)
}

/// Capture times from the captures' clocks (time of day, s). `stated`: the interval the rig
/// file states, which wins over the clock's median step.
pub fn from_clock(clock: &[f64], stated: Option<f64>) -> Result<CaptureTimes, String> {
    let (interval_s, interval_from) = match (stated, median_step(clock)) {
        (Some(dt), _) => (
            dt,
            "acquisition.capture_interval_s in the rig file".to_string(),
        ),
        (None, Some(dt)) => (
            dt,
            "the median step of the capture clock (state it with acquisition.capture_interval_s)"
                .to_string(),
        ),
        (None, None) if clock.len() <= 1 => (1.0, "one capture: no interval".to_string()),
        (None, None) => {
            return Err(
                "the capture clock never steps forward by up to an hour, so it gives no interval; \
                 set acquisition.capture_interval_s in the rig file"
                    .into(),
            )
        }
    };
    let mut times_s = Vec::with_capacity(clock.len());
    let mut jumps = Vec::new();
    for (k, &c) in clock.iter().enumerate() {
        if k == 0 {
            times_s.push(0.0);
            continue;
        }
        let d = step(clock[k - 1], c);
        let plausible = d >= 0.5 * interval_s && d <= MOST_INTERVALS * interval_s;
        if plausible {
            times_s.push(times_s[k - 1] + d);
        } else {
            jumps.push((k, c - clock[k - 1]));
            times_s.push(times_s[k - 1] + interval_s);
        }
    }
    Ok(CaptureTimes {
        times_s,
        interval_s,
        jumps,
        interval_from,
    })
}

/// Capture k at k x `interval_s`.
pub fn from_interval(n: usize, interval_s: f64) -> CaptureTimes {
    CaptureTimes {
        times_s: (0..n).map(|k| k as f64 * interval_s).collect(),
        interval_s,
        jumps: Vec::new(),
        interval_from: "acquisition.capture_interval_s in the rig file".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clock_that_jumps_is_replaced_by_the_interval_there_only() {
        // Like FEMTO Bearing1_1 at files 2120-2122: hours back, then forward again.
        let t = |h, m, s| time_of_day(h, m, s, 65_664.0);
        let clock = [
            t(15.0, 32.0, 29.0),
            t(15.0, 32.0, 39.0),
            t(15.0, 32.0, 49.0),
            t(9.0, 38.0, 46.0),
            t(15.0, 33.0, 19.0),
            t(15.0, 33.0, 29.0),
            t(15.0, 33.0, 49.0), // one capture missing: the clock's 20 s kept
        ];
        let c = from_clock(&clock, None).unwrap();
        assert_eq!(c.interval_s, 10.0);
        assert_eq!(c.jumps.iter().map(|j| j.0).collect::<Vec<_>>(), vec![3, 4]);
        let want = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 70.0];
        for (got, want) in c.times_s.iter().zip(want) {
            assert!((got - want).abs() < 1e-6, "{:?}", c.times_s);
        }
        assert!(c.interval_from.contains("median"));
        // A stated interval wins over the clock's.
        let c = from_clock(&clock, Some(20.0)).unwrap();
        assert_eq!(c.interval_s, 20.0);
        assert!(c.interval_from.contains("capture_interval_s"));
    }

    #[test]
    fn midnight_is_a_step_forward_and_the_text_reads_as_a_clock() {
        let clock = [
            time_of_day(23.0, 59.0, 55.0, 0.0),
            time_of_day(0.0, 0.0, 5.0, 0.0),
        ];
        let c = from_clock(&clock, Some(10.0)).unwrap();
        assert_eq!(c.times_s, vec![0.0, 10.0]);
        assert!(c.jumps.is_empty());
        assert_eq!(
            clock_text(time_of_day(9.0, 38.0, 46.0, 865_660.0)),
            "09:38:46.866"
        );
        assert!(from_clock(&[5.0, 5.0, 5.0], None).is_err());
    }
}
