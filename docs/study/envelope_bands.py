#!/usr/bin/env python3
"""Fan-end fault visibility by envelope band (the issue-18 feature study, README *Adapting to
one machine*). For each ../shared/data/cwru-fe record and the healthy 97 (FE channel): the
0.5-order band RMS of the whole-record envelope order spectrum at the labelled fault order (or
twice it), over the median band, for a 4 kHz low-pass envelope (rigmon's recipe), a 2-6 kHz
band-pass envelope and cepstral pre-whitening (with and without a band).

usage: python3 docs/study/envelope_bands.py   (from the repo root; needs numpy, scipy)
"""
import glob
import os

import numpy as np
import scipy.io as sio
import scipy.signal as ss

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data")
ORD = dict(bpfo=3.0530, bpfi=4.9469, bsf2=2 * 1.9953)


def load(path, ch="FE"):
    m = sio.loadmat(path)
    x = rpm = None
    for k, v in m.items():
        if k.endswith("_%s_time" % ch):
            x = v.ravel().astype(float)
        if k.endswith("RPM"):
            rpm = float(np.ravel(v)[0])
    return x, rpm


def env_spec(x, fs, rpm, mode, band=None):
    if mode == "lp":
        b, a = ss.butter(4, min(4000, fs / 2 * 0.95) / (fs / 2))
        y = ss.filtfilt(b, a, x)
    else:
        y = x
        if mode == "cpw":
            X = np.fft.rfft(x - x.mean())
            y = np.fft.irfft(X / (np.abs(X) + 1e-12), len(x))
        if band:
            b, a = ss.butter(4, [band[0] / (fs / 2), min(band[1], fs / 2 * 0.95) / (fs / 2)], "band")
            y = ss.filtfilt(b, a, y)
    e = np.abs(ss.hilbert(y))
    e = e - e.mean()
    E = np.abs(np.fft.rfft(e * np.hanning(len(e)))) ** 2
    return np.fft.rfftfreq(len(e), 1 / fs) / (rpm / 60), E


def ratio(o, E, order):
    idx = np.digitize(o, np.arange(0, 50.5, 0.5)) - 1
    bins = np.array([np.sqrt(E[idx == k].sum()) for k in range(100)])
    med = np.median(bins[1:])
    at = lambda v: bins[int(np.ceil(v / 0.5)) - 1] / med
    return max(at(order), at(2 * order))


def main():
    files = sorted(glob.glob(os.path.join(DATA, "cwru-fe", "*", "*.mat")))
    files.append(os.path.join(DATA, "cwru", "97_Normal_0.mat"))
    modes = [("lp", None), ("bp", (2000, 6000)), ("cpw", (1000, 6000)), ("cpw", (2000, 5900)), ("cpw", None)]
    print("%-32s" % "file", " ".join("%10s" % (m + str(b[0] if b else "")) for m, b in modes), "rpm")
    for p in files:
        x, rpm = load(p)
        fs = 48000 if "97_" in p else 12000
        x = x[: int(fs * 5)]
        name = os.path.basename(p)
        kind = "bpfi" if "IR" in name else "bpfo" if "OR" in name else "bsf2" if name.startswith("B") else None
        row = []
        for m, b in modes:
            o, E = env_spec(x, fs, rpm, m, b)
            row.append(ratio(o, E, ORD[kind]) if kind else max(ratio(o, E, ORD["bpfo"]), ratio(o, E, ORD["bpfi"])))
        print("%-32s" % name, " ".join("%10.2f" % r for r in row), rpm)


if __name__ == "__main__":
    main()
