#!/usr/bin/env python3
"""Checks made outside rigmon (numpy/scipy only) behind figures in docs/diagnosis.md:

1. HIT-SM Normal records: the raw spectrum's lines at 10, 15, 20 Hz over the spectrum's median
   (5-120 Hz) -- what speed the healthy machine turns at, whatever the file name says.
2. CWRU fan end B007_1 against the healthy 97 (FE channel): the envelope's 2x BSF harmonics
   (natural-log units above a running median, bands 1-3 and 2-5 kHz) and the kurtosis of
   1 s windows (hop 0.5 s), min / median / max.
3. The generator's `weak_inner_race` case (tests/python/measured_like.py, seed 2, 20 s): the
   BPFI line of the vertical channel's envelope (2-4.5 kHz band, 1 s windows, averaged) over
   the median of the envelope spectrum, inner-race and healthy records at 300 and 600 rpm.

usage: python3 docs/study/outside_checks.py   (from the repo root, ../shared beside it)
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
import scipy.io as sio
from scipy.ndimage import median_filter
from scipy.signal import butter, hilbert, sosfilt
from scipy.stats import kurtosis

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data")


def one_vector(path):
    m = sio.loadmat(path)
    return np.asarray(next(v for k, v in m.items() if not k.startswith("__")), float).ravel()


def channel(path, suffix):
    m = sio.loadmat(path)
    return np.ravel(next(v for k, v in m.items() if k.endswith(suffix)))


def hit_sm_normal():
    fs = 51200.0
    print("HIT-SM Normal records: raw line / spectrum median (5-120 Hz)")
    for rpm in (600, 900, 1200):
        x = one_vector(os.path.join(DATA, "hit-sm-self", f"Normal_{rpm}.mat"))
        x = x - x.mean()
        spec = np.abs(np.fft.rfft(x * np.hanning(len(x))))
        f = np.fft.rfftfreq(len(x), 1 / fs)
        med = np.median(spec[(f > 5) & (f < 120)])
        cells = []
        for f0 in (10.0, 15.0, 20.0):
            near = (f > f0 - 0.6) & (f < f0 + 0.6)
            i = np.argmax(spec[near])
            cells.append(f"{f[near][i]:.2f} Hz: {spec[near][i] / med:.1f}x")
        print(f"  Normal_{rpm}: " + ", ".join(cells))


def cwru_fe_ball():
    fs = 12000.0
    n, d, pitch = 8, 6.746, 28.50  # config/cwru-fe.toml [bearing]
    two_bsf = pitch / d * (1 - (d / pitch) ** 2)
    print("CWRU fan end, FE channel")
    for name, rel, rpm in (
        ("97_Normal_0", "cwru/97_Normal_0.mat", 1796.0),
        ("B007_1", "cwru-fe/007/B007_1.mat", 1777.0),
    ):
        x = channel(os.path.join(DATA, rel), "FE_time")
        fr = rpm / 60.0
        for band in ((1000, 3000), (2000, 5000)):
            sos = butter(4, band, btype="band", fs=fs, output="sos")
            e = np.abs(hilbert(sosfilt(sos, x - x.mean())))
            e -= e.mean()
            spec = np.log(np.abs(np.fft.rfft(e * np.hanning(len(e)))) + 1e-12)
            white = spec - median_filter(spec, size=301)
            f = np.fft.rfftfreq(len(e), 1 / fs)

            def at(order):
                near = (f > order * fr * 0.98) & (f < order * fr * 1.02)
                return white[near].max()

            lines = " ".join(f"{at(h * two_bsf):.1f}" for h in (1, 2, 3))
            print(f"  {name} envelope {band[0]}-{band[1]} Hz: 2xBSF harmonics 1-3 {lines}")
        k = [kurtosis(x[i : i + int(fs)]) for i in range(0, len(x) - int(fs) + 1, int(fs) // 2)]
        print(
            f"  {name} kurtosis per 1 s window ({len(k)}): "
            f"min {min(k):.2f} median {np.median(k):.2f} max {max(k):.2f}"
        )


def weak_inner_race():
    fs = 10_000.0
    balls, d, pitch = 11, 7.94, 48.0  # config/lut-rig.toml [bearing]
    bpfi = balls / 2 * (1 + d / pitch)
    gen = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "python", "measured_like.py")
    with tempfile.TemporaryDirectory() as out:
        subprocess.run(
            [sys.executable, gen, "--out", out, "--case", "weak_inner_race", "--seed", "2", "--seconds", "20"],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        print("generator weak_inner_race (seed 2): BPFI line / envelope median, vertical")
        sos = butter(4, (2000, 4500), btype="band", fs=fs, output="sos")
        for rpm in (300, 600):
            cells = []
            for label in ("healthy", "inner_race"):
                x = np.loadtxt(os.path.join(out, f"{label}-{rpm}rpm.csv"), delimiter=",", skiprows=1)[:, 2]
                e = np.abs(hilbert(sosfilt(sos, x)))
                n = int(fs)
                spec = np.mean(
                    [np.abs(np.fft.rfft((w - w.mean()) * np.hanning(n))) for w in e[: len(e) // n * n].reshape(-1, n)],
                    axis=0,
                )
                f = np.fft.rfftfreq(n, 1 / fs)
                near = (f > 0.97 * bpfi * rpm / 60) & (f < 1.03 * bpfi * rpm / 60)
                cells.append(f"{label} {spec[near].max() / np.median(spec[(f > 5) & (f < 500)]):.1f}x")
            print(f"  {rpm} rpm: " + ", ".join(cells))


if __name__ == "__main__":
    hit_sm_normal()
    cwru_fe_ball()
    weak_inner_race()
