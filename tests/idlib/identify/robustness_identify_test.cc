// Randomised robustness of identify's defaults (issue 11): plants drawn by the
// INDEPENDENT simulator (tests/support/independent_draw.h, no lpvid code) over the
// issue's ranges — closed-loop damping 0.02–0.5, integral time 0.1–3 s, ψ/θ stiffness
// ratio 0.3–3, masses and inertias ±50 %, sensor noise 0 (one draw in four) or
// 0.1–10 × 0.3 µm — one beam position per seed, 3 × 60 s at 1 kHz, every default.
//
// Stated error (mean of ‖P̂ − P‖₂ / ‖P‖₂ over 1–400 rad/s, the `identify --truth`
// measure): at most 0.01 % on noise-free logs, and at most max(0.1 %, 0.2 % × the noise
// scale) with sensor noise (the error grows with the noise).  Measured on seeds 2–25 at
// f1278e6: noise-free 0.0000–0.0001 %; noisy 0.005–0.68 %, at most 0.19 % per unit of
// noise scale (seed 2, ×0.42: 0.079 %).  Seed 6 has no draw with a stable loop.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "idlib/identify/identify.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/independent_case.h"
#include "tests/support/statistics.h"

namespace lpvid {
namespace robustness_identify_test {

constexpr double kNoiseFreeBound = 0.01 / 100;
constexpr double kNoisyFloorBound = 0.1 / 100;
constexpr double kNoisyPerScaleBound = 0.2 / 100;

void check_case(const testing::IndependentCase& c) {
  const testing::IndependentOutcome o = testing::run_independent(c);
  const IdentifyResult& r = o.result;
  const double bound =
      o.noise_scale > 0 ? std::max(kNoisyFloorBound, kNoisyPerScaleBound * o.noise_scale) : kNoiseFreeBound;
  std::printf("seed %llu position %d noise x%.3g, Ts %g: %ld lags, order %ld, mean %.4f %% (bound %.4f %%), max %.4f %%\n",
              static_cast<unsigned long long>(c.seed), c.position, o.noise_scale, c.sample_period_s,
              static_cast<long>(r.num_lags), static_cast<long>(r.plant.order()), 100 * o.error.mean, 100 * bound,
              100 * o.error.max);
  EXPECT_EQ(r.plant.order(), 6) << r.choices.order_reason;  // the platform's three rigid-body modes
  EXPECT_TRUE(is_stable(closed_loop_output(r.plant, o.controller)));
  EXPECT_LE(o.error.mean, bound) << o.description;
}

class IndependentRobustness : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(IndependentRobustness, DefaultsGiveAStableOrderSixPlantWithinTheStatedError) {
  const std::uint64_t seed = GetParam();
  check_case({seed, static_cast<int>(seed % 3), -1.0});
}

// The sanitizer build (tests/support/statistics.h) runs a subset on the same code paths:
// a noisy draw with the horizon at the cap (2), noise-free (3), the noisiest (5) and
// noise-free at the cap (21).
INSTANTIATE_TEST_SUITE_P(Seeds2To25, IndependentRobustness,
                         ::testing::ValuesIn(testing::statistical_cases<std::uint64_t>(
                             {2, 3, 4, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25},
                             {2, 3, 5, 21})));

// 10 kHz, 3 × 100 s: one noise-free and one noisy draw.
TEST(IndependentRobustness10kHz, DefaultsGiveAStableOrderSixPlantWithinTheStatedError) {
  // seed 3 draws no sensor noise, seed 4 × 0.53; the sanitizer build runs seed 3 only.
  for (const std::uint64_t seed : testing::statistical_cases<std::uint64_t>({3, 4}, {3}))
    check_case({seed, seed == 3 ? 0 : 1, -1.0, 1e-4, 100});
}

// The bands (issue 11: "a 95 % band contains the true response at 90–99 % of
// frequencies"): one drawn plant (seed 4, beam left: the lowest coverage of the four
// plants measured), noise ×1, 10 independent noise and excitation draws; the share
// of (frequency, entry) pairs over 1–400 rad/s whose true response lies within the disc
// of radius kBandRadiusPerSigma σ drawn by bode.  Measured: 0.954 pooled over the 10
// draws (0.88–1.00 per draw; 0.89–0.95 per decade over 12 draws in a separate run).  Coverage within one draw is strongly correlated
// across frequency (it is one parametric fit), so the pooled share over 10 draws
// scatters by ~3 points: the bounds [0.85, 0.995] are ~3 sigma below and the
// "hopelessly wide" side (every point inside) above.
TEST(IndependentBands, CoverTheTruthAtTheStatedLevelOverNoiseDraws) {
  // The sanitizer build runs the first 3 draws (tests/support/statistics.h) against the
  // same bounds: measured per draw 1.000, 0.966, 0.913, 0.968, 0.899, 0.882, 0.933, 0.973,
  // 0.999, 1.000, so the first three pool to 0.960.
  const std::vector<int> draws = testing::statistical_cases<int>({1, 2, 3, 4, 5, 6, 7, 8, 9, 10}, {1, 2, 3});
  constexpr double kMinCoverage = 0.85, kMaxCoverage = 0.995;
  const Eigen::VectorXd omega =
      log_frequency_grid(testing::kIndependentBandLow, testing::kIndependentBandHigh, testing::kIndependentBandPoints);
  Index inside = 0, total = 0;
  for (const int d : draws) {
    testing::IndependentCase c;
    c.seed = 4;
    c.position = 0;
    c.noise_scale = 1.0;
    c.realisation = static_cast<std::uint64_t>(d);
    const testing::IndependentOutcome o = testing::run_independent(c);
    ASSERT_GT(o.result.fit.replicates, 0) << o.result.choices.bands_reason;
    const auto est = evaluate_response(o.result.plant, omega), truth = evaluate_response(o.truth, omega);
    const auto var = plant_response_variance(o.result.fit, omega);
    const Index inside_before = inside;
    for (Index k = 0; k < omega.size(); ++k)
      for (Index i = 0; i < 3; ++i)
        for (Index j = 0; j < 3; ++j) {
          const double r2 = kBandRadiusPerSigma * kBandRadiusPerSigma * var[static_cast<std::size_t>(k)](i, j);
          inside += std::norm(est[static_cast<std::size_t>(k)](i, j) - truth[static_cast<std::size_t>(k)](i, j)) <= r2;
          ++total;
        }
    std::printf("draw %d: %.3f of its pairs inside\n", d, static_cast<double>(inside - inside_before) / (9.0 * static_cast<double>(omega.size())));
  }
  const double coverage = static_cast<double>(inside) / static_cast<double>(total);
  std::printf("95 %% bands: %.3f of %ld (frequency, entry) pairs over %zu draws contain the truth\n", coverage,
              static_cast<long>(total), draws.size());
  EXPECT_GE(coverage, kMinCoverage);
  EXPECT_LE(coverage, kMaxCoverage);
}

// Found by this suite (regression case): seed 2 at the left position (θ closed-loop
// damping 0.021; 17 % of the response energy beyond a quarter of the record).  The tail
// rounds contracted only ~0.7× per round and stopped after 6 rounds with the plant still
// moving 4 % — mean error 1.10 %.  With the slow modes' tail amplitudes refitted to the
// logs each round (refit_response_beyond) they converge in 5 rounds: 0.066 %.
TEST(IndependentRobustnessRegression, Seed2LeftSlowTail) { check_case({2, 0, -1.0}); }

}  // namespace robustness_identify_test
}  // namespace lpvid
