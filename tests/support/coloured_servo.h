// A 2 x 2 servo mechanism driven by strongly coloured inputs, the case of issue 24's
// held-out "precision servo" row: three lightly damped modes (5, 40 and 120 Hz at 1 kHz),
// each input white noise through two cascaded second-order Butterworth low-passes (a
// fourth-order roll-off: at the 120 Hz mode the input has (fc / 120)^8 of its power, so a
// least-squares FIR estimate is ill-posed there), and white output noise of a given
// fraction of each output's RMS.  Written here from the modes' poles (exact discrete
// rotations), not from lpvid's code: the truth for the Markov parameters is C A^(k−1) B.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <random>

#include "idlib/core/types.h"

namespace lpvid::testing {

struct ColouredServo {
  StateSpace plant;              // discrete, Ts = 1 ms, 2 inputs, 2 outputs, order 6
  Eigen::MatrixXd u, y, y_clean;  // N x 2 each: inputs, noisy and noise-free outputs
};

inline Eigen::VectorXd butterworth_lowpass_twice(const Eigen::VectorXd& x, double fc_hz, double fs_hz) {
  const double k = std::tan(std::numbers::pi * fc_hz / fs_hz), q = std::numbers::sqrt2 / 2.0;
  const double norm = 1.0 / (1.0 + k / q + k * k);
  const double b0 = k * k * norm, b1 = 2.0 * b0, b2 = b0, a1 = 2.0 * (k * k - 1.0) * norm,
               a2 = (1.0 - k / q + k * k) * norm;
  Eigen::VectorXd y = x;
  for (int pass = 0; pass < 2; ++pass) {
    double x1 = 0, x2 = 0, y1 = 0, y2 = 0;
    for (Index t = 0; t < y.size(); ++t) {
      const double xi = y(t), yi = b0 * xi + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
      x2 = x1;
      x1 = xi;
      y2 = y1;
      y1 = yi;
      y(t) = yi;
    }
  }
  return y;
}

// pole_radius > 0: every mode's pole radius set to it instead of its damping's (a response
// that dies out within a known number of lags, e.g. 0.95: 1e-12 after 540 lags).
inline ColouredServo make_coloured_servo(std::uint64_t seed, Index samples, double cutoff_hz, double noise_fraction,
                                         double pole_radius = 0.0) {
  constexpr double kFs = 1000.0;
  const double modes[3][2] = {{5.0, 0.05}, {40.0, 0.02}, {120.0, 0.03}};  // Hz, damping ratio
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  ColouredServo s;
  StateSpace& p = s.plant;
  p.A = Eigen::MatrixXd::Zero(6, 6);
  for (int i = 0; i < 3; ++i) {
    const double w = 2.0 * std::numbers::pi * modes[i][0], z = modes[i][1];
    const double r = pole_radius > 0.0 ? pole_radius : std::exp(-z * w / kFs), th = w * std::sqrt(1.0 - z * z) / kFs;
    p.A.block(2 * i, 2 * i, 2, 2) << r * std::cos(th), -r * std::sin(th), r * std::sin(th), r * std::cos(th);
  }
  p.B.resize(6, 2);
  p.C.resize(2, 6);
  for (Index i = 0; i < 6; ++i)
    for (Index j = 0; j < 2; ++j) p.B(i, j) = 0.05 * n01(rng);
  for (Index i = 0; i < 2; ++i)
    for (Index j = 0; j < 6; ++j) p.C(i, j) = n01(rng);
  p.D = Eigen::MatrixXd::Zero(2, 2);
  p.sample_period_s = 1.0 / kFs;
  p.input_names = {"u1", "u2"};
  p.output_names = {"y1", "y2"};
  s.u.resize(samples, 2);
  for (Index j = 0; j < 2; ++j) {
    Eigen::VectorXd w(samples);
    for (Index t = 0; t < samples; ++t) w(t) = n01(rng);
    s.u.col(j) = butterworth_lowpass_twice(w, cutoff_hz, kFs);
  }
  s.y_clean.resize(samples, 2);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(6);
  for (Index t = 0; t < samples; ++t) {
    s.y_clean.row(t) = (p.C * x).transpose();
    x = p.A * x + p.B * s.u.row(t).transpose();
  }
  s.y = s.y_clean;
  for (Index i = 0; i < 2; ++i) {
    const double rms = std::sqrt(s.y_clean.col(i).squaredNorm() / static_cast<double>(samples));
    for (Index t = 0; t < samples; ++t) s.y(t, i) += noise_fraction * rms * n01(rng);
  }
  return s;
}

}  // namespace lpvid::testing
