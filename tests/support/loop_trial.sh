#!/usr/bin/env bash
# The model-error loop tried as a new user would, through the program only: for
# each hidden effect and seed, the independent simulator (indep_sim) writes analyzer
# S exports (or logs, ROUTE=frf, which lpvid frf turns into S), the user writes the
# manifest, runs `model init` with the design values they know (the rods' bending
# stiffness off by a seeded 0.85-1.15 factor, the beam height to the centimetre),
# `fit`, then `diagnose --json`, and the table says whether the hidden effect was
# named first and the error fell >= 10x or to within 1.5x the noise floor; for the
# clean plant whether anything was called significant; for the out-of-library
# resonance whether it was claimed explained and where it was described.
#
#   tests/support/loop_trial.sh [SEEDS (default 5)] [FIRST_SEED (default 1000)]
#   ROUTE=frf EFFECTS="none delay" tests/support/loop_trial.sh 3
#   WEIGHTING=auto tests/support/loop_trial.sh 3   # fit and diagnose --weighting auto
#
# Writes /tmp/lpvid-loop-trial/<route>-<weighting>/<effect>_<seed>/ and prints one line per run
# and a summary.  Draw ranges: INDEP_ARGS (default: psi/theta stiffness ratio
# 0.6-1.6, closed-loop damping >= 0.05, noise 0.1-10x, never noise-free).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../../build/lpvid}"
indep_sim="${INDEP_SIM:-$here/../../build/indep_sim}"
seeds="${1:-5}"
first="${2:-1000}"
route="${ROUTE:-analyzer}"
effects="${EFFECTS:-none mode delay coil_lag com_offset rod_twist sensor_resonance}"
indep_args="${INDEP_ARGS:---ratio-min 0.6 --ratio-max 1.6 --cl-damping-min 0.05 --no-zero-noise}"
weighting="${WEIGHTING:-noise}"
case "$weighting" in noise|auto) ;; *) echo "loop_trial.sh: WEIGHTING=$weighting: give noise or auto" >&2; exit 2 ;; esac
root="/tmp/lpvid-loop-trial/$route-$weighting"
mkdir -p "$root"
: > "$root/results.txt"

expected() {
  case "$1" in
    mode) echo structural_mode ;; delay) echo input_delay ;; coil_lag) echo actuator_lag ;;
    com_offset) echo com_offset ;; rod_twist) echo rod_twist ;; *) echo "" ;;
  esac
}

for effect in $effects; do
  for ((k = 0; k < seeds; ++k)); do
    seed=$((first + k))
    dir="$root/${effect}_$seed"
    rm -rf "$dir" && mkdir -p "$dir" && cd "$dir"
    if ! "$indep_sim" --out . --seed "$seed" --hidden "$effect" $indep_args \
        $([ "$route" = frf ] && echo --no-analyzer || echo --no-logs) > sim.txt 2>&1; then
      echo "$effect seed $seed: no experiment ($(tail -1 sim.txt))"
      continue
    fi
    if [ "$route" = frf ]; then
      for p in left middle right; do
        "$lpvid" frf --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out "S_$p.csv" \
            "$p/exp_v1.csv" "$p/exp_v2.csv" "$p/exp_v3.csv" > /dev/null
      done
      files() { echo "\"S_$1.csv\""; }
    else
      files() { echo "\"$1/S_v1.csv\", \"$1/S_v2.csv\", \"$1/S_v3.csv\""; }
    fi
    cat > data.json <<EOF
{"format": "lpvid-datasets", "target": "S", "controller": "middle/controller.json",
 "datasets": [{"beam_position_m": -0.1, "files": [$(files left)]},
              {"beam_position_m": 0, "files": [$(files middle)]},
              {"beam_position_m": 0.1, "files": [$(files right)]}]}
EOF
    k_bend=$(awk '/^k_bend_per_rod/ {print $3}' truth.txt)
    z_b=$(awk '/^z_b_m/ {print $3}' truth.txt)
    design=$(python3 -c "import random; r = random.Random($seed); print(round($k_bend * r.uniform(0.85, 1.15), 1))")
    z_design=$(python3 -c "print(round($z_b, 2))")
    "$lpvid" model init --out model.json --set "k_torque_low_Nm_per_rad=$design" --set "beam_height_m=$z_design" > /dev/null
    start=$(date +%s.%N)
    "$lpvid" fit --model model.json --datasets data.json --weighting "$weighting" --out fit1.json > fit.txt 2>&1 || true
    "$lpvid" diagnose --model fit1.json --datasets data.json --weighting "$weighting" --json > diagnose.json \
        2> diagnose.err || true
    end=$(date +%s.%N)
    python3 - "$effect" "$seed" "$(expected "$effect")" "$start" "$end" <<'EOF' | tee -a "$root/results.txt"
import json, sys
effect, seed, want, t0, t1 = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5])
try:
    d = json.load(open("diagnose.json"))
except Exception as e:
    print(f"{effect:17s} {seed}: diagnose failed ({open('diagnose.err').read().strip()[:200]})")
    sys.exit(0)
e0 = d["baseline"]["error"]; f = d["effective_floor"]
missing = d["missing"]
# the winner: a single candidate or a combination ("A + B"); its members
members = d.get("missing_effects") or ([missing] if missing else [])
winner = next((c for c in d["candidates"] + d.get("combinations", []) if c["effect"] == missing), None)
after = winner["error"] if winner else e0
falls = missing is not None and (e0 / after >= 10 or after <= 1.5 * f)
desc = d["descriptions"][0]["text"] if d["descriptions"] else "-"
if effect == "none":
    ok = missing is None
    verdict = "ok (nothing significant)" if ok else f"FALSE ALARM: {missing}"
elif effect == "sensor_resonance":
    ok = not d["explained"] and "theta output row" in desc
    verdict = ("ok" if ok else "FAIL") + f" (explained={d['explained']}, missing={missing}): {desc[:110]}"
else:
    # named alone, or in a combination (beside what carries a design value the base
    # cannot reach, e.g. rod_twist when the rods' design is 2x off)
    ok = want in members and falls
    how = "first" if missing == want else ("in a combination" if want in members else "wrong")
    verdict = ("ok" if ok else "FAIL") + f" named {missing} ({how}), {'falls' if falls else 'does not fall'}"
print(f"{effect:17s} {seed}: error {100*e0:.3g} % -> {100*after:.3g} % (floor {100*f:.3g} %; {t1-t0:.0f} s)  {verdict}")
EOF
  done
done
echo "summary ($root/results.txt):"
for effect in $effects; do
  n=$(grep -c "^$effect " "$root/results.txt" || true)
  good=$(grep "^$effect " "$root/results.txt" | grep -c " ok" || true)
  echo "  $effect: $good of $n"
done
