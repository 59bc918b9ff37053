// Seed sets of the statistical acceptance runs, full or reduced per build.
//
// The normal (Release) build runs every seed of each statistical run with its full
// criterion: that is the acceptance and keeps its full statistical power.  The
// sanitizer build (CMake LPVID_FULL_STATISTICS, OFF by default when LPVID_SANITIZE
// is ON) runs every such test on a documented subset of its seeds: it checks memory
// and undefined behaviour on the same code paths, with fewer repeats, so that the
// whole suite under the sanitizers stays affordable (LPVID_CI_SANITIZE_ALL=1 .ci/run;
// CI itself runs only the readers' tests there: docs/dev/CI.md).  A subset run is no statistical evidence; its
// pass criterion is the full one scaled to the subset, never looser (below).
#pragma once

#include <algorithm>
#include <vector>

#include "idlib/core/error.h"

#ifndef LPVID_FULL_STATISTICS
#error "LPVID_FULL_STATISTICS (0 or 1) is defined for every test target by CMakeLists.txt (lpvid_tests)"
#endif

namespace lpvid::testing {

inline constexpr bool kFullStatistics = LPVID_FULL_STATISTICS != 0;

// The cases a statistical run uses in this build: `full` in the normal build,
// `subset` in the reduced one.  The subset must be non-empty and drawn from `full`
// (LPVID_ASSERT: a test that breaks this is a bug), so that a reduced run always
// checks something and checks nothing the full run does not.
template <class Case>
std::vector<Case> statistical_cases(const std::vector<Case>& full, const std::vector<Case>& subset) {
  LPVID_ASSERT(!subset.empty());
  for (const Case& c : subset) LPVID_ASSERT(std::find(full.begin(), full.end(), c) != full.end());
  return kFullStatistics ? full : subset;
}

// A criterion "at most `allowed` failures in `total` runs", applied to `runs` of
// those runs: floor(allowed * runs / total) failures.  The rate is never above the
// full set's (allowed / total), and whenever the full criterion can fail
// (0 <= allowed < total) the scaled one can too: allowed * runs / total < runs, so
// the allowance is below `runs` for every 1 <= runs <= total and the criterion is
// never vacuous (tests/idlib/diagnose/statistics_subset_test.cc checks both).
constexpr int scaled_allowance(int allowed, int total, int runs) {
  return allowed * runs / total;
}

}  // namespace lpvid::testing
