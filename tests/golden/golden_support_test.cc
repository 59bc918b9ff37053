// The scoring used by the golden tests counts agreeing leading digits.
#include <gtest/gtest.h>

#include <Eigen/LU>

#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace golden_support_test {

// A score is a log10, so a tolerance of one hundredth of a digit absorbs the
// rounding of the differences 1e-9 and 1e-3 themselves.
constexpr double kScoreTol = 1e-2;

TEST(GoldenScore, DigitsCountLeadingDigitsRelativeToTheScale) {
  EXPECT_NEAR(digits(1.0 + 1e-9, 1.0, 1.0), 9.0, kScoreTol);
  EXPECT_NEAR(digits(2e-3, 1e-3, 1.0), 3.0, kScoreTol);  // small entry, scored against its channel's peak
  EXPECT_EQ(digits(0.25, 0.25, 1.0), kExactDigits);
  EXPECT_EQ(digits(0.0, 0.0, 0.0), kExactDigits);
  EXPECT_EQ(digits(1e-300, 0.0, 0.0), 0.0);
  EXPECT_EQ(digits(std::nan(""), 1.0, 1.0), 0.0);
}

TEST(GoldenScore, FrequencyResponseScoreIgnoresAChangeOfStateBasis) {
  StateSpace a;
  a.A = (Eigen::MatrixXd(2, 2) << 0.9, 0.1, 0.0, 0.8).finished();
  a.B = (Eigen::MatrixXd(2, 1) << 0.0, 1.0).finished();
  a.C = (Eigen::MatrixXd(1, 2) << 1.0, 0.0).finished();
  a.D = Eigen::MatrixXd::Zero(1, 1);
  a.sample_period_s = 0.001;
  const Eigen::Matrix2d T = (Eigen::Matrix2d() << 2.0, 1.0, 0.0, 0.5).finished();
  StateSpace b = a;  // x_b = T x_a
  b.A = T * a.A * T.inverse();
  b.B = T * a.B;
  b.C = a.C * T.inverse();
  EXPECT_GE(compare_frequency_response(b, a).min_digits, 14.0);
  StateSpace c = a;
  c.A(1, 1) = 0.8 + 1e-6;
  EXPECT_LT(compare_frequency_response(c, a).min_digits, 8.0);
}

}  // namespace golden_support_test
}  // namespace lpvid::golden
