#!/usr/bin/env bash
# The model-error loop on a plant that is not lpvid's own (docs/model-error-walkthrough.md).
# The "rig" is tests/support's independent simulator (indep_sim: the platform's
# physics written apart from lpvid, coil by coil, with its own parameter values),
# standing in for your lab.  Three cases, each from the same drawn platform (seed 27):
#   1. a hidden coil lag: fit the model, diagnose names the missing effect, add it,
#      refit, watch the error fall to the noise floor;
#   2. a hidden theta-sensor resonance no library effect contains: diagnose says so,
#      describes it, writes it as a user-defined effect; define it, refit;
#   3. case 1 again from time-domain logs through `lpvid frf` instead of an analyzer;
#   4. case 1 with a weighed mass given as a prior (model set NAME=VALUE±SIGMA);
#   5. two effects missing at once (a centre-of-mass offset with its product of
#      inertia, and the coil lag): diagnose names the pair, model add takes both from
#      the diagnosis, the refit reaches what diagnose reported.
# Writes samples/loop/.  LPVID and INDEP_SIM override the programs' paths.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
indep_sim="${INDEP_SIM:-$here/../build/indep_sim}"
rm -rf "$here/loop" && mkdir -p "$here/loop" && cd "$here/loop"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }
sim() { echo "\$ indep_sim $*"; "$indep_sim" "$@"; echo; }

# The data sets, written once: three beam positions, each with three analyzer
# files (one per excited input v_j) of S = (I + C P)^-1, v -> u.
manifest() {  # $1: file, $2: the files of one position with {p} for left/middle/right
  local f="${2//\{p\}/left}" m="${2//\{p\}/middle}" r="${2//\{p\}/right}"
  cat > "$1" <<EOF
{"format": "lpvid-datasets", "target": "S", "controller": "middle/controller.json",
 "datasets": [
  {"beam_position_m": -0.1, "files": [$f]},
  {"beam_position_m": 0, "files": [$m]},
  {"beam_position_m": 0.1, "files": [$r]}]}
EOF
  echo "\$ cat $1"; cat "$1"; echo
}

# ---- 1. a hidden coil lag -------------------------------------------------------
mkdir -p lag && cd lag
sim --out . --seed 27 --hidden coil_lag --no-logs
manifest data.json '"{p}/S_v1.csv", "{p}/S_v2.csv", "{p}/S_v3.csv"'
# the design values we know: the rods' bending stiffness (datasheet) and the beam height
run model init --out model.json --set k_torque_low_Nm_per_rad=55 --set beam_height_m=0.08
run fit --model model.json --datasets data.json --out fit1.json --plot fit1.png
run diagnose --model fit1.json --datasets data.json --png where-it-fails.png
run model add actuator_lag --model fit1.json --out start2.json
run fit --model start2.json --datasets data.json --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
run diagnose --model fit2.json --datasets data.json
cd ..

# ---- 2. an effect no library contains ---------------------------------------------
mkdir -p sensor && cd sensor
sim --out . --seed 27 --hidden sensor_resonance --no-logs
manifest data.json '"{p}/S_v1.csv", "{p}/S_v2.csv", "{p}/S_v3.csv"'
run model init --out model.json --set k_torque_low_Nm_per_rad=55 --set beam_height_m=0.08
run fit --model model.json --datasets data.json --out fit1.json
run diagnose --model fit1.json --datasets data.json --png where-it-fails.png --out-effect theta_sensor.json
echo "\$ cat theta_sensor.json"; cat theta_sensor.json; echo
run model define --model fit1.json --from theta_sensor.json --add --out start2.json
run fit --model start2.json --datasets data.json --out fit2.json --plot fit2.png
run history --model fit2.json --png history.png
run diagnose --model fit2.json --datasets data.json
cd ..

# ---- 3. case 1 from time-domain logs ----------------------------------------------
mkdir -p logs && cd logs
sim --out . --seed 27 --hidden coil_lag --no-analyzer
for p in left middle right; do
  run frf --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out "S_$p.csv" \
      "$p/exp_v1.csv" "$p/exp_v2.csv" "$p/exp_v3.csv"
done
manifest data.json '"S_{p}.csv"'
run model init --out model.json --set k_torque_low_Nm_per_rad=55 --set beam_height_m=0.08
run fit --model model.json --datasets data.json --out fit1.json
run diagnose --model fit1.json --datasets data.json --out fit2.json
cd ..

# ---- 4. a design value you know: a prior (case 1's data) ---------------------------
cd lag
run model set --model model.json --set platform_mass_kg=3.83±0.02 --out prior.json
run fit --model prior.json --datasets data.json --out fitp.json
run model add actuator_lag --model fitp.json --out startp2.json
run fit --model startp2.json --datasets data.json --out fitp2.json
cd ..

# ---- 5. two effects missing at once -----------------------------------------------
mkdir -p pair && cd pair
sim --out . --seed 27 --hidden com_offset,coil_lag --no-logs
manifest data.json '"{p}/S_v1.csv", "{p}/S_v2.csv", "{p}/S_v3.csv"'
run model init --out model.json --set k_torque_low_Nm_per_rad=55 --set beam_height_m=0.08
run fit --model model.json --datasets data.json --out fit1.json
run diagnose --model fit1.json --datasets data.json --report report.json
run model add com_offset,actuator_lag --model fit1.json --from-diagnosis report.json --out start2.json
run fit --model start2.json --datasets data.json --out fit2.json --plot fit2.png
cd ..
