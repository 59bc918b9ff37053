// The 3-DOF magnetically levitated platform with a manipulator beam on top
// (Gajdušek et al., seed 000, eqs 1–9): an LPV model in the beam position x_b,
// its coil layout and actuator/sensor transformation T, and the three SISO PI
// controllers that stabilise it in the closed-loop experiments.
//
// Coordinates and sign conventions (used by every function in this header)
// -------------------------------------------------------------------------
//   q   = [psi theta z]              rad, rad, m   (tilts about x and y, height)
//   tau = [T_psi T_theta F_z]        N·m, N·m, N   (generalised forces of q)
//   A point (x, y) of the platform sits at height  h(x, y) = z + y·psi + x·theta
//   (small angles).  This is the convention under which eq 2's coupling entry
//   M_theta,z = +m_b·x_b holds; it makes psi right-handed about +x and theta
//   right-handed about -y.  By virtual work the wrench of vertical coil forces
//   F_i at (x_i, y_i) is  T_psi = Σ y_i F_i,  T_theta = +Σ x_i F_i,  F_z = Σ F_i.
//
// Physical values are assumptions: see docs/assumptions.md for every default
// with its reason.  All matrices are SI; angles in rad.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>

#include "idlib/core/types.h"

namespace lpvid {

// Beam positions of the paper's experiments ("most left, middle and most
// right"); the paper gives no numbers, these are the documented assumption.
inline constexpr double kBeamLeft_m = -0.1;
inline constexpr double kBeamMiddle_m = 0.0;
inline constexpr double kBeamRight_m = 0.1;
inline constexpr std::array<double, 3> kPaperBeamPositions_m = {kBeamLeft_m, kBeamMiddle_m, kBeamRight_m};

// Physical parameters of eqs 2–5.  Every field carries its unit in its name.
//
// Inertia: J_* are about the axes through the origin O of the platform frame
// (x, y in the coil plane, O at the centre coil), for the platform with the static
// part of the manipulator and without the beam; parallel-axis terms of the
// platform's own centre-of-mass offset are inside them.
//
// Reading of eq 2's "J_ψ θ": the paper lists J_ψ, J_θ and J_ψθ as three
// moments of inertia, so the off-diagonal entry is the product of inertia J_ψθ
// (a constant), not J_ψ times the angle θ; at the working point θ = 0 the latter
// would vanish.  J_psitheta_kgm2 is that constant.
//
// Suspension (eq 3's rows k_1, k_2, k_3): three horizontal rods with leaf
// springs at their ends.  Rod j lies along the horizontal unit vector
// a_j = (cos φ_j, sin φ_j), φ_j = rod_axis_angles_rad[j].
//   - vertical motion bends the leaf springs: together the three rods give
//     k_linear_N_per_m on z (their attachment points are taken symmetric about
//     O, so this stiffness does not couple z with the tilts);
//   - tilting about the rod's own axis twists the rod: k_torque_high (per rod);
//   - tilting about the horizontal axis b_j ⟂ a_j bends the leaf springs:
//     k_torque_low (per rod).
// With the rotation vector ω = (ω_x, ω_y) = (psi, -theta), the tilt block is
//   K_tilt = Σ_j k_torque_high·s_j s_jᵀ + k_torque_low·t_j t_jᵀ,
//   s_j = (cos φ_j, -sin φ_j),  t_j = (-sin φ_j, -cos φ_j),
// so k_1 = [K_tilt(0,0) K_tilt(0,1) 0], k_2 = [K_tilt(1,0) K_tilt(1,1) 0],
// k_3 = [0 0 k_linear].  For three rods 120° apart Σ s sᵀ = Σ t tᵀ = 1.5·I and
// K_tilt = 1.5·(k_torque_high + k_torque_low)·I: the rows are diagonal, as the
// default geometry gives.
struct PlatformParameters {
  double J_psi_kgm2 = 0.05;         // J_ψ: about x through O (no beam)
  double J_theta_kgm2 = 0.06;       // J_θ: about y through O (no beam)
  double J_psitheta_kgm2 = 0.001;   // J_ψθ: product of inertia (see above)
  double platform_mass_kg = 6.0;    // m_p: platform + static part of the manipulator
  double beam_mass_kg = 1.0;        // m_b: moving beam of the manipulator
  double beam_height_m = 0.08;      // z_b: beam centre of mass above O
  double beam_stroke_m = 0.15;      // |x_b| allowed; guards against mm-for-m mistakes
  double coil_arm_m = 0.1;          // r_vc: pitch of the 3×3 coil/sensor grid
  double coil_damping_Ns_per_m = 30.0;  // d: air/eddy damping of one voice coil
  double k_linear_N_per_m = 1500.0;     // vertical stiffness of the three rods together
  double k_torque_low_Nm_per_rad = 30.0;    // per rod, tilt about b_j (leaf springs bend)
  double k_torque_high_Nm_per_rad = 200.0;  // per rod, tilt about a_j (rod twists)
  std::array<double, 3> rod_axis_angles_rad = {1.5707963267948966, 3.6651914291880923,
                                               5.7595865315812871};  // 90°, 210°, 330°
  double com_x_m = 0.0;  // platform centre of mass (without beam) in x; couples theta–z
  double com_y_m = 0.0;  // platform centre of mass (without beam) in y; couples psi–z
  double gravity_m_per_s2 = 9.81;
  // Generalisations used by physical models (idlib/physical, docs/effects.md): a
  // symmetric stiffness added to eq 4's K (N·m/rad, N·m/m, N/m; zero by default),
  // and a symmetric damping matrix replacing eq 5's diag(6 r² d, 6 r² d, 9 d) when
  // its diagonal is > 0 (N·m·s/rad on the tilts, N·s/m on z; zero: eq 5).
  Eigen::Matrix3d stiffness_extra = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d damping_override = Eigen::Matrix3d::Zero();

