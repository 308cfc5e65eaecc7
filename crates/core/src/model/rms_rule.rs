//! The classic early-warning rule rigmon's alarm is measured against (issue 35): the RMS of
//! each window against its healthy baseline, the first part of the recording. The rule alarms
//! at the first window after the baseline whose RMS exceeds the baseline's mean + 3 standard
//! deviations and after which at least `hold` (90 %) of the windows stay above; one loud
//! window followed by quiet ones does not alarm.

/// The rule's baseline, threshold and alarm over one recording's windows.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RmsRule {
    /// Windows in the baseline (the first ones).
    pub baseline_windows: usize,
    pub mean: f64,
    pub sd: f64,
    /// mean + 3 sd.
    pub threshold: f64,
    /// The alarming window's index, if the rule alarms.
    pub alarm: Option<usize>,
    /// Of the windows from the alarm on, the fraction above the threshold.
    pub held: Option<f64>,
}

/// Apply the rule to `rms` (one value per window, in time order) with the first
/// `baseline_windows` as the baseline. Errors say what is missing.
pub fn rms_three_sigma(rms: &[f64], baseline_windows: usize, hold: f64) -> Result<RmsRule, String> {
    if baseline_windows < 2 {
        return Err(format!(
            "a baseline of {baseline_windows} window(s) has no spread; it needs at least 2"
        ));
    }
    if baseline_windows >= rms.len() {
        return Err(format!(
            "the baseline ({baseline_windows} windows) leaves none of the {} windows after it",
            rms.len()
        ));
    }
    let base = &rms[..baseline_windows];
    let mean = base.iter().sum::<f64>() / base.len() as f64;
    let var = base.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (base.len() - 1) as f64;
    let sd = var.sqrt();
    let threshold = mean + 3.0 * sd;
    // Windows above the threshold from each index to the end, counted from the back.
    let mut above_from = vec![0usize; rms.len() + 1];
    for i in (0..rms.len()).rev() {
        above_from[i] = above_from[i + 1] + usize::from(rms[i] > threshold);
    }
    let alarm = (baseline_windows..rms.len())
        .find(|&i| rms[i] > threshold && above_from[i] as f64 >= hold * (rms.len() - i) as f64);
    Ok(RmsRule {
        baseline_windows,
        mean,
        sd,
        threshold,
        alarm,
        held: alarm.map(|i| above_from[i] as f64 / (rms.len() - i) as f64),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rule_alarms_where_the_level_leaves_the_baseline_for_good() {
        // A quiet baseline, one loud window, a quiet stretch, then a rise that stays (with one
        // dip below, which the 90 % hold allows).
        let mut rms: Vec<f64> = (0..20).map(|i| 1.0 + 0.01 * (i % 3) as f64).collect();
        rms.push(5.0); // 20: loud once
        rms.extend([1.0; 9]); // 21..29
        rms.extend([2.0, 2.1, 2.2, 1.0, 2.4, 2.5, 2.6, 2.7, 2.8, 2.9, 3.0, 3.1]); // 30..41
        let r = rms_three_sigma(&rms, 10, 0.9).unwrap();
        assert!((r.mean - 1.009).abs() < 1e-3, "{r:?}");
        assert_eq!(r.alarm, Some(30));
        assert!((r.held.unwrap() - 11.0 / 12.0).abs() < 1e-9);
        // Never leaving the baseline: no alarm.
        let r = rms_three_sigma(&rms[..30], 10, 0.9).unwrap();
        assert_eq!(r.alarm, None);
        assert!(rms_three_sigma(&rms, 1, 0.9)
            .unwrap_err()
            .contains("at least 2"));
        assert!(rms_three_sigma(&rms[..5], 5, 0.9).is_err());
    }
}
