// Golden test of `lpvid unloop` (cli/unloop.cc) on the golden closed-loop model
// and the golden controller.
#include <gtest/gtest.h>

#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace unloop_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

// The input files are the golden ones, so the only differences come from the
// interconnection, the ordered Schur form and the decoupling (Sylvester) solve:
// backward-stable dense steps whose results are fixed only up to a change of
// basis.  Removing the six controller modes that nearly cancel divides by their
// small separation from the plant's modes, costing digits; 8 digits of each
// channel's peak is the same bar as realize and catches any change of the
// removed set or the plant order.
constexpr double kResponseDigits = 8.0;

TEST(UnloopGolden, PlantHasTheGoldenOrderAndFrequencyResponseToEightDigits) {
  TempDir dir("golden_unloop");
  const auto r = run_lpvid("unloop --closed-loop " + data("realize/closed_loop.json") + " --controller " + sim_dir() +
                           "/controller.json --out " + (dir / "plant.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const StateSpace a = read_state_space(dir / "plant.json");
  const StateSpace b = read_state_space(data("unloop/plant.json"));
  EXPECT_EQ(a.order(), b.order());
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.input_names, b.input_names);
  EXPECT_EQ(a.output_names, b.output_names);
  const Score s = compare_frequency_response(a, b);
  record_digits("unloop_response", s);
  EXPECT_GE(s.min_digits, kResponseDigits) << s.where;
}

}  // namespace unloop_golden_test
}  // namespace lpvid::golden
