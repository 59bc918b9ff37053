#!/usr/bin/env bash
# Builds the libFuzzer harnesses (one per reader, fuzz/README.md) with Debian's
# clang under AddressSanitizer + UBSan and runs each for a bounded time on a copy
# of its seed corpus.  Exit code 0 only if no harness found anything (a crash, a
# leak, a sanitizer report, or a reader that broke its contract: fuzz/readers.h).
#
#   scripts/fuzz.sh                  # every harness, FUZZ_SECONDS (default 60) each, FUZZ_JOBS (2) at a time
#   FUZZ_SECONDS=600 scripts/fuzz.sh frd_mat history
#
# Findings are kept in $LPVID_FUZZ_DIR/<harness>/ (default build-fuzz/findings);
# turn each into a regression input: copy it to fuzz/regressions/<harness>/.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/install-deps.sh" fuzz
build="${LPVID_FUZZ_BUILD_DIR:-$root/build-fuzz}"
seconds="${FUZZ_SECONDS:-60}"
jobs="${FUZZ_JOBS:-2}"
all=(log_csv log_mat frd_csv frd_mat state_space_json physical_model_json history markov_csv platform_json effect_json
     dataset_manifest)
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && harnesses=("${all[@]}")

# A tree already configured for the harnesses (LPVID_FUZZ_BUILD_DIR, e.g. CI's
# sanitizer tree, which also builds the tests) is used as it is; otherwise a tree of
# the harnesses alone is configured.
if ! grep -qs "^LPVID_BUILD_FUZZ:BOOL=ON" "$build/CMakeCache.txt"; then
  gen=()
  if [ ! -f "$build/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DLPVID_SANITIZE=ON \
    -DLPVID_BUILD_FUZZ=ON -DLPVID_BUILD_TESTS=OFF -DLPVID_BUILD_BENCH=OFF -DLPVID_BUILD_SIMULATORS=OFF >/dev/null
fi
cmake --build "$build" -j"$(nproc)" --target "${harnesses[@]/#/fuzz_}"

out="${LPVID_FUZZ_DIR:-$build/findings}"
mkdir -p "$out"
# Leaks, and every sanitizer report, are findings; a reader may take 64 MiB inputs
# (JSON limit), so libFuzzer's memory limit is raised above it.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:symbolize=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
run_one() {
  local h="$1" work="$out/$1"
  rm -rf "$work" && mkdir -p "$work/corpus" "$work/artifacts"
  cp "$root/fuzz/corpus/$h/"* "$work/corpus/"
  [ -d "$root/fuzz/regressions/$h" ] && cp "$root/fuzz/regressions/$h/"* "$work/corpus/" 2>/dev/null || true
  if "$build/fuzz_$h" "$work/corpus" -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=4096 -timeout=30 \
       -print_final_stats=1 -artifact_prefix="$work/artifacts/" >"$work/log.txt" 2>&1; then
    local execs
    execs=$(grep -m1 "stat::number_of_executed_units" "$work/log.txt" | awk '{print $2}')
    echo "fuzz $h: ${seconds} s, ${execs:-?} executions, no finding"
  else
    echo "fuzz $h: FINDING (log: $work/log.txt, inputs: $work/artifacts/)"
    grep -E "FINDING|ERROR: |SUMMARY" "$work/log.txt" | head -5
    return 1
  fi
}
export -f run_one
export root build out seconds
printf '%s\n' "${harnesses[@]}" | xargs -P "$jobs" -I{} bash -c 'run_one {}'
