#!/usr/bin/env python3
"""Measured-like recordings of the LUT rig from physics that is NOT rigmon's simulator.

rigmon's simulator integrates a flexible rotor on a nonlinear Hertzian ball bearing. This
generator knows nothing of that: it builds the signal the way a signal-processing text
describes a faulty bearing -- trains of impacts at the kinematic fault frequencies, each
ringing down through a few damped structural resonances, the inner-race train amplitude-
modulated by the rotating load zone, random slip of each impact, white sensor noise, a 1x
unbalance line that grows with speed squared and an analog once-per-rev tacho channel.

Each case injects ONE effect with parameters that are written to truth.json and never given
to `rigmon calibrate`; `baseline` injects nothing, `outside` injects a component that no
effect in rigmon's catalog explains (an order-locked narrowband line at a non-integer order),
`whirl` another one below 1x (a sub-synchronous line locked to the shaft at 0.46x, as
fluid-film whirl is). `slow_speed_fluctuation` is a speed fluctuation slower than the default
2 s of signal could show (period 4 s: generate 10 s or more).
`looseness` adds shaft harmonics 3x..Nx, `subharmonics` half orders 0.5x, 1.5x, 2.5x, ...
(a housing rocking between two stops every other revolution), `looseness_impacts` a 0.5x line
plus an impact once every two revolutions ringing down at 900 Hz (a loose housing that lifts
and lands every other revolution, issue 26), `noise` changes the sensor noise.

Two cases test fault detection where physics still allows it but the defaults do not go
(issue 26, "never below the physics"); neither has an effect for `rigmon calibrate`:
`weak_inner_race` makes the inner-race impacts a quarter of the default and runs at 300 and
600 rpm (the impact strength already scales with speed, so the 300 rpm inner race is an
eighth of the default 600 rpm one); `skf6205_low_load` puts a different bearing on the rig
(SKF 6205: 9 balls of 7.94 mm on a 39.04 mm pitch, 0 deg; its rig file is config/lut-rig.toml
with only [bearing] changed, which docs/per-set.sh writes) with strong inner-race impacts and
a light radial load: every ball is loaded all the way round (Harris's load distribution with
factor `load_zone_epsilon` > 0.5), so the inner-race train is barely modulated at 1x and its
1x sidebands are small.
`intermittent_ball` adds ball-defect records (label `ball`) to the draw: the defect strikes
the outer and the inner race in turn, twice per ball revolution (2x BSF, the inner-race
strike weaker), only while the ball is in the load zone (its cage angle in the lower half,
cos^1.5 over a floor of 0.15) and only while the ball's spin axis keeps the defect on its
rolling track: on and off episodes of random length (exponential, mean 0.3 s on, 0.6 s off),
so the impacts come in bursts. Ball motion is loosely guided, so each impact slips by 5 % of
its spacing (five times the races' jitter). A signal that is impulsive while its 2x BSF line
is smeared and intermittent: what a small ball defect looks like in the literature (Smith &
Randall, MSSP 2015, on the CWRU ball records), made here from that description alone.

    python3 measured_like.py --out DIR --case CASE [--seed N] [--seconds S]

writes DIR/<label>-<rpm>rpm.csv (rpm 600 and 1200; 300 and 600 for `weak_inner_race`) (header `time,axial,vertical,horizontal,tacho`; m/s^2 and V;
10 kHz; the channel names of config/lut-rig.toml), DIR/labels.csv (`path,label`) and
DIR/truth.json = {"case", "effect", "params", "outside"}.

Only numpy is needed.
"""

import argparse
import json
import os

import numpy as np

FS = 10_000.0
SPEEDS_RPM = (600.0, 1200.0)  # whole cycles in 3 s: no scalloping of 1x
LABELS = ("healthy", "outer_race", "inner_race")

# Bearings (balls, ball diameter mm, pitch diameter mm); contact angle 0 deg unless a case
# sets one. LUT rig: SKF 6007-2Z (config/lut-rig.toml [bearing]); the default of every case.
BEARINGS = {
    "skf6007": {"balls": 11, "ball_diameter_mm": 7.94, "pitch_diameter_mm": 48.0},
    "skf6205": {"balls": 9, "ball_diameter_mm": 7.94, "pitch_diameter_mm": 39.04},
}

