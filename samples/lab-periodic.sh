#!/usr/bin/env bash
# The lab workflow (issue "The lab workflow"): design the experiment, run it, measure
# FRFs with their noise, fit and diagnose.  The "rig" is lpvid's platform simulator
# (seed 000; its platform has rod twist, which the start model lacks).
#   excite: a log-spaced multisine, 0.5-150 Hz, one input at a time, 2 transient + 6
#           periods of 4 s per experiment, 2 random-phase realisations (BLA);
#   simulate: the closed loop at three beam positions driven by that signal (the log
#           carries the design line);
#   frf --method periodic: S (v -> u) and the plant P = (PS) S^-1 with noise and
#           nonlinear-distortion variance per line, the layout read from the log;
#   fit --target S through the known controller, diagnose (which effect is missing).
# Writes samples/lab/.  LPVID overrides the program's path.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
rm -rf "$here/lab" && mkdir -p "$here/lab" && cd "$here/lab"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }

run excite --kind multisine --rate-hz 1000 --period-samples 4000 --periods 6 --transient-periods 2 \
    --realisations 2 --band-hz 0.5,150 --grid log --lines-per-decade 40 --channels 3 --mimo one-at-a-time \
    --rms 0.05,0.05,1 --seed 7 --out multisine.csv
run simulate platform --excitation multisine.csv --positions left,middle,right --out rig
for p in left middle right; do
  run frf --method periodic --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out "S_$p.csv" \
      "rig/${p}_1000hz/exp_excitation.csv"
  run frf --method periodic --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 --quantity P \
      --out "P_$p.csv" "rig/${p}_1000hz/exp_excitation.csv"
done
run compare P_middle.csv rig/middle_1000hz/truth_plant.json --band-min 3 --band-max 900 --weights 0.1,0.1,1
run model init --out start.json
data=(--target S --controller rig/middle_1000hz/controller.json --data S_left.csv@-0.1 --data S_middle.csv@0
      --data S_right.csv@0.1)
run fit --model start.json "${data[@]}" --out fit1.json --plot fit1.png
run diagnose --model fit1.json "${data[@]}" --png where-it-fails.png
run model add rod_twist --model fit1.json --out start2.json
run fit --model start2.json "${data[@]}" --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
