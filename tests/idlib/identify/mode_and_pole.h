// The plant the output-error and held-out-order tests share, written here (not from
// idlib): a lightly damped mode (60 rad/s, ζ 0.05) and a real pole, order 3, at 1 kHz,
// y the mode's second state plus the pole; its open-loop logs from this file's own
// recursion; and the relative distance of two models' impulse responses.
#pragma once

#include <cmath>
#include <random>

#include <Eigen/Core>

#include "idlib/core/types.h"
#include "idlib/lti/analysis.h"

namespace lpvid::testing::mode_and_pole {

inline constexpr double kTs = 1e-3;

// The real pole at real_pole_rad_s (−20: stable; > 0 an open-loop unstable one);
// radius_scale moves the mode's poles (and a stable real pole) radially.
inline StateSpace plant(double real_pole_rad_s = -20.0, double radius_scale = 1.0) {
  StateSpace s;
  const double w = 60.0, z = 0.05, r = std::exp(-z * w * kTs) * radius_scale, th = w * std::sqrt(1 - z * z) * kTs;
  s.A = Eigen::MatrixXd::Zero(3, 3);
  s.A << r * std::cos(th), -r * std::sin(th), 0, r * std::sin(th), r * std::cos(th), 0, 0, 0,
      std::exp(real_pole_rad_s * kTs) * (real_pole_rad_s < 0 ? radius_scale : 1.0);
  s.B = (Eigen::MatrixXd(3, 1) << 0.02, 0.0, 0.01).finished();
  s.C = (Eigen::MatrixXd(1, 3) << 0.0, 1.0, 1.0).finished();
  s.D = Eigen::MatrixXd::Zero(1, 1);
  s.sample_period_s = kTs;
  return s;
}

// N samples of white u (seed), y from the initial state x0, plus white noise of
// `noise` × y's RMS.
inline void simulate_open_loop(const StateSpace& s, Index N, const Eigen::Vector3d& x0, double noise, unsigned seed,
                               Eigen::MatrixXd& u, Eigen::MatrixXd& y) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  u.resize(N, 1);
  y.resize(N, 1);
  Eigen::Vector3d x = x0;
  for (Index t = 0; t < N; ++t) {
    u(t, 0) = normal(rng);
    y(t, 0) = (s.C * x)(0);
    x = s.A * x + s.B * u(t, 0);
  }
  const double rms = std::sqrt((y.array() - y.mean()).square().mean());
  for (Index t = 0; t < N; ++t) y(t, 0) += noise * rms * normal(rng);
}

// ‖g_a − g_b‖ / ‖g_b‖ over the first 400 Markov parameters (lag 0 left out).
inline double markov_error(const StateSpace& a, const StateSpace& b) {
  const MarkovSequence ga = markov_parameters(a, 400), gb = markov_parameters(b, 400);
  double e = 0, n = 0;
  for (std::size_t k = 1; k < ga.size(); ++k) e += (ga[k] - gb[k]).squaredNorm(), n += gb[k].squaredNorm();
  return std::sqrt(e / n);
}

}  // namespace lpvid::testing::mode_and_pole
