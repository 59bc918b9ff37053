#!/usr/bin/env bash
# The model-error loop on a stage lpvid has no base for (base mechanical; docs/effects.md,
# "Base: mechanical"): a two-mass positioning axis you describe yourself
# (mechanical/two_mass_axis.json: carriage and load coupled by a spring and damper, a
# current-driven motor, an encoder and a load sensor) and its measured response
# (mechanical/P_axis.csv, written by mechanical/make_p_axis.py: the true values differ
# from the description's design values, and two flexible modes the description lacks
# hide in it, under 0.5 % noise).
#   init from the description -> fit -> diagnose names what is missing -> add -> fit,
#   and the error falls to the noise.
# Writes samples/mechanical/out/.  LPVID overrides the program's path.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
out="$here/mechanical/out"
rm -rf "$out" && mkdir -p "$out" && cd "$out"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }
data=(--data ../P_axis.csv --noise-level 0.005)

run model init --base mechanical --from ../two_mass_axis.json --out start.json
run fit --model start.json "${data[@]}" --out fit1.json
run diagnose --model fit1.json "${data[@]}" --report report1.json --png where-it-fails.png --out step2.json
run fit --model step2.json "${data[@]}" --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
