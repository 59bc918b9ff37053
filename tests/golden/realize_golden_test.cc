// Golden test of `lpvid realize` (cli/realize.cc) on the golden Markov parameters.
#include <gtest/gtest.h>

#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace realize_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

// ERA's matrices are fixed only up to a change of state basis (and the sign of
// each singular vector), so the model is compared by its frequency response.
// The response inherits the Hankel decomposition's error (see
// hankel_golden_test.cc: 1e-10-level Lanczos subspace, Rayleigh-Ritz) amplified
// by the truncation at order 9, whose gap s_9/s_10 is ~26: about a digit and a
// half lost.  8 digits of each channel's peak |G_ij| keep that margin and catch
// any change of order, scaling or shift equation.
constexpr double kResponseDigits = 8.0;

TEST(RealizeGolden, ClosedLoopHasTheGoldenOrderAndFrequencyResponseToEightDigits) {
  TempDir dir("golden_realize");
  const auto r = run_lpvid("realize " + data("markov/g.csv") + " --out " + (dir / "cl.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const StateSpace a = read_state_space(dir / "cl.json");
  const StateSpace b = read_state_space(data("realize/closed_loop.json"));
  EXPECT_EQ(a.order(), b.order());
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.input_names, b.input_names);
  EXPECT_EQ(a.output_names, b.output_names);
  const Score s = compare_frequency_response(a, b);
  record_digits("realize_response", s);
  EXPECT_GE(s.min_digits, kResponseDigits) << s.where;
}

}  // namespace realize_golden_test
}  // namespace lpvid::golden
