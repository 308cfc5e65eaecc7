#!/usr/bin/env python3
"""Write an MFPT-shaped dry-run set: 20 `.mat` files in the public MFPT layout (struct
`bearing` with `sr`, `gs` in g, `load` in lbs, `rate` = shaft Hz) from a small generator of its
own (not rigmon's simulator): impacts of an 8-element bearing (d = 0.235 in, D = 1.245 in,
BPFO 81.125 Hz, BPFI 118.875 Hz at 25 Hz) ringing a 3.3 kHz housing mode, a second mode,
1x/2x lines and sensor noise.

- 3 healthy baselines and 3 outer-race files at 97,656 Hz, 6 s, 270 lbs;
- 7 outer-race and 7 inner-race files at 48,828 Hz, 3 s, loads 0-300 lbs.

It checks that `rigmon adapt --rig config/mfpt.toml` runs on the second public rig's shape of
data (mixed rates far above the simulation's, speed and load from the struct) and how long it
takes; the synthetic faults are strong, so it says nothing about accuracy on the real set.

    pip install numpy scipy
    python3 docs/study/mfpt_like.py --out /tmp/mfpt
    # writes /tmp/mfpt/healthy.csv (the 3 baselines) and /tmp/mfpt/all.csv (all 20)
"""
import argparse
import os

import numpy as np
import scipy.io

SHAFT_HZ = 25.0
BPFO = 81.125
BPFI = 118.875


def ring(fs, hz, damping, seconds):
    t = np.arange(int(seconds * fs)) / fs
    return np.exp(-damping * 2 * np.pi * hz * t) * np.sin(2 * np.pi * hz * t)


def signal(kind, fs, seconds, load_lbs, rng):
    n = int(seconds * fs)
    t = np.arange(n) / fs
    x = 0.05 * np.sin(2 * np.pi * SHAFT_HZ * t + rng.uniform(0, 6.3))
    x += 0.02 * np.sin(2 * np.pi * 2 * SHAFT_HZ * t + rng.uniform(0, 6.3))
    x += 0.08 * rng.standard_normal(n)
    if kind != "healthy":
        rate = BPFO if kind == "outer_race" else BPFI
        pulses = np.zeros(n)
        k = 0
        while True:
            tk = k / rate + rng.normal(0, 0.01 / rate)
            if tk >= seconds:
                break
            if tk >= 0:
                i = int(tk * fs)
                a = 1.0 + 0.3 * load_lbs / 300.0
                if kind == "inner_race":  # carried through the load zone once per turn
                    a *= 0.6 + 0.4 * np.cos(2 * np.pi * SHAFT_HZ * tk)
                pulses[i] += a * rng.uniform(0.8, 1.2)
            k += 1
        h = 0.8 * ring(fs, 3300.0, 0.04, 0.01) + 0.3 * ring(fs, 5200.0, 0.05, 0.01)
        x += np.convolve(pulses, h)[:n]
    return x


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    rows = []
    for i in range(3):
        rows.append((f"baseline_{i + 1}.mat", "healthy", 97656.0, 6.0, 270.0))
    for i in range(3):
        rows.append((f"OuterRaceFault_{i + 1}.mat", "outer_race", 97656.0, 6.0, 270.0))
    for i, load in enumerate([25, 50, 100, 150, 200, 250, 300]):
        rows.append((f"OuterRaceFault_vload_{i + 1}.mat", "outer_race", 48828.0, 3.0, float(load)))
    for i, load in enumerate([0, 50, 100, 150, 200, 250, 300]):
        rows.append((f"InnerRaceFault_vload_{i + 1}.mat", "inner_race", 48828.0, 3.0, float(load)))
    for name, kind, fs, seconds, load in rows:
        gs = signal(kind, fs, seconds, load, rng)
        bearing = {"sr": fs, "gs": gs.reshape(-1, 1), "load": load, "rate": SHAFT_HZ}
        scipy.io.savemat(os.path.join(a.out, name), {"bearing": bearing})
    with open(os.path.join(a.out, "all.csv"), "w") as f:
        f.write("path,label\n")
        for name, kind, *_ in rows:
            f.write(f"{os.path.join(a.out, name)},{kind}\n")
    with open(os.path.join(a.out, "healthy.csv"), "w") as f:
        f.write("path,label\n")
        for name, kind, *_ in rows:
            if kind == "healthy":
                f.write(f"{os.path.join(a.out, name)},{kind}\n")
    print(f"wrote {len(rows)} files and all.csv / healthy.csv to {a.out}")


if __name__ == "__main__":
    main()
