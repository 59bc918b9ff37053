#!/usr/bin/env bash
# The model-error loop on data with a hidden effect (docs/model-error-walkthrough.md):
# a platform whose controller output reaches the coils one sample (1 ms) late is
# measured by a simulated analyzer at three beam positions; a model without the
# delay is fitted, diagnose names what is missing, the effect is added, the model
# refitted, and the history shows the error falling.  Writes samples/loop/.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
rm -rf "$here/loop" && mkdir -p "$here/loop" && cd "$here/loop"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }

# 1. The truth, with the hidden effect (a user edits the value in the file; here sed).
run model init --out truth.json
run model add input_delay --model truth.json
sed -i 's/"input_delay_s": {"value": [^,]*,/"input_delay_s": {"value": 0.001,/' truth.json
grep -q '"input_delay_s": {"value": 0.001,' truth.json
# 2. Analyzer measurements of S at three beam positions (16 averages, 4 s per frequency).
run simulate platform --out data --truth-model truth.json --duration-s 1 --seed 5 \
    --analyzer --analyzer-averages 16 --analyzer-integration-s 4
S() { echo "data/$1_1000hz/S_v1.csv,data/$1_1000hz/S_v2.csv,data/$1_1000hz/S_v3.csv@$2"; }
DATA=(--target S --controller data/middle_1000hz/controller.json
      --data "$(S left -0.1)" --data "$(S middle 0)" --data "$(S right 0.1)")
# 3. The documented model, without the delay, fitted to the data.
run model init --out model.json
run fit --model model.json "${DATA[@]}" --out fit1.json --plot fit1.png
# 4. Where does it fail, and what is missing?
run diagnose --model fit1.json "${DATA[@]}" --averages 16 --png where-it-fails.png
# 5. Add what diagnose named, refit, and look at the error falling.
run model add input_delay --model fit1.json
run fit --model fit1.json "${DATA[@]}" --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
# 6. Anything left?
run diagnose --model fit2.json "${DATA[@]}" --averages 16
