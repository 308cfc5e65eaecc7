#!/usr/bin/env python3
"""Independent check of a rigmon classifier file with the reference ONNX tooling.

usage: check_onnx.py MODEL.onnx [CASES.json]

- onnx.checker.check_model(full_check=True) must pass (schema + shape inference);
- IR version 8, default-domain opset >= 13;
- input `features` [N, n_features]; outputs `probabilities` and `novelty` (and
  `baseline_distance` for a model aligned to a machine's healthy baseline, and
  `baseline_deviation` for one aligned since the fault-family evidence exists);
- metadata_props carry the rigmon keys;
- with CASES.json ({"inputs": [[...]], "probabilities": [[...]], "novelty": [...]}) the
  onnxruntime outputs must equal the expected ones within 1e-5 (novelty: relative to
  max(1, |value|)).
Prints one JSON line with what was checked; exits non-zero on the first failure.
"""
import json
import sys

import numpy as np
import onnx
import onnxruntime as ort

REQUIRED_META = ["labels", "bin_width", "max_order", "axis", "rig_id", "data_hash",
                 "calibration_id", "rigmon_version", "novelty_threshold", "n_features"]


def fail(msg):
    print(f"check_onnx: FAIL: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    if len(sys.argv) not in (2, 3):
        fail(__doc__)
    path = sys.argv[1]
    model = onnx.load(path)
    onnx.checker.check_model(model, full_check=True)
    if model.ir_version != 8:
        fail(f"ir_version {model.ir_version}, expected 8")
    opset = {o.domain: o.version for o in model.opset_import}
    if opset.get("", 0) < 13:
        fail(f"default opset {opset.get('', None)}, expected >= 13")
    meta = {p.key: p.value for p in model.metadata_props}
    missing = [k for k in REQUIRED_META if k not in meta]
    if missing:
        fail(f"metadata_props lacks {missing}")
    labels = meta["labels"].split(",")
    n_features = int(meta["n_features"])

    sess = ort.InferenceSession(path, providers=["CPUExecutionProvider"])
    ins = sess.get_inputs()
    outs = [o.name for o in sess.get_outputs()]
    if [i.name for i in ins] != ["features"] or ins[0].shape[1] != n_features:
        fail(f"inputs {[(i.name, i.shape) for i in ins]}")
    aligned = "alignment" in meta
    want_outs = ["probabilities", "novelty"] + (["baseline_distance"] if aligned else [])
    # models aligned since the fault-family evidence exists add each bin's deviation
    if aligned and outs == want_outs + ["baseline_deviation"]:
        want_outs = outs
    if outs != want_outs:
        fail(f"outputs {outs}, expected {want_outs}")
    custom = sess.get_modelmeta().custom_metadata_map
    if custom.get("labels") != meta["labels"]:
        fail("onnxruntime does not see the metadata")

    report = {"model": path, "ir_version": model.ir_version, "opset": opset.get(""),
              "labels": labels, "n_features": n_features, "checker": "ok"}
    if len(sys.argv) == 3:
        with open(sys.argv[2]) as f:
            cases = json.load(f)
        x = np.asarray(cases["inputs"], dtype=np.float32)
        got = sess.run(want_outs, {"features": x})
        probs, novelty = got[0], got[1]
        want_p = np.asarray(cases["probabilities"], dtype=np.float32)
        want_n = np.asarray(cases["novelty"], dtype=np.float32)
        if probs.shape != want_p.shape or novelty.shape != want_n.shape:
            fail(f"shapes {probs.shape} {novelty.shape} vs expected {want_p.shape} {want_n.shape}")
        dp = float(np.max(np.abs(probs - want_p)))
        dn = float(np.max(np.abs(novelty - want_n) / np.maximum(1.0, np.abs(want_n))))
        report.update({"cases": int(x.shape[0]), "max_prob_diff": dp, "max_novelty_rel_diff": dn})
        if dp > 1e-5 or dn > 1e-5:
            fail(f"onnxruntime differs from rigmon: probabilities {dp:.3e}, novelty {dn:.3e} (limit 1e-5)")
        if "baseline_distance" in cases:
            want_d = np.asarray(cases["baseline_distance"], dtype=np.float32)
            dd = float(np.max(np.abs(got[2] - want_d) / np.maximum(1.0, np.abs(want_d))))
            report["max_baseline_rel_diff"] = dd
            if dd > 1e-5:
                fail(f"onnxruntime baseline_distance differs from rigmon by {dd:.3e} (limit 1e-5)")
        if "baseline_deviation" in cases:
            if "baseline_deviation" not in want_outs:
                fail("the cases give baseline_deviation but the model has no such output")
            want_v = np.asarray(cases["baseline_deviation"], dtype=np.float32)
            got_v = got[want_outs.index("baseline_deviation")]
            dv = float(np.max(np.abs(got_v - want_v) / np.maximum(1.0, np.abs(want_v))))
            report["max_deviation_rel_diff"] = dv
            if got_v.shape != want_v.shape or dv > 1e-4:
                fail(f"onnxruntime baseline_deviation differs from rigmon by {dv:.3e} (limit 1e-4)")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
