// Poles, stability and Markov parameters of a state-space model.
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid {

// Default stability margin of is_stable.  Eigenvalues from a backward-stable
// eigensolver are accurate to about ε‖A‖ ≈ 1e-16‖A‖ for simple ones; 1e-10
// keeps a pole that rounding could move across the boundary from counting as
// stable, while any physical pole (|z| ≤ 1 − 1e-7 for a −1e-3 rad/s pole at
// 10 kHz) is unaffected.
inline constexpr double kDefaultStabilityMargin = 1e-10;

// The eigenvalues of A (n of them, in no particular order): s-plane poles for a
// continuous model, z-plane poles for a discrete one.
// @throws InputError  sys invalid.
Eigen::VectorXcd poles(const StateSpace& sys);

// Asymptotic stability with a margin:
//   discrete:    max |z_i| < 1 − margin
//   continuous:  max Re(s_i) / max(1, |s_i|) < −margin   (relative for fast poles)
// An order-0 model is stable.
// @throws InputError  sys invalid; margin negative or non-finite.
bool is_stable(const StateSpace& sys, double margin = kDefaultStabilityMargin);

// Markov parameters (impulse response) of a discrete model:
//   g[0] = D,  g[k] = C A^{k−1} B  (k = 1..last_lag);  returns last_lag + 1 matrices p x m.
// @throws InputError  sys invalid or continuous; last_lag < 0.
MarkovSequence markov_parameters(const StateSpace& discrete, Index last_lag);

// The response of a discrete model from zero state to an input sequence (MATLAB lsim):
//   x[0] = 0,  y[k] = C x[k] + D u[k],  x[k+1] = A x[k] + B u[k].
// | u: N × m | result: N × p |.  O(N (n² + n m + p n)).  An unstable model's response
// grows without bound and may overflow to Inf: the caller checks.
// @throws InputError  sys invalid or continuous; u's columns differ from its inputs.
Eigen::MatrixXd simulate_discrete(const StateSpace& discrete, const Eigen::Ref<const Eigen::MatrixXd>& u);

}  // namespace lpvid
