// Test support for identify on the INDEPENDENT simulator (tests/support/): one drawn
// plant at one beam position, its three logs as `indep_sim` writes them, identify with
// every default, and the result measured against the true sampled plant.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <vector>

#include "idlib/identify/identify.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/validate/frequency_error.h"
#include "tests/support/independent_draw.h"

namespace lpvid::testing {

// The error measure of `identify --truth`: mean and max over 1–400 rad/s (200 log
// points) of ‖P̂ − P‖₂ / ‖P‖₂, unweighted (the platform model's valid band).
inline constexpr double kIndependentBandLow = 1.0, kIndependentBandHigh = 400.0;
inline constexpr Index kIndependentBandPoints = 200;

inline StateSpace to_state_space(const indep::Discrete& d) {
  StateSpace s;
  s.A = d.A;
  s.B = d.B;
  s.C = d.C;
  s.D = d.D;
  s.sample_period_s = d.Ts;
  return s;
}

struct IndependentCase {
  std::uint64_t seed = 1;
  int position = 1;          // 0, 1, 2: beam at −0.1, 0, +0.1 m
  double noise_scale = -1;   // × 0.3 µm per sensor; 0 = noise-free; < 0: as drawn
  double sample_period_s = 1e-3;
  double duration_s = 60;    // per experiment (3 experiments, one excited input each)
  std::uint64_t realisation = 0;  // 0: indep_sim's noise and excitation; k > 0: another draw of both
  bool identify = true;           // false: only the logs (and truth, controller)
  bool levitated = false;         // indep::levitate: no spring stiffness (indep_sim --levitated)
};

struct IndependentOutcome {
  StateSpace truth, controller;
  double noise_scale = 0;
  IdentifyResult result;
  ErrorSummary error;
  std::string description;  // the draw
  std::vector<Eigen::MatrixXd> v, q;  // the logs: excitation and measured output per experiment
};

// The logs reproduce `indep_sim --seed S [--noise-scale X]` (same draw, same noise seeds).
inline IndependentOutcome run_independent(const IndependentCase& c, const IdentifyOptions& options = {}) {
  const double xb[3] = {-0.1, 0.0, 0.1};
  indep::Draw d = indep::draw_stable(c.seed, indep::HiddenEffect::kNone, indep::DrawOptions{}, c.sample_period_s,
                                     {xb[0], xb[1], xb[2]});
  if (c.levitated && !indep::levitate(d, c.sample_period_s, {xb[0], xb[1], xb[2]}))
    throw std::runtime_error("the levitated loop of this seed is unstable");
  IndependentOutcome o;
  o.description = d.description;
  o.noise_scale = c.noise_scale < 0 ? d.noise_scale : c.noise_scale;
  indep::Noise noise;
  noise.sensor_std_m = 0.3e-6 * o.noise_scale;
  const indep::Discrete C = indep::pid_controller(d.plant, d.pid, c.sample_period_s);
  const indep::Discrete P = indep::sampled_plant(d.plant, xb[c.position], c.sample_period_s);
  std::vector<Eigen::MatrixXd>& v = o.v;
  std::vector<Eigen::MatrixXd>& q = o.q;
  v.resize(3);
  q.resize(3);
  std::vector<ExperimentView> views;
  const double amplitude[3] = {0.05, 0.05, 1.0};  // indep_sim's excitation levels
  const auto N = static_cast<Eigen::Index>(std::llround(c.duration_s / c.sample_period_s));
  for (int j = 0; j < 3; ++j) {
    const Eigen::MatrixXd log =
        indep::simulate_log(P, C, d.plant, noise, amplitude, j, N, c.seed * 1000 + 10 * c.position + j + 7919 * c.realisation);
    v[static_cast<std::size_t>(j)] = log.middleCols(1, 3);
    q[static_cast<std::size_t>(j)] = log.middleCols(7, 3);
  }
  for (int j = 0; j < 3; ++j) views.push_back({v[static_cast<std::size_t>(j)], q[static_cast<std::size_t>(j)]});
  o.truth = to_state_space(P);
  o.controller = to_state_space(C);
  if (!c.identify) return o;
  o.result = identify_closed_loop(views, c.sample_period_s, o.controller, options);
  const Eigen::VectorXd omega = log_frequency_grid(kIndependentBandLow, kIndependentBandHigh, kIndependentBandPoints);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(3);
  o.error = weighted_error_over(evaluate_response(o.result.plant, omega), evaluate_response(o.truth, omega), omega,
                                ones, ones);
  return o;
}

}  // namespace lpvid::testing
