// lpvid — evaluating a physical model at a beam position x_b: continuous state
// space, ZOH-discretised state space and frequency response (docs/effects.md,
// docs/math.md "Physical model").
//
// States, inputs and outputs (every effect in the model adds its block):
//
// | block            | states                 | when                 |
// |------------------|------------------------|----------------------|
// | rigid body       | psi theta z psi' theta' z' | always (eqs 7–8) |
// | structural mode  | eta eta'               | structural_mode      |
// | actuator lag     | three lagged wrenches  | actuator_lag         |
// inputs u = tau = [T_psi T_theta F_z] (N·m, N·m, N), outputs q = [psi theta z].
//
//   rigid:  M(x_b) q'' + D q' + K q = g ∘ w       (w the plant input wrench)
//   mode:   eta'' + 2 zeta w_m eta' + w_m² eta = phiᵀ (g ∘ w),   q += phi eta
//   lag:    tau_a w' = u_delayed - w   (without actuator_lag: w = u_delayed)
//   delay:  u_delayed(t) = u(t - tau)  -> response factor exp(-j omega tau)
// g = (gain_psi, gain_theta, gain_z) with gain_error, else 1.
//
// The matrices are built by templates on the scalar type (double, or
// ceres::Jet in idlib/fit for exact derivatives).  The parameter vector is the
// model's full list (PhysicalModel::parameters order); ModelLayout maps names
// to positions once.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

// The double value of a scalar; idlib/fit specialises it for ceres::Jet.
template <class T>
struct ScalarValue {
  static double of(const T& x) { return static_cast<double>(x); }
};

template <class T>
using MatrixT = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

// Positions of the parameters in the model's list; -1 for an effect that is off.
struct ModelLayout {
  Index J_psi = -1, J_theta = -1, m_p = -1, m_b = -1, z_b = -1, stroke = -1, r_vc = -1, d = -1, k_lin = -1,
        k_low = -1;
  Index rod[3] = {-1, -1, -1};
  Index k_high = -1, com_x = -1, com_y = -1, J_pt = -1, g = -1;
  Index mode_w = -1, mode_zeta = -1, phi[3] = {-1, -1, -1};
  Index delay = -1, lag = -1, gain[3] = {-1, -1, -1};

  // @throws InputError  model invalid (PhysicalModel::validate).
  explicit ModelLayout(const PhysicalModel& model);

  Index rigid_states() const { return 6; }
  Index mode_states() const { return mode_w >= 0 ? 2 : 0; }
  Index lag_states() const { return lag >= 0 ? 3 : 0; }
  Index order() const { return rigid_states() + mode_states() + lag_states(); }
};

