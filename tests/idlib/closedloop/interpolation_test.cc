#include "idlib/closedloop/interpolation.h"

#include <gtest/gtest.h>

#include <random>

#include "idlib/closedloop/unloop.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/closedloop/stage_fixture.h"

namespace lpvid {
namespace interpolation_test {

// Relative perturbation of the closed loop's A - I, B and C: 1e-4 moves G's
// response by ~3e-4, the size of the error of a good identification.
constexpr double kPerturbation = 1e-4;
// The conditions are linear equations solved by a complete orthogonal
// decomposition: they hold to rounding (relative to |R^-1|).
constexpr double kConditionTolerance = 1e-8;

// G(1) and G'(1) of a discrete model (z = 1).
std::pair<Eigen::MatrixXd, Eigen::MatrixXd> value_and_slope_at_one(const StateSpace& g) {
  const Eigen::MatrixXd M = (Eigen::MatrixXd::Identity(g.order(), g.order()) - g.A).inverse();
  return {g.C * M * g.B + g.D, -g.C * M * M * g.B};
}

TEST(ImposeControllerInterpolation, TrueClosedLoopAlreadySatisfiesTheConditions) {
  const double ts = 1e-3;
  const StateSpace C = stage_fixture::pi_controller(ts);
  const StateSpace G = closed_loop_output(stage_fixture::discrete_plant(ts), C);
  const InterpolationCorrection c = impose_controller_interpolation(G, C);
  ASSERT_TRUE(c.applied) << c.note;
  EXPECT_EQ(c.conditions, 6);  // one pole (z = 1, multiplicity 3): 3 + 3 scalar rows
  EXPECT_LT(c.relative_change, 1e-8);
}

TEST(ImposeControllerInterpolation, PerturbedLoopMeetsSlopeResidueInverseAndGZeroAfterCorrection) {
  const double ts = 1e-3;
  const StateSpace C = stage_fixture::pi_controller(ts);
  const StateSpace G = stage_fixture::perturbed(closed_loop_output(stage_fixture::discrete_plant(ts), C), kPerturbation, 3);
  const auto [g0, s0] = value_and_slope_at_one(G);
  const InterpolationCorrection c = impose_controller_interpolation(G, C);
  ASSERT_TRUE(c.applied) << c.note;
  const auto [g1, s1] = value_and_slope_at_one(c.closed_loop);
  // Residue of the PI controller at z = 1: R = C_c B_c (A_c = I, one pole).
  const Eigen::MatrixXd Rinv = (C.C * C.B).inverse();
  // G(1) is judged against G's peak gain over the band (G is tiny in m/N).
  double peak = 0;
  for (const auto& h : evaluate_response(G, log_frequency_grid(0.1, 3000.0, 400))) peak = std::max(peak, h.norm());
  std::printf("|G(1)|/peak before %.3g after %.3g; |G'(1) - R^-1|/|R^-1| before %.3g after %.3g\n", g0.norm() / peak,
              g1.norm() / peak, (s0 - Rinv).norm() / Rinv.norm(), (s1 - Rinv).norm() / Rinv.norm());
  // This perturbation (of A - I, B, C) keeps G(1) = 0 but breaks the slope
  // condition; after the correction both hold to rounding.
  EXPECT_LT(g1.norm(), kConditionTolerance * peak);
  EXPECT_LT((s1 - Rinv).norm(), kConditionTolerance * Rinv.norm());
  EXPECT_GT((s0 - Rinv).norm(), 1e3 * kConditionTolerance * Rinv.norm());
}

// With the conditions imposed the controller modes cancel exactly, so unloop
// removes the right ones for every seed (the residue search alone picked a
// genuine plant pole near z = 1 for some seeds).
class UnloopWithInterpolation : public ::testing::TestWithParam<double> {};

TEST_P(UnloopWithInterpolation, RecoversTheSixStatePlantForEverySeed) {
  // Loop inversion amplifies G's error by ~1/|S|: 3e-4 in G becomes 0.5-1.1e-2 in
  // the 12-state P_full = G (I - C G)^-1 before any reduction.  The minimum-norm
  // change of B spreads over every mode, which on this synthetic perturbation (of
  // all of A - I, B and C) costs up to 4x that inherent error (measured: 1.0-3.8x
  // over seeds 1-5); on loops identified by ERA from simulated logs the plant
  // error is 0.1-0.3 % (tests/idlib/identify).  What this test pins is that the
  // right modes go and the plant stays stable for every seed, within 5x.
  constexpr double kVersusInversionError = 5.0;
  const double ts = GetParam();
  const StateSpace P = stage_fixture::discrete_plant(ts);
  const StateSpace C = stage_fixture::pi_controller(ts);
  const Eigen::VectorXd band = log_frequency_grid(1.0, 400.0, 200);
  const auto truth = evaluate_response(P, band);
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    const StateSpace G = stage_fixture::perturbed(closed_loop_output(P, C), kPerturbation, seed);
    const UnloopResult r = plant_from_closed_loop(G, C, UnloopOptions{});
    ASSERT_EQ(r.plant.order(), 6);
    EXPECT_TRUE(r.interpolation_applied);
    EXPECT_TRUE(is_stable(r.plant)) << "seed " << seed;
    for (Index i = 0; i < r.removed_poles.size(); ++i)
      EXPECT_LT(std::abs(r.removed_poles[i] - 1.0), 1e-5) << "seed " << seed << " removed " << r.removed_poles[i];
    auto worst_error = [&](const StateSpace& model) {
      const auto est = evaluate_response(model, band);
      double worst = 0;
      for (std::size_t k = 0; k < est.size(); ++k) worst = std::max(worst, (est[k] - truth[k]).norm() / truth[k].norm());
      return worst;
    };
    const double reduced = worst_error(r.plant), inversion = worst_error(positive_feedback_with(G, C));
    std::printf("Ts=%g seed %u: plant error %.3g, inversion alone %.3g\n", ts, seed, reduced, inversion);
    EXPECT_LT(reduced, kVersusInversionError * inversion) << "seed " << seed;
  }
}

INSTANTIATE_TEST_SUITE_P(OneAndTenKilohertz, UnloopWithInterpolation, ::testing::Values(1e-3, 1e-4));

TEST(ImposeControllerInterpolation, StaticControllerImposesNothing) {
  StateSpace C;
  C.A.resize(0, 0);
  C.B.resize(0, 3);
  C.C.resize(3, 0);
  C.D = Eigen::Matrix3d::Identity();
  C.sample_period_s = 1e-3;
  const StateSpace G = closed_loop_output(stage_fixture::discrete_plant(1e-3), C);
  const InterpolationCorrection c = impose_controller_interpolation(G, C);
  EXPECT_FALSE(c.applied);
  EXPECT_NE(c.note.find("no states"), std::string::npos);
}

}  // namespace interpolation_test
}  // namespace lpvid
