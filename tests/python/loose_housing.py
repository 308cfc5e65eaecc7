#!/usr/bin/env python3
"""A loose bearing housing on the LUT rig, built from physics independently of rigmon's
simulator and of measured_like.py's `looseness_impacts` case (issue 39).

The housing is held down by a bolt that has lost its preload. The rotating unbalance lifts it
once every two revolutions (the joint's stiffness is so low that it responds at half the shaft
rate, a period-2 motion); on its way down the housing lands on its seat. Two things reach the
accelerometer:

- the rocking itself, a 0.5x motion clipped at the seat (`--clip`, the fraction of the stroke
  the seat lets through; 1 = not clipped): one-sided clipping gives 0.5x, 1x, 1.5x, ... with the
  half orders strongest. The stroke is set by the bolt's clearance (a fixed displacement), so
  its acceleration grows with speed squared;
- each landing, a short half-sine contact force (its width a third of the mode's period) that
  rings ONE structural mode of the loose joint (`--mode-hz`, `--damping`): the single-degree-
  of-freedom response to the pulse, computed by convolution. Landings jitter in time (0.5 % of
  their spacing) and strength (+-15 %, Gaussian), as a real joint's do.

The strength (`--impact`, m/s^2) is the peak of one landing's ring-down in the vertical channel
at 1200 rpm (the generator measures it on an isolated landing and writes it to truth.json). It
grows with speed to the first power: the housing falls through the same clearance at a speed
proportional to the shaft rate, and the ring-down's peak is proportional to the impulse. The
horizontal channel sees 0.6 of it, the axial 0.15. The rest of the signal (bearing faults, the
rig's own resonances, unbalance, noise, tacho) is measured_like.py's `baseline`, so calibrate
has nothing else to find. The looseness is on every recording, the faulty ones too (a loose
housing is loose whatever the bearing: looseness and a bearing fault together);
`--healthy-only-loose` keeps it to the healthy recordings.

    python3 loose_housing.py --out DIR [--impact 3] [--mode-hz 900] [--damping 0.04]
        [--clip 0.6] [--line 0.3] [--seed 1] [--seconds 3] [--healthy-only-loose]

writes DIR/<label>-<rpm>rpm.csv for healthy, outer_race, inner_race at 600 and 1200 rpm,
DIR/labels.csv and DIR/truth.json {"case": "loose_housing", "effect": "looseness_impacts",
"params": {...}} (`impact_m_s2` the landing peak at 1200 rpm, `peak_at_rpm_m_s2` at each speed,
`impact_exponent` the speed law).
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import measured_like as ml  # noqa: E402  (the rig's base signal only)

FS = ml.FS
AT_RPM = 1200.0
AXIS_SHARE = (0.15, 1.0, 0.6)  # axial, vertical, horizontal
TIME_JITTER = 0.005
STRENGTH_JITTER = 0.15
IMPACT_SPEED_EXPONENT = 1.0  # landing speed ~ shaft rate (fixed clearance)


OVERSAMPLE = 32  # the kernel's time grid: FS * OVERSAMPLE, so a landing lands between samples


def landing_kernel(mode_hz, damping):
    """Acceleration of a single-degree-of-freedom mode hit by a half-sine contact force a third
    of its period wide, on a grid OVERSAMPLE times finer than FS, scaled to a peak of 1."""
    fine = FS * OVERSAMPLE
    w = 2 * np.pi * mode_hz
    wd = w * np.sqrt(1 - damping**2)
    span = int(np.ceil(-np.log(1e-4) / (damping * w) * fine)) + 1
    t = np.arange(span) / fine
    # impulse response of the mode's acceleration (a force impulse into a damped oscillator)
    h = np.exp(-damping * w * t) * np.sin(wd * t)
    width = max(2, int(round(fine / (3.0 * mode_hz))))
    pulse = np.sin(np.pi * (np.arange(width) + 0.5) / width)
    k = np.convolve(pulse, h)[:span]
    return k / np.max(np.abs(k))


def rocking(revs, clip, phase):
    """The housing's 0.5x motion cut at the seat: cos(pi revs) lifts the housing up to 1 and
    would take it down to -1; the seat stops it at -clip."""
    x = np.cos(np.pi * revs + phase)
    return np.maximum(x, -clip) if clip < 1.0 else x


def landing_times(revs, clip, phase, rpm, rng):
    """When the housing reaches the seat on its way down: cos(pi revs + phase) = -clip."""
    target = np.arccos(-clip) if clip < 1.0 else np.pi
    # angle pi revs + phase crosses target + 2 pi k going down (cos decreasing)
    theta = np.pi * revs + phase - target
    k = np.floor(theta / (2 * np.pi))
    idx = np.nonzero(np.diff(k) > 0)[0]
    frac = (2 * np.pi * k[idx + 1] - theta[idx]) / (theta[idx + 1] - theta[idx])
    times = (idx + frac) / FS
    spacing = 2.0 * 60.0 / rpm
    return times + TIME_JITTER * spacing * rng.standard_normal(len(times))


def looseness(n, revs, rpm, p, rng):
    """The three channels' looseness signal: (axial, vertical, horizontal)."""
    gain = (rpm / AT_RPM) ** 2
    phase = rng.uniform(0, 2 * np.pi)
    line = p["line_m_s2"] * gain * rocking(revs, p["clip"], phase)
    gain = (rpm / AT_RPM) ** IMPACT_SPEED_EXPONENT
    line = line - line.mean()
    kernel = landing_kernel(p["mode_hz"], p["damping"])
    rings = np.zeros(n)
    for t0 in landing_times(revs, p["clip"], phase, rpm, rng):
        if t0 <= 0:
            continue
        a = p["impact_peak_m_s2"] * gain * max(0.0, 1 + STRENGTH_JITTER * rng.standard_normal())
        # the ring-down read at the samples after the landing, at its exact time
        i0 = int(np.ceil(t0 * FS))
        j = np.round((np.arange(i0, n) / FS - t0) * FS * OVERSAMPLE).astype(int)
        j = j[j < len(kernel)]
        rings[i0 : i0 + len(j)] += a * kernel[j]
    return [s * (line + rings) for s in AXIS_SHARE]