# The "real" rig this generator pretends to measure. Resonances: (Hz, damping ratio,
# participation axial, vertical, horizontal).
RESONANCES = [
    (2900.0, 0.03, (0.15, 1.0, 0.25)),
    (3700.0, 0.04, (0.3, 0.5, 0.5)),
]
NOISE_RMS = 0.3  # m/s^2, white, per channel
UNBALANCE_1X_AT_1200 = 0.008  # m/s^2, vertical 1x amplitude at 1200 rpm (grows with speed^2)
OR_IMPACT_AT_600 = 50.0  # m/s^2 peak of one outer-race impact response (vertical)
IR_IMPACT_AT_600 = 30.0
IMPACT_SPEED_EXPONENT = 1.0  # impact strength ~ speed
JITTER = 0.01  # random impact-time slip, fraction of the impact spacing
TACHO_HIGH_V = 5.0
TACHO_DUTY = 0.1
TACHO_NOISE_V = 0.01


def clipped_half_orders(stop_fraction, lines=4):
    """Amplitudes of 0.5x, 1.5x, ... (per unit stroke) of a motion at half the shaft speed cut
    off symmetrically at +-stop_fraction of its stroke (the Fourier series of one period, two
    shaft revolutions): a symmetric clip keeps the odd multiples of 0.5x only."""
    th = np.linspace(0.0, 2 * np.pi, 4096, endpoint=False)
    x = np.clip(np.cos(th), -stop_fraction, stop_fraction) / stop_fraction
    c = 2 * np.abs(np.fft.rfft(x)) / len(x)
    return [float(c[2 * j + 1]) for j in range(lines)]


# Mechanical looseness with sub-harmonics: the housing rocks between two stops, repeating
# every two revolutions; its acceleration is a 0.5x motion of `stroke_m_s2` clipped at
# `stop_fraction` of the stroke, growing with speed^2. `half_order_m_s2` is the resulting 0.5x
# line at `at_rpm` (the truth a calibration is scored on).
SUB_STROKE_M_S2 = 0.48
SUB_STOP_FRACTION = 0.3
SUB_LINES = clipped_half_orders(SUB_STOP_FRACTION)

# Looseness with impacts (issue 26): a loose housing lifts and lands once every two
# revolutions. Its rocking is a plain 0.5x line (`line_m_s2` at `at_rpm`, speed^2, vertical;
# 0.7 of it 90 degrees on in the horizontal channel); each landing is an impact, half a
# rocking period after the line's crest (at the bottom of the stroke), that rings down through
# a resonance of the loose joint at `ring_hz` (BELOW the rig's 2900/3700 Hz structural modes)
# with its own damping, strength `impact_m_s2` at `at_rpm` growing with speed^2 too, +-10 %
# from landing to landing and 1 % of the two-revolution spacing of random slip.
# The truth scored is the 0.5x line of the **total** looseness signal in the vertical channel
# (the classifier channel of config/lut-rig.toml), as its spectrum shows it at `at_rpm`: the
# line plus the impact train's own 0.5x Fourier component, computed by `half_order_truth`
# (the ring-down is velocity-like, zero-mean, so that component is tiny: it is written out
# as `impact_half_order_m_s2`).
LOOSE = {
    "line_m_s2": 0.3,
    "impact_m_s2": 12.0,
    "ring_hz": 900.0,
    "damping": 0.04,
    "participation": (0.2, 1.0, 0.6),  # axial, vertical, horizontal
    "at_rpm": 1200.0,
}

