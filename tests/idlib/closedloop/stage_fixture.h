// The 3-DOF test stage of the unloop tests: a coupled mass-spring-damper plant
// (tilt ψ, tilt θ, height z) under a discrete PI controller per axis.
//
// Assumed values (test-only; chosen so modes sit at a few to tens of rad/s and
// the slowest plant pole is near −2 rad/s):
//   inertia  0.1, 0.1 kg·m², mass 7 kg
//   stiffness diag(4 N·m/rad, 2.5 N·m/rad, 700 N/m) with small symmetric coupling
//   damping  1.5 N·m·s/rad, 0.3 N·m·s/rad, 350 N·s/m
//   → poles ≈ −3.4, −11.6; −1.5 ± 4.8j; −2.09, −47.9 rad/s
//   PI: Kp = (40, 40, 2800), Ki = (200, 50, 5000) 1/s; d(k+Kp) > m Ki per axis.
#pragma once

#include <random>

#include <Eigen/Dense>

#include "idlib/core/types.h"
#include "idlib/lti/discretize.h"

namespace lpvid::stage_fixture {

inline StateSpace continuous_plant() {
  const Eigen::Vector3d mass(0.1, 0.1, 7.0);
  Eigen::Matrix3d K;
  K << 4.0, 0.3, 0.5, 0.3, 2.5, 0.2, 0.5, 0.2, 700.0;
  const Eigen::Matrix3d Dm = Eigen::Vector3d(1.5, 0.3, 350.0).asDiagonal();
  const Eigen::Matrix3d Minv = mass.cwiseInverse().asDiagonal();
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(6, 6);
  s.A.topRightCorner(3, 3).setIdentity();
  s.A.bottomLeftCorner(3, 3) = -Minv * K;
  s.A.bottomRightCorner(3, 3) = -Minv * Dm;
  s.B = Eigen::MatrixXd::Zero(6, 3);
  s.B.bottomRows(3) = Minv;
  s.C = Eigen::MatrixXd::Zero(3, 6);
  s.C.leftCols(3).setIdentity();
  s.D = Eigen::MatrixXd::Zero(3, 3);
  s.input_names = {"T_psi", "T_theta", "F_z"};
  s.output_names = {"psi", "theta", "z"};
  return s;
}

// u_c[k] = Kp e[k] + Ki Ts Σ_{i<=k} e[i]:  x[k+1] = x[k] + Ts e[k],
// u_c = Ki x[k] + (Kp + Ki Ts) e[k].  Poles at z = 1, direct feedthrough.
inline StateSpace pi_controller(double sample_period_s) {
  const Eigen::Vector3d kp(40.0, 40.0, 2800.0), ki(200.0, 50.0, 5000.0);
  StateSpace c;
  c.A = Eigen::MatrixXd::Identity(3, 3);
  c.B = sample_period_s * Eigen::MatrixXd::Identity(3, 3);
  c.C = ki.asDiagonal();
  c.D = (kp + ki * sample_period_s).asDiagonal();
  c.sample_period_s = sample_period_s;
  return c;
}

inline StateSpace discrete_plant(double sample_period_s) { return discretize_zoh(continuous_plant(), sample_period_s); }


// The closed loop with relative Gaussian noise on A - I, B and C (seeded): a
// stand-in for an identified loop (1e-4 moves G's response by ~3e-4).
inline StateSpace perturbed(const StateSpace& G, double relative, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  StateSpace g = G;
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(G.order(), G.order());
  Eigen::MatrixXd dA = G.A - I;
  for (Index i = 0; i < dA.size(); ++i) dA(i) *= 1.0 + relative * N(rng);
  g.A = I + dA;
  for (Index i = 0; i < g.B.size(); ++i) g.B(i) *= 1.0 + relative * N(rng);
  for (Index i = 0; i < g.C.size(); ++i) g.C(i) *= 1.0 + relative * N(rng);
  return g;
}

}  // namespace lpvid::stage_fixture
