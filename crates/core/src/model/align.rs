//! Healthy-reference alignment: move a simulation-trained classifier onto one real machine
//! using only that machine's healthy recordings. The model's in-graph standardisation is
//! shifted per feature by how the machine's healthy windows differ from the simulated healthy
//! windows the model was trained on (both as `ln(x / mean(x) + floor)`, the graph's own scale-
//! free transform). A measured healthy window then enters the network where a simulated
//! healthy window would, and a fault shows as what stands above that machine's own healthy
//! spectrum. Nothing is trained: the network, the novelty detector and the labels stay; only
//! the per-feature offset (a reference level) changes, so the model file keeps its layout.
//! The same healthy windows fit the machine's healthy-baseline gate ([`HealthyBaseline`]): a
//! window far from them is never called healthy. The same recordings' windows fit the
//! machine's healthy indicator baseline (`adapt::align_to_recordings`), which the departure
//! test of the health state machine reads.

use super::alignment::Alignment;
use super::baseline::HealthyBaseline;
use super::classifier::TrainedModel;
use super::impulsiveness::ImpulseBaseline;
use super::preprocess::Preprocess;
use anyhow::{bail, Result};
use ndarray::{Array1, ArrayView2, Axis};

/// Fewest healthy windows an alignment accepts: below this the per-bin means are mostly noise.
pub const MIN_WINDOWS: usize = 4;

/// Per-feature mean of the scale-free log ratios of `windows` (rows = windows).
pub fn log_mean(windows: ArrayView2<f32>, floor: f32) -> Array1<f32> {
    let l = Preprocess::log_ratio(windows, floor);
    l.mean_axis(Axis(0))
        .unwrap_or_else(|| Array1::zeros(windows.ncols()))
}