# Hidden parameters per case (a test must not pass them to calibrate).
CASES = {
    "baseline": (None, {}),
    "slip": ("slip", {"slip": 0.02}),
    "contact_angle": ("contact_angle", {"contact_angle_deg": 20.0}),
    "resonance": ("resonance", {"hz": 2300.0, "damping": 0.03}),
    "unbalance": ("unbalance", {"order1_m_s2": 0.25, "at_rpm": 1200.0}),
    "line_interference": ("line_interference", {"line_hz": 60.0, "amplitude_m_s2": 0.6}),
    "speed_fluctuation": ("speed_fluctuation", {"fraction": 0.04, "period_s": 0.8}),
    "looseness": ("looseness", {"harmonics_m_s2": 0.1, "highest_order": 10, "at_rpm": 1200.0}),
    "noise": ("noise", {"noise_rms_m_s2": 0.1}),
    "subharmonics": (
        "subharmonics",
        {
            "stroke_m_s2": SUB_STROKE_M_S2,
            "stop_fraction": SUB_STOP_FRACTION,
            "at_rpm": 1200.0,
            "half_order_m_s2": round(SUB_STROKE_M_S2 * SUB_LINES[0], 4),
            # 0.5x, 1.5x, 2.5x, 3.5x relative to 0.5x
            "line_ratios": [round(r / SUB_LINES[0], 4) for r in SUB_LINES],
        },
    ),
    # params completed by `half_order_truth` in main (it needs the ring-down below)
    "looseness_impacts": ("subharmonics", {}),
    "outside": (None, {}),
    "whirl": (None, {}),
    "slow_speed_fluctuation": ("speed_fluctuation", {"fraction": 0.04, "period_s": 4.0}),
    # Fault detection near the physics (issue 26), no calibration effect. A quarter of the
    # default inner-race impact at half the low speed and at the low speed.
    "weak_inner_race": (None, {"ir_impact_scale": 0.25, "speeds_rpm": [300.0, 600.0]}),
    # Ball defects seen only in bursts, as strong as `weak_inner_race`'s impacts (a quarter of
    # the default inner race); with all four labels in the draw.
    "intermittent_ball": (
        None,
        {
            "ball_impact_at_600_m_s2": 7.5,
            "ball_on_s": 0.3,
            "ball_off_s": 0.6,
            "ball_jitter": 0.05,
            "labels": ["healthy", "outer_race", "inner_race", "ball"],
        },
    ),
    # Another bearing, strong inner-race impacts (peak at the load zone's centre equal to the
    # outer race's, 50 m/s^2 at 600 rpm), light radial load: strength follows Harris's
    # q(psi)/q_max = (1 - (1 - cos psi) / (2 eps))^1.5 with eps = 4, so the impacts at the top
    # are 0.65 of those at the bottom (the default LUT train goes from 1.15 to 0.15).
    "skf6205_low_load": (
        None,
        {
            "bearing": "skf6205",
            **BEARINGS["skf6205"],
            "contact_angle_deg": 0.0,
            "ir_impact_at_600_m_s2": 50.0,
            "load_zone_epsilon": 4.0,
        },
    ),
}
OUTSIDE = {"location": 17.3, "unit": "order", "locked_to": "speed", "amplitude_m_s2": 0.5}
WHIRL = {"location": 0.46, "unit": "order", "locked_to": "speed", "amplitude_m_s2": 0.3}


def shaft_revolutions(n, rpm, fluct):
    """Shaft angle in revolutions at each sample, and the instantaneous speed in Hz."""
    t = np.arange(n) / FS
    f = rpm / 60.0 * np.ones(n)
    if fluct is not None:
        f = f * (1.0 + fluct["fraction"] * np.sin(2 * np.pi * t / fluct["period_s"]))
    revs = np.concatenate(([0.0], np.cumsum(f[:-1]) / FS))
    return revs, f


def crossing_times(phase):
    """Times (s) at which a monotonic phase (in cycles) crosses each integer, by linear
    interpolation between samples."""
    k = np.floor(phase)
    idx = np.nonzero(np.diff(k) > 0)[0]
    out = []
    for i in idx:
        target = k[i] + 1.0
        frac = (target - phase[i]) / (phase[i + 1] - phase[i])
        out.append((i + frac) / FS)
    return np.array(out)


