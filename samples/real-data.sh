#!/usr/bin/env bash
# lpvid on real measured data (docs/real-data.md): every route on the public benchmark
# recordings in DIR (on the development machine ../shared/real-data; they are not the
# project's to ship, so this is not part of the main job).
#   F-16 ground vibration test: the periodic FRF with the measured voltage as reference,
#     levels 1 and 7 (the wing-torsion mode softens), also from the raw .mat file;
#   DaISy robot arm: markov's default horizon (sample time unknown), identify --open-loop,
#     compare --log of the identified model on the record;
#   DaISy steel subframe: identify --open-loop with the defaults (about 11 min on one
#     core: order 20, refined in modal form), compare --log of its model on the record;
#   the robot arm's raw .mat (one unnamed matrix) with --log-columns and --log-rate.
# Writes samples/real/.  LPVID overrides the program's path.
#   ./samples/real-data.sh ../shared/real-data
set -euo pipefail
if [[ $# -ne 1 || ! -d "$1" ]]; then
  echo "usage: $0 DIR   (DIR holds f16_gvt/, daisy_robot_arm/, daisy_flexible_structure/)" >&2
  exit 2
fi
data="$(cd "$1" && pwd)"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
lpvid="${LPVID:-$here/../build/lpvid}"
rm -rf "$here/real" && mkdir -p "$here/real" && cd "$here/real"
run() { echo "\$ lpvid $*"; "$lpvid" "$@"; echo; }

f16=(--method periodic --period-samples 8192 --periods 8 --transient-periods 1
     --excitation voltage --input force --output "acc1,acc2,acc3" --quantity P)
run frf "${f16[@]}" --out P_level1.csv "$data/f16_gvt/f16_fullmsine_level1.csv"
run frf "${f16[@]}" --out P_level7.csv "$data/f16_gvt/f16_fullmsine_level7.csv"
run frf --method lpm --excitation voltage --input force --output acc1,acc2,acc3 --quantity P \
    --out P_level1_lpm.csv "$data/f16_gvt/f16_fullmsine_level1.csv"
# The raw file as the lab saved it (Force, Voltage, Acceleration 3 x N, Fs).
run frf --method periodic --period-samples 8192 --periods 8 --transient-periods 1 --excitation Voltage \
    --input Force --output Acceleration1,Acceleration2,Acceleration3 --quantity P --out P_level1_raw.csv \
    "$data/f16_gvt/raw/F16Data_FullMSine_Level1.mat"
run bode --hz --min 2 --max 15 --labels "level 1,level 7" --title "F-16 GVT: force -> acceleration" \
    --out f16_levels.png P_level1.csv P_level7.csv

run markov --excitation u --output y --out arm_markov.csv "$data/daisy_robot_arm/robot_arm.csv"
run identify --open-loop --excitation u --output y --out arm "$data/daisy_robot_arm/robot_arm.csv"
# The identified model judged on the record (fit from rest and with its initial state,
# residual tests, the overlay).
run compare --log "$data/daisy_robot_arm/robot_arm.csv" --model arm/plant.json --out-png arm_compare.png

# The raw DaISy file as the lab saved it: one unnamed 1024 x 2 matrix, no rate.
run markov --log-columns u,y --log-rate 1 --excitation u --output y --out arm_markov_raw.csv \
    "$data/daisy_robot_arm/raw/robot_arm_dat.mat"

run identify --open-loop --excitation f1,f2 --output a1..a28 --out subframe \
    "$data/daisy_flexible_structure/flexible_structure.csv"
run compare --log "$data/daisy_flexible_structure/flexible_structure.csv" --model subframe/plant.json \
    --out-png subframe_compare.png
echo "real data: $here/real/ (f16_levels.png, arm/bode.png, arm_compare.png, subframe/bode.png, subframe_compare.png, the FRD files)"
