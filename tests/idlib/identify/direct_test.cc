// The direct route's pieces (idlib/identify/direct.h, identify.h applied_plant_input),
// against truths written here: a second-order plant's ARX coefficients set by hand and
// recovered from its noise-free response, a PD's output computed by hand.  The route as
// a whole is tried on the independent friction-axis simulator in
// tests/cli/reference_identify_test.cc.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include <Eigen/Dense>

#include "idlib/core/error.h"
#include "idlib/identify/direct.h"
#include "idlib/identify/identify.h"

namespace lpvid {
namespace direct_test {

// q(k) = 1.6 q(k−1) − 0.64 q(k−2) + 0.5 u(k−1) + 0.3 u(k−2): a double pole at 0.8.
std::complex<double> hand_response(double omega) {
  const std::complex<double> zi = std::polar(1.0, -omega);
  return (0.5 * zi + 0.3 * zi * zi) / (1.0 - 1.6 * zi + 0.64 * zi * zi);
}

std::complex<double> model_response(const StateSpace& s, double omega) {
  const std::complex<double> z = std::polar(1.0, omega);
  const Eigen::MatrixXcd M = z * Eigen::MatrixXcd::Identity(s.order(), s.order()) - s.A.cast<std::complex<double>>();
  return (s.C.cast<std::complex<double>>() * M.inverse() * s.B.cast<std::complex<double>>())(0, 0);
}

TEST(ArxStrictlyProper, RecoversAPlantWrittenByHandFromItsNoiseFreeResponse) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  const Index N = 400;
  Eigen::MatrixXd u(N, 1), q = Eigen::MatrixXd::Zero(N, 1);
  for (Index k = 0; k < N; ++k) u(k, 0) = n01(rng);
  for (Index k = 2; k < N; ++k) q(k, 0) = 1.6 * q(k - 1, 0) - 0.64 * q(k - 2, 0) + 0.5 * u(k - 1, 0) + 0.3 * u(k - 2, 0);
  q.array() += 2.5;  // an operating point: the regression's constant takes it
  const std::vector<ExperimentView> x{{u, q}};
  const StateSpace s = arx_strictly_proper(x, 2, 0.01);
  ASSERT_EQ(s.order(), 2);
  EXPECT_EQ(s.D(0, 0), 0.0);  // strictly proper by construction
  EXPECT_DOUBLE_EQ(s.sample_period_s, 0.01);
  // Exact data and the exact structure: the coefficients to round-off (1e-9 relative
  // leaves room for the QR's conditioning on 400 samples).
  for (double w : {0.01, 0.3, 1.0, 3.0})
    EXPECT_LE(std::abs(model_response(s, w) / hand_response(w) - 1.0), 1e-9) << "at " << w << " rad/sample";
}

TEST(ArxStrictlyProper, AnInputWithNoPowerGivesNoModelAndShortRecordsAreRefused) {
  const Eigen::MatrixXd u = Eigen::MatrixXd::Zero(100, 1);
  Eigen::MatrixXd q(100, 1);
  for (Index k = 0; k < 100; ++k) q(k, 0) = std::sin(0.1 * static_cast<double>(k));
  EXPECT_EQ(arx_strictly_proper({{u, q}}, 2, 1.0).order(), 0);  // rank-deficient: no model, not a wrong one
  EXPECT_THROW(arx_strictly_proper({{u.topRows(8), q.topRows(8)}}, 2, 1.0), InputError);
  EXPECT_THROW(arx_strictly_proper({{u, q}}, 0, 1.0), InputError);
}

// u = v + C(e − e(0)), e = r − q, from the controller's zero state: a PD
// u = k_p e + k_d (e_k − e_{k−1}) computed by hand.
// The friction inputs of a position that rests, moves up at constant speed, rests and
// moves down: sign +1 / −1 while it moves (the central difference over ±5 samples sees
// the move 5 samples before it starts: the ends of each move are widened by that), 0 at
// rest (inside the 2 % deadband), the last column all ones.
TEST(FrictionInputs, AreTheVelocitysSignOutsideRestAndAConstant) {
  const Index N = 100;
  Eigen::MatrixXd q(N, 1);
  for (Index k = 0; k < N; ++k)
    q(k, 0) = k < 20 ? 0.0 : k < 40 ? 0.5 * (k - 20) : k < 60 ? 10.0 : k < 80 ? 10.0 - 0.5 * (k - 60) : 0.0;
  q(50, 0) += 1e-3;  // a count of noise at rest: inside the deadband
  const Eigen::MatrixXd w = friction_inputs(q);
  ASSERT_EQ(w.rows(), N);
  ASSERT_EQ(w.cols(), 2);
  EXPECT_TRUE(w.col(1).isOnes());
  for (Index k = 0; k < N; ++k) {
    const double expected = k >= 16 && k <= 44 ? 1.0 : k >= 56 && k <= 84 ? -1.0 : 0.0;
    EXPECT_EQ(w(k, 0), expected) << "sample " << k;
  }
}

TEST(AppliedPlantInput, IsThePdsOutputOnTheTrackingErrorAboutItsStandingValue) {
  const double kp = 3.0, kd = 40.0;
  StateSpace pd;  // x = e_{k−1}: u = (k_p + k_d) e_k − k_d x
  pd.A = Eigen::MatrixXd::Zero(1, 1);
  pd.B = Eigen::MatrixXd::Ones(1, 1);
  pd.C = Eigen::MatrixXd::Constant(1, 1, -kd);
  pd.D = Eigen::MatrixXd::Constant(1, 1, kp + kd);
  pd.sample_period_s = 0.001;
  const Index N = 30;
  Eigen::MatrixXd r(N, 1), q(N, 1), v(N, 1);
  for (Index k = 0; k < N; ++k) {
    r(k, 0) = 0.2 + 0.01 * static_cast<double>(k);
    q(k, 0) = 0.19 + 0.009 * static_cast<double>(k) + 0.001 * std::sin(static_cast<double>(k));
    v(k, 0) = 0.5 * std::cos(0.3 * static_cast<double>(k));
  }
  const auto by_hand = [&](const Eigen::MatrixXd& e_raw) {
    Eigen::VectorXd out(N);
    double prev = 0.0;
    for (Index k = 0; k < N; ++k) {
      const double e = e_raw(k, 0) - e_raw(0, 0);
      out(k) = kp * e + kd * (e - prev);
      prev = e;
    }
    return out;
  };
  const Eigen::MatrixXd none(0, 0);
  const Eigen::MatrixXd at_reference = applied_plant_input(pd, none, r, q);
  EXPECT_LE((at_reference.col(0) - by_hand(r - q)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(at_reference(0, 0), 0.0);  // the standing error gives no kick
  const Eigen::MatrixXd at_input = applied_plant_input(pd, v, none, q);
  EXPECT_LE((at_input.col(0) - (v.col(0) + by_hand(-q))).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_THROW(applied_plant_input(pd, none, r.topRows(5), q), InputError);
  Eigen::MatrixXd bad = q;
  bad(4, 0) = std::nan("");
  EXPECT_THROW(applied_plant_input(pd, none, r, bad), InputError);
}

}  // namespace direct_test
}  // namespace lpvid