def isolated_peak(p):
    """The peak of one landing's ring-down in the vertical channel at AT_RPM (no jitter)."""
    k = landing_kernel(p["mode_hz"], p["damping"])
    return float(p["impact_peak_m_s2"] * np.max(np.abs(k)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--impact", type=float, default=3.0, help="landing peak at 1200 rpm, m/s^2")
    ap.add_argument("--mode-hz", type=float, default=900.0)
    ap.add_argument("--damping", type=float, default=0.04)
    ap.add_argument("--clip", type=float, default=0.6, help="seat at this fraction of the stroke; 1: no clip")
    ap.add_argument("--line", type=float, default=0.3, help="0.5x stroke at 1200 rpm, m/s^2 (0: landings only)")
    ap.add_argument("--healthy-only-loose", action="store_true", help="looseness on healthy recordings only")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=3.0)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    p = {
        "impact_peak_m_s2": a.impact,
        "mode_hz": a.mode_hz,
        "damping": a.damping,
        "clip": a.clip,
        "line_m_s2": a.line,
        "at_rpm": AT_RPM,
    }
    rows = ["path,label"]
    for rpm in ml.SPEEDS_RPM:
        for label in ml.LABELS:
            t, chans, tacho = ml.record(label, rpm, "baseline", {}, a.seconds, rng)
            if label == "healthy" or not a.healthy_only_loose:
                n = len(t)
                revs, _ = ml.shaft_revolutions(n, rpm, None)
                for c, extra in zip(chans, looseness(n, revs, rpm, p, rng)):
                    c += extra
            name = f"{label}-{int(rpm)}rpm.csv"
            data = np.column_stack([t] + chans + [tacho])
            np.savetxt(os.path.join(a.out, name), data, delimiter=",",
                       header="time,axial,vertical,horizontal,tacho", comments="",
                       fmt=["%.6f", "%.5f", "%.5f", "%.5f", "%.4f"])
            rows.append(f"{name},{label}")
    with open(os.path.join(a.out, "labels.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")
    peak = isolated_peak(p)
    # the landing peak at each recorded speed (the generator's own speed law), so a fit
    # reported at either speed is compared with the truth there
    by_rpm = {str(int(r)): round(peak * (r / AT_RPM) ** IMPACT_SPEED_EXPONENT, 4) for r in ml.SPEEDS_RPM}
    truth = dict(p, impact_m_s2=round(peak, 4), impact_exponent=IMPACT_SPEED_EXPONENT, peak_at_rpm_m_s2=by_rpm)
    with open(os.path.join(a.out, "truth.json"), "w") as f:
        json.dump({"case": "loose_housing", "effect": "looseness_impacts", "params": truth}, f, indent=1)


if __name__ == "__main__":
    main()
