#!/usr/bin/env bash
# The main job on sample data: install dependencies, build, simulate the sample
# datasets (3 beam positions at 1 kHz, 60 s per experiment) and identify each one,
# writing models, PNG plots and reports under samples/out/.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/build.sh"
make -C "$root/samples" -j"$(nproc)" all
echo "results: $root/samples/out/ (one folder per dataset; summary in samples/out/summary.txt)"