  // The documented defaults (docs/assumptions.md); same as a default-constructed value.
  static PlatformParameters defaults();

  // @throws InputError naming the first field that breaks its rule: inertias and
  //   masses finite and > 0; |J_psitheta| < sqrt(J_psi·J_theta); coil_arm_m and
  //   beam_stroke_m finite and > 0; damping, stiffnesses and gravity finite and
  //   >= 0; beam_height_m, com_*_m and rod angles finite.
  void validate() const;
};

// The platform's mass matrix and the rods' tilt stiffness, once, as templates on
// the scalar type: doubles here (mass_matrix, stiffness_matrix), ceres::Jet in the
// physical base's fits (idlib/physical/platform/platform_base.h).  M as mass_matrix
// below; `M` is filled whole.
template <class T>
void platform_mass_matrix(const T& J_psi, const T& J_theta, const T& J_psitheta, const T& m_p, const T& m_b,
                          const T& z_b, const T& com_x, const T& com_y, double x_b, T M[3][3]) {
  M[0][0] = J_psi + m_b * z_b * z_b;
  M[1][1] = J_theta + m_b * (z_b * z_b + x_b * x_b);
  M[2][2] = m_p + m_b;
  M[0][1] = M[1][0] = J_psitheta;
  M[0][2] = M[2][0] = m_p * com_y;
  M[1][2] = M[2][1] = m_b * x_b + m_p * com_x;
}

// The tilt block (psi, theta) of one rod at the axis angle phi (the rotation vector
// is (psi, −theta)): k_twist s sᵀ + k_bend t tᵀ with s = (cos phi, −sin phi) along
// the rod and t = (−sin phi, −cos phi) across it; added into K[2][2].
template <class T>
void add_rod_tilt_stiffness(const T& phi, const T& k_twist, const T& k_bend, T K[2][2]) {
  using std::cos;
  using std::sin;
  const T s0 = cos(phi), s1 = -sin(phi), t0 = -sin(phi), t1 = -cos(phi);
  K[0][0] += k_twist * s0 * s0 + k_bend * t0 * t0;
  K[0][1] += k_twist * s0 * s1 + k_bend * t0 * t1;
  K[1][0] += k_twist * s1 * s0 + k_bend * t1 * t0;
  K[1][1] += k_twist * s1 * s1 + k_bend * t1 * t1;
}

// Mass matrix M(x_b) of eq 2, linearised at q = 0, with the centre-of-mass terms
// the paper leaves out "for simplicity":
//
//   M = [ J_ψ + m_b z_b²     J_ψθ                      m_p c_y          ]
//       [ J_ψθ               J_θ + m_b (z_b² + x_b²)   m_b x_b + m_p c_x ]
//       [ m_p c_y            m_b x_b + m_p c_x         m_p + m_b        ]
//
// Output: 3×3, symmetric; units kg·m² (tilt–tilt), kg·m (tilt–z), kg (z–z).
// @throws InputError  parameters invalid (PlatformParameters::validate);
//   |beam_position_m| > beam_stroke_m or not finite; M not positive definite
//   (centre-of-mass offsets too large for the inertias).
Eigen::Matrix3d mass_matrix(const PlatformParameters& params, double beam_position_m);

// Stiffness matrix K of eq 4: the rod rows k_1..k_3 (see PlatformParameters)
// plus the destabilising gravity term of the raised beam, -z_b m_b g, on the two
// tilt diagonals.  Independent of x_b.  3×3 symmetric; N·m/rad, N/m.
// @throws InputError  parameters invalid.
Eigen::Matrix3d stiffness_matrix(const PlatformParameters& params);

// Damping matrix D of eq 5: diag(6 r_vc² d, 6 r_vc² d, 9 d) — nine coil dampers on
// the 3×3 grid (equal to d·W·Wᵀ for the grid's wrench map W).  N·m·s/rad, N·s/m.
// @throws InputError  parameters invalid.
Eigen::Matrix3d damping_matrix(const PlatformParameters& params);

// Continuous LPV state-space model of eqs 7–8 frozen at x_b = beam_position_m:
//   x = [psi theta z psi' theta' z'],  u = tau = [T_psi T_theta F_z],  y = q.
//   A = [0 I; -M⁻¹K -M⁻¹D],  B = [0; M⁻¹],  C = [I 0],  D = 0.
//
// | matrix | shape | units |
// |--------|-------|-------|
// | A      | 6×6   | 1/s, 1/s² |
// | B      | 6×3   | per kg·m² (tilts), per kg (z) |
// | C      | 3×6   | 1 |
// | D      | 3×3   | zero |
// input_names  {"T_psi", "T_theta", "F_z"}, output_names {"psi", "theta", "z"},
// sample_period_s = 0.
// @throws InputError  as mass_matrix.
StateSpace platform_model(const PlatformParameters& params, double beam_position_m);

// ---------------------------------------------------------------------------
// Coil layout and the transformation T of eq 9
// ---------------------------------------------------------------------------

// Positions (x_i, y_i) in m of the nine voice coils (and the inductive sensor
// under each), i = 1..9 stored at index i-1.
//
// Numbering read from eq 9 under the convention h = z + y·psi + x·theta: the ψ
// row of T is +,0,- repeating (coils 1,4,7 at y = +r; 2,5,8 at y = 0; 3,6,9 at
// y = -r) and the θ row is +,+,+,0,0,0,-,-,- (coils 1–3 at x = +r, 4–6 at x = 0,
// 7–9 at x = -r):
//
//            y = +r   y = 0   y = -r
//   x = +r     1        2        3
//   x =  0     4        5        6
//   x = -r     7        8        9
struct CoilLayout {
  std::array<Eigen::Vector2d, 9> position_m;

