#!/usr/bin/env bash
# The model-error loop in the time domain on a positioning axis you describe yourself
# (base mechanical; docs/effects.md, "Time-domain effects of a mechanical base"): a
# carriage on a ball screw (mechanical/ball_screw_axis.json: mass and viscous friction,
# the datasheet force constant), logged in closed loop under a PD controller tracking a
# reference (mechanical/make_axis_log.py writes the log: Coulomb friction and a constant
# force the description lacks, a 1 µm encoder, a noisy current sensor).
#   init -> diagnose --log names Coulomb friction -> diagnose --log names the offset ->
#   fit --log: the error falls to the noise floor (where1.png, fit3.png: the force, the
#   model's and the residual over time).  Then a motion that never reverses:
#   diagnose says the two cannot be separated and what to record.
# Writes samples/mechanical/out-friction/.  LPVID overrides the program's path.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
out="$here/mechanical/out-friction"
rm -rf "$out" && mkdir -p "$out" && cd "$out"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }
python3 ../make_axis_log.py run.csv
python3 ../make_axis_log.py one_way.csv --one-way

run model init --base mechanical --from ../ball_screw_axis.json --out start.json
run fit --model start.json --log run.csv --out fit1.json
run diagnose --model fit1.json --log run.csv --out step2.json --report report1.json --png where1.png
run diagnose --model step2.json --log run.csv --out step3.json --report report2.json
run fit --model step3.json --log run.csv --out fit3.json --plot fit3.png
run history --model fit3.json
run diagnose --model start.json --log one_way.csv
