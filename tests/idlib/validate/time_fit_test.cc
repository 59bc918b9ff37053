#include "idlib/validate/time_fit.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "idlib/core/error.h"

namespace lpvid {
namespace time_fit_test {

using ::testing::HasSubstr;

// Named seed of the random tests in this file.
constexpr std::uint64_t kSeed = 4242;

Eigen::MatrixXd white(Index n, Index channels, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd x(n, channels);
  for (Index k = 0; k < n; ++k)
    for (Index c = 0; c < channels; ++c) x(k, c) = normal(rng);
  return x;
}

TEST(StandardNormalQuantile, MatchesTabulatedValues) {
  // Abramowitz & Stegun table 26.5: z(0.995) = 2.575829, z(0.975) = 1.959964.
  EXPECT_NEAR(standard_normal_quantile(0.995), 2.5758293035489, 1e-10);
  EXPECT_NEAR(standard_normal_quantile(0.975), 1.9599639845401, 1e-10);
  EXPECT_NEAR(standard_normal_quantile(0.5), 0.0, 1e-12);
  EXPECT_THROW(standard_normal_quantile(1.0), InputError);
}

TEST(NrmseFit, FollowsTheDefinition) {
  Eigen::MatrixXd y(4, 2), yh(4, 2);
  y << 1, 5, 2, 5, 3, 5, 4, 5;
  yh << 1.5, 5, 2, 5, 3, 5, 4, 6;
  const Eigen::VectorXd fit = nrmse_fit_percent(y, yh);
  // ‖y - mean‖ = sqrt(2.25 + 0.25 + 0.25 + 2.25) = sqrt(5); ‖e‖ = 0.5.
  EXPECT_NEAR(fit(0), 100.0 * (1.0 - 0.5 / std::sqrt(5.0)), 1e-12);
  EXPECT_TRUE(std::isinf(fit(1)) && fit(1) < 0);  // constant measurement, wrong prediction
  EXPECT_EQ(nrmse_fit_percent(y, y)(0), 100.0);
  EXPECT_THAT([&] { nrmse_fit_percent(y, yh.topRows(3)); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("they must match")));
}

TEST(ResidualWhiteness, WhiteNoisePassesAndAnAr1ResidualFails) {
  const Index n = 20000;
  const Eigen::MatrixXd w = white(n, 2, kSeed);
  Eigen::MatrixXd e = w;
  for (Index k = 1; k < n; ++k) e(k, 1) = 0.5 * e(k - 1, 1) + w(k, 1);  // r(1) = 0.5
  const auto tests = residual_whiteness(e, TimeFitOptions{});
  ASSERT_EQ(tests.size(), 2u);
  EXPECT_TRUE(tests[0].pass) << tests[0].worst_ratio;
  EXPECT_NEAR(tests[0].bound_per_lag, 2.5758293035489 / std::sqrt(double(n)), 1e-9);
  EXPECT_GT(tests[0].bound, tests[0].bound_per_lag);  // Bonferroni over 25 lags
  EXPECT_FALSE(tests[1].pass);
  EXPECT_EQ(tests[1].worst_lag, 1);
  // Sample r(1) of AR(1) with a = 0.5: standard error ~ sqrt((1 - a²)/n) = 0.006.
  EXPECT_NEAR(tests[1].r(0), 0.5, 0.03);
}

TEST(ResidualInputCorrelation, IndependentPassesAndAFedThroughInputFailsAtItsLag) {
  const Index n = 20000;
  const Eigen::MatrixXd u = white(n, 2, kSeed + 1);
  Eigen::MatrixXd e = white(n, 1, kSeed + 2);
  for (Index k = 3; k < n; ++k) e(k, 0) += 0.3 * u(k - 3, 1);  // unmodelled path u2 -> e at lag 3
  Eigen::MatrixXd u3(n, 3);
  u3 << u, Eigen::VectorXd::Zero(n);  // third input not excited: skipped
  const auto tests = residual_input_correlation(e, u3, TimeFitOptions{});
  ASSERT_EQ(tests.size(), 2u);
  EXPECT_TRUE(tests[0].pass) << tests[0].worst_ratio;
  EXPECT_FALSE(tests[1].pass);
  EXPECT_EQ(tests[1].worst_lag, 3);
  // r = 0.3 / sqrt(1 + 0.09) = 0.287; standard error 1/sqrt(n) = 0.007.
  EXPECT_NEAR(tests[1].r(25 + 3), 0.3 / std::sqrt(1.09), 0.03);
}

TEST(FailingWindows, FindsABurstWithItsTimesAndSize) {
  const Index n = 10000;  // 10 s at 1 kHz
  const double Ts = 1e-3;
  Eigen::MatrixXd y(n, 1), yh(n, 1);
  for (Index k = 0; k < n; ++k) y(k, 0) = std::sin(2 * M_PI * 0.5 * k * Ts);  // rms 1/sqrt 2
  yh = y;
  for (Index k = 4000; k < 5000; ++k) yh(k, 0) += 0.5;  // model wrong during 4.0–5.0 s
  TimeFitOptions o;
  o.window_s = 0.5;
  o.window_threshold_percent = 10.0;
  const auto f = failing_windows(y, yh, 0.0, Ts, o);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].channel, 0);
  // Half-overlapping 0.5 s windows touching the burst: 3.75 s ... 5.25 s.
  EXPECT_NEAR(f[0].t_start_s, 3.75, 1e-9);
  EXPECT_NEAR(f[0].t_end_s, 5.249, 1e-9);
  // A window fully inside the burst: rms 0.5 over record rms 1/sqrt 2 -> 70.7 %.
  EXPECT_NEAR(f[0].size_percent, 100 * 0.5 * std::sqrt(2.0), 0.5);
  EXPECT_TRUE(failing_windows(y, y, 0.0, Ts, o).empty());
}

TEST(TimeFitOptions, RejectsBadValues) {
  TimeFitOptions o;
  o.confidence = 1.0;
  EXPECT_THAT([&] { o.validate(); }, ::testing::ThrowsMessage<InputError>(HasSubstr("confidence")));
  o = {};
  o.max_lag = 0;
  EXPECT_THROW(o.validate(), InputError);
  EXPECT_THAT([&] { residual_whiteness(Eigen::MatrixXd::Ones(10, 1), TimeFitOptions{}); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("max_lag + 2")));
}

}  // namespace time_fit_test
}  // namespace lpvid