  // The 3×3 grid above with pitch coil_arm_m (r_vc).
  // @throws InputError  coil_arm_m not finite or <= 0.
  static CoilLayout regular_grid(double coil_arm_m);

  // @throws InputError  a position is not finite; the coils do not span the
  //   plane (all on one line), so no wrench could be produced in every direction.
  void validate() const;
};

// Wrench map W: tau = W·u for the nine vertical coil forces u = [F_1..F_9] (N).
// Row 0: y_i (m), row 1: x_i (m), row 2: 1.  3×9.  By duality the sensor heights
// are h = Wᵀ·q.
// @throws InputError  layout invalid (CoilLayout::validate).
Eigen::Matrix<double, 3, 9> wrench_map(const CoilLayout& layout);

// The exact transformation: T = (W Wᵀ)⁻¹ W, so that u = Tᵀ·tau reproduces tau
// (W·Tᵀ = I) with the least total squared coil force, and q = T·h inverts the
// sensor map (T·Wᵀ = I) with least-squares averaging of the nine sensors.
// For the regular grid its ψ and θ rows equal eq 9's and its z row is 1/9 on
// every coil.  3×9, rows [ψ; θ; z] in 1/m, 1/m, 1.
// @throws InputError  layout invalid.
Eigen::Matrix<double, 3, 9> transformation_from_layout(const CoilLayout& layout);

// Eq 9 exactly as printed: ψ row (1/6r)·[1 0 -1 1 0 -1 1 0 -1], θ row
// (1/6r)·[1 1 1 0 0 0 -1 -1 -1], z row 1/6 on every coil.  With the grid's W,
// W·Tᵀ = diag(1, 1, 1.5): the printed z row produces 1.5·F_z and reads 1.5·z
// (DESIGN.md item 5).  Provided so that a user can reproduce the paper's setup.
// @throws InputError  coil_arm_m not finite or <= 0.
Eigen::Matrix<double, 3, 9> printed_transformation(double coil_arm_m);

// ---------------------------------------------------------------------------
// The stabilising controller: three SISO PI loops (paper section 4)
// ---------------------------------------------------------------------------

// Gains of one PI loop, C(s) = kp + ki/s in continuous time.
// Units for the tilt loops: kp in N·m/rad, ki in N·m/(rad·s); for z: N/m, N/(m·s).
struct PiGains {
  double kp = 0.0;
  double ki = 0.0;
};

// Discrete diagonal PI controller, input e = -q (3), output u_c (3, a wrench).
// Integrator: backward rectangle (forward Euler on the running sum, including
// the current error), per channel
//   u_c[k] = kp·e[k] + ki·Ts·Σ_{i=0..k} e[i],     C(z) = kp + ki·Ts·z/(z-1).
// Realisation with the state s[k] = ki·Ts·Σ_{i<k} e[i] (in wrench units):
//   A = I, B = diag(ki·Ts), C = I, D = diag(kp + ki·Ts).
//
// | matrix | shape |
// |--------|-------|
// | A, B, C, D | 3×3 |
// input_names {"e_psi","e_theta","e_z"}, output_names {"u_psi","u_theta","u_z"}.
// @throws InputError  a gain not finite or negative; sample_period_s not finite
//   or <= 0.
StateSpace discrete_pi_controller(const std::array<PiGains, 3>& gains, double sample_period_s);

// Default PI gains [psi, theta, z], designed per axis on the diagonal of the
// model at x_b = 0 (m = M_ii, d = D_ii, k = K_ii).  In continuous time the loop's
// characteristic polynomial is  s³ + (d/m) s² + ((k + kp)/m) s + ki/m;  the sum
// of its poles is fixed at -d/m by the coil damping.  The design places
//   - a real (integrator) pole at -a,  a = 0.4·d/m,
//   - a complex pair with real part -(d/m - a)/2 = -0.3·d/m and natural
//     frequency ω_p = max(1.2·sqrt(k/m), 2·0.3·d/m)  (ζ <= 0.5),
// giving kp = m·(a·(d/m - a) + ω_p²) - k and ki = m·a·ω_p².  This satisfies the
// PI stability rule d·(k + kp) > m·ki (Routh) with margin, keeps every pole at
// least 0.3·d/m (≈ 7 rad/s at the default parameters) left of the imaginary axis
// so impulse responses die out within ~1 s, and puts crossover below ~100 rad/s
// (well inside the 400 rad/s model validity).  Discretised at 1 kHz or 10 kHz the
// same gains stay stable (tests/idlib/plants/platform_test.cc).
// @throws InputError  parameters invalid; coil_damping_Ns_per_m == 0 (a PI loop
//   on an undamped plant m s² + k cannot be stabilised).
std::array<PiGains, 3> default_pi_gains(const PlatformParameters& params);

}  // namespace lpvid
