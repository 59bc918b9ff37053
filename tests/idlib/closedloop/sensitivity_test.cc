#include "idlib/closedloop/sensitivity.h"
#include "idlib/core/eigen_decompositions.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>

#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/closedloop/stage_fixture.h"

namespace lpvid {
namespace sensitivity_test {

using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::StartsWith;

constexpr double kSamplePeriod_s = 1e-3;
constexpr std::uint32_t kAnalyzerNoiseSeed = 9151;
// Band of the seed's model (valid to ~400 rad/s), log-spaced like an analyzer sweep.
constexpr double kBandLo_rad_s = 1.0;
constexpr double kBandHi_rad_s = 400.0;
constexpr Index kBandPoints = 200;

struct Stage {
  StateSpace plant = stage_fixture::discrete_plant(kSamplePeriod_s);
  StateSpace controller = stage_fixture::pi_controller(kSamplePeriod_s);
  StateSpace sensitivity = closed_loop_input_sensitivity(plant, controller);
  StateSpace closed_loop = closed_loop_output(plant, controller);
};

// ‖W (P̂ − P) W‖₂ / ‖W P W‖₂ with W = diag(r, r, 1), r = 0.1 on both sides (the
// weighted error of idlib/validate/frequency_error.h, inlined: test_closedloop
// does not link idlib_validate).  r brings rad-per-N·m and m-per-N to one scale.
constexpr double kChannelWeight = 0.1;
double weighted_error(const Eigen::MatrixXcd& est, const Eigen::MatrixXcd& truth) {
  const Eigen::Vector3d w(kChannelWeight, kChannelWeight, 1.0);
  const Eigen::MatrixXcd W = w.cast<Complex>().asDiagonal();
  const auto norm2 = [](const Eigen::MatrixXcd& a) { return Eigen::JacobiSVD<Eigen::MatrixXcd>(a).singularValues()(0); };
  return norm2(W * (est - truth) * W) / norm2(W * truth * W);
}

// Exact S (from the state-space loop): P back to round-off.  The recovery
// subtracts I from S⁻¹, losing digits where |S| ≈ 1 and C P is small (high
// frequency), about eps · ‖S⁻¹‖ / ‖C P‖; measured max 6.5e-11 on a grid from 1 rad/s
// to 0.99 · Nyquist (where ‖C P‖ ~ 1e-5).
constexpr double kExactRelTol = 1e-10;

TEST(PlantFromSensitivity, ExactSensitivityRecoversPlant) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(kBandLo_rad_s, 0.99 * std::numbers::pi / kSamplePeriod_s, 300);
  const FrequencyResponse S = frequency_response(st.sensitivity, w);
  SensitivityUnloopOptions no_loop_gain_check;  // the grid reaches ‖C P‖ ~ 1e-5, below the default 1e-4
  no_loop_gain_check.min_loop_gain = 0.0;
  const SensitivityUnloopResult r = plant_from_sensitivity(S, st.controller, no_loop_gain_check);
  const std::vector<Eigen::MatrixXcd> P = evaluate_response(st.plant, w);
  double max_err = 0;
  for (Index k = 0; k < w.size(); ++k) {
    const size_t kk = static_cast<size_t>(k);
    max_err = std::max(max_err, (r.plant.response[kk] - P[kk]).norm() / P[kk].norm());
  }
  EXPECT_LE(max_err, kExactRelTol);
  EXPECT_EQ(r.flagged_count, 0);
  EXPECT_TRUE(r.report.usable);
}

TEST(PlantFromClosedLoopFrd, ExactClosedLoopRecoversPlant) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(kBandLo_rad_s, kBandHi_rad_s, kBandPoints);
  const FrequencyResponse P_hat = plant_from_closed_loop_frd(frequency_response(st.closed_loop, w), st.controller);
  const std::vector<Eigen::MatrixXcd> P = evaluate_response(st.plant, w);
  for (Index k = 0; k < w.size(); ++k) {
    const size_t kk = static_cast<size_t>(k);
    ASSERT_LE((P_hat.response[kk] - P[kk]).norm() / P[kk].norm(), kExactRelTol) << "omega " << w(k);
    ASSERT_FALSE(P_hat.flagged[kk]);
  }
}

