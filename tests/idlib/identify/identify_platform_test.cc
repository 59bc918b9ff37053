// End-to-end accuracy of the time-domain chain on the simulated 3-DOF platform,
// against the exact ZOH-sampled plant (issue: foundation, "What must hold").
#include "idlib/identify/identify.h"

#include <gtest/gtest.h>

#include <array>
#include <random>

#include "idlib/lti/analysis.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"
#include "idlib/validate/frequency_error.h"

namespace lpvid {
namespace identify_platform_test {

// The accuracy band of the issue: the platform model is valid to ~400 rad/s.
constexpr double kBandLowRadPerS = 1.0;
constexpr double kBandHighRadPerS = 400.0;
constexpr Index kBandPoints = 200;
// Seed of the simulated experiments (any seed must pass; this one is pinned so
// that a failure can be reproduced).
constexpr std::uint64_t kSeed = 20261123;

struct Dataset {
  StateSpace plant, controller;
  std::vector<Eigen::MatrixXd> excitation, output;
  std::vector<ExperimentView> views() const {
    std::vector<ExperimentView> v;
    for (std::size_t i = 0; i < excitation.size(); ++i) v.push_back({excitation[i], output[i]});
    return v;
  }
};

Dataset simulate(double beam_position_m, double sample_period_s, double duration_s, std::uint64_t seed) {
  const PlatformParameters params = PlatformParameters::defaults();
  Dataset d;
  d.plant = discretize_zoh(platform_model(params, beam_position_m), sample_period_s);
  d.controller = discrete_pi_controller(default_pi_gains(params), sample_period_s);
  for (int input = 0; input < 3; ++input) {
    ExcitationOptions ex;
    ex.duration_s = duration_s;
    ex.sample_period_s = sample_period_s;
    ex.excited_input = input;
    ex.seed = seed + static_cast<std::uint64_t>(input);
    const SimulatedLog log = simulate_excitation(d.plant, d.controller, ex);
    d.excitation.push_back(log.data.middleCols(1, 3));
    d.output.push_back(log.data.middleCols(7, 3));
  }
  return d;
}

// The accuracy measure of the issue: W = diag(r_vc, r_vc, 1) turns the angles
// into displacements at the coils (r_vc psi, in m) and the torques into forces
// (T / r_vc, in N), so W P W has every entry in m/N and the 2-norm compares like
// with like.  The issue prints W (P^ - P) W^-1; with W^-1 on the right the
// (z, T_psi) entry is scaled up by 1/r_vc^2 = 100 against the rest while the
// (psi, F_z) entry is scaled down, which is not unit-consistent (it is in 1/N and
// rad/N, not m/N).  We assert the unit-consistent form and print both.
struct Errors {
  ErrorSummary wpw;      // ||W (P^ - P) W|| / ||W P W||: every entry in m/N (asserted)
  ErrorSummary wpw_inv;  // ||W (P^ - P) W^-1|| / ||W P W^-1||: as printed in the issue (reported)
};

Errors plant_errors(const StateSpace& estimate, const StateSpace& truth) {
  const PlatformParameters params = PlatformParameters::defaults();
  const Eigen::Vector3d w(params.coil_arm_m, params.coil_arm_m, 1.0);
  const Eigen::VectorXd omega = log_frequency_grid(kBandLowRadPerS, kBandHighRadPerS, kBandPoints);
  const auto est = evaluate_response(estimate, omega);
  const auto ref = evaluate_response(truth, omega);
  return {weighted_error_over(est, ref, omega, w, w), weighted_error_over(est, ref, omega, w, w.cwiseInverse())};
}

// The paper's recipe (--method era), which these tests pin; the default structured
// method is tested on independent plants in independent_identify_test.cc.
IdentifyOptions era_recipe() {
  IdentifyOptions o;
  o.method = IdentifyMethod::kEra;
  return o;
}

class PlatformAt1kHz : public ::testing::TestWithParam<double> {};

// 3 experiments x 60 s at 1 kHz with the default sensor noise.
TEST_P(PlatformAt1kHz, IdentifyChoosesOrder9And6AndIsAccurateTo0p3PercentMean) {
  // Thresholds of the issue: mean <= 0.3 %, max <= 1 % over 1-400 rad/s.
  constexpr double kMaxMeanError = 0.003;
  constexpr double kMaxMaxError = 0.01;
  const Dataset d = simulate(GetParam(), 1e-3, 60.0, kSeed);
  const IdentifyResult r = identify_closed_loop(d.views(), 1e-3, d.controller, era_recipe());
  EXPECT_EQ(r.closed_loop.order(), 9) << r.era.selection.reason;
  ASSERT_EQ(r.plant.order(), 6);
  EXPECT_TRUE(is_stable(r.closed_loop));
  const Errors e = plant_errors(r.plant, d.plant);
  RecordProperty("mean_error_wpw", std::to_string(e.wpw.mean));
  RecordProperty("max_error_wpw", std::to_string(e.wpw.max));
  std::printf("x_b=%+.3f m: weighted error W P W mean %.4f %% max %.4f %%; W P W^-1 mean %.4f %% max %.4f %%\n",
              GetParam(), 100 * e.wpw.mean, 100 * e.wpw.max, 100 * e.wpw_inv.mean, 100 * e.wpw_inv.max);
  EXPECT_LE(e.wpw.mean, kMaxMeanError);
  EXPECT_LE(e.wpw.max, kMaxMaxError);
}

INSTANTIATE_TEST_SUITE_P(BeamPositions, PlatformAt1kHz, ::testing::Values(-0.1, 0.0, 0.1));

// The paper's plain estimate (cross-correlation over the excitation variance)
// is biased: the sample autocorrelation of a finite white record is not a delta.
TEST(PlatformAt1kHzPaperRecipe, PlainCorrelationEstimateIsAtLeast10TimesWorseThanLeastSquares) {
  const Dataset d = simulate(0.0, 1e-3, 60.0, kSeed);
  IdentifyOptions ls = era_recipe(), plain = era_recipe();
  plain.markov_method = MarkovOptions::Method::kCorrelation;
  plain.closed_loop_order = 9;  // give the paper's recipe the right order
  const IdentifyResult a = identify_closed_loop(d.views(), 1e-3, d.controller, ls);
  const IdentifyResult b = identify_closed_loop(d.views(), 1e-3, d.controller, plain);
  const double ea = plant_errors(a.plant, d.plant).wpw.mean;
  const double eb = plant_errors(b.plant, d.plant).wpw.mean;
  std::printf("mean weighted error: least squares %.4f %%, paper's correlation recipe %.4f %%\n", 100 * ea, 100 * eb);
  EXPECT_GT(eb, 10 * ea);
}

// 3 experiments x 100 s at 10 kHz: all poles crowd near z = 1.
TEST(PlatformAt10kHz, IdentifyIsAccurateTo1PercentMean) {
  constexpr double kMaxMeanError = 0.01;  // the threshold at 10 kHz
  const Dataset d = simulate(0.0, 1e-4, 100.0, kSeed);
  const IdentifyResult r = identify_closed_loop(d.views(), 1e-4, d.controller, era_recipe());
  EXPECT_EQ(r.closed_loop.order(), 9) << r.era.selection.reason;
  ASSERT_EQ(r.plant.order(), 6);
  const Errors e = plant_errors(r.plant, d.plant);
  std::printf("10 kHz: weighted error W P W mean %.4f %% max %.4f %%; W P W^-1 mean %.4f %% (stride %ld, %ld x %ld blocks)\n",
              100 * e.wpw.mean, 100 * e.wpw.max, 100 * e.wpw_inv.mean, static_cast<long>(r.era.stride), static_cast<long>(r.era.block_rows),
              static_cast<long>(r.era.block_cols));
  EXPECT_LE(e.wpw.mean, kMaxMeanError);
}

// Logs from a "closed loop" with a pole outside the unit circle (z = 1.01):
// the realised model is unstable, which a loop that ran stably cannot be.
TEST(IdentifyErrors, UnstableRealisationIsAComputationFailure) {
  constexpr std::uint64_t kNoiseSeed = 7;
  const Index n = 3000;  // short: 1.01^3000 stays finite (1e13)
  std::mt19937_64 rng(kNoiseSeed);
  std::normal_distribution<double> N(0.0, 1.0);
  Eigen::MatrixXd v(n, 3), q = Eigen::MatrixXd::Zero(n, 3);
  for (Index t = 0; t < n; ++t)
    for (Index j = 0; j < 3; ++j) v(t, j) = N(rng);
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  for (Index t = 0; t < n; ++t) {  // q = x, x+ = 1.01 x + v (per channel)
    q.row(t) = x.transpose();
    x = 1.01 * x + v.row(t).transpose();
  }
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace controller = discrete_pi_controller(default_pi_gains(params), 1e-3);
  IdentifyOptions options = era_recipe();
  options.num_lags = 300;  // 1.01^300 = 20: the growth is plain in the Markov parameters
  options.closed_loop_order = 3;
  try {
    identify_closed_loop({ExperimentView{v, q}}, 1e-3, controller, options);
    FAIL() << "expected NumericalError";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("is unstable"), std::string::npos) << e.what();
  }
}

}  // namespace identify_platform_test
}  // namespace lpvid
