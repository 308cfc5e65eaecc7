#!/usr/bin/env python3
"""A second generator of LUT-rig-like recordings, written apart from measured_like.py and
from rigmon's simulator, for timing `rigmon calibrate` on data nobody tuned it to (issue 37).

Different choices on purpose: speeds 750 and 1450 rpm (not whole cycles in a segment), three
structural modes (2450, 3350, 4300 Hz) excited by half-sine force pulses (acceleration
response, not a velocity-like ring-down), pink-ish sensor noise (white plus a one-pole
low-passed part), a 1x and a 2x line, impacts whose spacing slips by 1.5 %, and an analog
tacho of 0-10 V with a 20 % duty. One effect per case, never given to calibrate:
`mains` (a 50 Hz line), `misalign` (a 2x line growing with speed^2), `resonance` (the first
mode at 2150 Hz), `fluct` (a 3 % speed fluctuation of period 1.3 s), `none`.

    python3 second_generator.py --out DIR --case CASE [--seed N] [--seconds S]

writes DIR/<label>-<rpm>rpm.csv (`time,axial,vertical,horizontal,tacho`, 10 kHz) and
DIR/labels.csv (`path,label`). Only numpy is needed.
"""

import argparse
import os

import numpy as np

FS = 10_000.0
SPEEDS = (750.0, 1450.0)
LABELS = ("healthy", "outer_race", "inner_race")
MODES = [(2450.0, 0.025, (0.4, 1.0, 0.3)), (3350.0, 0.035, (0.2, 0.6, 0.9)), (4300.0, 0.05, (0.5, 0.3, 0.4))]
BALLS, BD, PD = 11, 7.94, 48.0
CASES = ("none", "mains", "misalign", "resonance", "fluct")


def mode_kernel(hz, zeta, pulse_s=1.2e-4):
    """Acceleration response of one mode to a unit half-sine force pulse (convolution)."""
    n = int(0.05 * FS)
    t = np.arange(n) / FS
    w = 2 * np.pi * hz
    wd = w * np.sqrt(1 - zeta**2)
    h = np.exp(-zeta * w * t) * np.sin(wd * t + 0.3)
    m = max(2, int(round(pulse_s * FS * 10)))
    p = np.sin(np.pi * np.arange(m) / m)
    return np.convolve(h, p / p.sum())[:n]


def record(label, rpm, case, seconds, rng):
    n = int(round(seconds * FS))
    t = np.arange(n) / FS
    f = rpm / 60.0 * (1 + (0.03 * np.sin(2 * np.pi * t / 1.3) if case == "fluct" else 0.0 * t))
    revs = np.concatenate(([0.0], np.cumsum(f[:-1]) / FS))
    r = BD / PD
    cage = revs * 0.5 * (1 - r)
    train = np.zeros(n)
    if label != "healthy":
        phase = BALLS * (cage if label == "outer_race" else revs - cage)
        k = np.nonzero(np.diff(np.floor(phase)) > 0)[0]
        spacing = np.median(np.diff(k)) if len(k) > 1 else 1.0
        k = np.clip(np.round(k + 0.015 * spacing * rng.standard_normal(len(k))).astype(int), 0, n - 1)
        a = (40.0 if label == "outer_race" else 25.0) * (rpm / 750.0)
        if label == "inner_race":
            a = a * (0.2 + np.clip(np.cos(2 * np.pi * revs[k]), 0, None))
        np.add.at(train, k, a * (1 + 0.15 * rng.standard_normal(len(k))))
    modes = list(MODES)
    if case == "resonance":
        modes[0] = (2150.0, 0.025, MODES[0][2])
    chans = []
    for axis in range(3):
        y = np.zeros(n)
        for hz, zeta, part in modes:
            y += part[axis] * np.convolve(train, mode_kernel(hz, zeta))[:n]
        white = rng.standard_normal(n)
        low = np.convolve(white, 0.2 * 0.98 ** np.arange(400))[:n]  # one-pole low-pass
        y += 0.25 * white + 0.1 * low
        chans.append(y)
    g = (rpm / 1450.0) ** 2
    chans[1] += 0.03 * g * np.cos(2 * np.pi * revs + 1.0) + 0.01 * g * np.cos(4 * np.pi * revs)
    chans[2] += 0.02 * g * np.sin(2 * np.pi * revs + 1.0)
    if case == "mains":
        for c, gain in zip(chans, (0.3, 0.5, 0.4)):
            c += gain * np.sin(2 * np.pi * 50.0 * t + 0.7)
    if case == "misalign":
        for c, gain in zip(chans, (0.25, 0.2, 0.15)):
            c += gain * g * np.cos(4 * np.pi * revs + 0.2)
    tacho = np.where(np.mod(revs, 1.0) < 0.2, 10.0, 0.0) + 0.02 * rng.standard_normal(n)
    return t, chans, tacho


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--case", required=True, choices=CASES)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    rows = ["path,label"]
    for rpm in SPEEDS:
        for label in LABELS:
            t, chans, tacho = record(label, rpm, a.case, a.seconds, rng)
            name = f"{label}-{int(rpm)}rpm.csv"
            data = np.column_stack([t] + chans + [tacho])
            np.savetxt(os.path.join(a.out, name), data, delimiter=",", fmt="%.6g",
                       header="time,axial,vertical,horizontal,tacho", comments="")
            rows.append(f"{name},{label}")
    with open(os.path.join(a.out, "labels.csv"), "w") as fh:
        fh.write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
