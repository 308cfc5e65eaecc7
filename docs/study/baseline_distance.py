#!/usr/bin/env python3
"""Which healthy-baseline distance flags the faint fan-end faults (README *Adapting to one
machine*, src/model/baseline.rs). Reads `rigmon features --json` output of every
../shared/data/cwru-fe record and of 97 (FE channel), takes 97's windows as the machine's
healthy windows, and prints per record the median distance and the share of windows beyond
1.5 x the largest leave-one-out healthy distance, for: RMS over all 100 bins, RMS of the 5 /
10 largest squared deviations, and of the 5 largest positive ones.

usage (from the repo root; needs numpy):
    mkdir -p /tmp/fj
    for f in ../shared/data/cwru-fe/*/*.mat ../shared/data/cwru/97_Normal_0.mat; do
      rigmon features "$f" --rig config/cwru-fe.toml --json > /tmp/fj/$(basename "$f" .mat).jsonl
    done
    python3 docs/study/baseline_distance.py /tmp/fj
"""
import glob
import json
import os
import sys

import numpy as np


def log_ratio(path):
    X = np.array([json.loads(l)["features"]["FE"] for l in open(path)])
    return np.log(X / X.mean(1, keepdims=True) + 1e-3)


def metrics(dev):
    sq = dev ** 2
    top = lambda a, k: np.sqrt(np.sort(a, -1)[..., -k:].mean(-1))
    return dict(rms=np.sqrt(sq.mean(-1)), top5=top(sq, 5), top10=top(sq, 10),
                pos5=top(np.clip(dev, 0, None) ** 2, 5))


def main():
    d = sys.argv[1]
    H = log_ratio(os.path.join(d, "97_Normal_0.jsonl"))
    n = len(H)
    ref = H.mean(0)
    sd = np.sqrt(((H - ref) ** 2).mean())
    loo = {k: [] for k in ["rms", "top5", "top10", "pos5"]}
    for i in range(n):
        m = metrics((H[i] - (H.sum(0) - H[i]) / (n - 1)) / sd)
        for k in loo:
            loo[k].append(m[k])
    thr = {k: 1.5 * max(v) for k, v in loo.items()}
    print("thresholds", {k: round(float(v), 2) for k, v in thr.items()})
    for f in sorted(glob.glob(os.path.join(d, "*.jsonl"))):
        m = metrics((log_ratio(f) - ref) / sd)
        print("%-30s" % os.path.basename(f),
              " ".join("%s %.2f/%3.0f%%" % (k, np.median(m[k]), 100 * np.mean(m[k] > thr[k])) for k in m))


if __name__ == "__main__":
    main()
