// lpvid — the base "platform": the 3-DOF planar actuator with manipulator of seed 000
// (Gajdušek et al., eqs 2–8), linear in q = [psi theta z], scheduled by the beam
// position x_b, with inputs tau = [T_psi T_theta F_z] (N·m, N·m, N) and outputs q
// (rad, rad, m).  docs/effects.md, "Base: platform".
//
//   M(x_b) q'' + D q' + K q = w
//
// | matrix | entries (base; + the physics effects of this base) |
// |--------|-----------------------------------------------------|
// | M(x_b) | diag(J_psi + m_b z_b², J_theta + m_b (z_b² + x_b²), m_p + m_b), M_theta,z = m_b x_b; com_offset: M_psi,z = m_p c_y, M_theta,z += m_p c_x, M_psi,theta = J_psitheta |
// | D      | diag(d_psi, d_theta, d_z) and D_ij = rho_ij sqrt(D_ii D_jj): damping per DOF and their couplings (eq 5 gives diag(6 r_vc² d, 6 r_vc² d, 9 d) for nine equal coil dampers; D = Σ d_i c_i c_iᵀ for unequal ones is a general symmetric matrix, and a coil arm other than designed changes the tilt/z ratio) |
// | K      | K_zz = k_linear; tilt block = the rods' designed bending stiffness Σ_j k_torque_low t_j t_jᵀ (eq 4 rows k_1, k_2 with the rod angles), its diagonal scaled per axis by bending_scale_psi / _theta and a coupling bending_coupling·sqrt(Kb_psipsi Kb_thth) added (manufacturing tolerance of the leaf springs, bounded to a factor 2 of the design); rod_twist: + twist stiffness per tilt axis; com_offset: + the rods' vertical stiffness about its centre (e_x, e_y): k_linear a aᵀ − k_linear e_z e_zᵀ, a = (e_y, e_x, 1); beam_gravity: − z_b m_b g on both tilt diagonals |
//
// The matrices are built by a template on the scalar type (double, or ceres::Jet in
// idlib/fit for exact derivatives).
#pragma once

#include <cmath>

#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"
#include "idlib/plants/platform/platform.h"

namespace lpvid {

// The platform's BaseInfo (parameters with defaults from docs/assumptions.md).
BaseInfo make_platform_base();

// Positions of the platform's parameters in a model's list (-1: effect off).
struct PlatformIndices {
  Index J_psi = -1, J_theta = -1, m_p = -1, m_b = -1, z_b = -1, stroke = -1;
  Index d_psi = -1, d_theta = -1, d_z = -1, rho_pt = -1, rho_pz = -1, rho_tz = -1;
  Index k_lin = -1, k_low = -1, rod[3] = {-1, -1, -1};
  Index s_psi = -1, s_theta = -1, s_pt = -1;
  Index tw_psi = -1, tw_theta = -1;                                 // rod_twist
  Index com_x = -1, com_y = -1, J_pt = -1, sc_x = -1, sc_y = -1;    // com_offset
  Index g = -1;                                                     // beam_gravity
  explicit PlatformIndices(const PhysicalModel& model);
};

// M(x_b), D, K (3×3, symmetric) for the parameter values p (the model's full list).
template <class T>
void platform_matrices(const PlatformIndices& L, const T* p, double x_b, T M[3][3], T D[3][3], T K[3][3]) {
  using std::sqrt;
  const T zero(0.0);
  auto get = [&](Index i, double fallback) { return i >= 0 ? p[i] : T(fallback); };
  const T mp = p[L.m_p], mb = p[L.m_b], zb = p[L.z_b];
  const T cx = get(L.com_x, 0.0), cy = get(L.com_y, 0.0), Jpt = get(L.J_pt, 0.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) D[i][j] = K[i][j] = zero;
  platform_mass_matrix(p[L.J_psi], p[L.J_theta], Jpt, mp, mb, zb, cx, cy, x_b, M);
  D[0][0] = p[L.d_psi];
  D[1][1] = p[L.d_theta];
  D[2][2] = p[L.d_z];
  // + 1e-300 (as for the bending coupling below): an undamped axis (a levitated stage
  // whose user sets a damping and its lower bound to 0) would otherwise give the Jet's
  // sqrt an infinite slope at 0, and its derivatives NaN (0 · ∞).
  D[0][1] = D[1][0] = p[L.rho_pt] * sqrt(D[0][0] * D[1][1] + T(1e-300));
  D[0][2] = D[2][0] = p[L.rho_pz] * sqrt(D[0][0] * D[2][2] + T(1e-300));
  D[1][2] = D[2][1] = p[L.rho_tz] * sqrt(D[1][1] * D[2][2] + T(1e-300));
  // The rods' designed bending (eq 4 rows with rod angles): bend axis t_j in (psi, theta).
  T Kb[2][2] = {{zero, zero}, {zero, zero}};
  for (int j = 0; j < 3; ++j) add_rod_tilt_stiffness(p[L.rod[j]], zero, p[L.k_low], Kb);
  K[0][0] = Kb[0][0] * p[L.s_psi];
  K[1][1] = Kb[1][1] * p[L.s_theta];
  K[0][1] = Kb[0][1] + p[L.s_pt] * sqrt(Kb[0][0] * Kb[1][1] + T(1e-300));
  K[2][2] = p[L.k_lin];
  if (L.tw_psi >= 0) {
    K[0][0] += p[L.tw_psi];
    K[1][1] += p[L.tw_theta];
  }
  if (L.sc_x >= 0) {
    const T ex = p[L.sc_x], ey = p[L.sc_y], kl = p[L.k_lin];
    K[0][0] += kl * ey * ey;
    K[1][1] += kl * ex * ex;
    K[0][1] += kl * ex * ey;
    K[0][2] += kl * ey;
    K[1][2] += kl * ex;
  }
  if (L.g >= 0) {
    K[0][0] -= zb * mb * p[L.g];
    K[1][1] -= zb * mb * p[L.g];
  }
  K[1][0] = K[0][1];
  K[2][0] = K[0][2];
  K[2][1] = K[1][2];
}

// lpvid's own simulated platform (PlatformParameters::defaults(), docs/assumptions.md)
// as a physical model: the base with rod_twist, com_offset (J_psitheta = 0.001) and
// beam_gravity.  Its response equals platform_model(PlatformParameters::defaults(), x_b).
PhysicalModel platform_defaults_model();

// @throws InputError  |x_b| > beam_stroke_m of model, or not finite.
void check_platform_beam_position(const PhysicalModel& model, double beam_position_m);

// The rigid-body physics of a platform model as PlatformParameters (for the
// closed-loop and moving-beam simulators and the PI design): the same M(x_b), D
// and K (the generalised terms in stiffness_extra and damping_override).  Block
// effects (delays, lags, modes, gains, cross-talk) have no counterpart there and
// are left out; `blocks_left_out` (if given) receives their names.
// @throws InputError  the model is invalid or not of base "platform".
PlatformParameters platform_parameters(const PhysicalModel& model, std::vector<std::string>* blocks_left_out = nullptr);

}  // namespace lpvid