def ring(n, times, amps, resonances, axis, rng):
    """Sum of damped-resonance responses to impacts at `times` with strengths `amps`."""
    y = np.zeros(n)
    span = int(0.04 * FS)
    tau = np.arange(span) / FS
    for t0, a in zip(times, amps):
        i0 = int(np.ceil(t0 * FS))
        if i0 >= n:
            continue
        m = min(span, n - i0)
        dt = (i0 - t0 * FS) / FS + tau[:m]
        resp = np.zeros(m)
        for hz, zeta, part in resonances:
            w = 2 * np.pi * hz
            wd = w * np.sqrt(1 - zeta * zeta)
            sigma = zeta * w
            # velocity-like ring-down: zero mean, so an impact adds nothing at DC or 1x
            resp += part[axis] * np.exp(-sigma * dt) * (np.cos(wd * dt) - sigma / wd * np.sin(wd * dt))
        y[i0 : i0 + m] += a * resp
    return y


def inner_race_strength(shaft_angle, params):
    """Relative strength of inner-race impacts at each shaft angle (0 = defect at the bottom,
    the centre of the load zone). Default: a load zone of the lower half, cos^1.5, over a
    floor of 0.15. With `load_zone_epsilon` (a light radial load, every ball loaded): Harris's
    load distribution (1 - (1 - cos psi) / (2 eps))^1.5, 1 at the bottom."""
    eps = params.get("load_zone_epsilon")
    if eps is None:
        return 0.15 + np.clip(np.cos(shaft_angle), 0.0, None) ** 1.5
    return np.clip(1.0 - (1.0 - np.cos(shaft_angle)) / (2.0 * eps), 0.0, None) ** 1.5


def fault_impacts(label, revs, rpm, rng, slip, contact_deg, params):
    """Impact times and strengths (before the resonance gains) of a localized defect."""
    b = BEARINGS[params.get("bearing", "skf6007")]
    r = b["ball_diameter_mm"] / b["pitch_diameter_mm"] * np.cos(np.radians(contact_deg))
    cage = revs * 0.5 * (1.0 - r) * (1.0 - slip)  # cage revolutions
    speed_gain = (rpm / 600.0) ** IMPACT_SPEED_EXPONENT
    if label == "outer_race":
        times = crossing_times(b["balls"] * cage)
        amps = OR_IMPACT_AT_600 * speed_gain * (1.0 + 0.1 * rng.standard_normal(len(times)))
    elif label == "inner_race":
        times = crossing_times(b["balls"] * (revs - cage))
        # the defect turns with the shaft: strength follows the load zone at the bottom
        shaft_angle = np.interp(times, np.arange(len(revs)) / FS, revs) * 2 * np.pi
        load = inner_race_strength(shaft_angle, params)
        at_600 = params.get("ir_impact_at_600_m_s2", IR_IMPACT_AT_600) * params.get("ir_impact_scale", 1.0)
        amps = at_600 * speed_gain * load * (1.0 + 0.1 * rng.standard_normal(len(times)))
    elif label == "ball":
        return ball_impacts(revs, cage, r, b, speed_gain, rng, params)
    else:
        return np.zeros(0), np.zeros(0)
    spacing = np.median(np.diff(times)) if len(times) > 1 else 0.0
    times = times + JITTER * spacing * rng.standard_normal(len(times))
    keep = times > 0
    return times[keep], amps[keep]


def ball_impacts(revs, cage, r, b, speed_gain, rng, params):
    """A ball defect (`intermittent_ball`): strikes at twice the ball spin frequency,
    alternately on the outer race (1) and the inner race (0.5), gated by the load zone the
    ball is in and by on/off episodes of the defect meeting the races."""
    # ball revolutions: (D / 2d)(1 - r^2) per shaft revolution, = (inner race - cage)(D/d)(1 - r)
    spin = (revs - cage) * b["pitch_diameter_mm"] / b["ball_diameter_mm"] * (1.0 - r)
    times = crossing_times(2.0 * spin)
    cage_angle = np.interp(times, np.arange(len(revs)) / FS, cage) * 2 * np.pi
    load = 0.15 + np.clip(np.cos(cage_angle), 0.0, None) ** 1.5
    race = np.where(np.arange(len(times)) % 2 == 0, 1.0, 0.5)
    at_600 = params["ball_impact_at_600_m_s2"]
    amps = at_600 * speed_gain * load * race * (1.0 + 0.1 * rng.standard_normal(len(times)))
    # on/off episodes of the defect meeting the races (telegraph process)
    end = len(revs) / FS
    on = np.zeros(len(times), bool)
    t, state = 0.0, rng.random() < params["ball_on_s"] / (params["ball_on_s"] + params["ball_off_s"])
    while t < end:
        d = rng.exponential(params["ball_on_s"] if state else params["ball_off_s"])
        if state:
            on |= (times >= t) & (times < t + d)
        t, state = t + d, not state
    spacing = np.median(np.diff(times)) if len(times) > 1 else 0.0
    times = times + params["ball_jitter"] * spacing * rng.standard_normal(len(times))
    keep = on & (times > 0)
    return times[keep], amps[keep]


