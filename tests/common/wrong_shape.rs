//! A real ONNX model of the wrong shape for the LUT rig, for start-up and reload tests: the
//! shipped model cut down to its first 50 inputs (orders 0-25), written by rigmon's exporter.
//! tract loads it; the rig gives 100 bins, so the daemon must refuse it.

use std::path::Path;

/// Inputs the cut model keeps.
pub const KEEP: usize = 50;

/// Write the cut-down copy of `model` to `out`.
pub fn write_wrong_shape_model(model: &Path, out: &Path) {
    use rigmon::model::export;
    let mut m = export::read(model).unwrap();
    let first = &mut m.mlp.layers[0];
    first.w = first.w.slice(ndarray::s![.., ..KEEP]).to_owned();
    m.pre.mean = m.pre.mean.slice(ndarray::s![..KEEP]).to_owned();
    m.pre.inv_std = m.pre.inv_std.slice(ndarray::s![..KEEP]).to_owned();
    m.meta.n_features = KEEP;
    m.meta.max_order = KEEP as f64 * m.meta.bin_width;
    export::write(&m, out).unwrap();
}
