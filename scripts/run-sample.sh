#!/usr/bin/env bash
# The main job on sample data: install dependencies, build, simulate the sample
# datasets (3 beam positions at 1 kHz, 60 s per experiment) and identify each one,
# writing models, PNG plots and reports under samples/out/; then the model-error
# loop on data with a hidden effect (samples/loop/), on the 6-DOF stage
# (samples/stage6/), the lab workflow (samples/lab/) and a stage described by the user
# (samples/mechanical/out/).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# Builds only what the samples run: the program and the independent simulator that
# the model-error loop uses as its rig (no tests, no benchmarks: scripts/run-tests.sh
# builds those into the same tree).
LPVID_DEPS="" LPVID_BUILD_TARGETS="lpvid indep_sim" bash "$root/scripts/build.sh" \
  -DLPVID_BUILD_TESTS=OFF -DLPVID_BUILD_BENCH=OFF -DLPVID_BUILD_SIMULATORS=ON
make -C "$root/samples" -j"$(nproc)" all
echo "results: $root/samples/out/ (one folder per dataset; summary in samples/out/summary.txt)"
# The model-error loop on analyzer data with a hidden 1 ms delay (docs/model-error-walkthrough.md).
bash "$root/samples/model-error-loop.sh"
echo "model-error loop: $root/samples/loop/ (where-it-fails.png, history.png)"
# The same loop on the 6-DOF maglev stage (base stage6; the walkthrough's last part).
bash "$root/samples/stage6-loop.sh"
echo "stage6 loop: $root/samples/stage6/ (where-it-fails.png, history.png)"
# The lab workflow: a designed multisine -> the simulated experiment -> periodic FRFs
# with their noise and distortion -> fit -> diagnose (samples/lab-periodic.sh).
bash "$root/samples/lab-periodic.sh"
echo "lab workflow: $root/samples/lab/ (where-it-fails.png, history.png)"
# A stage of your own: a two-mass axis described in JSON (base mechanical), its measured
# response with two flexible modes the description lacks (samples/mechanical-loop.sh).
bash "$root/samples/mechanical-loop.sh"
echo "your own stage: $root/samples/mechanical/out/ (where-it-fails.png, fit2.png)"
# A positioning axis with friction, logged in closed loop: the loop in the time domain
# (force error) names Coulomb friction, then the offset (samples/friction-loop.sh).
bash "$root/samples/friction-loop.sh"
echo "friction loop: $root/samples/mechanical/out-friction/ (report1.json, report2.json)"