// Continuous (A, B, C, D) of the model at x_b for the parameter values p (full
// list).  Returns false when M(x_b) is not positive definite (no model).
// Shapes: A n×n, B n×3, C 3×n, D 3×3 (n = layout.order()).
template <class T>
bool build_continuous(const ModelLayout& L, const T* p, double x_b, MatrixT<T>& A, MatrixT<T>& B, MatrixT<T>& C,
                      MatrixT<T>& D) {
  using std::cos;
  using std::sin;
  const T zero(0.0);
  auto get = [&](Index i, double fallback) { return i >= 0 ? p[i] : T(fallback); };
  const T mp = p[L.m_p], mb = p[L.m_b], zb = p[L.z_b];
  const T cx = get(L.com_x, 0.0), cy = get(L.com_y, 0.0), Jpt = get(L.J_pt, 0.0);
  T M[3][3];
  M[0][0] = p[L.J_psi] + mb * zb * zb;
  M[1][1] = p[L.J_theta] + mb * (zb * zb + x_b * x_b);
  M[2][2] = mp + mb;
  M[0][1] = M[1][0] = Jpt;
  M[0][2] = M[2][0] = mp * cy;
  M[1][2] = M[2][1] = mb * x_b + mp * cx;
  // Positive definiteness by leading minors (Sylvester).
  const T minor2 = M[0][0] * M[1][1] - M[0][1] * M[0][1];
  const T det = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[1][2]) - M[0][1] * (M[0][1] * M[2][2] - M[1][2] * M[0][2]) +
                M[0][2] * (M[0][1] * M[1][2] - M[1][1] * M[0][2]);
  if (!(ScalarValue<T>::of(M[0][0]) > 0.0) || !(ScalarValue<T>::of(minor2) > 0.0) || !(ScalarValue<T>::of(det) > 0.0))
    return false;
  // Inverse by the adjugate (symmetric).
  T Mi[3][3];
  Mi[0][0] = (M[1][1] * M[2][2] - M[1][2] * M[1][2]) / det;
  Mi[0][1] = Mi[1][0] = (M[0][2] * M[1][2] - M[0][1] * M[2][2]) / det;
  Mi[0][2] = Mi[2][0] = (M[0][1] * M[1][2] - M[0][2] * M[1][1]) / det;
  Mi[1][1] = (M[0][0] * M[2][2] - M[0][2] * M[0][2]) / det;
  Mi[1][2] = Mi[2][1] = (M[0][1] * M[0][2] - M[0][0] * M[1][2]) / det;
  Mi[2][2] = minor2 / det;

  // Stiffness (eq 4 with the rod geometry of idlib/models/platform.h).
  T K[3][3];
  for (auto& row : K)
    for (auto& x : row) x = zero;
  const T k_high = get(L.k_high, 0.0), k_low = p[L.k_low];
  for (int j = 0; j < 3; ++j) {
    const T phi = p[L.rod[j]];
    const T s0 = cos(phi), s1 = -sin(phi);  // twist axis a_j in (psi, theta) coordinates
    const T t0 = -sin(phi), t1 = -cos(phi);  // bend axis b_j
    K[0][0] += k_high * s0 * s0 + k_low * t0 * t0;
    K[0][1] += k_high * s0 * s1 + k_low * t0 * t1;
    K[1][1] += k_high * s1 * s1 + k_low * t1 * t1;
  }
  K[1][0] = K[0][1];
  const T gravity = L.g >= 0 ? -zb * mb * p[L.g] : zero;
  K[0][0] += gravity;
  K[1][1] += gravity;
  K[2][2] = p[L.k_lin];
  // Damping (eq 5).
  const T d = p[L.d], r = p[L.r_vc];
  const T Dd[3] = {T(6.0) * r * r * d, T(6.0) * r * r * d, T(9.0) * d};

  const Index n = L.order(), np = L.rigid_states() + L.mode_states();
  A = MatrixT<T>::Constant(n, n, zero);
  B = MatrixT<T>::Constant(n, 3, zero);
  C = MatrixT<T>::Constant(3, n, zero);
  D = MatrixT<T>::Constant(3, 3, zero);
  for (int i = 0; i < 3; ++i) {
    A(i, 3 + i) = T(1.0);
    C(i, i) = T(1.0);
    for (int j = 0; j < 3; ++j) {
      T mk = zero;
      for (int l = 0; l < 3; ++l) mk += Mi[i][l] * K[l][j];
      A(3 + i, j) = -mk;
      A(3 + i, 3 + j) = -Mi[i][j] * Dd[j];
    }
  }
  // Plant input map (rigid + mode) with the actuator gains.
  MatrixT<T> Bp = MatrixT<T>::Constant(np, 3, zero);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Bp(3 + i, j) = Mi[i][j];
  if (L.mode_w >= 0) {
    const T w = p[L.mode_w], zeta = p[L.mode_zeta];
    A(6, 7) = T(1.0);
    A(7, 6) = -w * w;
    A(7, 7) = T(-2.0) * zeta * w;
    for (int j = 0; j < 3; ++j) {
      Bp(7, j) = p[L.phi[j]];
      C(j, 6) = p[L.phi[j]];
    }
  }
  for (int j = 0; j < 3; ++j) {
    const T gj = get(L.gain[j], 1.0);
    for (Index i = 0; i < np; ++i) Bp(i, j) *= gj;
  }
  if (L.lag >= 0) {
    const T inv_tau = T(1.0) / p[L.lag];
    A.block(0, np, np, 3) = Bp;
    for (int j = 0; j < 3; ++j) {
      A(np + j, np + j) = -inv_tau;
      B(np + j, j) = inv_tau;
    }
  } else {
    B.topRows(np) = Bp;
  }
  return true;
}

