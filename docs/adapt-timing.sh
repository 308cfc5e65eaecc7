#!/usr/bin/env bash
# Adapt's wall time on the no-tacho cases of issue 37 (docs/benchmarks.md, "Adapt within a
# minute with margin"): HIT-SM three healthy halves, HIT-SM four healthy records, CWRU drive
# end from one healthy record (as docs/per-set.sh), and a held-out-like rig the project was
# not tuned to: `rig-x`, a no-tacho rig built here from config/hit-sm-self.toml with another
# bearing (6206), shaft, disc, unbalance, housing, speeds and sample rate, whose "measured"
# recordings come from the simulator with a heavier load, more slip, another contact angle,
# another resonance and more noise than its rig file says (three healthy 2.5 s records to
# adapt on; faults and two healthy records of 5 s to score).
#
#   bash docs/adapt-timing.sh BINARY WORKDIR      (from the repository root, ../shared beside it)
#
# Prints one line per case: wall and CPU seconds (/usr/bin/time), the report's step times,
# and the zero-shot / adapted / rule scores of the held-out records.
set -euo pipefail
cd "$(dirname "$0")/.."
R=$(realpath "$1")
W=${2:-adapt-timing}
D=$(cd ../shared/data && pwd)
mkdir -p "$W"

# CWRU drive end, as docs/per-set.sh builds it
printf "path,label,start_s,end_s\n$D/cwru/97_Normal_0.mat,healthy,0,2.5\n" > "$W/h1.csv"
{
  printf "path,label,start_s,end_s\n$D/cwru/97_Normal_0.mat,healthy,2.5,\n"
  for f in "$D"/cwru/12k_Drive_End_Bearing_Fault_Data/*/*/*.mat "$D"/cwru/12k_Drive_End_Bearing_Fault_Data/OR/*/@6/*.mat; do
    case "$f" in */IR/*) echo "$f,inner_race,,";; */B/*) echo "$f,ball,,";; */OR/*/@6/*) echo "$f,outer_race,,";; esac
  done
} | awk '!seen[$0]++' > "$W/de-score.csv"

# rig-x: the rig file adapt gets
sed -e 's/^id = "hit-sm-self"/id = "rig-x"/' \
    -e 's/^ball_diameter_mm = 7.94/ball_diameter_mm = 9.525/' \
    -e 's/^pitch_diameter_mm = 39.04/pitch_diameter_mm = 46.0/' \
    -e 's/^sample_rate_hz = 51200.0 .*/sample_rate_hz = 25600.0/' \
    -e 's/^min_rpm = 500.0/min_rpm = 700.0/' -e 's/^max_rpm = 1500.0/max_rpm = 1800.0/' \
    -e 's/^shaft_length_mm = 300.0/shaft_length_mm = 360.0/' \
    -e 's/^nde_bearing_mm = 280.0/nde_bearing_mm = 340.0/' \
    -e 's/position_mm = 150.0, mass_kg = 8.0, diameter_mm = 90.0, thickness_mm = 120.0, unbalance_g_mm = 40.0/position_mm = 180.0, mass_kg = 6.0, diameter_mm = 110.0, thickness_mm = 80.0, unbalance_g_mm = 30.0/' \
    -e 's/^vertical_stiffness_n_per_m = 5.0e7/vertical_stiffness_n_per_m = 7.0e7/' \
    -e 's/^width_mm = 2.05/width_mm = 1.5/' \
    config/hit-sm-self.toml > "$W/rig-x.toml"
grep -q 'id = "rig-x"' "$W/rig-x.toml" && grep -q 'pitch_diameter_mm = 46.0' "$W/rig-x.toml" \
  && grep -q 'unbalance_g_mm = 30.0' "$W/rig-x.toml" || { echo "rig-x: an edit did not apply" >&2; exit 1; }
# its "measured" recordings: the simulator with what the rig file does not know
X="--noise 0.08 --resonance-hz 3600 --load 250 --slip 0.008 --contact-angle 5"
mkdir -p "$W/rig-x-data"
sim() { # fault rpm seconds seed
  [ -f "$W/rig-x-data/$1-$2-$3s.mcap" ] || "$R" simulate --log warn --rig "$W/rig-x.toml" --fault "$1" \
    --rpm "$2" --seconds "$3" --seed "$4" $X -o "$W/rig-x-data/$1-$2-$3s.mcap" > /dev/null
}
sim healthy 750 2.5 41; sim healthy 1200 2.5 42; sim healthy 1650 2.5 43
sim healthy 950 5 44; sim healthy 1450 5 45
s=50; for f in outer_race inner_race; do for r in 800 1250 1700; do s=$((s+1)); sim $f $r 5 $s; done; done
X_DIR=$(realpath "$W/rig-x-data")
printf "path,label\n$X_DIR/healthy-750-2.5s.mcap,healthy\n$X_DIR/healthy-1200-2.5s.mcap,healthy\n$X_DIR/healthy-1650-2.5s.mcap,healthy\n" > "$W/x-healthy3.csv"
{
  printf "path,label\n$X_DIR/healthy-950-5s.mcap,healthy\n$X_DIR/healthy-1450-5s.mcap,healthy\n"
  for f in outer_race inner_race; do for r in 800 1250 1700; do echo "$X_DIR/$f-$r-5s.mcap,$f"; done; done
} > "$W/x-score.csv"

run() { # name rig measured holdout
  local out="$W/$1"
  rm -rf "$out"
  local load; load=$(cut -d' ' -f1 /proc/loadavg)
  /usr/bin/time -f "%e %U %S" -o "$W/$1.time" "$R" adapt -q --rig "$2" --measured "$3" \
    --holdout "$4" -o "$out" --accept-regression > "$W/$1.log" 2>&1
  python3 - "$1" "$out" "$W/$1.time" "$load" <<'PY'
import json, sys
name, out, tf, load = sys.argv[1:5]
wall, user, sys_ = map(float, open(tf).read().split()[-3:])
v = json.load(open(f"{out}/report.json"))
steps = {t["step"].split(" ")[0]: t["wall_s"] for t in v["timings"]}
h = v["holdout_scores"]
def cell(s):
    return f"{s['balanced_accuracy']:.3f} ({s['n_records']} rec, {s['missed_alarms']} missed, {s['false_alarms']} false)"
print(f"{name}: {wall:.1f} s wall, {user + sys_:.1f} s CPU (load {load} at start); "
      f"calibrate {steps.get('calibrate', 0):.1f} s, simulate {steps.get('simulate', 0):.1f} s, "
      f"train {steps.get('train', 0):.1f} s; cal {v['calibration']['id']}; "
      f"zero-shot {cell(h['before'])}, adapted {cell(h['after'])}, rule {cell(h['rule'])}")
PY
}
CASES=${CASES:-"hit3 hit4 cwru-de rig-x"}
for c in $CASES; do
  case $c in
    hit3) run hit3 config/hit-sm-self.toml docs/hit-sm/healthy-first-halves.csv docs/hit-sm/scored.csv;;
    hit4) run hit4 config/hit-sm-self.toml docs/hit-sm/healthy-four.csv docs/hit-sm/scored-without-normal-600.csv;;
    cwru-de) run cwru-de config/cwru-de.toml "$W/h1.csv" "$W/de-score.csv";;
    rig-x) run rig-x "$W/rig-x.toml" "$W/x-healthy3.csv" "$W/x-score.csv";;
  esac
done
