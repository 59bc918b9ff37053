// plant_fit.h against truth computed without it: a known 2 × 2 plant of order 4 in a
// loop with a known PI controller (small_loop.h).  The data bins are the direct sums
// Σ_{k=1}^{L} g[k] z_f^{−k} of the loop's Markov parameters (markov_parameters, no FFT),
// with a horizon L over which the response has NOT died out, so the truncation term of
// the model is exercised; the covariance is checked against the scatter of fits over
// seeded noise draws of the documented bin statistics.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "idlib/core/error.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/small_loop.h"

namespace lpvid {
namespace plant_fit_test {

using testing::coupled_plant;
using testing::kSmallLoopTs_s;
using testing::pi_controller_2x2;

// A 128-lag horizon: the plant's poles (radius 0.995) keep 0.995^128 = 53 % of their
// amplitude beyond it.
constexpr Index kLags = 128;
constexpr Index kBins = kLags / 2 + 1;
// Noise density per output (Φ = σ² I) and the excitation Gram matrix R₀ = N I of N
// samples of unit white excitation.
constexpr double kNoiseVariance = 1e-8;
constexpr double kSamples = 60000.0;
constexpr double kMarkovAccuracy = 1e-8;  // identify.cc's kMarkovRelativeAccuracy
constexpr std::uint64_t kNoiseSeed = 20261124;

MarkovBins truth_bins(const StateSpace& plant, const StateSpace& controller) {
  const MarkovSequence g = markov_parameters(closed_loop_output(plant, controller), kLags);
  MarkovBins b;
  std::vector<Eigen::MatrixXcd> spectrum(kBins, kNoiseVariance * Eigen::MatrixXcd::Identity(2, 2));
  b = make_markov_bins(g, kLags, kBins, spectrum, kSamples * Eigen::MatrixXd::Identity(2, 2), kSmallLoopTs_s,
                       kMarkovAccuracy);
  return b;
}

Eigen::MatrixXcd direct_sum(const MarkovSequence& g, Index f) {
  Eigen::MatrixXcd s = Eigen::MatrixXcd::Zero(g.front().rows(), g.front().cols());
  for (Index k = 1; k <= kLags; ++k)
    s += g[static_cast<std::size_t>(k)].cast<Complex>() *
         std::polar(1.0, -2.0 * M_PI * static_cast<double>(f * k) / static_cast<double>(kLags));
  return s;
}

double max_relative_response_difference(const StateSpace& a, const StateSpace& b) {
  const Eigen::VectorXd w = log_frequency_grid(0.1, 3000.0, 200);
  const auto ra = evaluate_response(a, w), rb = evaluate_response(b, w);
  double worst = 0;
  for (std::size_t k = 0; k < ra.size(); ++k) worst = std::max(worst, (ra[k] - rb[k]).norm() / rb[k].norm());
  return worst;
}

TEST(MarkovBins, ResponseIsTheDirectSumOfTheMarkovParametersAtEachBin) {
  // FFT vs direct sum of ≤ 128 terms of size ≤ 1e-2: agreement to round-off.
  constexpr double kRoundOff = 1e-12;
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovSequence g = markov_parameters(closed_loop_output(plant, controller), kLags);
  const MarkovBins b = truth_bins(plant, controller);
  ASSERT_EQ(b.num_bins(), kBins);
  EXPECT_EQ(b.real_residuals(), 2 * 4 + (kBins - 2) * 2 * 4);  // DC and Nyquist real
  double peak = 0;
  for (Index f = 0; f < kBins; ++f) peak = std::max(peak, direct_sum(g, f).norm());
  for (Index f = 0; f < kBins; ++f) {
    EXPECT_LE((b.response[static_cast<std::size_t>(f)] - direct_sum(g, f)).norm(), kRoundOff * peak) << "bin " << f;
    EXPECT_NEAR(b.omega_rad_s(f), 2.0 * M_PI * static_cast<double>(f) / (kLags * kSmallLoopTs_s), 1e-9);
  }
}

TEST(PlantFitCost, TruthHasZeroCostOnATruncatedResponseAndAOnePercentErrorDoesNot) {
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  ASSERT_TRUE(is_stable(closed_loop_output(plant, controller)));
  const MarkovBins b = truth_bins(plant, controller);
  StateSpace off = plant;
  off.B *= 1.01;
  const double at_truth = plant_fit_cost(b, controller, plant, PlantFitOptions{});
  const double at_off = plant_fit_cost(b, controller, off, PlantFitOptions{});
  EXPECT_GT(at_off, 1.0);  // a 1 % gain error is far outside the noise
  // Round-off (~1e-13 relative on the response) squared against a 1e-2 error squared.
  EXPECT_LE(at_truth, 1e-12 * at_off);
}

TEST(PlantFit, NoiseFreeBinsFromAPerturbedStartReturnTheTruthByFrequencyResponse) {
  // Noise-free bins: LM converges to the truth (measured 3e-14 after 4 iterations); the
  // bar leaves room for a stop at the cost tolerance (1e-3 of a whitened cost whose
  // unit is 1e-8 of the response squared).
  constexpr double kResponseTolerance = 1e-6;
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovBins b = truth_bins(plant, controller);
  StateSpace start = plant;
  start.A *= 0.999;
  start.B.col(0) *= 1.05;
  start.C.row(1) *= 0.97;
  ASSERT_GT(max_relative_response_difference(start, plant), 0.03);
  const PlantFitResult r = fit_plant_closed_loop(b, controller, start, PlantFitOptions{});
  EXPECT_TRUE(r.report.usable) << r.report.termination;
  EXPECT_TRUE(r.closed_loop_stable);
  EXPECT_EQ(r.parameters, 4 * (2 + 2));
  EXPECT_EQ(r.residuals, b.real_residuals());
  EXPECT_LT(r.cost, 1e-6 * r.initial_cost);
  const double diff = max_relative_response_difference(r.plant, plant);
  EXPECT_LE(diff, kResponseTolerance) << r.report.termination;
  std::printf("max relative response difference to the truth: %.3g (%d iterations)\n", diff, r.iterations);
}

TEST(PlantFit, BandsMatchTheScatterOfFitsOverNoiseDraws) {
  // Noise with the statistics V assumes (complex Gaussian bin errors of covariance
  // L R₀⁻¹ ⊗ Φ; real at DC and Nyquist).  Over kDraws fits, the mean predicted variance
  // of P at each test frequency must match the empirical E|P̂ − P|²: with 2 kDraws real
  // degrees of freedom the empirical value has a relative spread of ~1/√kDraws = 0.1,
  // so a ratio in [0.6, 1.6] is a ≥ 4-sigma bound (measured 0.84..1.31).  The noise
  // scale σ̂² must be ~1 (measured 1.001).
  constexpr int kDraws = 100;
  constexpr double kMinRatio = 0.6, kMaxRatio = 1.6;
  constexpr double kNoiseScaleTolerance = 0.1;
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovBins clean = truth_bins(plant, controller);
  const double bin_std = std::sqrt(kNoiseVariance * kLags / kSamples);  // per complex entry
  const Eigen::VectorXd w = log_frequency_grid(1.0, 150.0, 5);  // around the two modes (50, 120 rad/s)
  const auto truth = evaluate_response(plant, w);
  std::mt19937_64 rng(kNoiseSeed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Eigen::MatrixXd> empirical(w.size(), Eigen::MatrixXd::Zero(2, 2)), predicted = empirical;
  double noise_scale = 0;
  for (int d = 0; d < kDraws; ++d) {
    MarkovBins b = clean;
    for (Index f = 0; f < b.num_bins(); ++f) {
      const bool real_bin = f == 0 || 2 * f == kLags;
      for (Index i = 0; i < 2; ++i)
        for (Index j = 0; j < 2; ++j) {
          const double re = n01(rng), im = real_bin ? 0.0 : n01(rng);
          const double s = real_bin ? bin_std : bin_std / std::sqrt(2.0);
          b.response[static_cast<std::size_t>(f)](i, j) += Complex(s * re, s * im);
        }
    }
    const PlantFitResult r = fit_plant_closed_loop(b, controller, plant, PlantFitOptions{});
    ASSERT_TRUE(r.report.usable) << r.report.termination;
    noise_scale += r.noise_scale / kDraws;
    const auto est = evaluate_response(r.plant, w);
    const auto var = plant_response_variance(r, w);
    for (Index k = 0; k < w.size(); ++k) {
      empirical[static_cast<std::size_t>(k)] += (est[k] - truth[k]).cwiseAbs2() / kDraws;
      predicted[static_cast<std::size_t>(k)] += var[static_cast<std::size_t>(k)] / kDraws;
    }
  }
  EXPECT_NEAR(noise_scale, 1.0, kNoiseScaleTolerance);
  double lo = 1e300, hi = 0;
  for (Index k = 0; k < w.size(); ++k)
    for (Index i = 0; i < 2; ++i)
      for (Index j = 0; j < 2; ++j) {
        const double ratio = predicted[k](i, j) / empirical[k](i, j);
        lo = std::min(lo, ratio), hi = std::max(hi, ratio);
        EXPECT_GE(ratio, kMinRatio) << "omega " << w(k) << " entry " << i << "," << j;
        EXPECT_LE(ratio, kMaxRatio) << "omega " << w(k) << " entry " << i << "," << j;
      }
  std::printf("predicted / empirical variance over %d draws: %.3f .. %.3f; mean noise scale %.3f\n", kDraws, lo, hi,
              noise_scale);
}

// Bin errors that are correlated across frequency (a common complex offset per entry
// carrying 90 % of the variance, plus independent parts): the model's σ̂² (JᵀJ)⁺ assumes
// independent bins and must under-predict the scatter of the fits; the sandwich of
// use_replicate_covariance, given replicates drawn from the same correlated law (each
// with 1/S of the covariance, as the segments of a record are), must match it.  Bounds
// as in BandsMatchTheScatterOfFitsOverNoiseDraws ([0.6, 1.6] is ≥ 4 sigma for 100 draws;
// the sandwich's own estimate from 60 replicates adds ~18 % spread per draw, averaged
// out over the draws).
TEST(PlantFit, ReplicateBandsMatchTheScatterWhenBinErrorsAreCorrelated) {
  constexpr int kDraws = 100, kReplicates = 60;
  constexpr double kMinRatio = 0.6, kMaxRatio = 1.6, kModelTooNarrow = 0.6;
  constexpr double kCommon = 0.9, kOwn = 0.3;  // per real part, × the bin's std
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovBins clean = truth_bins(plant, controller);
  const double bin_std = std::sqrt(kNoiseVariance * kLags / kSamples);
  const Eigen::VectorXd w = log_frequency_grid(1.0, 150.0, 5);
  const auto truth = evaluate_response(plant, w);
  std::mt19937_64 rng(kNoiseSeed + 7);
  std::normal_distribution<double> n01(0.0, 1.0);
  // One draw of the correlated error, scaled by `scale`: per entry a common offset of
  // variance bin_std²/2 at every bin plus an independent part of the same variance.
  auto draw_error = [&](double scale) {
    std::vector<Eigen::MatrixXcd> e(static_cast<std::size_t>(clean.num_bins()), Eigen::MatrixXcd::Zero(2, 2));
    for (Index i = 0; i < 2; ++i)
      for (Index j = 0; j < 2; ++j) {
        const Complex common(n01(rng) * kCommon * bin_std, n01(rng) * kCommon * bin_std);
        for (Index f = 0; f < clean.num_bins(); ++f) {
          const bool real_bin = f == 0 || 2 * f == kLags;
          const Complex own(n01(rng) * kOwn * bin_std, real_bin ? 0.0 : n01(rng) * kOwn * bin_std);
          e[static_cast<std::size_t>(f)](i, j) = scale * (real_bin ? Complex(common.real(), 0.0) + own : common + own);
        }
      }
    return e;
  };
  std::vector<Eigen::MatrixXd> empirical(w.size(), Eigen::MatrixXd::Zero(2, 2)), model = empirical, sandwich = empirical;
  for (int d = 0; d < kDraws; ++d) {
    MarkovBins b = clean;
    const auto err = draw_error(1.0);
    for (Index f = 0; f < b.num_bins(); ++f) b.response[static_cast<std::size_t>(f)] += err[static_cast<std::size_t>(f)];
    PlantFitResult r = fit_plant_closed_loop(b, controller, plant, PlantFitOptions{});
    ASSERT_TRUE(r.report.usable) << r.report.termination;
    const auto est = evaluate_response(r.plant, w);
    const auto var_model = plant_response_variance(r, w);
    std::vector<std::vector<Eigen::MatrixXcd>> reps;
    for (int s = 0; s < kReplicates; ++s) reps.push_back(draw_error(1.0 / std::sqrt(static_cast<double>(kReplicates))));
    use_replicate_covariance(r, b, controller, reps, PlantFitOptions{});
    EXPECT_EQ(r.replicates, kReplicates);
    const auto var_sandwich = plant_response_variance(r, w);
    for (Index k = 0; k < w.size(); ++k) {
      empirical[static_cast<std::size_t>(k)] += (est[k] - truth[k]).cwiseAbs2() / kDraws;
      model[static_cast<std::size_t>(k)] += var_model[static_cast<std::size_t>(k)] / kDraws;
      sandwich[static_cast<std::size_t>(k)] += var_sandwich[static_cast<std::size_t>(k)] / kDraws;
    }
  }
  double lo = 1e300, hi = 0, model_mean = 0;
  for (Index k = 0; k < w.size(); ++k)
    for (Index i = 0; i < 2; ++i)
      for (Index j = 0; j < 2; ++j) {
        const double ratio = sandwich[k](i, j) / empirical[k](i, j), model_ratio = model[k](i, j) / empirical[k](i, j);
        lo = std::min(lo, ratio), hi = std::max(hi, ratio), model_mean += model_ratio / static_cast<double>(4 * w.size());
        EXPECT_GE(ratio, kMinRatio) << "omega " << w(k) << " entry " << i << "," << j;
        EXPECT_LE(ratio, kMaxRatio) << "omega " << w(k) << " entry " << i << "," << j;
      }
  EXPECT_LT(model_mean, kModelTooNarrow) << "the correlated errors did not fool the independent-bin model";
  std::printf("sandwich predicted / empirical variance over %d draws: %.3f .. %.3f; the model's %.3f on average\n",
              kDraws, lo, hi, model_mean);
}

TEST(PlantFit, ReplicateCovarianceRejectsTooFewReplicatesAndMismatchedBins) {
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovBins b = truth_bins(plant, controller);
  PlantFitResult r = fit_plant_closed_loop(b, controller, plant, PlantFitOptions{});
  const std::vector<Eigen::MatrixXcd> zero(static_cast<std::size_t>(b.num_bins()), Eigen::MatrixXcd::Zero(2, 2));
  EXPECT_THROW(use_replicate_covariance(r, b, controller, {zero}, PlantFitOptions{}), InputError);
  const std::vector<Eigen::MatrixXcd> short_one(zero.begin(), zero.end() - 1);
  EXPECT_THROW(use_replicate_covariance(r, b, controller, {zero, short_one}, PlantFitOptions{}), InputError);
}

TEST(PlantFit, RejectsAStartWithFeedthroughAndMismatchedShapes) {
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const MarkovBins b = truth_bins(plant, controller);
  StateSpace with_d = plant;
  with_d.D(0, 0) = 1.0;
  try {
    fit_plant_closed_loop(b, controller, with_d, PlantFitOptions{});
    FAIL() << "feedthrough accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "plant fit: the initial plant must have D = 0 (ZOH-sampled plant)");
  }
  StateSpace one_input = plant;
  one_input.B = plant.B.leftCols(1);
  one_input.D = Eigen::MatrixXd::Zero(2, 1);
  try {
    fit_plant_closed_loop(b, controller, one_input, PlantFitOptions{});
    FAIL() << "a 2x1 plant accepted for 2x2 data";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "plant fit: the initial plant is 2x1 but the data are 2x2");
  }
}

}  // namespace plant_fit_test
}  // namespace lpvid