def looseness_landings(revs, rpm, rng):
    """Times of the loose housing's landings, once every two revolutions at the bottom of the
    0.5x rocking (revolutions 1, 3, 5, ...), with random slip (none with `rng` None)."""
    times = crossing_times(0.5 * (revs + 1.0))
    if rng is not None:
        spacing = 2.0 * 60.0 / rpm
        times = times + JITTER * spacing * rng.standard_normal(len(times))
    return times[times > 0]


def looseness_impacts(n, revs, rpm, axis, p, rng):
    """One channel's looseness with impacts: the 0.5x line (radial channels) and the
    landings' ring-down (no randomness with `rng` None)."""
    gain = (rpm / p["at_rpm"]) ** 2
    a = p["line_m_s2"] * gain
    line = (0.0, a * np.cos(np.pi * revs), 0.7 * a * np.sin(np.pi * revs))[axis]
    times = looseness_landings(revs, rpm, rng)
    amps = p["impact_m_s2"] * gain * np.ones(len(times))
    if rng is not None:
        amps = amps * (1.0 + 0.1 * rng.standard_normal(len(times)))
    joint = [(p["ring_hz"], p["damping"], p["participation"])]
    return line + ring(n, times, amps, joint, axis, rng)


def half_order_truth(p):
    """The 0.5x amplitude of the total looseness signal in the vertical channel at `at_rpm`
    (line and impacts, no randomness), and the impact train's share of it alone: a DFT at
    0.5x over 20 two-revolution periods after one period of settling."""
    rpm = p["at_rpm"]
    periods = 20
    n = int(round((periods + 1) * 2.0 * 60.0 / rpm * FS))
    revs = np.arange(n) * rpm / 60.0 / FS
    total = looseness_impacts(n, revs, rpm, 1, p, None)
    line_free = dict(p, line_m_s2=0.0)
    impacts = looseness_impacts(n, revs, rpm, 1, line_free, None)
    start = int(round(2.0 * 60.0 / rpm * FS))
    ph = np.exp(-1j * np.pi * revs[start:])

    def amp(y):
        return float(2.0 * np.abs(np.mean(y[start:] * ph)))

    return amp(total), amp(impacts)


