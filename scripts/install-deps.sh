#!/usr/bin/env bash
# Installs lpvid's dependencies from Debian 12 packages, by set:
#   install-deps.sh              what the program needs (scripts/run-sample.sh)
#   install-deps.sh tests        + GoogleTest/GoogleMock, Google Benchmark and snakemake
#                                  (scripts/run-tests.sh; snakemake runs samples/Snakefile in a test)
#   install-deps.sh fuzz         + Debian's clang with its libFuzzer and sanitizer runtimes
#                                  (scripts/fuzz.sh, the sanitizer stage of .ci/run)
# Sets combine (`install-deps.sh tests fuzz`).  Idempotent: does nothing (and needs
# no network) when everything asked for is present.
set -euo pipefail
pkgs=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libceres-dev libnlopt-cxx-dev libnlopt-dev
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev libpng-dev
  libcli11-dev libfmt-dev nlohmann-json3-dev libfast-float-dev
  libfftw3-dev libmatio-dev zlib1g-dev libspectra-dev libopenblas-dev liblapacke-dev
  fonts-dejavu-core python3
)
for set in "$@"; do
  case "$set" in
    tests) pkgs+=(libgtest-dev libgmock-dev libbenchmark-dev snakemake) ;;
    fuzz) pkgs+=(clang libclang-rt-14-dev) ;;
    *) echo "install-deps: unknown set '$set' (sets: tests, fuzz); run without arguments for the program's own" >&2
       exit 2 ;;
  esac
done
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
