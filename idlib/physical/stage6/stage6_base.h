// lpvid — the base "stage6": the 6-DOF magnetically levitated stage of seed 001
// (Nam et al.) linearised about hover, as a physical model of the same framework as
// the platform (idlib/physical/physical_model.h; docs/effects.md, "Base: stage6").
//
// Coordinates as in idlib/plants/stage6/stage6.h: q = [x y z psi theta phi] (m, m, m, rad,
// rad, rad; Z-Y-X Euler angles: yaw psi about z, pitch theta about y, roll phi about
// x), inputs the commanded body wrench that the controller hands to the
// allocation f = A(r)⁺ w of eqs 27–30 (r the DESIGNED lever arms of the four
// magnet arrays), outputs q.  The inputs are in the order of the generalised
// forces, [F_x F_y F_z tau_z tau_y tau_x] (N, N·m), so that input k drives output k
// (a square response's diagonal is its direct channels; the fit's channel scale
// sqrt(|P_ii| |P_jj|) relies on it).  A log in wrench order (u1..u6 = F_x F_y F_z
// tau_x tau_y tau_z, as `simulate stage6` writes) is read in this order by naming
// its columns u1,u2,u3,u6,u5,u4 (docs/effects.md, "Base: stage6").  The scheduling
// variable is the hover height z_0 above the reference gap (m; 0 = hovering at the
// reference gap z_ref, where the force constant is the nominal one).
//
// Linearised about q_0 = (0, 0, z_0, psi_0, theta_0, phi_0), q' = 0, the attitude
// being the base's hover_*_rad parameters (the sliding-mode law, without integral
// action, holds the stage ~1 mrad off level; the lift then leaks into x and y):
//
//   M q'' + K q = B_w w_l,        w_l = the wrench after the input blocks,
//
// | term | value (+ the physics effects of this base) |
// |------|---------------------------------------------|
// | M    | blockdiag(m I₃, W₀ᵀ H W₀), H = diag(I_xx, I_yy, I_zz), omega = W₀ [psi' theta' phi'] (eqs 4–5 at the attitude; at zero angles diag(I_zz, I_yy, I_xx)) |
// | B_w  | G₀ T₀ with its columns in generalised order, G₀ = blockdiag(R₀, W₀ᵀ) (eq 8's u = G w), T₀ = kappa A(r − c) diag(alpha) A(r)⁺: the true wrench of the allocated commands (eqs 27–30) |
// | K    | the tilt of the lift, −∂(R F_b0)/∂(psi, theta, phi) with F_b0 = R₀ᵀ (0, 0, m g) (at zero angles K_x,theta = −m g, K_y,phi = +m g); gap_dependence: + G₀ kappa gamma A(r − c) diag(alpha ⊙ f₀) J, f₀ = A(r)⁺ T₀⁻¹ (F_b0; 0) the hover forces, J_k = ∂gap/∂q of the array that exerts force k = [0 0 1, (∂R/∂(psi, theta, phi) r)_z] |
// | feedback | electrical_lag: the back-EMF of eq 25, −b alpha v_k per force channel (v_k the velocity of the array that exerts force k along that force, in the motor's own (body) axes: the centre of mass's R₀ᵀ p' plus omega × (r_i − c), so v = A(r − c)ᵀ G₀ᵀ q' — the rotation terms damp the tilts by ~4 b r²), fed into the current loop: the input chain sees w − F q' with F = T₀⁻¹ kappa A(r − c) diag(alpha²) b A(r − c)ᵀ G₀ᵀ (rows in generalised order) |
// | output | the sensors look at the reference point, which the designed arms r are measured from: y = (p − R c, angles), linearised C_q = [I, −(dR/d(psi, theta, phi)) c; 0, I] (com_offset; identity without it), applied to every body output (modes included) |
//
// q is the configuration of the centre of mass; the hover height z_0 and the gaps
// are the reference point's (gap_k − z_ref = z_0 + ((R₀ − I) r_i)_z with the
// designed arm of the array of force k).
// with c the centre-of-mass offset (com_offset), alpha_k = exp(−gamma (gap_k − z_ref))
// the gap factor of the array of force k at the operating point (gap_dependence;
// else 1), kappa the force-constant scale.  The equations are homogeneous in
// (m, H, kappa) except through gravity, whose terms (tilt of the lift, gap
// stiffness) are themselves ∝ m: a response determines H/m and kappa/m only, so the
// mass is held (weighed) and kappa fitted by default.  Checked against a numerical
// linearisation of the nonlinear stage (tests/idlib/physical/stage6_base_test.cc).
//
// The matrices are built by a template on the scalar type (double, or ceres::Jet in
// idlib/fit for exact derivatives).  The allocation A(r)⁺ is the controller's (its
// designed geometry): it is computed once from the lever-arm parameters' values.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "idlib/core/types.h"
#include "idlib/physical/gauss_jordan.h"
#include "idlib/physical/physical_model.h"
#include "idlib/plants/stage6/kinematics.h"

