//! Order statistics of a slice (median, nearest-rank quantile) shared by the calibration
//! views and the detectors they call ([`super::modes`], [`super::shaft_orders`],
//! [`super::fractional_orders`], [`super::impacts`]).

/// Median of a slice (0 when empty).
pub fn median(x: &[f64]) -> f64 {
    quantile(x, 0.5)
}

/// The `q` quantile of a slice (nearest rank; 0 when empty).
pub fn quantile(x: &[f64], q: f64) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mut v = x.to_vec();
    let k = ((q.clamp(0.0, 1.0) * v.len() as f64) as usize).min(v.len() - 1);
    v.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    v[k]
}
