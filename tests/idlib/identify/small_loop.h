// Small closed loops with responses known in closed form, for the unit tests of
// plant_fit.h and response_tail.h (no identification code: plant, controller and
// truth are written out here).
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "idlib/core/types.h"

namespace lpvid::testing {

constexpr double kSmallLoopTs_s = 1e-3;

// SISO: plant q(t+1) = a q(t) + b u(t) (one state, C = 1), controller the static gain
// u_c = k e (e = −q) carried by a state that nothing excites (A_K = 0.5, B_K = 0,
// C_K = 0): the closed loop is x(t+1) = λ x(t) + b v(t), λ = a − b k, so its impulse
// response is g[j] = b λ^(j−1) for j ≥ 1 and g[0] = 0.
struct FirstOrderLoop {
  double a = 0.99, b = 0.5, k = 0.04;
  double lambda() const { return a - b * k; }
  StateSpace plant() const {
    StateSpace s;
    s.A = Eigen::MatrixXd::Constant(1, 1, a);
    s.B = Eigen::MatrixXd::Constant(1, 1, b);
    s.C = Eigen::MatrixXd::Ones(1, 1);
    s.D = Eigen::MatrixXd::Zero(1, 1);
    s.sample_period_s = kSmallLoopTs_s;
    return s;
  }
  StateSpace controller() const {
    StateSpace s;
    s.A = Eigen::MatrixXd::Constant(1, 1, 0.5);
    s.B = Eigen::MatrixXd::Zero(1, 1);
    s.C = Eigen::MatrixXd::Zero(1, 1);
    s.D = Eigen::MatrixXd::Constant(1, 1, k);
    s.sample_period_s = kSmallLoopTs_s;
    return s;
  }
};

// 2 × 2 plant of order 4: two lightly damped modes (pole radius 0.995 at 0.05 and 0.12
// rad/sample), coupled through B and C, and a PI controller per channel (integrator
// states, A_K = I).  Small gains: the loop is stable (checked by the tests).
inline StateSpace coupled_plant() {
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(4, 4);
  const double r = 0.995;
  const double w[2] = {0.05, 0.12};
  for (int i = 0; i < 2; ++i) {
    s.A(2 * i, 2 * i) = r * std::cos(w[i]);
    s.A(2 * i, 2 * i + 1) = -r * std::sin(w[i]);
    s.A(2 * i + 1, 2 * i) = r * std::sin(w[i]);
    s.A(2 * i + 1, 2 * i + 1) = r * std::cos(w[i]);
  }
  s.B.resize(4, 2);
  s.B << 0.010, 0.002, -0.004, 0.001, 0.003, 0.012, 0.001, -0.005;
  s.C.resize(2, 4);
  s.C << 1.0, 0.3, 0.2, -0.1, -0.2, 0.1, 0.9, 0.4;
  s.D = Eigen::MatrixXd::Zero(2, 2);
  s.sample_period_s = kSmallLoopTs_s;
  return s;
}

inline StateSpace pi_controller_2x2() {
  StateSpace s;
  s.A = Eigen::MatrixXd::Identity(2, 2);
  s.B = 0.002 * Eigen::MatrixXd::Identity(2, 2);
  s.C = Eigen::MatrixXd::Identity(2, 2);
  s.D = 0.05 * Eigen::MatrixXd::Identity(2, 2);
  s.sample_period_s = kSmallLoopTs_s;
  return s;
}

}  // namespace lpvid::testing