/// A copy of `model` whose reference levels are those of the measured healthy `windows`
/// (and, given their classifier-channel excess `kurtosis`, one per row of `windows`, whose
/// impulsiveness baseline is theirs).
/// The model must carry the simulated healthy reference (`healthy_reference` in its
/// metadata, written by `rigmon train`); an aligned model is aligned again from its original
/// offsets, so aligning twice with the same data gives the same file.
pub fn align_to_healthy(
    model: &TrainedModel,
    windows: ArrayView2<f32>,
    kurtosis: Option<&[f32]>,
    records: &[String],
) -> Result<TrainedModel> {
    let sim = &model.meta.healthy_reference;
    let n = model.pre.n_features();
    if sim.len() != n {
        bail!(
            "the model carries no simulated healthy reference ({} values for {n} features); retrain it with `rigmon train` (models trained before the reference was stored cannot be aligned)",
            sim.len()
        );
    }
    if windows.ncols() != n {
        bail!(
            "the healthy recordings give {} features per window, the model expects {n}: use the rig file the model was trained for",
            windows.ncols()
        );
    }
    if windows.nrows() < MIN_WINDOWS {
        bail!(
            "{} healthy window(s) in {}: an alignment needs at least {MIN_WINDOWS}; give longer or more healthy recordings",
            windows.nrows(),
            records.join(", ")
        );
    }
    let measured = log_mean(windows, model.pre.floor);
    let mut out = model.clone();
    // Undo an earlier alignment so the shift is always taken from the trained offsets.
    let base = &model.meta.trained_mean;
    let trained: Array1<f32> = if base.len() == n {
        Array1::from(base.clone())
    } else {
        model.pre.mean.clone()
    };
    let shift: Array1<f32> = &measured - &Array1::from(sim.clone());
    out.pre.mean = &trained + &shift;
    let (k, big) =
        shift.iter().enumerate().fold(
            (0, 0.0f32),
            |b, (i, &v)| if v.abs() > b.1.abs() { (i, v) } else { b },
        );
    let rms = (shift.iter().map(|v| v * v).sum::<f32>() / n.max(1) as f32).sqrt();
    let baseline = HealthyBaseline::fit(windows, model.pre.floor)?;
    let info = Alignment {
        windows: windows.nrows(),
        records: records.to_vec(),
        shift_rms: rms,
        largest_shift_feature: k,
        largest_shift: big,
        baseline_threshold: Some(baseline.threshold),
        baseline_inv_spread: Some(baseline.inv_spread),
        healthy_kurtosis: kurtosis.and_then(ImpulseBaseline::fit),
        healthy_indicators: None,
    };
    out.baseline = Some(baseline);
    out.meta.trained_mean = trained.to_vec();
    out.meta.alignment = Some(info);
    out.meta.sha256.clear();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::meta::ModelMeta;
    use crate::model::mlp::Mlp;
    use crate::model::novelty::Mahalanobis;
    use ndarray::Array2;
    use rand::SeedableRng;

    fn model(reference: Vec<f32>) -> TrainedModel {
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        let x = Array2::from_shape_fn((8, 4), |(i, j)| 1.0 + ((i * 7 + j * 3) % 5) as f32);
        let pre = Preprocess::fit(x.view(), 1e-3);
        let mlp = Mlp::new(&[4, 8, 2], &mut rng);
        let h = Array2::from_shape_fn((8, 8), |(i, j)| ((i + j) % 3) as f32);
        let novelty = Mahalanobis::fit(h.view(), &[0, 0, 0, 0, 1, 1, 1, 1], 2, 0.1).unwrap();
        TrainedModel {
            pre,
            mlp,
            novelty,
            meta: ModelMeta {
                labels: vec!["healthy".into(), "outer_race".into()],
                n_features: 4,
                healthy_reference: reference,
                ..ModelMeta::default()
            },
            baseline: None,
        }
    }

    #[test]
    fn measured_healthy_windows_land_on_the_simulated_healthy_reference() {
        let sim_h = Array2::from_shape_fn((6, 4), |(i, j)| {
            [1.0f32, 2.0, 1.0, 0.5][j] * (1.0 + 0.01 * i as f32)
        });
        let reference = log_mean(sim_h.view(), 1e-3).to_vec();
        let m = model(reference.clone());
        // The "real" machine has a strong line in feature 2 and a weaker one in feature 3.
        let real_h = Array2::from_shape_fn((6, 4), |(i, j)| {
            [1.0f32, 2.0, 9.0, 0.1][j] * (1.0 + 0.01 * i as f32)
        });
        let kurtosis = [-0.3, -0.2, -0.25, -0.3, -0.2, -0.25];
        let a = align_to_healthy(&m, real_h.view(), Some(&kurtosis), &["97.mat".into()]).unwrap();
        // Standardised real healthy == standardised simulated healthy, feature by feature.
        let zr = a.pre.apply(real_h.view()).mean_axis(Axis(0)).unwrap();
        let zs = m.pre.apply(sim_h.view()).mean_axis(Axis(0)).unwrap();
        for j in 0..4 {
            assert!(
                (zr[j] - zs[j]).abs() < 1e-3,
                "feature {j}: {} vs {}",
                zr[j],
                zs[j]
            );
        }
        let info = a.meta.alignment.as_ref().expect("aligned");
        assert_eq!(info.windows, 6);
        let k = info.impulse().expect("the kurtosis baseline is stored");
        assert!((k.mean + 0.25).abs() < 1e-6 && k.windows == 6, "{k:?}");
        assert_eq!(info.largest_shift_feature, 3); // 0.5 -> 0.1 of a larger mean: ln 0.44 -> ln 0.033
                                                   // Aligning the aligned model again with the same data gives the same offsets.
        let b = align_to_healthy(&a, real_h.view(), None, &["97.mat".into()]).unwrap();
        assert_eq!(a.pre.mean, b.pre.mean);
    }

    #[test]
    fn refuses_models_without_a_reference_and_too_few_windows() {
        let w = Array2::<f32>::ones((6, 4));
        let e = align_to_healthy(&model(vec![]), w.view(), None, &[]).unwrap_err();
        assert!(e.to_string().contains("retrain"), "{e}");
        let e = align_to_healthy(
            &model(vec![0.0; 4]),
            w.slice(ndarray::s![..2, ..]),
            None,
            &["a".into()],
        )
        .unwrap_err();
        assert!(e.to_string().contains("at least"), "{e}");
    }
}