// Analyzer-like data: each entry of S multiplied by (1 + 0.01 ε), ε complex
// standard normal (1 % relative noise, seeded).  Since S⁻¹ − I = C P, an error dS
// gives dP ≈ −C⁻¹ S⁻¹ dS S⁻¹, i.e. a relative error ~ 1 % · (1 + 1/σ_min(C P)): fine
// while the loop gain is large, growing as 1/|C P| above crossover.  On this stage
// (PI crossover ~20 rad/s) σ_min(C P) falls to 0.004 at 300 rad/s, so NO formula can
// meet 1 % there from 1 %-noisy S (measured 231 % at 305 rad/s, equal to the bound).
// Hence: (i) 1 % mean / 8 % max is pinned on the high-gain band 1..30 rad/s
// (σ_min(C P) >= 0.25); (ii) over 1..400 rad/s the error is pinned against the bound
// kBoundFactor · 1 % · (1 + 1/σ_min(C P)) per frequency; (iii) eq 15 is compared on
// the whole band.  Measured (seed 9151): 1..30 rad/s mean 1.07e-2 (the noise level
// itself: no estimator does better from these data), max 3.0e-2; 1..400 rad/s mean
// 0.36, max 4.9 (at the top, where σ_min(C P) = 0.004); eq 15 mean 6.7e3, i.e.
// 18 000 × worse than the corrected formula.
constexpr double kAnalyzerNoise = 0.01;
constexpr double kHighGainBandHi_rad_s = 30.0;
constexpr double kNoisyMeanErrorMax = 0.02;  // 2 × the noise level
constexpr double kNoisyMaxErrorMax = 0.08;
// The 2-norm of a 3x3 matrix of independent complex errors of RMS 1 % is up to
// ~3 % (√9 entries); measured worst ratio error / (1 % (1 + 1/σ_min)) = 1.87.
constexpr double kBoundFactor = 3.0;
constexpr double kEq15MinWorseFactor = 100.0;

TEST(PlantFromSensitivity, OnePercentNoisySensitivityErrorFollowsLoopGainAndEq15Fails) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(kBandLo_rad_s, kBandHi_rad_s, kBandPoints);
  FrequencyResponse S = frequency_response(st.sensitivity, w);
  std::mt19937 rng(kAnalyzerNoiseSeed);
  std::normal_distribution<double> N(0.0, std::sqrt(0.5));
  for (Eigen::MatrixXcd& s : S.response)
    for (Index i = 0; i < s.size(); ++i) s(i) *= 1.0 + kAnalyzerNoise * Complex(N(rng), N(rng));
  const std::vector<Eigen::MatrixXcd> P = evaluate_response(st.plant, w);
  const std::vector<Eigen::MatrixXcd> C = evaluate_response(st.controller, w);
  const SensitivityUnloopResult r = plant_from_sensitivity(S, st.controller, {});
  const std::vector<Eigen::MatrixXcd> P15 = plant_from_sensitivity_printed_eq15(S, st.controller).response;
  double band_sum = 0, band_max = 0, all_sum = 0, eq15_sum = 0, worst_ratio = 0;
  Index band_count = 0;
  for (Index k = 0; k < w.size(); ++k) {
    const size_t kk = static_cast<size_t>(k);
    const double e = weighted_error(r.plant.response[kk], P[kk]);
    const double sigma_min = Eigen::JacobiSVD<Eigen::MatrixXcd>(C[kk] * P[kk]).singularValues()(2);
    worst_ratio = std::max(worst_ratio, e / (kAnalyzerNoise * (1.0 + 1.0 / sigma_min)));
    all_sum += e;
    eq15_sum += weighted_error(P15[kk], P[kk]);
    if (w(k) <= kHighGainBandHi_rad_s) {
      band_sum += e;
      band_max = std::max(band_max, e);
      ++band_count;
    }
  }
  const double band_mean = band_sum / static_cast<double>(band_count);
  const double all_mean = all_sum / static_cast<double>(w.size());
  const double eq15_mean = eq15_sum / static_cast<double>(w.size());
  EXPECT_LE(band_mean, kNoisyMeanErrorMax);
  EXPECT_LE(band_max, kNoisyMaxErrorMax);
  EXPECT_LE(worst_ratio, kBoundFactor);
  EXPECT_GE(eq15_mean, kEq15MinWorseFactor * all_mean);
  EXPECT_EQ(r.flagged_count, 0);
}

