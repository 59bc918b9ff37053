// Test-only truth for the local FRF methods (lpm_test.cc, lrm_test.cc): a lightly
// damped discrete second-order system written out here, its transfer function
// evaluated in closed form from its two poles (not by lpvid), and a white-noise record
// through it; and the 3-DOF stage loop (stage_fixture.h) driven by three white
// references, with the 99 % band coverage of a plant estimate against its truth.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/lti/frequency_response.h"
#include "tests/idlib/closedloop/stage_fixture.h"
#include "tests/idlib/signal/multisine.h"  // f2_quantile

namespace lpvid::testing {

inline constexpr double kResonatorTs = 1e-3;

// G(z) = b z⁻¹ / (1 − 2ρ cos θ z⁻¹ + ρ² z⁻²), poles ρ e^{±iθ} of a mode at ω0 with
// damping ζ (ρ = e^{−ζ ω0 Ts}, θ = ω0 Ts sqrt(1 − ζ²)), unit DC gain.
struct Resonator {
  double omega0 = 60.0, zeta = 0.005;
  double rho() const { return std::exp(-zeta * omega0 * kResonatorTs); }
  double theta() const { return omega0 * kResonatorTs * std::sqrt(1 - zeta * zeta); }
  double a1() const { return -2 * rho() * std::cos(theta()); }
  double a2() const { return rho() * rho(); }
  double b() const { return 1 + a1() + a2(); }
  Complex response(double omega) const {
    const Complex zi = std::exp(Complex(0, -omega * kResonatorTs));
    return b() * zi / (1.0 + a1() * zi + a2() * zi * zi);
  }
};

// N samples of white u (after a warm-up, so the record starts and ends mid-response)
// and y = G u + white noise of rms `noise`.
inline void record(const Resonator& g, Index N, double noise, std::uint64_t seed, Eigen::MatrixXd& u,
                   Eigen::MatrixXd& y) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> d(0.0, 1.0);
  const Index warm = 20000;  // 20 s = 6 time constants 1/(ζ ω0) at ζ = 0.005: the state is stationary
  u.resize(N, 1);
  y.resize(N, 1);
  double y1 = 0, y2 = 0, u1 = 0;
  for (Index t = -warm; t < N; ++t) {
    const double ut = d(rng);
    const double yt = g.b() * u1 - g.a1() * y1 - g.a2() * y2;
    if (t >= 0) {
      u(t, 0) = ut;
      y(t, 0) = yt + noise * d(rng);
    }
    y2 = y1;
    y1 = yt;
    u1 = ut;
  }
}

inline double median(std::vector<double> x) {
  std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2), x.end());
  return x[x.size() / 2];
}

// The stage loop with three simultaneous white references v (rms 1, 1, 100) and sensor
// noise (rms 1e-3, 1e-3, 1e-4) on q, N samples: v (N × 3) and z = [q u] (N × 6).
inline void stage_loop_record(Index N, double sample_period_s, std::uint64_t seed, Eigen::MatrixXd& v,
                              Eigen::MatrixXd& z) {
  const StateSpace P = stage_fixture::discrete_plant(sample_period_s),
                   C = stage_fixture::pi_controller(sample_period_s);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> d(0.0, 1.0);
  const Eigen::Vector3d v_rms(1.0, 1.0, 100.0), n_rms(1e-3, 1e-3, 1e-4);
  v.resize(N, 3);
  z.resize(N, 6);
  Eigen::VectorXd xp = Eigen::VectorXd::Zero(6), xc = Eigen::VectorXd::Zero(3);
  for (Index t = 0; t < N; ++t) {
    Eigen::Vector3d qm = P.C * xp;
    for (int c = 0; c < 3; ++c) {
      qm(c) += n_rms(c) * d(rng);
      v(t, c) = v_rms(c) * d(rng);
    }
    const Eigen::Vector3d e = -qm, u = C.C * xc + C.D * e + v.row(t).transpose();
    z.row(t) << qm.transpose(), u.transpose();
    xp = P.A * xp + P.B * u;
    xc = C.A * xc + C.B * e;
  }
}

// Share of the 3 × 3 entries at 5–300 rad/s with |P̂ − P|² inside the 99 % band of
// F(2, 2q) times their own variance; P = the fixture's plant (idlib/lti).
inline double stage_plant_coverage(const FrequencyResponse& frd, Index dof, double sample_period_s) {
  const auto truth = evaluate_response(stage_fixture::discrete_plant(sample_period_s), frd.omega_rad_s);
  const double band = f2_quantile(0.99, 2.0 * static_cast<double>(dof));
  double inside = 0;
  Index count = 0;
  for (Index f = 0; f < frd.num_frequencies(); ++f) {
    const double w = frd.omega_rad_s(f);
    if (w < 5 || w > 300) continue;
    for (Index i = 0; i < 3; ++i)
      for (Index j = 0; j < 3; ++j) {
        const double e2 = std::norm(frd.response[static_cast<size_t>(f)](i, j) - truth[static_cast<size_t>(f)](i, j));
        inside += e2 <= band * frd.variance[static_cast<size_t>(f)](i, j) ? 1 : 0;
        ++count;
      }
  }
  return inside / static_cast<double>(count);
}

}  // namespace lpvid::testing
