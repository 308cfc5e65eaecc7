#!/usr/bin/env bash
# Reruns the table of docs/early-warning.md: for each FEMTO learning bearing, `rigmon trend`
# (the RMS 3-sigma rule and rigmon's departure test over the first 10 % of the captures, and
# the picture), then the daemon's path the held-out check uses: `rigmon adapt` (healthy only)
# on the first 10 % of the captures (a manifest row naming the folder, end_s from trend's
# baseline_end_s) and `rigmon replay` of the whole life with the adapted model; prints one
# row per bearing: captures, the rule's and rigmon's alarm and lead time (h), the replay's
# first departed window and its state, the replay's and adapt's wall time, and the states of
# the windows after the baseline and before the departure.
#
#   FEMTO=/path/to/ieee-phm-2012-data-challenge-dataset bash docs/early-warning.sh
#
# Uses only Learning_set/. RIGMON defaults to the dev build (cargo build --all-features).
set -euo pipefail
FEMTO=${FEMTO:?set FEMTO to the dataset folder holding Learning_set/}
RIGMON=${RIGMON:-target/debug/rigmon}
OUT=${OUT:-$(mktemp -d)}
rpm() { case $1 in 1_*) echo 1800 ;; 2_*) echo 1650 ;; 3_*) echo 1500 ;; esac; }
for b in 1_1 1_2 2_1 2_2 3_1 3_2; do
  dir=$FEMTO/Learning_set/Bearing$b
  t=$("$RIGMON" trend "$dir" --rig config/femto.toml --json --png docs/early-warning/Bearing$b.png)
  end=$(jq -r .baseline_end_s <<<"$t")
  printf 'path,label,rpm,start_s,end_s\n%s,healthy,%s,0,%s\n' "$dir" "$(rpm $b)" "$end" >"$OUT/h$b.csv"
  a0=$(date +%s.%N)
  "$RIGMON" adapt -q --rig config/femto.toml --measured "$OUT/h$b.csv" -o "$OUT/a$b" >"$OUT/a$b.log" 2>&1
  a1=$(date +%s.%N)
  s=$(date +%s.%N)
  "$RIGMON" replay "$dir" --rig "$OUT/a$b/rig.toml" --rpm "$(rpm $b)" --model "$OUT/a$b/model.onnx" \
    --json 2>/dev/null >"$OUT/r$b.jsonl"
  e=$(date +%s.%N)
  before=$(jq -r --argjson e0 "$end" 'select(.window.end_s > $e0 and .indicators.departure.departed_since_s == null) | .state' "$OUT/r$b.jsonl" | sort | uniq -c | tr '\n' ' ')
  first=$(jq -c -n 'first(inputs | select(.indicators.departure.departed_since_s != null) | [.window.end_s, .state])' "$OUT/r$b.jsonl")
  jq -r --arg b "$b" --arg first "$first" --arg wall "$(echo "$e - $s" | bc)" \
    --arg adapt "$(echo "$a1 - $a0" | bc)" --arg before "$before" \
    '[$b, .windows, (.end_s/3600*1000|round/1000), (.alarm_s//null|if . then ./3600*1000|round/1000 else "-" end),
      (.lead_s//null|if . then ./3600*1000|round/1000 else "-" end),
      (.rigmon.alarm_s//null|if . then ./3600*1000|round/1000 else "-" end),
      (.rigmon.lead_s//null|if . then ./3600*1000|round/1000 else "-" end),
      (.rigmon.leading//"-"), (.rigmon.beyond_after//null|if . then .*100|round else "-" end),
      $first, $wall, $adapt, $before] | @tsv' <<<"$t"
done