// The propagated variance of P against the scatter of P̂ over noise draws of S: S from
// the state-space loop (not from the formula under test), each entry perturbed by
// independent circular Gaussian noise of variance v_kl = (1e-3 |S_kl| + 1e-4)², P̂ by
// plant_from_sensitivity.  With 2000 draws the empirical E|P̂_ab − P_ab|² (|dP|² is
// exponential to first order) has a relative standard error of 1/√2000 = 2.2 %; the
// bound 15 % leaves ~5 of them plus the second-order terms (relative noise 1e-3).
TEST(PlantVarianceFromSensitivity, MatchesTheScatterOfPlantsFromNoisySensitivities) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(kBandLo_rad_s, kBandHi_rad_s, 12);
  const FrequencyResponse S = frequency_response(st.sensitivity, w);
  std::vector<Eigen::MatrixXd> v;
  for (const Eigen::MatrixXcd& s : S.response) v.push_back((1e-3 * s.cwiseAbs().array() + 1e-4).square().matrix());
  const std::vector<Eigen::MatrixXd> predicted = plant_variance_from_sensitivity(S, v, st.controller);
  const std::vector<Eigen::MatrixXcd> P = evaluate_response(st.plant, w);
  std::vector<Eigen::MatrixXd> scatter(predicted.size(), Eigen::MatrixXd::Zero(3, 3));
  std::mt19937 rng(kAnalyzerNoiseSeed + 1);
  std::normal_distribution<double> N(0.0, 1.0);
  constexpr int kDraws = 2000;
  SensitivityUnloopOptions no_checks;
  no_checks.min_loop_gain = 0.0;
  no_checks.max_condition = 1e12;
  for (int d = 0; d < kDraws; ++d) {
    FrequencyResponse noisy = S;
    for (std::size_t k = 0; k < noisy.response.size(); ++k)
      for (Index i = 0; i < 9; ++i)
        noisy.response[k](i) += std::sqrt(v[k](i) / 2.0) * Complex(N(rng), N(rng));
    const SensitivityUnloopResult r = plant_from_sensitivity(noisy, st.controller, no_checks);
    for (std::size_t k = 0; k < P.size(); ++k) scatter[k] += (r.plant.response[k] - P[k]).cwiseAbs2() / kDraws;
  }
  double lo = 1e300, hi = 0;
  for (std::size_t k = 0; k < P.size(); ++k)
    for (Index i = 0; i < 9; ++i) {
      ASSERT_TRUE(std::isfinite(predicted[k](i)));
      const double ratio = scatter[k](i) / predicted[k](i);
      lo = std::min(lo, ratio);
      hi = std::max(hi, ratio);
    }
  std::printf("empirical / propagated variance of P over %d draws: %.3f .. %.3f\n", kDraws, lo, hi);
  EXPECT_GT(lo, 0.85);
  EXPECT_LT(hi, 1.15);
  // Nothing is known where the variance of S is not.
  v[3](0, 0) = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isinf(plant_variance_from_sensitivity(S, v, st.controller)[3](1, 1)));
  v[3](0, 0) = -1.0;
  EXPECT_THROW(plant_variance_from_sensitivity(S, v, st.controller), InputError);
}

