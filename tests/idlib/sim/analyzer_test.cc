// The simulated analyzer (idlib/sim/analyzer.h) and the plant recovered from its
// S data at the paper's three beam positions (issue 3, "What must hold").
#include "idlib/sim/analyzer.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdio>

#include "idlib/closedloop/sensitivity.h"
#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/validate/frequency_error.h"

namespace lpvid {
namespace analyzer_test {

using ::testing::HasSubstr;

constexpr double kSamplePeriod_s = 1e-3;
// The accuracy band of the issue (the paper's model is valid to ~400 rad/s).
constexpr double kBandLo_rad_s = 1.0;
constexpr double kBandHi_rad_s = 400.0;
constexpr Index kBandPoints = 200;
constexpr std::uint64_t kAnalyzerSeed = 31;

struct Loop {
  StateSpace plant, controller;
  explicit Loop(double beam_position_m) {
    const PlatformParameters params = PlatformParameters::defaults();
    plant = discretize_zoh(platform_model(params, beam_position_m), kSamplePeriod_s);
    controller = discrete_pi_controller(default_pi_gains(params), kSamplePeriod_s);
  }
};

AnalyzerOptions band_options() {
  AnalyzerOptions o;
  o.omega_rad_s = log_frequency_grid(kBandLo_rad_s, kBandHi_rad_s, kBandPoints);
  o.sample_period_s = kSamplePeriod_s;
  o.seed = kAnalyzerSeed;
  return o;
}

// W = diag(r_vc, r_vc, 1) on both sides: every entry of W P W in m/N (the
// foundation issue's weighted matrix error, idlib/validate/frequency_error.h).
ErrorSummary plant_error(const std::vector<Eigen::MatrixXcd>& estimate, const StateSpace& truth,
                         const Eigen::VectorXd& omega) {
  const Eigen::Vector3d w(PlatformParameters::defaults().coil_arm_m, PlatformParameters::defaults().coil_arm_m, 1.0);
  return weighted_error_over(estimate, evaluate_response(truth, omega), omega, w, w);
}

TEST(Analyzer, NoiseFreeMeasurementIsTheExactSensitivityWithUnitCoherence) {
  const Loop loop(kBeamRight_m);
  AnalyzerOptions o = band_options();
  o.sensor_noise_std.setZero();
  const AnalyzerMeasurement m = measure_sensitivity(loop.plant, loop.controller, o);
  // The truth from its definition S = (I + C P)⁻¹, independent of interconnect.h.
  const auto P = evaluate_response(loop.plant, o.omega_rad_s);
  const auto C = evaluate_response(loop.controller, o.omega_rad_s);
  // Round-off: near the PI integrators' pole z = 1 the state-space evaluations
  // amplify it by ~1 / |z − 1| = 1 / (ω Ts) = 1e3 at 1 rad/s (measured 5.9e-11 there,
  // |S| <= ~2); 1e-9 leaves a factor of 15.
  constexpr double kRoundOff = 1e-9;
  for (std::size_t k = 0; k < P.size(); ++k) {
    const Eigen::MatrixXcd S = (Eigen::MatrixXcd::Identity(3, 3) + C[k] * P[k]).inverse();
    ASSERT_LE((m.exact_sensitivity.response[k] - S).norm(), kRoundOff) << k;
    ASSERT_LE((m.sensitivity.response[k] - S).norm(), kRoundOff) << k;
    ASSERT_LE((m.sensitivity.coherence[k].array() - 1.0).abs().maxCoeff(), 1e-12) << k;  // exact ratio of equal sums
  }
  EXPECT_EQ(m.mean_relative_noise, 0.0);
  EXPECT_EQ(m.sensitivity.output_names, (std::vector<std::string>{"u1", "u2", "u3"}));
  EXPECT_EQ(m.sensitivity.input_names, (std::vector<std::string>{"v1", "v2", "v3"}));
}

// The error of Ŝ is the sensor noise seen through the controller: ΔS = −S C Ñ with
// Ñ(l, j) = ñ_l / a_j, so −(S C)⁻¹ ΔS recovers Ñ, whose entries must be circular
// complex normal of variance 4 σ_l² / (N_b K a_j²).  Normalised, |·|² is a unit
// exponential variable: its mean over 200 independent frequencies has std 1/√200 =
// 0.07, so [0.7, 1.3] is a 4-sigma band (a wrong noise path or level misses it).
constexpr double kUnitMeanBand = 0.3;

TEST(Analyzer, ErrorIsSensorNoiseThroughTheControllerWithThePredictedVariance) {
  const Loop loop(kBeamMiddle_m);
  const AnalyzerOptions o = band_options();
  const AnalyzerMeasurement m = measure_sensitivity(loop.plant, loop.controller, o);
  const auto C = evaluate_response(loop.controller, o.omega_rad_s);
  const double n_total = std::round(o.integration_s / o.sample_period_s);
  Eigen::Matrix3d mean_sq = Eigen::Matrix3d::Zero();
  double mean_eps_ratio = 0;
  const Index F = o.omega_rad_s.size();
  for (Index k = 0; k < F; ++k) {
    const std::size_t kk = static_cast<std::size_t>(k);
    const Eigen::MatrixXcd& S = m.exact_sensitivity.response[kk];
    const Eigen::MatrixXcd dS = m.sensitivity.response[kk] - S;
    const Eigen::MatrixXcd N = -(S * C[kk]).inverse() * dS;
    for (Index l = 0; l < 3; ++l)
      for (Index j = 0; j < 3; ++j) {
        const double var = 4.0 * o.sensor_noise_std(l) * o.sensor_noise_std(l) /
                           (n_total * o.excitation_amplitude(j) * o.excitation_amplitude(j));
        mean_sq(l, j) += std::norm(N(l, j)) / var / static_cast<double>(F);
      }
    // ε_S is the predicted RMS of ‖ΔS‖_F / ‖S‖_F: the mean of the squared ratio is 1.
    mean_eps_ratio += std::pow(dS.norm() / (m.relative_noise(k) * S.norm()), 2) / static_cast<double>(F);
  }
  EXPECT_LE((mean_sq.array() - 1.0).abs().maxCoeff(), kUnitMeanBand) << mean_sq;
  EXPECT_NEAR(mean_eps_ratio, 1.0, kUnitMeanBand);
}

TEST(Analyzer, SameSeedGivesTheSameMeasurementAndAnotherSeedDiffers) {
  const Loop loop(kBeamLeft_m);
  AnalyzerOptions o = band_options();
  const AnalyzerMeasurement a = measure_sensitivity(loop.plant, loop.controller, o);
  const AnalyzerMeasurement b = measure_sensitivity(loop.plant, loop.controller, o);
  o.seed += 1;
  const AnalyzerMeasurement c = measure_sensitivity(loop.plant, loop.controller, o);
  for (std::size_t k = 0; k < a.sensitivity.response.size(); ++k) {
    ASSERT_EQ(a.sensitivity.response[k], b.sensitivity.response[k]);
    ASSERT_EQ(a.sensitivity.coherence[k], b.sensitivity.coherence[k]);
  }
  EXPECT_NE(a.sensitivity.response[0], c.sensitivity.response[0]);
}

TEST(Analyzer, RejectsBadOptionsAndModelsWithMessages) {
  const Loop loop(kBeamMiddle_m);
  const auto message = [&](const AnalyzerOptions& o, const StateSpace& plant) {
    try {
      measure_sensitivity(plant, loop.controller, o);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  AnalyzerOptions o = band_options();
  o.omega_rad_s(3) = o.omega_rad_s(2);
  EXPECT_THAT(message(o, loop.plant), HasSubstr("omega_rad_s[3] = 1.0"));
  EXPECT_THAT(message(o, loop.plant), HasSubstr("must be strictly increasing"));
  o = band_options();
  o.omega_rad_s(0) = 4000.0;
  EXPECT_THAT(message(o, loop.plant), HasSubstr("below the Nyquist frequency 3141.59 rad/s"));
  o = band_options();
  o.omega_rad_s.resize(0);
  EXPECT_THAT(message(o, loop.plant), HasSubstr("omega_rad_s is empty"));
  o = band_options();
  o.excitation_amplitude(2) = 0.0;
  EXPECT_THAT(message(o, loop.plant), HasSubstr("excitation_amplitude[2] = 0; it must be finite and > 0"));
  o = band_options();
  o.sensor_noise_std(1) = -1.0;
  EXPECT_THAT(message(o, loop.plant), HasSubstr("sensor_noise_std[1] = -1"));
  o = band_options();
  o.averages = 1;
  EXPECT_THAT(message(o, loop.plant), HasSubstr("averages = 1; it must be >= 2"));
  o = band_options();
  o.integration_s = 1e-4;
  EXPECT_THAT(message(o, loop.plant), HasSubstr("integration_s = 0.0001"));
  StateSpace continuous = loop.plant;
  continuous.sample_period_s = 0.0;
  EXPECT_THAT(message(band_options(), continuous), HasSubstr("the plant is continuous"));
  StateSpace other_rate = loop.plant;
  other_rate.sample_period_s = 1e-4;
  EXPECT_THAT(message(band_options(), other_rate), HasSubstr("the plant has ts = 0.0001 s but sample_period_s = 0.001 s"));
}

// The issue's targets on analyzer data with the default (physical) settings: the
// sensor noise of the logs, sines of the logs' per-sample std, 1 s per point.
// Noise on S: ε_S = 1.23 % at 1 rad/s (where C's integral gain is large) falling to
// 0.05 % above 100 rad/s, mean 0.23 % — "about 1 %" where S is noisiest.
constexpr double kMeanErrorMax = 0.01;  // the issue: mean <= 1 %
constexpr double kMaxErrorMax = 0.08;   // the issue: max <= 8 %
// Eq (15) gives −C⁻¹ − C⁻¹P⁻¹C⁻¹, not P: its error does not depend on the noise and
// is O(1000) times P itself here (measured mean relative error ~1.8e3); the issue
// says "about 1000× worse".
constexpr double kEq15MinRelativeError = 100.0;

class AnalyzerAtBeamPosition : public ::testing::TestWithParam<double> {};

TEST_P(AnalyzerAtBeamPosition, PlantFromSMeetsTheIssueBoundsAndPrintedEq15Fails) {
  const Loop loop(GetParam());
  const AnalyzerOptions o = band_options();
  const AnalyzerMeasurement m = measure_sensitivity(loop.plant, loop.controller, o);
  const SensitivityUnloopResult r = plant_from_sensitivity(m.sensitivity, loop.controller, {});
  const ErrorSummary e = plant_error(r.plant.response, loop.plant, o.omega_rad_s);
  const ErrorSummary e15 =
      plant_error(plant_from_sensitivity_printed_eq15(m.sensitivity, loop.controller).response, loop.plant, o.omega_rad_s);
  std::printf("x_b %+.2f m: noise on S mean %.3f %% (max %.3f %%); P from S mean %.3f %% max %.3f %% (at %.0f rad/s); "
              "printed eq 15 mean %.4g (x %.3g worse)\n",
              GetParam(), 100 * m.mean_relative_noise, 100 * m.relative_noise.maxCoeff(), 100 * e.mean, 100 * e.max,
              e.omega_at_max_rad_s, e15.mean, e15.mean / e.mean);
  RecordProperty("mean_error", std::to_string(e.mean));
  RecordProperty("max_error", std::to_string(e.max));
  EXPECT_LE(e.mean, kMeanErrorMax);
  EXPECT_LE(e.max, kMaxErrorMax);
  EXPECT_EQ(r.flagged_count, 0) << "the band 1-400 rad/s has no ill-conditioned frequency";
  EXPECT_GE(e15.mean, kEq15MinRelativeError);
  EXPECT_GE(e15.mean, 1000.0 * e.mean);
}

INSTANTIATE_TEST_SUITE_P(PaperPositions, AnalyzerAtBeamPosition,
                         ::testing::Values(kBeamLeft_m, kBeamMiddle_m, kBeamRight_m));

// Noise on S of 1 % MEAN over the band (the sensor noise scaled by 1 % / 0.23 %):
// with the same seed the draws are the same, ΔS scales exactly with the noise and
// the plant's error to first order, so the errors scale by the same factor.  This
// shows what a "1 % on S everywhere" reading means for P: the max (at the top of
// the band, where |P| is smallest) grows past the issue's 8 %.
constexpr double kTargetMeanNoise = 0.01;
// Second-order terms of the inversion (relative size ~ the error itself, < 15 %):
constexpr double kScalingTolerance = 0.15;

TEST(Analyzer, PlantErrorScalesWithTheNoiseOnS) {
  const Loop loop(kBeamMiddle_m);
  AnalyzerOptions o = band_options();
  const AnalyzerMeasurement base = measure_sensitivity(loop.plant, loop.controller, o);
  const double scale = kTargetMeanNoise / base.mean_relative_noise;
  o.sensor_noise_std *= scale;
  const AnalyzerMeasurement noisy = measure_sensitivity(loop.plant, loop.controller, o);
  const ErrorSummary e0 =
      plant_error(plant_from_sensitivity(base.sensitivity, loop.controller, {}).plant.response, loop.plant, o.omega_rad_s);
  const ErrorSummary e1 =
      plant_error(plant_from_sensitivity(noisy.sensitivity, loop.controller, {}).plant.response, loop.plant, o.omega_rad_s);
  std::printf("noise on S mean %.3f %% (x%.2f): P from S mean %.3f %% max %.3f %% (at %.0f rad/s)\n",
              100 * noisy.mean_relative_noise, scale, 100 * e1.mean, 100 * e1.max, e1.omega_at_max_rad_s);
  EXPECT_NEAR(noisy.mean_relative_noise, kTargetMeanNoise, 1e-12);
  EXPECT_NEAR(e1.mean / e0.mean / scale, 1.0, kScalingTolerance);
  EXPECT_NEAR(e1.max / e0.max / scale, 1.0, kScalingTolerance);
}

}  // namespace analyzer_test
}  // namespace lpvid
