#!/usr/bin/env bash
# The model-error loop on the 6-DOF maglev stage of seed 001 (docs/model-error-walkthrough.md,
# "The 6-DOF stage"): the same commands as the platform's, base stage6.
# The "rig" is lpvid's nonlinear stage simulator (Lagrange equations with Euler angles,
# RK4, the paper's sliding-mode controller at 1 kHz) with a stage that differs from the
# design (inertias, force constant) and hides the gap dependence of the force constant.
# A 60 s closed-loop log with white excitation -> the plant by `frf --input` (the
# excitation as instrument: valid under the nonlinear controller) -> model init ->
# fit -> diagnose -> add the effect -> refit -> history.
# Writes samples/stage6/.  LPVID overrides the program's path.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
rm -rf "$here/stage6" && mkdir -p "$here/stage6" && cd "$here/stage6"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }

run simulate stage6 --experiment --hover --duration-s 60 --effects gap --inertia-kgm2 0.034,0.025,0.061 \
    --force-constant-scale 1.04 --seed 3 --out rig
# the base's input order is that of the generalised forces: F_x F_y F_z tau_z tau_y tau_x
run frf --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,q2,q3,q4,q5,q6 \
    --quantity P --segment 2048 --out P.csv rig/exp_stage6.csv
run model init --base stage6 --out model.json
run fit --model model.json --data P.csv@0 --rate-hz 1000 --out fit1.json --plot fit1.png
run diagnose --model fit1.json --data P.csv@0 --rate-hz 1000 --png where-it-fails.png
run model add gap_dependence --model fit1.json --out start2.json
run fit --model start2.json --data P.csv@0 --rate-hz 1000 --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
run diagnose --model fit2.json --data P.csv@0 --rate-hz 1000