// A controller with a nearly singular gain: C = diag(1, 1, 1e-8) (static).
TEST(PlantFromSensitivity, IllConditionedControllerIsFlagged) {
  StateSpace c;
  c.A = Eigen::MatrixXd::Zero(0, 0);
  c.B = Eigen::MatrixXd::Zero(0, 3);
  c.C = Eigen::MatrixXd::Zero(3, 0);
  c.D = Eigen::Vector3d(1.0, 1.0, 1e-8).asDiagonal();
  c.sample_period_s = kSamplePeriod_s;
  FrequencyResponse S;
  S.omega_rad_s = Eigen::VectorXd::Constant(1, 10.0);
  S.response = {Eigen::MatrixXcd::Identity(3, 3) * 0.5};
  const SensitivityUnloopResult r = plant_from_sensitivity(S, c, {});
  EXPECT_EQ(r.flagged_count, 1);
  EXPECT_TRUE(r.plant.flagged[0]);
  EXPECT_THAT(r.flag_reasons[0], StartsWith("C ill-conditioned (cond 1e+08)"));
  EXPECT_FALSE(r.report.usable);
}

// S = diag(0.5, 0.5, 1 − 1e-9): S⁻¹ − I = diag(1, 1, ~1e-9), the z loop gain is lost.
TEST(PlantFromSensitivity, NearlyIdentitySensitivityDirectionIsFlagged) {
  const Stage st;
  FrequencyResponse S;
  S.omega_rad_s = Eigen::Vector2d(10.0, 20.0);
  const Eigen::MatrixXcd bad = Eigen::Vector3cd(0.5, 0.5, 1.0 - 1e-9).asDiagonal();
  const Eigen::MatrixXcd good = Eigen::Vector3cd(0.5, 0.5, 0.5).asDiagonal();
  S.response = {good, bad};
  const SensitivityUnloopResult r = plant_from_sensitivity(S, st.controller, {});
  EXPECT_TRUE(r.flag_reasons[0].empty()) << r.flag_reasons[0];
  EXPECT_THAT(r.flag_reasons[1], StartsWith("S^-1 - I ill-conditioned (cond 1e+09)"));
  EXPECT_THAT(r.flag_reasons[1], HasSubstr("low loop gain (sigma_min(C P) 1e-09 < 0.0001)"));
  EXPECT_EQ(r.flagged_count, 1);
  EXPECT_TRUE(r.report.usable);
  ASSERT_EQ(r.report.warnings.size(), 2u);
  EXPECT_EQ(r.report.warnings[0], "S^-1 - I ill-conditioned: 1 of 2 frequencies");
  EXPECT_EQ(r.report.warnings[1], "low loop gain: 1 of 2 frequencies");
}

// Exact S of the stage up to 0.99 · Nyquist: the loop gain falls below 1e-4 near
// the top of the grid.  Exactly the frequencies where σ_min(C P) < min_loop_gain
// are flagged, "low loop gain" and nothing else (S itself is well conditioned).
TEST(PlantFromSensitivity, LowLoopGainIsFlaggedWhereSigmaMinOfCPIsBelowTheThreshold) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(kBandLo_rad_s, 0.99 * std::numbers::pi / kSamplePeriod_s, 300);
  const FrequencyResponse S = frequency_response(st.sensitivity, w);
  const SensitivityUnloopOptions options;
  const SensitivityUnloopResult r = plant_from_sensitivity(S, st.controller, options);
  const std::vector<Eigen::MatrixXcd> P = evaluate_response(st.plant, w);
  const std::vector<Eigen::MatrixXcd> C = evaluate_response(st.controller, w);
  Index expected = 0;
  for (Index k = 0; k < w.size(); ++k) {
    const size_t kk = static_cast<size_t>(k);
    const double sigma_min = Eigen::JacobiSVD<Eigen::MatrixXcd>(C[kk] * P[kk]).singularValues()(2);
    const bool low = sigma_min < options.min_loop_gain;
    expected += low ? 1 : 0;
    ASSERT_EQ(r.plant.flagged[kk], low) << "omega " << w(k) << " sigma_min " << sigma_min;
    if (low) {
      ASSERT_THAT(r.flag_reasons[kk], StartsWith("low loop gain (sigma_min(C P) ")) << r.flag_reasons[kk];
    }
  }
  EXPECT_GT(expected, 0);
  EXPECT_EQ(r.flagged_count, expected);
}

