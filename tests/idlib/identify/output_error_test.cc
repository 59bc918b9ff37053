// refine_output_error and simulation_fit_percent (output_error.h).  The truth is a plant
// written here (a lightly damped mode and a real pole), its logs simulated here by its own
// recursion; the start handed to the refinement is the truth with its poles moved.
#include "idlib/identify/output_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "idlib/core/error.h"
#include "idlib/identify/output_error_detail.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/lti/analysis.h"
#include "tests/idlib/identify/mode_and_pole.h"

namespace lpvid {
namespace output_error_test {

using testing::mode_and_pole::kTs;
using testing::mode_and_pole::markov_error;

StateSpace truth(double radius_scale = 1.0) { return testing::mode_and_pole::plant(-20.0, radius_scale); }

// 4000 samples of white u (seed 7), y from the initial state x0, plus white noise.
void simulate(const StateSpace& s, const Eigen::Vector3d& x0, double noise, Eigen::MatrixXd& u, Eigen::MatrixXd& y) {
  testing::mode_and_pole::simulate_open_loop(s, 4000, x0, noise, 7, u, y);
}

TEST(OutputError, RefinesAStartWithMovedPolesToTheTruthAndItsInitialState) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d(0.5, -0.3, 0.2), 0.0, u, y);
  const StateSpace start = truth(0.995);  // every pole 0.5 % further in: 30-180 % slower decay
  ASSERT_GT(markov_error(start, truth()), 0.3);
  OutputErrorOptions o;
  const OutputErrorResult r = refine_output_error({{u, y}}, start, o);
  ASSERT_TRUE(r.accepted) << r.reason;
  std::printf("%s; Markov error %.3g\n", r.reason.c_str(), markov_error(r.model, truth()));
  // Noise-free: the optimum is the truth (u as logged, the output's offset and initial
  // state fitted): to the solver's tolerance.
  EXPECT_LE(markov_error(r.model, truth()), 1e-6);
  EXPECT_NEAR(simulation_fit_percent(r.model, {{u, y}}, true)(0), 100.0, 1e-4);
  // From zero state the record's own transient is missing: below 100 %.
  EXPECT_LT(simulation_fit_percent(r.model, {{u, y}}, false)(0), 99.9);
}

// Residual weights (OutputErrorOptions::residual_weights): samples weighed 0 leave the
// criterion while the simulation runs through them.  The truth's noise-free logs with a
// stretch of 500 output samples overwritten (a disturbance no linear model of u follows,
// as a stuck axis's rests are for the direct route): unweighted, the refinement is pulled
// away from the truth; with that stretch weighed 0 it reaches the truth to the solver's
// tolerance, as on clean logs (the test above).  Weights of the wrong size or negative
// are refused, and so is the modal form, which has none.
TEST(OutputError, SamplesWeighedZeroLeaveTheCriterion) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d(0.5, -0.3, 0.2), 0.0, u, y);
  const double rms = std::sqrt(y.squaredNorm() / static_cast<double>(y.rows()));
  y.middleRows(1500, 500).array() += 3.0 * rms;
  const StateSpace start = truth(0.995);
  const OutputErrorResult plain = refine_output_error({{u, y}}, start);
  OutputErrorOptions o;
  o.residual_weights = {Eigen::VectorXd::Ones(u.rows())};
  o.residual_weights[0].segment(1500, 500).setZero();
  const OutputErrorResult weighed = refine_output_error({{u, y}}, start, o);
  ASSERT_TRUE(weighed.accepted) << weighed.reason;
  std::printf("unweighted: Markov error %.3g (%s); weighed: %.3g\n", markov_error(plain.model, truth()),
              plain.reason.c_str(), markov_error(weighed.model, truth()));
  EXPECT_GT(markov_error(plain.model, truth()), 1e-3);
  EXPECT_LE(markov_error(weighed.model, truth()), 1e-6);
  o.residual_weights[0].resize(10);
  EXPECT_THROW(refine_output_error({{u, y}}, start, o), InputError);
  o.residual_weights[0] = -Eigen::VectorXd::Ones(u.rows());
  EXPECT_THROW(refine_output_error({{u, y}}, start, o), InputError);
  o.residual_weights[0] = Eigen::VectorXd::Ones(u.rows());
  EXPECT_THROW(refine_output_error_modal({{u, y}}, start, o), InputError);
}

