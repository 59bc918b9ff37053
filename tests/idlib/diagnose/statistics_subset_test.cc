// tests/support/statistics.h: the seed subsets the sanitizer build runs instead of
// the statistical acceptance runs' full sets (here: their users are this folder's
// IndependentPlant* runs).  A reduced run must check something, nothing the full
// run does not, and with a criterion that can still fail.
#include "tests/support/statistics.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace lpvid {
namespace statistics_subset_test {

TEST(StatisticalSubset, ScaledAllowanceIsBelowTheRunsAndNeverALooserRate) {
  // every full criterion "at most `allowed` of `total`" that can fail, every subset size
  constexpr int kLargestSet = 60;
  for (int total = 1; total <= kLargestSet; ++total) {
    for (int allowed = 0; allowed < total; ++allowed) {
      EXPECT_EQ(testing::scaled_allowance(allowed, total, total), allowed);  // the full run keeps its criterion
      for (int runs = 1; runs <= total; ++runs) {
        const int scaled = testing::scaled_allowance(allowed, total, runs);
        ASSERT_GE(scaled, 0);
        ASSERT_LT(scaled, runs) << allowed << " of " << total << " over " << runs << " runs is vacuous";
        ASSERT_LE(scaled * total, allowed * runs) << "a looser rate than " << allowed << " of " << total;
      }
    }
  }
  // the clean-plant run (diagnose_test.cc): 1 of 10, reduced to 3 seeds -> no alarm allowed
  EXPECT_EQ(testing::scaled_allowance(1, 10, 3), 0);
}

TEST(StatisticalSubset, TheBuildPicksTheFullSetOrTheSubset) {
  const std::vector<std::uint64_t> full = {201, 202, 203, 204}, subset = {204};
  EXPECT_EQ(testing::statistical_cases(full, subset), testing::kFullStatistics ? full : subset);
}

TEST(StatisticalSubsetDeathTest, AnEmptySubsetOrACaseOutsideTheFullSetIsABug) {
  const std::vector<std::uint64_t> full = {401, 402, 403};
  EXPECT_DEATH(testing::statistical_cases<std::uint64_t>(full, {}), "subset.empty");
  EXPECT_DEATH(testing::statistical_cases<std::uint64_t>(full, {401, 999}), "std::find");
}

}  // namespace statistics_subset_test
}  // namespace lpvid
