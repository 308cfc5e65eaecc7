#!/usr/bin/env bash
# Every figure of docs/diagnosis.md's per-set table (issue 26), rerun by one command:
#
#   bash docs/per-set.sh [WORKDIR]        (from the repository root, ../shared beside it)
#
# Builds the manifests, runs `rigmon adapt` (healthy data only for the real sets; one
# labelled draw for the generator cases) and prints one line per set: zero-shot, adapted and
# the rule on the held-out records of the same run (records right, balanced accuracy, missed
# and false alarms), plus the self-check's verdict. Release build; ~25 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
W=${1:-per-set}
D=$(cd ../shared/data && pwd)
mkdir -p "$W"
[ -n "${RIGMON_NO_BUILD:-}" ] || cargo build --release -q
R=target/release/rigmon

row() { # name out-dir
  python3 - "$1" "$2" <<'PY'
import json, sys
name, out = sys.argv[1], sys.argv[2]
v = json.load(open(f"{out}/report.json"))
h = v["holdout_scores"]
def cell(s):
    return f"{s['balanced_accuracy']:.3f} ({s['missed_alarms']} missed, {s['false_alarms']} false)"
regressions = v["self_check"]["regressions"]
ok = "passed" if not regressions else f"refused ({len(regressions)} regression(s))"
print(f"| {name} | {h['after']['n_records']} | {cell(h['before'])} | **{cell(h['after'])}** | {cell(h['rule'])} | {ok} |")
PY
}

# CWRU drive end and fan end: adapt on 97's first half, score 97's second half and every
# fault record of the set, ball records included (a class the model lacks counts as an alarm
# or a miss).
printf "path,label,start_s,end_s\n$D/cwru/97_Normal_0.mat,healthy,0,2.5\n" > "$W/h1.csv"
{
  printf "path,label,start_s,end_s\n$D/cwru/97_Normal_0.mat,healthy,2.5,\n"
  for f in "$D"/cwru/12k_Drive_End_Bearing_Fault_Data/*/*/*.mat "$D"/cwru/12k_Drive_End_Bearing_Fault_Data/OR/*/@6/*.mat; do
    case "$f" in */IR/*) echo "$f,inner_race,,";; */B/*) echo "$f,ball,,";; */OR/*/@6/*) echo "$f,outer_race,,";; esac
  done
} | awk '!seen[$0]++' > "$W/de-score.csv"
{
  printf "path,label,start_s,end_s\n$D/cwru/97_Normal_0.mat,healthy,2.5,\n"
  for f in "$D"/cwru-fe/*/*.mat; do
    case "$(basename "$f")" in IR*) echo "$f,inner_race,,";; OR*) echo "$f,outer_race,,";; B*) echo "$f,ball,,";; esac
  done
} > "$W/fe-score.csv"
$R adapt -q --rig config/cwru-de.toml --measured "$W/h1.csv" --holdout "$W/de-score.csv" -o "$W/de" --accept-regression > /dev/null
$R adapt -q --rig config/cwru-fe.toml --measured "$W/h1.csv" --holdout "$W/fe-score.csv" -o "$W/fe" --accept-regression > /dev/null
# HIT-SM: one accelerometer, no tacho, [speed] estimate; the manifests of docs/hit-sm/.
$R adapt -q --rig config/hit-sm-self.toml --measured docs/hit-sm/healthy-first-halves.csv \
  --holdout docs/hit-sm/scored.csv -o "$W/hit" --accept-regression > /dev/null
# The independent generator: one undeclared effect per case, adapt on draw 1 (labelled),
# score draw 2. weak_inner_race: inner-race impacts a quarter of the default at 300/600 rpm;
# skf6205_low_load: an SKF 6205 on the LUT rig (its rig file is config/lut-rig.toml with only
# [bearing] changed; the simulator's [simulation.bearing] stiffness stays LUT's, an
# assumption), strong inner-race impacts barely modulated by a light load.
GEN_CASES="contact_angle slip speed_fluctuation resonance unbalance line_interference weak_inner_race skf6205_low_load intermittent_ball"
mkdir -p "$W/gen"
python3 - config/lut-rig.toml "$W/gen/skf6205-rig.toml" <<'PY'
import re, sys
src, dst = sys.argv[1], sys.argv[2]
bearing = """[bearing]
# SKF 6205 (tests/python/measured_like.py case skf6205_low_load); every other section is
# config/lut-rig.toml's, [simulation.bearing] stiffness included (an assumption).
balls = 9
ball_diameter_mm = 7.94
pitch_diameter_mm = 39.04
contact_angle_deg = 0.0

"""
new, n = re.subn(r"(?ms)^\[bearing\]\n.*?(?=^\[)", bearing, open(src).read())
assert n == 1, f"{src}: expected one [bearing] section followed by another section"
open(dst, "w").write(new)
PY
for c in $GEN_CASES; do
  rig=config/lut-rig.toml
  [ "$c" = skf6205_low_load ] && rig="$W/gen/skf6205-rig.toml"
  python3 tests/python/measured_like.py --out "$W/gen/$c-1" --case $c --seed 1 --seconds 20 > /dev/null
  python3 tests/python/measured_like.py --out "$W/gen/$c-2" --case $c --seed 2 --seconds 20 > /dev/null
  $R adapt -q --rig "$rig" --measured "$W/gen/$c-1/labels.csv" \
    --holdout "$W/gen/$c-2/labels.csv" -o "$W/gen/$c" --accept-regression > /dev/null
done

echo "| set | held-out records | zero-shot | adapted | rule | self-check |"
echo "|---|---|---|---|---|---|"
row "CWRU drive end (healthy only)" "$W/de"
row "CWRU fan end (healthy only)" "$W/fe"
row "HIT-SM, estimate (healthy only)" "$W/hit"
for c in $GEN_CASES; do
  row "generator: $c (one labelled draw)" "$W/gen/$c"
done
