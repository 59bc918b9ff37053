// identify with every default on plants from the INDEPENDENT simulator
// (tests/support/independent_platform.h: coil-level physics, RK4, no lpvid code), as a
// new user would run it (issue 11).  Plants are drawn over the ranges
// (tests/support/independent_draw.h: closed-loop damping 0.02–0.5, integral time
// 0.1–3 s, ψ/θ stiffness ratio 0.3–3, masses and inertias ±50 %); the draws below are
// the cases that failed before the order check on the final data (pinned as regression
// cases), with and without sensor noise.
#include <gtest/gtest.h>

#include <cstdio>

#include "idlib/identify/identify.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/independent_case.h"

namespace lpvid {
namespace independent_identify_test {

struct Case {
  std::uint64_t seed;
  int position;        // 0, 1, 2: beam at −0.1, 0, +0.1 m
  double noise_scale;  // × 0.3 µm per sensor; 0 = noise-free
  // Bounds, with what they stand for:
  double max_mean_error;  // measured (this commit) mean error × ~3, at least 0.05 % noisy / 0.005 % noise-free
};

class IndependentIdentify : public ::testing::TestWithParam<Case> {};

TEST_P(IndependentIdentify, DefaultsGiveAStableOrderSixPlantNearTheTruth) {
  const Case c = GetParam();
  const testing::IndependentOutcome o = testing::run_independent({c.seed, c.position, c.noise_scale});
  const IdentifyResult& r = o.result;
  const ErrorSummary& e = o.error;
  std::printf("seed %llu position %d noise %.3g: horizon %ld lags, order %ld, mean %.4f %%, max %.4f %%\n  %s\n  %s\n",
              static_cast<unsigned long long>(c.seed), c.position, c.noise_scale, static_cast<long>(r.num_lags),
              static_cast<long>(r.plant.order()), 100 * e.mean, 100 * e.max, r.choices.horizon_reason.c_str(),
              r.choices.order_reason.c_str());
  EXPECT_EQ(r.plant.order(), 6);  // the platform's three rigid-body modes
  EXPECT_TRUE(is_stable(closed_loop_output(r.plant, o.controller)));
  EXPECT_LE(e.mean, c.max_mean_error);
}

// Seed 1 draws (truth.txt of indep_sim --seed 1): ψ/θ stiffness ratio 0.31, closed-loop
// damping 0.05–0.19, integral times 0.15–2.6 s (slow integral action on ψ).
// Measured (mean error): noise-free left 0.0001 %, middle 0.0000 %, right 0.0102 %
// (0.0047 % before issue 24: the plant's impulse response behind the starting models is
// now exact, not time-aliased, and the right position's fit ends elsewhere within the
// tail rounds' limit); default noise ×1: left 0.059 %, middle 0.051 %, right 0.070 %.
// Left, noisy, chose order 9 (173 % error) before the order check on the final data;
// middle, noise-free, chose order 7 (23 %); right, noise-free, order 7 (0.045 %).
INSTANTIATE_TEST_SUITE_P(
    Seed1, IndependentIdentify,
    ::testing::Values(Case{1, 0, 0.0, 0.005 / 100}, Case{1, 1, 0.0, 0.005 / 100}, Case{1, 2, 0.0, 0.02 / 100},
                      Case{1, 0, 1.0, 0.2 / 100}, Case{1, 1, 1.0, 0.2 / 100}, Case{1, 2, 1.0, 0.2 / 100}));

}  // namespace independent_identify_test
}  // namespace lpvid
