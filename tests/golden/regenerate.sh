#!/usr/bin/env bash
# Regenerates the golden files of tests/golden/data/ with the lpvid program given
# as $1 (default: build-golden/lpvid).  RUN ONLY DELIBERATELY: the golden files
# pin today's numbers, and the tests in tests/golden/ fail when a change moves
# them beyond the tolerances in golden_test.cc.  A commit that changes any file
# under tests/golden/data/ must say in its message WHY the numbers moved (which
# change, and why the new numbers are right), and name the lpvid commit and
# compiler that made them.
#
# What it runs (from tests/golden/data/, with relative paths so that no file
# holds an absolute path), each step reading the golden output of the step
# before it, never a fresh one:
#   simulate platform --positions middle --rate-hz 1000 --duration-s 2 --seed 11
#                                              -> simulate/middle_1000hz/*
#   markov  (3 logs T_psi, T_theta, F_z; v1..v3 -> q1..q3; default 500 lags)
#                                              -> markov/g.csv
#   hankel  markov/g.csv --count 12 --json     -> hankel/sv.csv, hankel/summary.json
#   realize markov/g.csv (automatic order)     -> realize/closed_loop.json
#   unloop  realize/closed_loop.json + simulate/.../controller.json
#                                              -> unloop/plant.json
#   identify --method era (same logs, --truth truth_plant.json --json)
#                                              -> identify/{report.json, plant.json, closed_loop.json}
#                                                 (its markov.csv equals markov/g.csv, its hankel_sv.csv
#                                                 is in report.json, its PNGs are large: not kept)
#   bode    bode/resonance.json bode/lowpass.json (hand-written SISO inputs,
#           kept, not regenerated) --labels resonance,lowpass
#                                              -> bode/bode.png
# The only random input is the simulation seed 11 (each experiment's noise
# stream is derived from it; the logs' first comment line records it).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="$(realpath "${1:-$here/../../build-golden/lpvid}")"
[[ -x "$lpvid" ]] || { echo "regenerate.sh: no lpvid program at $lpvid; build it first" >&2; exit 2; }

cd "$here/data"
rm -rf simulate markov hankel realize unloop identify bode/bode.png
mkdir -p markov hankel realize unloop identify

sim=simulate/middle_1000hz
logs="$sim/exp_T_psi.csv $sim/exp_T_theta.csv $sim/exp_F_z.csv"

"$lpvid" simulate platform --out simulate --positions middle --rate-hz 1000 --duration-s 2 --seed 11
"$lpvid" markov --excitation v1,v2,v3 --output q1,q2,q3 --out markov/g.csv $logs
"$lpvid" hankel markov/g.csv --out hankel/sv.csv --count 12 --json > hankel/summary.json
"$lpvid" realize markov/g.csv --out realize/closed_loop.json
"$lpvid" unloop --closed-loop realize/closed_loop.json --controller "$sim/controller.json" --out unloop/plant.json
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
"$lpvid" identify --method era --controller "$sim/controller.json" --excitation v1,v2,v3 --output q1,q2,q3 \
  --truth "$sim/truth_plant.json" --out "$tmp/identify" --json $logs > /dev/null
cp "$tmp/identify/report.json" "$tmp/identify/plant.json" "$tmp/identify/closed_loop.json" identify/
"$lpvid" bode --out bode/bode.png --labels resonance,lowpass bode/resonance.json bode/lowpass.json

du -sh "$here/data"