def record(label, rpm, case, params, seconds, rng):
    n = int(round(seconds * FS))
    t = np.arange(n) / FS
    fluct = params if case in ("speed_fluctuation", "slow_speed_fluctuation") else None
    revs, _ = shaft_revolutions(n, rpm, fluct)
    slip = params.get("slip", 0.0) if case == "slip" else 0.0
    contact = params.get("contact_angle_deg", 0.0) if case == "contact_angle" else 0.0
    resonances = list(RESONANCES)
    if case == "resonance":
        resonances[0] = (params["hz"], params["damping"], resonances[0][2])
    times, amps = fault_impacts(label, revs, rpm, rng, slip, contact, params)
    chans = []
    for axis in range(3):
        y = ring(n, times, amps, resonances, axis, rng)
        if axis == 0 and contact > 0:
            # an angular contact carries part of each impact axially
            y += np.sin(np.radians(contact)) * ring(n, times, amps, resonances, 1, rng)
        y += params.get("noise_rms_m_s2", NOISE_RMS) * rng.standard_normal(n)
        chans.append(y)
    # 1x unbalance, vertical and horizontal (90 degrees apart), amplitude ~ speed^2
    a1 = UNBALANCE_1X_AT_1200 * (rpm / 1200.0) ** 2
    if case == "unbalance":
        a1 = params["order1_m_s2"] * (rpm / params["at_rpm"]) ** 2
    chans[1] += a1 * np.cos(2 * np.pi * revs + 0.4)
    chans[2] += 0.7 * a1 * np.sin(2 * np.pi * revs + 0.4)
    if case == "looseness":
        # mechanical looseness: shaft harmonics 3x..Nx, each growing with speed^2
        a = params["harmonics_m_s2"] * (rpm / params["at_rpm"]) ** 2
        for k in range(3, params["highest_order"] + 1):
            ph = rng.uniform(0, 2 * np.pi)
            chans[1] += a * np.cos(2 * np.pi * k * revs + ph)
            chans[2] += 0.7 * a * np.sin(2 * np.pi * k * revs + ph)
    if case == "subharmonics":
        # the housing rocks between two stops: a motion at half the shaft speed (it takes two
        # revolutions to repeat), cut off symmetrically at the stops, so 0.5x, 1.5x, 2.5x, ...
        # and no integer order
        a = params["stroke_m_s2"] * (rpm / params["at_rpm"]) ** 2
        stop = params["stop_fraction"]
        ph = rng.uniform(0, 2 * np.pi)
        chans[1] += a * np.clip(np.cos(np.pi * revs + ph), -stop, stop) / stop
        chans[2] += 0.7 * a * np.clip(np.sin(np.pi * revs + ph), -stop, stop) / stop
    if case == "looseness_impacts":
        for axis in range(3):
            chans[axis] += looseness_impacts(n, revs, rpm, axis, params, rng)
    if case == "line_interference":
        ph = rng.uniform(0, 2 * np.pi)
        for c, g in zip(chans, (0.5, 1.0, 0.8)):
            c += g * params["amplitude_m_s2"] * np.sin(2 * np.pi * params["line_hz"] * t + ph)
    if case == "outside":
        # a gear-mesh-like component at a non-integer order, locked to the shaft
        ph = rng.uniform(0, 2 * np.pi)
        for c, g in zip(chans, (0.3, 1.0, 0.6)):
            c += g * OUTSIDE["amplitude_m_s2"] * np.sin(2 * np.pi * OUTSIDE["location"] * revs + ph)
    if case == "whirl":
        # sub-synchronous whirl: a line locked to the shaft below 1x
        ph = rng.uniform(0, 2 * np.pi)
        for c, g in zip(chans, (0.3, 1.0, 0.6)):
            c += g * WHIRL["amplitude_m_s2"] * np.sin(2 * np.pi * WHIRL["location"] * revs + ph)
    tacho = np.where(np.mod(revs, 1.0) < TACHO_DUTY, TACHO_HIGH_V, 0.0)
    tacho = tacho + TACHO_NOISE_V * rng.standard_normal(n)
    return t, chans, tacho


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--case", required=True, choices=sorted(CASES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=3.0)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    effect, params = CASES[a.case]
    if a.case == "looseness_impacts":
        total, impacts = half_order_truth(LOOSE)
        params = dict(LOOSE, participation=list(LOOSE["participation"]))
        params["half_order_m_s2"] = round(total, 4)
        params["impact_half_order_m_s2"] = round(impacts, 6)
    rows = ["path,label"]
    for rpm in params.get("speeds_rpm", SPEEDS_RPM):
        for label in params.get("labels", LABELS):
            t, chans, tacho = record(label, rpm, a.case, params, a.seconds, rng)
            name = f"{label}-{int(rpm)}rpm.csv"
            data = np.column_stack([t] + chans + [tacho])
            np.savetxt(
                os.path.join(a.out, name),
                data,
                delimiter=",",
                header="time,axial,vertical,horizontal,tacho",
                comments="",
                fmt=["%.6f", "%.5f", "%.5f", "%.5f", "%.4f"],
            )
            rows.append(f"{name},{label}")
    with open(os.path.join(a.out, "labels.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")
    outside = None
    if a.case == "outside":
        outside = {k: OUTSIDE[k] for k in ("location", "unit", "locked_to")}
    if a.case == "whirl":
        outside = {k: WHIRL[k] for k in ("location", "unit", "locked_to")}
    with open(os.path.join(a.out, "truth.json"), "w") as f:
        json.dump({"case": a.case, "effect": effect, "params": params, "outside": outside}, f, indent=1)


if __name__ == "__main__":
    main()