// e^X by scaling and squaring with a degree-14 Taylor polynomial: X is scaled by
// 2^-s so that its 1-norm is <= 0.5, where the truncation error is below
// 0.5^15/15! ≈ 2e-17 relative (Moler & Van Loan, "Nineteen dubious ways",
// method 3).  Works for Jets (derivatives are exact derivatives of the
// approximation).
template <class T>
MatrixT<T> expm_taylor(const MatrixT<T>& X) {
  const Index n = X.rows();
  double norm = 0.0;
  for (Index j = 0; j < n; ++j) {
    double col = 0.0;
    for (Index i = 0; i < n; ++i) col += std::abs(ScalarValue<T>::of(X(i, j)));
    norm = std::max(norm, col);
  }
  int s = 0;
  while (norm > 0.5) {
    norm *= 0.5;
    ++s;
  }
  const MatrixT<T> Y = X * T(std::ldexp(1.0, -s));
  const MatrixT<T> I = MatrixT<T>::Identity(n, n);
  MatrixT<T> E = I;
  constexpr int kTaylorDegree = 14;
  for (int k = kTaylorDegree; k >= 1; --k) E = I + (Y * E) * T(1.0 / k);
  for (int k = 0; k < s; ++k) E = E * E;
  return E;
}

// ZOH: exp([[A B]; [0 0]] Ts) = [[Ad Bd]; [0 I]].
template <class T>
void zoh_discretize(const MatrixT<T>& A, const MatrixT<T>& B, double sample_period_s, MatrixT<T>& Ad, MatrixT<T>& Bd) {
  const Index n = A.rows(), m = B.cols();
  MatrixT<T> Z = MatrixT<T>::Constant(n + m, n + m, T(0.0));
  Z.topLeftCorner(n, n) = A * T(sample_period_s);
  Z.topRightCorner(n, m) = B * T(sample_period_s);
  const MatrixT<T> E = expm_taylor<T>(Z);
  Ad = E.topLeftCorner(n, n);
  Bd = E.topRightCorner(n, m);
}

// The model at one x_b: continuous or discrete state space and the input delay.
struct PhysicalStateSpace {
  StateSpace system;         // inputs T_psi T_theta F_z, outputs psi theta z
  double input_delay_s = 0;  // to apply on top of system (0 without input_delay)
  Index delay_samples = 0;   // discrete only: round(input_delay_s / Ts), already inside system
};

// Continuous (sample_period_s == 0) or ZOH-discretised model at x_b.  In
// discrete time the delay is rounded to whole samples and realised as 3·d extra
// states (a shift register per input) at the end of the state vector, so that
// system alone simulates it; in continuous time it is returned in
// input_delay_s and not in system.
// @throws InputError  model invalid; |x_b| > beam_stroke_m or not finite;
//   sample_period_s < 0 or not finite; M(x_b) not positive definite.
PhysicalStateSpace physical_state_space(const PhysicalModel& model, double beam_position_m,
                                        double sample_period_s = 0.0);

// Frequency response P at omega_rad_s (layout of idlib/core/types.h):
//   continuous: P(jω) = (C (jωI − A)⁻¹ B + D) e^{−jωτ}
//   discrete:   P(e^{jωTs}) = (C (e^{jωTs}I − Ad)⁻¹ Bd + D) e^{−jωτ}
// with the exact delay factor e^{−jωτ} (not rounded) in both cases; the ZOH
// response is exact for τ a whole number of samples.
// @throws InputError  as physical_state_space; an ω not finite.
std::vector<Eigen::MatrixXcd> physical_response(const PhysicalModel& model, double beam_position_m,
                                                const Eigen::VectorXd& omega_rad_s, double sample_period_s = 0.0);

// @throws InputError  |x_b| > beam_stroke_m of model, or not finite.
void check_beam_position(const PhysicalModel& model, double beam_position_m);

}  // namespace lpvid
