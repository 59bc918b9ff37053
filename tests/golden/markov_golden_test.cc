// Golden test of `lpvid markov` (cli/markov.cc) on the golden logs.
#include <gtest/gtest.h>

#include "formats/io/markov_csv.h"
#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace markov_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

// The estimate is deterministic: FFT correlations (FFTW's plan is chosen by
// estimate, not measurement, so the same arithmetic each run) and a preconditioned
// conjugate-gradient solve of the normal equations stopped at relative residual
// 1e-10.  On one build the output is bit-identical; across compilers the PCG may
// stop one iteration earlier or later, which moves g by at most about the 1e-10
// tolerance relative to its size.  Hence 10 digits, scored relative to each
// channel's peak |g_ij(k)| over the lags (an entry near zero has no meaningful
// relative digits of its own).
constexpr double kMarkovDigits = 10.0;
// noise_std and the rms figures are plain sums over the same data.
constexpr double kStatisticsDigits = 10.0;

TEST(MarkovGolden, MarkovParametersAgreeToTenDigitsOfEachChannelsPeak) {
  TempDir dir("golden_markov");
  const auto r = run_lpvid(std::string("markov ") + kChannels + " --out " + (dir / "g.csv") + " " + golden_logs());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const MarkovFile a = read_markov_csv(dir / "g.csv");
  const MarkovFile b = read_markov_csv(data("markov/g.csv"));
  ASSERT_EQ(a.g.size(), b.g.size());
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.inputs, b.inputs);
  EXPECT_EQ(a.outputs, b.outputs);
  const Index p = b.g.front().rows(), m = b.g.front().cols();
  Score g, stats;
  for (Index i = 0; i < p; ++i) {
    for (Index j = 0; j < m; ++j) {
      double peak = 0;
      for (const auto& gk : b.g) peak = std::max(peak, std::abs(gk(i, j)));
      for (std::size_t k = 0; k < b.g.size(); ++k)
        g.add(digits(a.g[k](i, j), b.g[k](i, j), peak),
              "g_" + b.outputs[static_cast<std::size_t>(i)] + "_" + b.inputs[static_cast<std::size_t>(j)] +
                  " lag " + std::to_string(k));
      stats.add(digits(a.noise_std(i, j), b.noise_std(i, j), std::abs(b.noise_std(i, j))), "noise_std");
    }
  }
  for (Index j = 0; j < m; ++j)
    stats.add(digits(a.input_rms(j), b.input_rms(j), std::abs(b.input_rms(j))), "input_rms");
  for (Index i = 0; i < p; ++i)
    stats.add(digits(a.output_rms(i), b.output_rms(i), std::abs(b.output_rms(i))), "output_rms");
  record_digits("markov_g", g);
  record_digits("markov_statistics", stats);
  EXPECT_GE(g.min_digits, kMarkovDigits) << g.where;
  EXPECT_GE(stats.min_digits, kStatisticsDigits) << stats.where;
}

}  // namespace markov_golden_test
}  // namespace lpvid::golden
