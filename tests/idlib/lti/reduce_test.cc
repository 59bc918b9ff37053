#include "idlib/lti/reduce.h"
#include "idlib/core/eigen_decompositions.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "tests/idlib/lti/test_systems.h"

namespace lpvid {
namespace reduce_test {

using test_systems::max_relative_difference;
using test_systems::random_system;

constexpr std::uint32_t kSeedBlock = 505;
constexpr std::uint32_t kSeedHankel = 506;
constexpr std::uint32_t kSeedBalanced = 507;
// Exact reductions (removing an exactly uncontrollable/unobservable part) of
// well-separated spectra: agreement to ~1e3 ε.
constexpr double kExactReductionTol = 1e-10;

// Block-diagonal: a random 4-state part plus `extra` modes with B rows = 0
// (uncontrollable) at the given poles, coupled into the output.
StateSpace with_uncontrollable(const StateSpace& base, const Eigen::MatrixXd& extra_A) {
  const Index n = base.order(), e = extra_A.rows();
  StateSpace s = base;
  s.A = Eigen::MatrixXd::Zero(n + e, n + e);
  s.A.topLeftCorner(n, n) = base.A;
  s.A.bottomRightCorner(e, e) = extra_A;
  s.B = Eigen::MatrixXd::Zero(n + e, base.num_inputs());
  s.B.topRows(n) = base.B;
  s.C = Eigen::MatrixXd::Ones(base.num_outputs(), n + e);
  s.C.leftCols(n) = base.C;
  // Mix the states so the structure is not visible in A.
  Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(random_system(n + e, 1, 1, 0.0, kSeedBlock + 1).A).householderQ();
  s.A = Q.transpose() * s.A * Q;
  s.B = Q.transpose() * s.B;
  s.C = s.C * Q;
  return s;
}

TEST(RemoveModes, UncontrollableRealModeIsRemovedExactly) {
  const StateSpace base = random_system(4, 2, 2, 1e-3, kSeedBlock, 0.8);
  const StateSpace s = with_uncontrollable(base, Eigen::MatrixXd::Constant(1, 1, 0.99));
  Eigen::VectorXcd target(1);
  target << Complex(1.0, 0.0);
  const StateSpace r = remove_modes(s, target, 1);
  EXPECT_EQ(r.order(), 4);
  const auto w = log_frequency_grid(1.0, 3000.0, 60);
  EXPECT_LT(max_relative_difference(evaluate_response(r, w), evaluate_response(base, w)), kExactReductionTol);
}

TEST(RemoveModes, UncontrollableComplexPairIsRemovedTogether) {
  const StateSpace base = random_system(4, 2, 2, 1e-3, kSeedBlock, 0.8);
  Eigen::MatrixXd pair(2, 2);
  pair << 0.95, 0.1, -0.1, 0.95;  // 0.95 ± 0.1j
  const StateSpace s = with_uncontrollable(base, pair);
  Eigen::VectorXcd target(1);
  target << Complex(0.95, 0.1);  // one target absorbs both members
  const StateSpace r = remove_modes(s, target, 2);
  const auto w = log_frequency_grid(1.0, 3000.0, 60);
  EXPECT_LT(max_relative_difference(evaluate_response(r, w), evaluate_response(base, w)), kExactReductionTol);
  try {
    remove_modes(s, target, 1);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "remove modes: count = 1 would split the complex pair 0.95±0.1j from its conjugate; use count = 0 or 2");
  }
}

TEST(RemoveModes, KeptPolesAreTheUnselectedOnes) {
  // Spectral removal of controllable modes: the kept poles are exactly the rest.
  const StateSpace s = random_system(6, 1, 1, 0.0, kSeedBlock);
  const Eigen::VectorXcd p = poles(s);
  Eigen::VectorXcd target(1);
  target << p[0];
  const Index count = p[0].imag() != 0.0 ? 2 : 1;
  const Eigen::VectorXcd kept = poles(remove_modes(s, target, count));
  ASSERT_EQ(kept.size(), 6 - count);
  for (Index i = 0; i < kept.size(); ++i) EXPECT_GT(std::abs(kept[i] - p[0]), 1e-6);
  for (Index i = 0; i < kept.size(); ++i) EXPECT_LT((p.array() - kept[i]).abs().minCoeff(), 1e-9 * (1 + std::abs(kept[i])));
}

TEST(RemoveModes, CountOutOfRangeIsRejected) {
  const StateSpace s = random_system(3, 1, 1, 0.0, kSeedBlock);
  try {
    remove_modes(s, Eigen::VectorXcd::Zero(1), 4);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "remove modes: count = 4 for a model of order 3; it must be in [0, 3]");
  }
}

TEST(MinimalRealization, DuplicatedModeIsRemoved) {
  // Two identical parallel first-order lags from the same input to the same
  // output: a 2-state realisation of a first-order system.
  StateSpace s{Eigen::Vector2d(-2.0, -2.0).asDiagonal(), Eigen::MatrixXd::Ones(2, 1), (Eigen::MatrixXd(1, 2) << 1.0, 3.0).finished(),
               Eigen::MatrixXd::Zero(1, 1), 0.0, {}, {}};
  const StateSpace r = minimal_realization(s, 1e-10);
  EXPECT_EQ(r.order(), 1);
  const auto w = log_frequency_grid(0.1, 100.0, 30);
  EXPECT_LT(max_relative_difference(evaluate_response(r, w), evaluate_response(s, w)), kExactReductionTol);
}

