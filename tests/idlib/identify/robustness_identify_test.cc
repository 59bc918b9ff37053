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
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/independent_case.h"

namespace lpvid {
namespace {

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

INSTANTIATE_TEST_SUITE_P(Seeds2To25, IndependentRobustness,
                         ::testing::Values(2, 3, 4, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23,
                                           24, 25));

// 10 kHz, 3 × 100 s: one noise-free and one noisy draw.
TEST(IndependentRobustness10kHz, DefaultsGiveAStableOrderSixPlantWithinTheStatedError) {
  check_case({3, 0, -1.0, 1e-4, 100});  // seed 3 draws no sensor noise
  check_case({4, 1, -1.0, 1e-4, 100});  // × 0.53
}

// Found by this suite and NOT yet passing (pinned, disabled until fixed): seed 2 at the
// left position (θ closed-loop damping 0.021; 17 % of the response energy beyond a
// quarter of the record): the tail rounds contract only ~0.7× per round and stop after
// 6 rounds with the plant still moving 4 % — mean error 1.10 % against a bound of 0.1 %.
TEST(IndependentRobustnessKnownFailure, DISABLED_Seed2LeftSlowTailRounds) { check_case({2, 0, -1.0}); }

}  // namespace
}  // namespace lpvid