TEST(OutputError, WithNoiseTheBandsHoldTheTruthsResponse) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.05, u, y);
  OutputErrorOptions o;
  o.estimate_initial_states = false;
  const OutputErrorResult r = refine_output_error({{u, y}}, truth(0.995), o);
  ASSERT_TRUE(r.accepted) << r.reason;
  ASSERT_EQ(r.covariance.rows(), 9 + 3 + 3);
  EXPECT_GE(r.replicates, 8);
  // 5 % output noise on 4000 samples: measured 0.16 % error in the Markov parameters
  // (400 lags); the bound is 3x that.
  const double err = markov_error(r.model, truth());
  std::printf("noisy: Markov error %.4f, %ld replicates\n", err, static_cast<long>(r.replicates));
  EXPECT_LE(err, 0.005);
  EXPECT_GT(simulation_fit_percent(r.model, {{u, y}}, false)(0), 90.0);
}

TEST(OutputError, AnUnstableOptimumOrABadShapeIsNotUsed) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.0, u, y);
  StateSpace wrong = truth();
  wrong.B.resize(3, 2);
  wrong.B.setZero();
  wrong.D = Eigen::MatrixXd::Zero(1, 2);
  EXPECT_THROW(refine_output_error({{u, y}}, wrong, {}), InputError);
  // A start that diverges on the logs is kept, with the reason.
  StateSpace diverging = truth();
  diverging.A *= 1.2;
  const OutputErrorResult r = refine_output_error({{u, y}}, diverging, {});
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.reason.find("not refined"), std::string::npos) << r.reason;
}

TEST(SimulationFit, IsOneHundredForTheModelThatMadeTheData) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.0, u, y);
  EXPECT_NEAR(simulation_fit_percent(truth(), {{u, y}}, false)(0), 100.0, 1e-6);
  StateSpace unstable = truth();
  unstable.A *= 1.5;
  EXPECT_EQ(simulation_fit_percent(unstable, {{u, y}}, false).size(), 0);
}

// ---- the separable modal form (refine_output_error_modal) ----

// A 2-input, 12-output structure: three lightly damped modes (order 6) seen by every
// sensor with its own mode shape, as an accelerometer array on a shaken frame.
StateSpace mimo_truth() {
  StateSpace s;
  const int modes = 3, p = 12;
  s.A = Eigen::MatrixXd::Zero(2 * modes, 2 * modes);
  s.B = Eigen::MatrixXd::Zero(2 * modes, 2);
  s.C = Eigen::MatrixXd::Zero(p, 2 * modes);
  const double w[modes] = {40.0, 95.0, 210.0}, z[modes] = {0.02, 0.04, 0.01};
  for (int k = 0; k < modes; ++k) {
    const double r = std::exp(-z[k] * w[k] * kTs), th = w[k] * std::sqrt(1 - z[k] * z[k]) * kTs;
    s.A.block(2 * k, 2 * k, 2, 2) << r * std::cos(th), -r * std::sin(th), r * std::sin(th), r * std::cos(th);
    s.B(2 * k, 0) = 0.01 * (k + 1);
    s.B(2 * k + 1, 1) = 0.015 / (k + 1);
    for (int i = 0; i < p; ++i) s.C(i, 2 * k + 1) = std::sin((k + 1) * 3.14159 * (i + 0.5) / p);
  }
  s.D = Eigen::MatrixXd::Zero(p, 2);
  s.sample_period_s = kTs;
  return s;
}

