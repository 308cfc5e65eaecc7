#!/usr/bin/env python3
"""Band selection by kurtogram, measured (issue 18; docs/features.md "Band selection by
kurtogram: measured"). Runs `rigmon inspect REC --rig RIG --json` on every row of the two
manifests beside this script (kurtogram-de.csv: the drive-end records, DE channel,
config/cwru-de.toml; kurtogram-fe.csv: the fan-end records, FE channel, config/cwru-fe.toml;
both hold the healthy 97) and prints Markdown tables of the rule's statistic for the labelled
fault family (BPFO for outer race, BPFI for inner race, 2xBSF for ball: the larger of the
0.5-order bands at the order and at twice it, over the median band, per 1 s window), as the
mean over a record's windows and the share of windows >= 3, under three envelope bands: the
fixed 4 kHz low-pass, the kurtogram's best band per window, the kurtogram's best band per
record, for each kurtogram depth asked. The healthy 97 gets all three families. Separation
from 97 (same family, same channel): a fault record's margin is its mean over 97's mean; its
AUC the share of (record window, 97 window) pairs where the record's window is higher.

Every kurtogram searches 0-6 kHz (--kurtogram-max-hz 6000): the fault records' Nyquist, so the
48 kHz healthy record is searched on the same grid of bands.

usage (from the repo root, after `cargo build --release`):
    python3 docs/study/kurtogram_bands.py [--rigmon target/release/rigmon] [--levels 6 2]
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SETS = [
    ("drive end (DE)", "kurtogram-de.csv", "config/cwru-de.toml"),
    ("fan end (FE)", "kurtogram-fe.csv", "config/cwru-fe.toml"),
]
FAMILY = {"outer_race": "bpfo", "inner_race": "bpfi", "ball": "two_bsf"}
FAMILY_NAME = {"bpfo": "BPFO", "bpfi": "BPFI", "two_bsf": "2xBSF"}


def inspect(rigmon, path, rig, levels):
    cmd = [rigmon, "inspect", path, "--rig", rig, "--json",
           "--kurtogram-levels", str(levels), "--kurtogram-max-hz", "6000"]
    run = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit("failed: %s\n%s" % (" ".join(cmd), run.stderr))
    return json.loads(run.stdout)


def cell(summary, auc=None):
    text = "%.2f (%.0f %%" % (summary["mean"], 100 * summary["share_at_threshold"])
    return text + (", %.2f)" % auc if auc is not None else ")")


def auc(record, healthy):
    """Share of (record window, healthy window) pairs where the record's ratio is higher."""
    return sum((f > g) + 0.5 * (f == g) for f in record for g in healthy) / (len(record) * len(healthy))


def band_text(doc):
    b = doc["kurtogram"]["best"]
    return "%.0f-%.0f (%s, K %.2f)" % (b["lo_hz"], b["hi_hz"], b["level_label"], b["kurtosis"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default = os.path.join(ROOT, "target", "release", "rigmon")
    if not os.path.exists(default):
        default = os.path.join(ROOT, "target", "debug", "rigmon")
    ap.add_argument("--rigmon", default=default)
    ap.add_argument("--levels", type=int, nargs="+", default=[6, 2])
    args = ap.parse_args()

    variants = [("lowpass", None, "low-pass 4 kHz")]
    for lv in args.levels:
        variants.append(("kurtogram_window", lv, "per window, %d levels" % lv))
        variants.append(("kurtogram_record", lv, "per record, %d levels" % lv))

    for set_name, manifest, rig in SETS:
        rows = []
        with open(os.path.join(HERE, manifest)) as f:
            for r in csv.DictReader(f):
                path = os.path.normpath(os.path.join(HERE, r["path"]))
                docs = {lv: inspect(args.rigmon, path, rig, lv) for lv in args.levels}
                rows.append((os.path.basename(path), r["label"], docs))

        def summary(docs, choice, lv, fam):
            doc = docs[lv if lv is not None else args.levels[0]]
            band = next(b for b in doc["bands"] if b["choice"] == choice)
            return band[fam]

        def ratios(docs, choice, lv, fam):
            doc = docs[lv if lv is not None else args.levels[0]]
            band = next(b for b in doc["bands"] if b["choice"] == choice)
            return [w["ratios"][fam] for w in band["windows"]]

        healthy = [d for _, label, d in rows if label == "healthy"]
        if len(healthy) != 1:
            sys.exit("%s: need exactly one healthy row, found %d" % (manifest, len(healthy)))
        healthy = healthy[0]

        print("\n### %s: `%s`, `docs/study/%s`\n" % (set_name, rig, manifest))
        print("mean ratio over 1 s windows (share of windows >= 3; for a fault record, AUC against 97)\n")
        head = ["record", "label", "family"] + [v[2] for v in variants]
        head += ["record band, Hz (level, K), %d levels" % lv for lv in args.levels]
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for fam in ["bpfo", "bpfi", "two_bsf"]:
            cells = [cell(summary(healthy, c, lv, fam)) for c, lv, _ in variants]
            bands = [band_text(healthy[lv]) for lv in args.levels]
            print("| 97 | healthy | %s | %s | %s |" % (FAMILY_NAME[fam], " | ".join(cells), " | ".join(bands)))
        for name, label, docs in rows:
            if label == "healthy":
                continue
            fam = FAMILY[label]
            cells = [cell(summary(docs, c, lv, fam), auc(ratios(docs, c, lv, fam), ratios(healthy, c, lv, fam)))
                     for c, lv, _ in variants]
            bands = [band_text(docs[lv]) for lv in args.levels]
            print("| %s | %s | %s | %s | %s |" % (name, label, FAMILY_NAME[fam], " | ".join(cells), " | ".join(bands)))

        print("\nseparation from the healthy 97, same family and channel: margin = the record's mean "
              "ratio / 97's; AUC = share of (record window, 97 window) pairs in which the record's "
              "window has the higher ratio (1: every window above every healthy one); 97 >= 3 = "
              "share of 97's windows the rule would flag\n")
        head = ["envelope band", "margin > 1", "margin > 1.5", "median margin", "AUC >= 0.9",
                "median AUC", "not above 97 (margin <= 1)", "97 >= 3 (BPFO / BPFI / 2xBSF)"]
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for c, lv, title in variants:
            margins, aucs, below = [], [], []
            for name, label, docs in rows:
                if label == "healthy":
                    continue
                fam = FAMILY[label]
                h = summary(healthy, c, lv, fam)["mean"]
                m = summary(docs, c, lv, fam)["mean"] / h if h > 0 else float("inf")
                margins.append(m)
                if m <= 1:
                    below.append("%s %.2f" % (name.replace(".mat", ""), m))
                aucs.append(auc(ratios(docs, c, lv, fam), ratios(healthy, c, lv, fam)))
            alarms = " / ".join("%.0f %%" % (100 * summary(healthy, c, lv, f)["share_at_threshold"])
                                for f in ["bpfo", "bpfi", "two_bsf"])
            print("| %s | %d / %d | %d | %.2f | %d | %.2f | %s | %s |" % (
                title, sum(m > 1 for m in margins), len(margins), sum(m > 1.5 for m in margins),
                statistics.median(margins), sum(a >= 0.9 for a in aucs), statistics.median(aucs),
                ", ".join(below) or "none", alarms))


if __name__ == "__main__":
    main()
