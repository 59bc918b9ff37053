#include "idlib/closedloop/unloop.h"

#include <gtest/gtest.h>

#include <random>

#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/lti/reduce.h"
#include "tests/idlib/closedloop/stage_fixture.h"

namespace lpvid {
namespace unloop_test {

constexpr std::uint32_t kSeedPerturbation = 1;
// Exact closed loop: cancellation exact up to the Schur/Sylvester rounding
// amplified by sep(cluster at z = 1, slow plant pole 0.9998); measured 4e-8
// (1 kHz) and 2.5e-9 (10 kHz).
constexpr double kExactRecoveryTol = 1e-6;
// Perturbed loop (relative 1e-4 on A − I, B, C): G's response moves by 3.2e-4,
// the untruncated G(I − CG)⁻¹ is then 5.1e-3 from the plant (the 1/S² amplification
// of loop inversion, inherent); the recovered 6th-order plant measured 4.75e-3.
constexpr double kPerturbedRecoveryTol = 1e-2;
// Distance-only removal of the same loop measured 6.0e-2.
constexpr double kNaiveRemovalMinError = 5e-2;

Eigen::VectorXd band() { return log_frequency_grid(1.0, 400.0, 200); }

double max_relative_error(const StateSpace& estimate, const StateSpace& truth) {
  const auto he = evaluate_response(estimate, band()), ht = evaluate_response(truth, band());
  double e = 0.0;
  for (size_t k = 0; k < ht.size(); ++k) e = std::max(e, (he[k] - ht[k]).norm() / ht[k].norm());
  return e;
}

// Relative noise on A − I (i.e. on the discrete increment, equivalent to a
// relative error in the continuous-time matrices at any sample rate), B and C.
class ExactClosedLoop : public ::testing::TestWithParam<double> {};

TEST_P(ExactClosedLoop, RecoversTheSixStatePlant) {
  const double Ts = GetParam();
  const StateSpace P = stage_fixture::discrete_plant(Ts);
  const StateSpace C = stage_fixture::pi_controller(Ts);
  const StateSpace G = closed_loop_output(P, C);
  ASSERT_TRUE(is_stable(G));
  const UnloopResult r = plant_from_closed_loop(G, C, UnloopOptions{});
  EXPECT_EQ(r.interconnection_order, 12);
  EXPECT_EQ(r.plant.order(), 6);
  EXPECT_EQ(r.removed_poles.size(), 6);
  for (Index i = 0; i < r.removed_poles.size(); ++i) EXPECT_LT(std::abs(r.removed_poles[i] - 1.0), 1e-6);
  EXPECT_LT(max_relative_error(r.plant, P), kExactRecoveryTol);
  EXPECT_TRUE(r.report.warnings.empty());
  EXPECT_EQ(r.plant.output_names, G.output_names);
}

INSTANTIATE_TEST_SUITE_P(OneAndTenKilohertz, ExactClosedLoop, ::testing::Values(1e-3, 1e-4));

TEST(PlantFromClosedLoop, PerturbedLoopGivesStableSixStatePlantWhereTruncationFails) {
  const double Ts = 1e-4;
  const StateSpace P = stage_fixture::discrete_plant(Ts);
  const StateSpace C = stage_fixture::pi_controller(Ts);
  const StateSpace G = stage_fixture::perturbed(closed_loop_output(P, C), 1e-4, kSeedPerturbation);
  // This test exercises the candidate search on its own (step 0 off); with step 0
  // on, see interpolation_test.cc.
  UnloopOptions search_only;
  search_only.impose_controller_interpolation = false;
  const UnloopResult r = plant_from_closed_loop(G, C, search_only);
  EXPECT_EQ(r.plant.order(), 6);
  EXPECT_TRUE(is_stable(r.plant));
  EXPECT_LT(max_relative_error(r.plant, P), kPerturbedRecoveryTol);
  // Inexact cancellation is reported.
  ASSERT_FALSE(r.report.warnings.empty());
  EXPECT_NE(r.report.warnings[0].find("did not cancel exactly"), std::string::npos);

  // The contrast: the 12-state interconnection is unstable (the perturbed
  // multiple eigenvalue at z = 1 splits across the unit circle), so balanced
  // truncation is not even defined ...
  const StateSpace full = positive_feedback_with(G, C);
  EXPECT_FALSE(is_stable(full));
  EXPECT_THROW(balanced_truncation(full, 6), InputError);
  // ... and removing the 6 eigenvalues nearest z = 1 without the residue refit is 10x worse.
  const StateSpace naive = remove_modes(full, poles(C), 6);
  EXPECT_GT(max_relative_error(naive, P), kNaiveRemovalMinError);
}

TEST(PlantFromClosedLoop, DifferentSamplePeriodsAreRejected) {
  const StateSpace C = stage_fixture::pi_controller(1e-3);
  const StateSpace G = closed_loop_output(stage_fixture::discrete_plant(1e-4), stage_fixture::pi_controller(1e-4));
  try {
    plant_from_closed_loop(G, C, UnloopOptions{});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "unloop: the closed loop has ts = 0.0001 s but the controller ts = 0.001 s (0 = continuous); identify "
                           "and control at the same sample period");
  }
}

TEST(PlantFromClosedLoop, ControllerShapeMismatchIsRejected) {
  const StateSpace G = closed_loop_output(stage_fixture::discrete_plant(1e-3), stage_fixture::pi_controller(1e-3));
  StateSpace C = stage_fixture::pi_controller(1e-3);
  C.B = C.B.leftCols(2).eval();
  C.D = C.D.leftCols(2).eval();
  try {
    plant_from_closed_loop(G, C, UnloopOptions{});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "unloop: the controller is 3x2 (outputs x inputs) but the closed loop v → q is 3x3; give the controller "
                           "that maps the 3 outputs back to the 3 inputs");
  }
}

TEST(PlantFromClosedLoop, AlgebraicLoopIsRejected) {
  StateSpace G{Eigen::MatrixXd(0, 0), Eigen::MatrixXd(0, 1), Eigen::MatrixXd(1, 0), Eigen::MatrixXd::Constant(1, 1, 2.0), 1e-3, {}, {}};
  StateSpace C{Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Constant(1, 1, 0.5),
               1e-3, {}, {}};
  UnloopOptions o;
  o.plant_order = 1;
  EXPECT_THROW(plant_from_closed_loop(G, C, o), InputError);
}

TEST(UnloopOptions, NegativePlantOrderIsRejected) {
  UnloopOptions o;
  o.plant_order = -1;
  try {
    o.validate();
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "unloop: plant_order = -1; it must be >= 1, or 0 for n_G − n_C");
  }
}

}  // namespace unloop_test
}  // namespace lpvid
