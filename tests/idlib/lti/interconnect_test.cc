#include "idlib/lti/interconnect.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "tests/idlib/lti/test_systems.h"

namespace lpvid {
namespace interconnect_test {

using test_systems::random_system;

constexpr std::uint32_t kSeedPlant = 404;
constexpr std::uint32_t kSeedController = 405;
constexpr std::uint32_t kSeedSecond = 406;
// Identities between responses of well-conditioned random models (‖(I+CP)⁻¹‖
// of order 10 at the grid points): agreement to ~1e3 ε.
constexpr double kIdentityTol = 1e-10;

Eigen::VectorXd test_grid() { return log_frequency_grid(0.1, 3000.0, 40); }

TEST(Series, ResponseIsProductOfResponses) {
  const StateSpace a = random_system(3, 2, 3, 1e-3, kSeedPlant);
  const StateSpace b = random_system(4, 3, 2, 1e-3, kSeedSecond);
  const StateSpace ab = series(a, b);
  EXPECT_EQ(ab.order(), 7);
  const auto w = test_grid();
  const auto ha = evaluate_response(a, w), hb = evaluate_response(b, w), hab = evaluate_response(ab, w);
  for (size_t k = 0; k < hab.size(); ++k) EXPECT_LT((hab[k] - hb[k] * ha[k]).norm(), kIdentityTol * (1 + hab[k].norm()));
}

TEST(ClosedLoop, OutputAndSensitivitySatisfyTheLoopEquations) {
  const StateSpace P = random_system(5, 2, 3, 1e-3, kSeedPlant);
  StateSpace C = random_system(3, 3, 2, 1e-3, kSeedController);
  C.D *= 0.1;  // keep I + D_C D_P far from singular
  const StateSpace G = closed_loop_output(P, C);
  const StateSpace S = closed_loop_input_sensitivity(P, C);
  EXPECT_EQ(G.order(), 8);
  const auto w = test_grid();
  const auto hp = evaluate_response(P, w), hc = evaluate_response(C, w), hg = evaluate_response(G, w),
             hs = evaluate_response(S, w);
  const Eigen::MatrixXcd I = Eigen::MatrixXcd::Identity(2, 2);
  for (size_t k = 0; k < hp.size(); ++k) {
    EXPECT_LT(((I + hc[k] * hp[k]) * hs[k] - I).norm(), kIdentityTol) << "(I + CP) S = I at ω = " << w[k];
    EXPECT_LT((hg[k] - hp[k] * hs[k]).norm(), kIdentityTol * (1 + hg[k].norm())) << "G = P S at ω = " << w[k];
    EXPECT_LT((hs[k] + hc[k] * hg[k] - I).norm(), kIdentityTol) << "S + C G = I at ω = " << w[k];
  }
}

TEST(PositiveFeedback, UndoesTheClosedLoop) {
  const StateSpace P = random_system(4, 2, 2, 1e-3, kSeedPlant);
  const StateSpace C = random_system(2, 2, 2, 1e-3, kSeedController);
  const StateSpace G = closed_loop_output(P, C);
  const StateSpace Pfull = positive_feedback_with(G, C);
  EXPECT_EQ(Pfull.order(), 4 + 2 + 2);  // no reduction
  const auto w = test_grid();
  const auto hp = evaluate_response(P, w), hf = evaluate_response(Pfull, w);
  for (size_t k = 0; k < hp.size(); ++k) EXPECT_LT((hf[k] - hp[k]).norm(), 1e-9 * hp[k].norm()) << "ω = " << w[k];
}

TEST(ClosedLoop, DifferentSamplePeriodsAreRejected) {
  const StateSpace P = random_system(2, 1, 1, 1e-3, kSeedPlant);
  const StateSpace C = random_system(1, 1, 1, 1e-4, kSeedController);
  try {
    closed_loop_output(P, C);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "closed loop: sample periods differ (0.001 s vs 0.0001 s; 0 = continuous); use models sampled at the same rate");
  }
}

TEST(PositiveFeedback, AlgebraicLoopIsRejected) {
  StateSpace G{Eigen::MatrixXd(0, 0), Eigen::MatrixXd(0, 1), Eigen::MatrixXd(1, 0), Eigen::MatrixXd::Constant(1, 1, 2.0), 0.0, {}, {}};
  StateSpace C = G;
  C.D(0, 0) = 0.5;  // 1 − 0.5·2 = 0
  try {
    positive_feedback_with(G, C);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "positive feedback: algebraic loop: I ∓ D_C·D_G is singular (smallest singular value 0); the direct "
                           "feedthroughs of controller and model make the loop ill-posed, check D of both");
  }
}

TEST(Series, MismatchedDimensionsAreRejected) {
  const StateSpace a = random_system(2, 1, 2, 0.0, kSeedPlant);
  const StateSpace b = random_system(2, 3, 1, 0.0, kSeedSecond);
  try {
    series(a, b);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "series connection: first model has 2 outputs but second has 3 inputs; they must be equal");
  }
}

}  // namespace interconnect_test
}  // namespace lpvid
