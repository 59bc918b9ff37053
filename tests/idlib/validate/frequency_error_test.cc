#include "idlib/validate/frequency_error.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"

namespace lpvid {
namespace frequency_error_test {

TEST(WeightedMatrixError, ScaledTruthGivesTheScaleError) {
  Eigen::MatrixXcd P(2, 2);
  P << Complex(1, 1), 2, 0, Complex(0, -3);
  EXPECT_NEAR(weighted_matrix_error(1.1 * P, P, {}, {}), 0.1, 1e-15);
  EXPECT_EQ(weighted_matrix_error(P, P, {}, {}), 0.0);
}

TEST(WeightedMatrixError, WeightsSelectChannels) {
  Eigen::MatrixXcd P = Eigen::MatrixXcd::Identity(2, 2);
  Eigen::MatrixXcd E = P;
  E(1, 1) = 5.0;  // error only in output 2
  EXPECT_EQ(weighted_matrix_error(E, P, Eigen::Vector2d(1.0, 0.0), {}), 0.0);
  EXPECT_NEAR(weighted_matrix_error(E, P, {}, {}), 4.0, 1e-14);
}

TEST(WeightedErrorOver, MeanMaxAndWhere) {
  const Eigen::MatrixXcd P = Eigen::MatrixXcd::Ones(1, 1);
  std::vector<Eigen::MatrixXcd> truth{P, P, P}, est{1.1 * P, 1.3 * P, P};
  const ErrorSummary s = weighted_error_over(est, truth, Eigen::Vector3d(1.0, 10.0, 100.0), {}, {});
  EXPECT_NEAR(s.max, 0.3, 1e-15);
  EXPECT_NEAR(s.mean, 0.4 / 3.0, 1e-15);
  EXPECT_EQ(s.omega_at_max_rad_s, 10.0);
  EXPECT_EQ(s.per_frequency.size(), 3);
}

TEST(WeightedMatrixError, ZeroTruthIsRejected) {
  try {
    weighted_matrix_error(Eigen::MatrixXcd::Ones(1, 1), Eigen::MatrixXcd::Zero(1, 1), {}, {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "weighted error: the weighted truth is zero, so the relative error is undefined; drop this frequency or "
                           "change the weights");
  }
}

TEST(WeightedMatrixError, WrongWeightLengthIsRejected) {
  try {
    weighted_matrix_error(Eigen::MatrixXcd::Ones(2, 1), Eigen::MatrixXcd::Ones(2, 1), Eigen::Vector3d::Ones(), {});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "weighted error: left weight has 3 entries for 2 outputs; give one per channel or none");
  }
}

}  // namespace frequency_error_test
}  // namespace lpvid