namespace lpvid {

// The stage's BaseInfo (defaults from seed 001 / docs/assumptions.md).
BaseInfo make_stage6_base();

// Positions of the stage's parameters in a model's list (-1: effect off), and the
// controller's allocation from the lever arms' values.
struct Stage6Indices {
  Index mass = -1, I_xx = -1, I_yy = -1, I_zz = -1, kappa = -1, g = -1;
  Index arm[4][3] = {{-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}, {-1, -1, -1}};
  Index com[3] = {-1, -1, -1};  // com_offset
  Index gamma = -1;             // gap_dependence
  Index back_emf = -1;          // electrical_lag (its time constant is an input block)
  Index attitude[3] = {-1, -1, -1};  // hover_yaw_rad, hover_pitch_rad, hover_roll_rad
  Eigen::Matrix<double, 8, 6> allocation_pinv;  // A(r)⁺ of the designed arms
  explicit Stage6Indices(const PhysicalModel& model);
};

namespace stage6_detail {

template <class T>
using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;

}  // namespace stage6_detail

// M, D (zero), K (6×6), B_w (6×6), the back-EMF feedback F (6×6; zero without
// electrical_lag) and the output map C_q (6×6; identity without com_offset) about hover at the height z0 (m above the reference gap) and the
// attitude (psi0, theta0, phi0) of the base's hover_* parameters.  Returns false
// when T₀ = kappa A(r − c) diag(alpha) A(r)⁺ cannot be inverted (a centre-of-mass
// offset as large as the platen).  `value` gives the double value of a scalar.
template <class T>
bool stage6_matrices(const Stage6Indices& L, const T* p, double z0, double (*value)(const T&),
                     stage6_detail::Mat<T>& M, stage6_detail::Mat<T>& D, stage6_detail::Mat<T>& K,
                     stage6_detail::Mat<T>& Bw, stage6_detail::Mat<T>& F, stage6_detail::Mat<T>& Cq) {
  using Mat = stage6_detail::Mat<T>;
  using std::exp;
  const T zero(0.0), one(1.0);
  const T m = p[L.mass], kappa = p[L.kappa], g = p[L.g];
  const T psi0 = p[L.attitude[0]], theta0 = p[L.attitude[1]], phi0 = p[L.attitude[2]];
  M = Mat::Constant(6, 6, zero);
  D = Mat::Constant(6, 6, zero);
  K = Mat::Constant(6, 6, zero);
  F = Mat::Constant(6, 6, zero);
  Cq = Mat::Identity(6, 6);
  // Kinematics at the hover attitude (idlib/plants/stage6/kinematics.h): R₀ and
  // dR₀/d(psi, theta, phi); W₀ (eq 4, columns in q's order [psi' theta' phi']):
  // omega = W₀ [psi' theta' phi'].
  const Mat R0 = stage6::rotation_zyx<T>(psi0, theta0, phi0);
  const auto dR0 = stage6::rotation_zyx_derivatives<T>(psi0, theta0, phi0);
  const Mat dR[3] = {dR0[0], dR0[1], dR0[2]};
  const Mat W0 = stage6::angular_velocity_map<T>(theta0, phi0);
  Mat H = Mat::Constant(3, 3, zero);
  H(0, 0) = p[L.I_xx];
  H(1, 1) = p[L.I_yy];
  H(2, 2) = p[L.I_zz];
  for (int i = 0; i < 3; ++i) M(i, i) = m;
  M.bottomRightCorner(3, 3) = W0.transpose() * H * W0;
  // G₀: body wrench (wrench order) → generalised force.
  Mat G0 = Mat::Constant(6, 6, zero);
  G0.topLeftCorner(3, 3) = R0;
  G0.bottomRightCorner(3, 3) = W0.transpose();
  // True lever arms r − c and the true allocation A(r − c) (6×8; columns: the
  // horizontal then vertical force of motors 1..4; horizontal is x for motors 1, 3
  // and y for 2, 4).
  T r[4][3];
  Eigen::Matrix<T, 3, 4> true_arms;
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a)
      true_arms(a, i) = r[i][a] = p[L.arm[i][a]] - (L.com[a] >= 0 ? p[L.com[a]] : zero);
  const Mat At = stage6::allocation_matrix<T>(true_arms);
  // Each array's gap above the reference at hover, gap_i − z_ref = z0 + ((R₀ − I) r_i)_z
  // (the reference point's height z0, the designed arm r_i), and, the centre of
  // mass being at the reference point plus R c, ∂gap_i/∂q = [0 0 1, (dR/d(psi,
  // theta, phi) (r_i − c))_z] (J, one row per force).
  Mat alpha = Mat::Constant(8, 1, one), J = Mat::Constant(8, 6, zero);
  for (int i = 0; i < 4; ++i) {
    T height = T(z0) - p[L.arm[i][2]];
    for (int a = 0; a < 3; ++a) height += R0(2, a) * p[L.arm[i][a]];
    T dgap[3] = {zero, zero, zero};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) dgap[k] += dR[k](2, a) * r[i][a];
    for (int c : {2 * i, 2 * i + 1}) {
      if (L.gamma >= 0) alpha(c, 0) = exp(-p[L.gamma] * height);
      J(c, 2) = one;
      for (int k = 0; k < 3; ++k) J(c, 3 + k) = dgap[k];
    }
  }
  Mat scaled = At;  // A(r − c) diag(alpha)
  for (Index k = 0; k < 8; ++k) scaled.col(k) *= alpha(k, 0);
  const Mat T0 = scaled * L.allocation_pinv.cast<T>() * kappa;  // wrench order
  Mat T0inv;
  double scale = 0.0;  // pivots below 1e-9 of the largest diagonal entry: singular
  for (Index k = 0; k < 6; ++k) scale = std::max(scale, std::abs(value(T0(k, k))));
  if (!physical_detail::gauss_jordan_inverse<T>(T0, T0inv, value, false, 1e-9 * scale)) return false;
  // Generalised order of the inputs: F_x F_y F_z tau_z tau_y tau_x (swap 3 ↔ 5).
  auto from_generalised_inputs = [](const Mat& X) {
    Mat Y = X;
    Y.col(3) = X.col(5);
    Y.col(5) = X.col(3);
    return Y;
  };
  auto to_generalised_rows = [](const Mat& X) {
    Mat Y = X;
    Y.row(3) = X.row(5);
    Y.row(5) = X.row(3);
    return Y;
  };
  Bw = from_generalised_inputs(G0 * T0);
  // The body force at hover holds the weight: F_b0 = R₀ᵀ (0, 0, m g); the tilt of
  // that lift with the attitude: ∂(R F_b0)/∂(psi, theta, phi) (a negative stiffness
  // term: M q'' + K q = ..., so K = −∂u/∂q).
  Mat Fb0 = R0.transpose().col(2) * (m * g);
  for (int k = 0; k < 3; ++k) K.block(0, 3 + k, 3, 1) = -(dR[k] * Fb0);
  if (L.gamma >= 0) {
    // Hover commands w₀ = T₀⁻¹ (F_b0; 0), forces f₀ = A⁺ w₀; the lift changes with
    // the gaps: δu = G₀ kappa A(r − c) diag(f₀ ⊙ δalpha), δalpha_k = −gamma alpha_k J_k δq.
    Mat wb = Mat::Constant(6, 1, zero);
    wb.topRows(3) = Fb0;
    const Mat f0 = L.allocation_pinv.cast<T>() * (T0inv * wb);
    Mat lift = At;
    for (Index k = 0; k < 8; ++k) lift.col(k) *= f0(k, 0) * alpha(k, 0);
    K += G0 * lift * J * (kappa * p[L.gamma]);
  }
  if (L.com[0] >= 0) {
    // The sensors' point p − R c: ∂/∂(psi, theta, phi) = −dR c.
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) {
        T v = zero;
        for (int b = 0; b < 3; ++b) v -= dR[k](a, b) * p[L.com[b]];
        Cq(a, 3 + k) = v;
      }
  }
  if (L.back_emf >= 0) {
    // P (8×6): the velocity of each array along its force in body axes, by virtual
    // work the allocation's transpose of the body twist (R₀ᵀ p', omega = W₀ q'_a):
    // P = A(r − c)ᵀ G₀ᵀ.  The back-EMF −b alpha_k v_k enters the current loop:
    // w − F q', T₀ F = kappa A diag(alpha²) b P.
    const Mat P = At.transpose() * G0.transpose();
    Mat emf = scaled;
    for (Index k = 0; k < 8; ++k) emf.col(k) *= alpha(k, 0);
    F = to_generalised_rows(T0inv * emf * P * (kappa * p[L.back_emf]));
  }
  return true;
}

// The seed-001 stage (stage6::StageParameters defaults) as a physical model: the
// base alone.
PhysicalModel stage6_defaults_model();

// @throws InputError  |z_0| > 1 mm or not finite (the linearisation is about a
//   hover height near the reference gap).
void check_stage6_hover_height(double z0_m);

}  // namespace lpvid
