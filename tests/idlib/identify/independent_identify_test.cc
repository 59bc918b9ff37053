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
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/validate/frequency_error.h"
#include "tests/support/independent_draw.h"

namespace lpvid {
namespace {

// The error measure of `identify --truth`: mean and max over 1–400 rad/s (200 log
// points) of ‖P̂ − P‖₂ / ‖P‖₂, unweighted (the platform model's valid band).
constexpr double kBandLow = 1.0, kBandHigh = 400.0;
constexpr Index kBandPoints = 200;
// 3 × 60 s at 1 kHz, one excited input per experiment (indep_sim's logs).
constexpr double kTs = 1e-3;
constexpr double kDuration_s = 60.0;

StateSpace to_ss(const indep::Discrete& d) {
  StateSpace s;
  s.A = d.A;
  s.B = d.B;
  s.C = d.C;
  s.D = d.D;
  s.sample_period_s = d.Ts;
  return s;
}

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
  const double xb[3] = {-0.1, 0.0, 0.1};
  const indep::Draw d = indep::draw_stable(c.seed, indep::HiddenEffect::kNone, indep::DrawOptions{}, kTs,
                                           {xb[0], xb[1], xb[2]});
  indep::Noise noise;
  noise.sensor_std_m = 0.3e-6 * c.noise_scale;
  const indep::Discrete C = indep::pid_controller(d.plant, d.pid, kTs);
  const indep::Discrete P = indep::sampled_plant(d.plant, xb[c.position], kTs);
  std::vector<Eigen::MatrixXd> v(3), q(3);
  std::vector<ExperimentView> views;
  const double amplitude[3] = {0.05, 0.05, 1.0};  // indep_sim's excitation levels
  for (int j = 0; j < 3; ++j) {
    const auto N = static_cast<Eigen::Index>(std::llround(kDuration_s / kTs));
    // seed as indep_sim's: the test reproduces `indep_sim --seed S --noise-scale X` logs
    const Eigen::MatrixXd log =
        indep::simulate_log(P, C, d.plant, noise, amplitude, j, N, c.seed * 1000 + 10 * c.position + j);
    v[static_cast<std::size_t>(j)] = log.middleCols(1, 3);
    q[static_cast<std::size_t>(j)] = log.middleCols(7, 3);
  }
  for (int j = 0; j < 3; ++j) views.push_back({v[static_cast<std::size_t>(j)], q[static_cast<std::size_t>(j)]});

  const IdentifyResult r = identify_closed_loop(views, kTs, to_ss(C), IdentifyOptions{});
  const Eigen::VectorXd omega = log_frequency_grid(kBandLow, kBandHigh, kBandPoints);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(3);
  const ErrorSummary e =
      weighted_error_over(evaluate_response(r.plant, omega), evaluate_response(to_ss(P), omega), omega, ones, ones);
  std::printf("seed %llu position %d noise %.3g: horizon %ld lags, order %ld, mean %.4f %%, max %.4f %%\n  %s\n  %s\n",
              static_cast<unsigned long long>(c.seed), c.position, c.noise_scale, static_cast<long>(r.num_lags),
              static_cast<long>(r.plant.order()), 100 * e.mean, 100 * e.max, r.choices.horizon_reason.c_str(),
              r.choices.order_reason.c_str());
  EXPECT_EQ(r.plant.order(), 6);  // the platform's three rigid-body modes
  EXPECT_TRUE(is_stable(closed_loop_output(r.plant, to_ss(C))));
  EXPECT_LE(e.mean, c.max_mean_error);
}

// Seed 1 draws (truth.txt of indep_sim --seed 1): ψ/θ stiffness ratio 0.31, closed-loop
// damping 0.05–0.19, integral times 0.15–2.6 s (slow integral action on ψ).
// Measured at this commit (mean error): noise-free left 0.0001 %, middle 0.0000 %,
// right 0.0047 %; default noise ×1: left 0.059 %, middle 0.051 %, right 0.070 %.
// Left, noisy, chose order 9 (173 % error) before the order check on the final data;
// middle, noise-free, chose order 7 (23 %); right, noise-free, order 7 (0.045 %).
INSTANTIATE_TEST_SUITE_P(
    Seed1, IndependentIdentify,
    ::testing::Values(Case{1, 0, 0.0, 0.005 / 100}, Case{1, 1, 0.0, 0.005 / 100}, Case{1, 2, 0.0, 0.02 / 100},
                      Case{1, 0, 1.0, 0.2 / 100}, Case{1, 1, 1.0, 0.2 / 100}, Case{1, 2, 1.0, 0.2 / 100}));

}  // namespace
}  // namespace lpvid
