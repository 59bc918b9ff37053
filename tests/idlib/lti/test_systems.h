// Seeded random state-space models for the lti tests.
#pragma once

#include "idlib/core/eigen_decompositions.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <cstdint>
#include <random>

#include "idlib/core/types.h"

namespace lpvid::test_systems {

// A random n-state model with every pole of magnitude <= pole_radius (discrete)
// or real part <= -0.1 (continuous, pole_radius ignored).
inline StateSpace random_system(Index n, Index m, Index p, double sample_period_s, std::uint32_t seed,
                                double pole_radius = 0.9) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  auto rnd = [&](Index r, Index c) {
    Eigen::MatrixXd M(r, c);
    for (Index i = 0; i < r; ++i)
      for (Index j = 0; j < c; ++j) M(i, j) = N(rng);
    return M;
  };
  StateSpace s;
  Eigen::MatrixXd A = rnd(n, n);
  Eigen::EigenSolver<Eigen::MatrixXd> es(A, false);
  const double rho = es.eigenvalues().cwiseAbs().maxCoeff();
  if (sample_period_s > 0.0) {
    s.A = A * (pole_radius / rho);
  } else {
    const double max_re = es.eigenvalues().real().maxCoeff();
    s.A = A - (max_re + 0.1) * Eigen::MatrixXd::Identity(n, n);
  }
  s.B = rnd(n, m);
  s.C = rnd(p, n);
  s.D = rnd(p, m);
  s.sample_period_s = sample_period_s;
  return s;
}

// Direct evaluation C (λI − A)⁻¹ B + D by a dense LU (the reference).
inline Eigen::MatrixXcd direct_response(const StateSpace& s, double omega_rad_s) {
  const Complex lambda = s.is_discrete() ? std::polar(1.0, omega_rad_s * s.sample_period_s) : Complex(0.0, omega_rad_s);
  const Index n = s.order();
  Eigen::MatrixXcd M = lambda * Eigen::MatrixXcd::Identity(n, n) - s.A.cast<Complex>();
  return s.C.cast<Complex>() * M.partialPivLu().solve(s.B.cast<Complex>()) + s.D.cast<Complex>();
}

// max over the grid of ‖H1 − H2‖_F / ‖H2‖_F
inline double max_relative_difference(const std::vector<Eigen::MatrixXcd>& h1, const std::vector<Eigen::MatrixXcd>& h2) {
  double e = 0.0;
  for (size_t k = 0; k < h1.size(); ++k) e = std::max(e, (h1[k] - h2[k]).norm() / h2[k].norm());
  return e;
}

}  // namespace lpvid::test_systems