void simulate_mimo(const StateSpace& s, double noise, Eigen::MatrixXd& u, Eigen::MatrixXd& y) {
  const Index N = 3000;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  u.resize(N, s.num_inputs());
  for (Index t = 0; t < N; ++t)
    for (Index j = 0; j < u.cols(); ++j) u(t, j) = normal(rng);
  y = simulate_discrete(s, u);
  for (Index i = 0; i < y.cols(); ++i) {
    const double rms = std::sqrt((y.col(i).array() - y.col(i).mean()).square().mean());
    for (Index t = 0; t < N; ++t) y(t, i) += noise * rms * normal(rng);
  }
}

TEST(OutputErrorModal, RefinesAStartWithMovedPolesToTheTruthAndItsInitialState) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d(0.5, -0.3, 0.2), 0.0, u, y);
  const StateSpace start = truth(0.995);
  ASSERT_GT(markov_error(start, truth()), 0.3);
  const OutputErrorResult r = refine_output_error_modal({{u, y}}, start, {});
  ASSERT_TRUE(r.accepted) << r.reason;
  std::printf("%s; Markov error %.3g\n", r.reason.c_str(), markov_error(r.model, truth()));
  // θ: 3 modal numbers, 3 of B, 3 of x(0); C and the offset eliminated.
  EXPECT_EQ(r.parameters, 9);
  // Noise-free: the optimum is the truth, to the solver's tolerance (as the full form).
  EXPECT_LE(markov_error(r.model, truth()), 1e-6);
  EXPECT_NEAR(simulation_fit_percent(r.model, {{u, y}}, true)(0), 100.0, 1e-4);
}

TEST(OutputErrorModal, RecoversAManyOutputStructureFromAStartWithMovedPoles) {
  Eigen::MatrixXd u, y;
  simulate_mimo(mimo_truth(), 0.0, u, y);
  StateSpace start = mimo_truth();
  start.A *= 0.996;  // every pole 0.4 % further in
  ASSERT_GT(markov_error(start, mimo_truth()), 0.3);
  OutputErrorOptions o;
  o.estimate_initial_states = false;
  const OutputErrorResult r = refine_output_error_modal({{u, y}}, start, o);
  ASSERT_TRUE(r.accepted) << r.reason;
  std::printf("%s; Markov error %.3g\n", r.reason.c_str(), markov_error(r.model, mimo_truth()));
  EXPECT_LE(markov_error(r.model, mimo_truth()), 1e-6);
  ASSERT_EQ(r.covariance.rows(), 36 + 12 + 72);
}

TEST(OutputErrorModal, AgreesWithTheFullFormOnTheSameNoisyLogs) {
  // The two forms minimise the same criterion over the same model set (distinct poles),
  // written in other coordinates: from the same start they must reach the same model and,
  // to first order, the same response variance.  The full form is the independent check.
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.05, u, y);
  OutputErrorOptions o;
  o.estimate_initial_states = false;
  const OutputErrorResult full = refine_output_error({{u, y}}, truth(0.995), o);
  const OutputErrorResult modal = refine_output_error_modal({{u, y}}, truth(0.995), o);
  ASSERT_TRUE(full.accepted) << full.reason;
  ASSERT_TRUE(modal.accepted) << modal.reason;
  EXPECT_NEAR(modal.cost / full.cost, 1.0, 1e-8);
  EXPECT_LE(markov_error(modal.model, full.model), 1e-5);
  EXPECT_EQ(modal.replicates, full.replicates);
  PlantFitResult a, b;
  a.plant = full.model;
  a.covariance = full.covariance;
  b.plant = modal.model;
  b.covariance = modal.covariance;
  const Eigen::Vector3d omega(10.0, 60.0, 300.0);
  const auto va = plant_response_variance(a, omega), vb = plant_response_variance(b, omega);
  for (int w = 0; w < 3; ++w) {
    std::printf("omega %g: variance full %.6g modal %.6g\n", omega(w), va[w](0, 0), vb[w](0, 0));
    // Same point, same segments: equal up to the pseudo-inverse's rounding on the
    // similarity directions (measured: within 1e-4 relative).
    EXPECT_NEAR(vb[w](0, 0) / va[w](0, 0), 1.0, 1e-3);
  }
}

