#!/usr/bin/env bash
# Interleaved A/B of what a user waits for (issue 51): `dampnet diagnose` on the thesis and quick
# plans, and `dampnet --help`, `dampnet train --help`, `dampnet diagnose --help`, between two
# installs of dampnet (each a checkout's .venv, e.g. a clone at the commit before and this tree).
#
#   bash bench/experiments/interactive_speed.sh OLD_CHECKOUT NEW_CHECKOUT [ROUNDS]
#
# Data: the rig's thesis plan with the gas spring hidden (seed 0) diagnosed with the shipped model,
# and the quick plan (gas spring, seed 0) with a model `dampnet train` made of it; both made once,
# in a scratch folder, by NEW's dampnet. Prints one line per run and the medians; the JSON of every
# diagnosis is kept (old_*.json, new_*.json) to compare the verdicts.
set -euo pipefail
OLD="$(cd "$1" && pwd)"; NEW="$(cd "$2" && pwd)"; ROUNDS="${3:-3}"
WORK="$(mktemp -d)"; trap 'echo "kept: $WORK"' EXIT
cd "$WORK"
export OPENBLAS_NUM_THREADS=1
"$NEW/.venv/bin/dampnet" rig thesis_data --plan thesis --effects gas_spring --seed 0 --no-progress > /dev/null
"$NEW/.venv/bin/dampnet" rig quick_data --plan quick --effects gas_spring --seed 0 --no-progress > /dev/null
"$NEW/.venv/bin/dampnet" train quick_data --out quick_model --quiet > /dev/null
MODEL_THESIS="$NEW/export/dn_model_default.json"
for rep in $(seq "$ROUNDS"); do
  for side in old new; do
    if [ "$side" = old ]; then BIN="$OLD/.venv/bin/dampnet"; else BIN="$NEW/.venv/bin/dampnet"; fi
    /usr/bin/time -f "$side diagnose-thesis %e %U" "$BIN" diagnose "$MODEL_THESIS" thesis_data --json "${side}_thesis.json" > /dev/null 2>> times.txt
    /usr/bin/time -f "$side diagnose-quick %e %U" "$BIN" diagnose quick_model quick_data --json "${side}_quick.json" > /dev/null 2>> times.txt
    for cmd in "" train diagnose; do
      /usr/bin/time -f "$side help-${cmd:-top} %e %U" "$BIN" $cmd --help > /dev/null 2>> times.txt
    done
  done
done
cat times.txt
python3 - <<'PY'
import collections, statistics
d = collections.defaultdict(list)
for line in open("times.txt"):
    side, what, wall, user = line.split()
    d[(what, side)].append(float(wall))
for (what, side), w in sorted(d.items()):
    print(f"{what:18s} {side}: wall median {statistics.median(w):.2f} s, min {min(w):.2f}, max {max(w):.2f} ({len(w)} runs)")
PY