TEST(MinimalRealization, UncontrollableAndUnobservablePartsAreRemoved) {
  const StateSpace base = random_system(4, 2, 2, 1e-3, kSeedBlock, 0.8);
  StateSpace s = with_uncontrollable(base, Eigen::MatrixXd::Constant(1, 1, 0.5));
  // Add an unobservable state too (C column = 0, B row = 1).
  const Index n = s.order();
  s.A.conservativeResize(n + 1, n + 1);
  s.A.row(n).setZero();
  s.A.col(n).setZero();
  s.A(n, n) = -0.3;
  s.B.conservativeResize(n + 1, Eigen::NoChange);
  s.B.row(n).setOnes();
  s.C.conservativeResize(Eigen::NoChange, n + 1);
  s.C.col(n).setZero();
  const StateSpace r = minimal_realization(s, 1e-10);
  EXPECT_EQ(r.order(), 4);
  const auto w = log_frequency_grid(1.0, 3000.0, 40);
  EXPECT_LT(max_relative_difference(evaluate_response(r, w), evaluate_response(base, w)), kExactReductionTol);
}

TEST(Gramians, SatisfyTheirDefiningEquations) {
  for (const double Ts : {0.0, 1e-3}) {
    const StateSpace s = random_system(8, 2, 3, Ts, kSeedHankel);
    const Gramians g = gramians(s);
    const Eigen::MatrixXd& P = g.controllability;
    const Eigen::MatrixXd& Q = g.observability;
    Eigen::MatrixXd rp, rq;
    if (Ts > 0) {
      rp = s.A * P * s.A.transpose() - P + s.B * s.B.transpose();
      rq = s.A.transpose() * Q * s.A - Q + s.C.transpose() * s.C;
    } else {
      rp = s.A * P + P * s.A.transpose() + s.B * s.B.transpose();
      rq = s.A.transpose() * Q + Q * s.A + s.C.transpose() * s.C;
    }
    // Backward-stable solve: residual ~ ε ‖A‖ ‖P‖ n.
    EXPECT_LT(rp.norm(), 1e-12 * (1 + s.A.norm()) * P.norm()) << "Ts = " << Ts;
    EXPECT_LT(rq.norm(), 1e-12 * (1 + s.A.norm()) * Q.norm()) << "Ts = " << Ts;
  }
}

TEST(HankelSingularValues, FirstOrderClosedForm) {
  // Discrete x+ = a x + b u, y = c x: P = b²/(1−a²), Q = c²/(1−a²), σ = |bc|/(1−a²).
  const double a = 0.9, b = 2.0, c = 0.5;
  StateSpace s{Eigen::MatrixXd::Constant(1, 1, a), Eigen::MatrixXd::Constant(1, 1, b), Eigen::MatrixXd::Constant(1, 1, c),
               Eigen::MatrixXd::Zero(1, 1), 1e-3, {}, {}};
  EXPECT_NEAR(hankel_singular_values(s)[0], b * c / (1 - a * a), 1e-12);
  // Continuous ẋ = −a x + b u: σ = |bc|/(2a).
  s.A(0, 0) = -3.0;
  s.sample_period_s = 0.0;
  EXPECT_NEAR(hankel_singular_values(s)[0], b * c / 6.0, 1e-14);
}

TEST(HankelSingularValues, UnstableModelIsRejected) {
  StateSpace s{Eigen::MatrixXd::Constant(1, 1, 1.0), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1),
               Eigen::MatrixXd::Zero(1, 1), 1e-3, {}, {}};
  try {
    hankel_singular_values(s);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "Gramians: the model is not stable (a pole on or outside the stability boundary); Gramians exist only "
                           "for stable models, remove the unstable modes first (remove_modes)");
  }
}

TEST(BalancedTruncation, ErrorWithinTwiceTheTailBound) {
  const StateSpace s = random_system(10, 2, 2, 1e-3, kSeedBalanced, 0.95);
  const Eigen::VectorXd hsv = hankel_singular_values(s);
  const Index r = 5;
  const StateSpace red = balanced_truncation(s, r);
  EXPECT_EQ(red.order(), r);
  EXPECT_TRUE(is_stable(red));
  const double bound = 2.0 * hsv.tail(10 - r).sum();
  // The H∞ bound holds on the whole unit circle; check it on a dense grid.
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(2000, 0.0, M_PI / 1e-3);
  const auto h = evaluate_response(s, w), hr = evaluate_response(red, w);
  double worst = 0.0;
  for (size_t k = 0; k < h.size(); ++k)
    worst = std::max(worst, Eigen::JacobiSVD<Eigen::MatrixXcd>(h[k] - hr[k]).singularValues()(0));
  EXPECT_LE(worst, bound * (1 + 1e-9));
  // A balanced truncation to the full order reproduces the model.
  EXPECT_LT(max_relative_difference(evaluate_response(balanced_truncation(s, 10), w), h), 1e-9);
}

}  // namespace reduce_test
}  // namespace lpvid