TEST(OutputErrorModal, AStartOutsideTheUnitCircleStartsInsideAndEndsStable) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.0, u, y);
  StateSpace diverging = truth();
  diverging.A *= 1.01;  // the mode just outside the unit circle (radius 1.007)
  ASSERT_FALSE(is_stable(diverging));
  const OutputErrorResult r = refine_output_error_modal({{u, y}}, diverging, {});
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_TRUE(is_stable(r.model));
  std::printf("%s; Markov error %.3g\n", r.reason.c_str(), markov_error(r.model, truth()));
  EXPECT_LE(markov_error(r.model, truth()), 1e-6);
}

TEST(OutputErrorModal, LogsThatPullAPoleOutsideGiveTheBestStableModel) {
  // The outputs hold a growing drift no stable model makes from u: the full form's optimum
  // is unstable; the result must still be a stable model that lowers the error (the modal
  // form, its pole on the bound and said), never the unstable optimum.
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.01, u, y);
  const Index N = y.rows();
  for (Index t = 0; t < N; ++t) y(t, 0) += 20.0 * std::exp(3.0 * static_cast<double>(t) / static_cast<double>(N));
  const OutputErrorResult r = refine_output_error({{u, y}}, truth(0.995), {});
  std::printf("%s\n", r.reason.c_str());
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_TRUE(is_stable(r.model));
  EXPECT_LT(r.cost, r.start_cost);
  EXPECT_NE(r.reason.find("unstable"), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("at the bound"), std::string::npos) << r.reason;
}

// The sandwich's segments (output_error_detail::sandwich_segment_length) follow the
// residual's correlation: an AR(1) residual e(t) = ρ e(t−1) + w(t) has the integrated
// autocorrelation time τ = (1 + ρ)/(1 − ρ) (closed form), and the segments are 10 τ long
// within [N/64, N/8] and at least 64 samples.  White: the shortest, N/64; ρ = 0.9 (τ 19):
// 190 samples, within ±25 % (the sample ρ(k) of 8000 samples scatters by ~1/√N each,
// summed over the ~40 lags to ρ's first zero); ρ = 0.999 (τ 1999): the longest, N/8.
TEST(SandwichSegments, FollowTheResidualsCorrelationTimeBetweenEightAndSixtyFourSegments) {
  constexpr Index kN = 8000;
  std::mt19937 rng(5);
  std::normal_distribution<double> w;
  auto ar1 = [&](double rho) {
    Eigen::MatrixXd e(kN, 2);
    for (Index c = 0; c < 2; ++c) {
      double x = 0.0;
      for (Index t = 0; t < kN; ++t) e(t, c) = x = (c == 0 ? rho : 0.0) * x + w(rng);  // column 1 white
    }
    return e;
  };
  using output_error_detail::sandwich_segment_length;
  EXPECT_EQ(sandwich_segment_length(ar1(0.0), 64), kN / 64);
  const Index l = sandwich_segment_length(ar1(0.9), 64);  // the correlated output decides
  std::printf("AR(1) rho 0.9: segments of %ld samples for 10 tau = 190\n", static_cast<long>(l));
  EXPECT_NEAR(static_cast<double>(l), 190.0, 0.25 * 190.0);
  EXPECT_EQ(sandwich_segment_length(ar1(0.999), 64), kN / 8);
  EXPECT_EQ(sandwich_segment_length(ar1(0.0).topRows(1024), 64), 64);  // never below 64 samples
  EXPECT_EQ(sandwich_segment_length(ar1(0.0).topRows(300), 64), 64);    // nor 8 segments below that
}

}  // namespace output_error_test
}  // namespace lpvid