TEST(PlantFromSensitivity, LowCoherenceAndFlaggedInputAreFlagged) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(10.0, 100.0, 4);
  FrequencyResponse S = frequency_response(st.sensitivity, w);
  S.coherence.assign(4, Eigen::MatrixXd::Constant(3, 3, 0.9));
  S.coherence[1].row(2).setConstant(0.3);  // output u_z explained by no excitation
  S.coherence[2](0, 1) = 0.1;              // a weak cross entry alone: not a flag
  S.flagged = {false, false, false, true};
  const SensitivityUnloopResult r = plant_from_sensitivity(S, st.controller, {});
  EXPECT_TRUE(r.flag_reasons[0].empty());
  EXPECT_EQ(r.flag_reasons[1], "low coherence (0.3 < 0.5)");
  EXPECT_TRUE(r.flag_reasons[2].empty()) << r.flag_reasons[2];
  EXPECT_EQ(r.flag_reasons[3], "input flagged");
  EXPECT_EQ(r.flagged_count, 2);
  // The values are still computed where S and C are invertible.
  EXPECT_GT(r.plant.response[1].norm(), 0.0);
}

TEST(PlantFromSensitivity, RejectsBadInputWithMessages) {
  const Stage st;
  const Eigen::VectorXd w = log_frequency_grid(10.0, 100.0, 3);
  const FrequencyResponse S = frequency_response(st.sensitivity, w);
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  SensitivityUnloopOptions bad_opt;
  bad_opt.max_condition = 1.0;
  EXPECT_THAT(message([&] { plant_from_sensitivity(S, st.controller, bad_opt); }),
              HasSubstr("sensitivity unloop options: max_condition = 1; it must be > 1"));
  bad_opt = {};
  bad_opt.min_coherence = 1.5;
  EXPECT_THAT(message([&] { plant_from_sensitivity(S, st.controller, bad_opt); }),
              HasSubstr("min_coherence = 1.5; it must be in [0, 1]"));
  bad_opt = {};
  bad_opt.min_loop_gain = -1.0;
  EXPECT_THAT(message([&] { plant_from_sensitivity(S, st.controller, bad_opt); }),
              HasSubstr("min_loop_gain = -1; it must be finite and >= 0"));
  FrequencyResponse wrong = S;
  for (auto& s : wrong.response) s = s.leftCols(2).eval();
  EXPECT_THAT(message([&] { plant_from_sensitivity(wrong, st.controller, {}); }),
              HasSubstr("plant_from_sensitivity: S (v → u) at frequency 0 (10 rad/s) is 3x2, the controller needs 3x3"));
  StateSpace c2 = st.controller;
  c2.B = c2.B.leftCols(2).eval();
  c2.D = c2.D.leftCols(2).eval();
  EXPECT_THAT(message([&] { plant_from_sensitivity(S, c2, {}); }),
              HasSubstr("the controller has 2 inputs and 3 outputs; P = C⁻¹ (S⁻¹ − I) needs a square controller"));
  FrequencyResponse high = S;
  high.omega_rad_s(2) = 4000.0;
  EXPECT_THAT(message([&] { plant_from_sensitivity(high, st.controller, {}); }),
              HasSubstr("frequency 2 is 4000 rad/s, above the Nyquist frequency 3141.59"));
  FrequencyResponse nan = S;
  nan.response[1](0, 0) = Complex(std::nan(""), 0.0);
  EXPECT_THAT(message([&] { plant_from_sensitivity(nan, st.controller, {}); }),
              AllOf(HasSubstr("S (v → u) at frequency 1 (31.62"), HasSubstr("rad/s) holds NaN or Inf")));
  EXPECT_THAT(message([&] { plant_from_sensitivity(FrequencyResponse{}, st.controller, {}); }),
              HasSubstr("S (v → u) has no frequencies"));
  EXPECT_THAT(message([&] { plant_from_closed_loop_frd(wrong, st.controller); }),
              HasSubstr("plant_from_closed_loop_frd: G (v → q) at frequency 0 (10 rad/s) is 3x2, the controller needs 3x3"));
}

}  // namespace sensitivity_test
}  // namespace lpvid
