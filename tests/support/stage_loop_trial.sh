#!/usr/bin/env bash
# The 6-DOF stage's model-error loop tried as a new user would, through the program
# only, on logs from the INDEPENDENT stage simulator (indep_stage_sim,
# tests/support/independent_stage.h; not lpvid's own simulator).  For each hidden
# effect and seed: a 60 s closed-loop log, then the documented session
# (docs/model-error-walkthrough.md, samples/stage6-loop.sh): `frf --input` -> `model
# init --base stage6` with the design values the user knows (the weighed mass and
# the lever arms, from truth.txt) -> `fit` -> `diagnose --json` -> `model add` the
# named effect -> `fit`; and the time-domain route `stage6 diagnose --log` (which
# cannot be told the mass or the arms: it assumes lpvid's design values).
# One line per run:
#   frf route: named first? error fell >= 10x or to within 1.5x the floor (the
#   diagnosis' candidate, and the refit)?  clean: nothing significant?
#   time route: what `stage6 diagnose` names (delay is not among its effects).
#
#   tests/support/stage_loop_trial.sh [SEEDS (default 3)] [FIRST_SEED (default 100)]
#   EFFECTS="none gap" NONE_SEEDS=10 SEGMENT=2048 NOISE_SCALE=0 tests/support/stage_loop_trial.sh 3
#   WEIGHTING=auto tests/support/stage_loop_trial.sh 3   # the frf route's fit and diagnose --weighting auto
#
# Writes /tmp/lpvid-stage-trial/<effect>_<seed>/ and prints one line per run and a
# summary.  CPU heavy (a diagnosis refits 8 candidates): run it niced.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../../build/lpvid}"
sim="${INDEP_STAGE_SIM:-$here/../../build/indep_stage_sim}"
seeds="${1:-3}"
first="${2:-100}"
none_seeds="${NONE_SEEDS:-$seeds}"
effects="${EFFECTS:-none gap lag com delay}"
segment="${SEGMENT:-2048}"
noise_args=""
[ -n "${NOISE_SCALE:-}" ] && noise_args="--noise-scale $NOISE_SCALE"
weighting="${WEIGHTING:-noise}"
case "$weighting" in noise|auto) ;; *) echo "stage_loop_trial.sh: WEIGHTING=$weighting: give noise or auto" >&2; exit 2 ;; esac
root="${ROOT:-/tmp/lpvid-stage-trial}"
mkdir -p "$root"
: > "$root/results.txt"

expected() {
  case "$1" in
    gap) echo gap_dependence ;; lag) echo electrical_lag ;; com) echo com_offset ;; delay) echo input_delay ;; *) echo "" ;;
  esac
}

for effect in $effects; do
  n=$seeds
  [ "$effect" = none ] && n=$none_seeds
  for ((k = 0; k < n; ++k)); do
    seed=$((first + k))
    dir="$root/${effect}_$seed"
    rm -rf "$dir" && mkdir -p "$dir" && cd "$dir"
    if ! "$sim" --out . --seed "$seed" --hidden "$effect" $noise_args > sim.txt 2>&1; then
      echo "$effect seed $seed: no experiment ($(tail -1 sim.txt))" | tee -a "$root/results.txt"
      continue
    fi
    start=$(date +%s.%N)
    "$lpvid" frf --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,q2,q3,q4,q5,q6 \
        --quantity P --segment "$segment" --out P.csv exp_stage6.csv > frf.txt 2>&1
    sets=$(awk '/^mass_kg|^lever_arm_/ {printf " --set %s=%s", $1, $3}' truth.txt)
    "$lpvid" model init --base stage6 --out model.json $sets > init.txt 2>&1
    "$lpvid" fit --model model.json --data P.csv@0 --rate-hz 1000 --weighting "$weighting" --out fit1.json > fit1.txt 2>&1 || true
    "$lpvid" diagnose --model fit1.json --data P.csv@0 --rate-hz 1000 --weighting "$weighting" --json > diagnose.json 2> diagnose.err || true
    # a single effect, or a combination's members joined by commas (model add A,B)
    named=$(python3 -c "import json; d = json.load(open('diagnose.json')); print(','.join(d.get('missing_effects') or ([d['missing']] if d['missing'] else [])))" 2>/dev/null || true)
    refit="-"
    if [ -n "$named" ]; then
      "$lpvid" model add "$named" --model fit1.json --out start2.json > add.txt 2>&1 || true
      "$lpvid" fit --model start2.json --data P.csv@0 --rate-hz 1000 --weighting "$weighting" --out fit2.json > fit2.txt 2>&1 || true
      refit=$(python3 -c "
import json
h = [json.loads(l) for l in open('fit2.json.history.jsonl')]
print(h[-1]['error'])" 2>/dev/null || echo "-")
    fi
    "$lpvid" stage6 diagnose --log exp_stage6.csv --json > stage6_diagnose.json 2> stage6_diagnose.err || true
    end=$(date +%s.%N)
    python3 - "$effect" "$seed" "$(expected "$effect")" "$start" "$end" "$refit" <<'EOF' | tee -a "$root/results.txt"
import json, sys
effect, seed, want, t0, t1, refit = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5]), sys.argv[6]
try:
    s6 = json.load(open("stage6_diagnose.json"))
    s6_named = s6["missing"] or "nothing"
    s6_text = f"stage6 diagnose: {s6_named} ({s6['baseline']['rms_residual']:.3g}"
    if s6["missing"]:
        c = [c for c in s6["candidates"] if c.get("effect") == s6["missing"]]
        if c: s6_text += f" -> {c[0]['rms_residual']:.3g}"
    s6_text += ")"
except Exception:
    s6_text = "stage6 diagnose failed: " + open("stage6_diagnose.err").read().strip()[:120]
try:
    d = json.load(open("diagnose.json"))
except Exception:
    print(f"{effect:6s} {seed}: diagnose failed ({open('diagnose.err').read().strip()[:200]}); {s6_text}")
    sys.exit(0)
e0 = d["baseline"]["error"]; f = d["effective_floor"]
missing = d["missing"]
# the winner: a single candidate or a combination ("A + B"); its members
members = d.get("missing_effects") or ([missing] if missing else [])
winner = next((c for c in d["candidates"] + d.get("combinations", []) if c["effect"] == missing), None)
after = winner["error"] if winner else e0
falls = missing is not None and (e0 / after >= 10 or after <= 1.5 * f)
r = float(refit) if refit not in ("-", "") else None
refit_falls = r is not None and (e0 / r >= 10 or r <= 1.5 * f)
if effect == "none":
    ok = missing is None
    verdict = "ok (nothing significant)" if ok else f"FALSE ALARM: {missing}"
else:
    ok = want in members and falls
    how = "first" if missing == want else ("in a combination" if want in members else "wrong")
    verdict = ("ok" if ok else "FAIL") + f" named {missing} ({how}), {'falls' if falls else 'does not fall'}"
rtxt = f", refit {100*r:.3g} %{' (falls)' if refit_falls else ' (does not fall)'}" if r is not None else ""
print(f"{effect:6s} {seed}: error {100*e0:.3g} % -> {100*after:.3g} % (floor {100*f:.3g} %{rtxt}; {t1-t0:.0f} s)  {verdict}; {s6_text}")
EOF
  done
done
echo "summary ($root/results.txt):"
for effect in $effects; do
  n=$(grep -c "^$effect " "$root/results.txt" || true)
  good=$(grep "^$effect " "$root/results.txt" | grep -c ": .* ok" || true)
  echo "  $effect: $good of $n"
done
