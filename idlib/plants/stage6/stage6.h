// The 6-DOF magnetically levitated stage of seed 001 (Nam et al.): rigid-body
// dynamics of the platen from the Lagrangian with Euler angles (eqs 1–9), the
// force allocation of four linear motors (eqs 27–30, with the printed errors
// of DESIGN.md item 6), and the motor d-q force/current model (eqs 20–26, with
// DESIGN.md item 7).  Derivations and the printed errors: docs/math.md, section
// "6-DOF maglev stage"; the values: docs/assumptions.md.
//
// Coordinates (used everywhere in this module):
//   q = [x, y, z, ψ, θ, φ]  (m, m, m, rad, rad, rad): position of the centre of
//   mass in the inertial frame (z up) and the Z-Y-X Euler angles yaw ψ, pitch θ,
//   roll φ; the body-to-inertial rotation is R = Rz(ψ) Ry(θ) Rx(φ) (= J₁ of eq 1).
//   ω = W(θ, φ) [ψ̇ θ̇ φ̇]ᵀ is the body angular velocity (eq 4, columns in q order).
//   Body wrench w = [F_b; τ_b] (N, N·m): the sum of the motor forces and their
//   moments about the centre of mass, in body axes.
//   Generalised force (eq 8's u) u = G(q) w = [R F_b; Wᵀ τ_b].
//   Motor forces f (8, N) in the order of eq 30:
//     f = [f1x, f1z, f2y, f2z, f3x, f3z, f4y, f4z]   (motors 1, 3 push along x,
//   motors 2, 4 along y; all four lift along z; body axes).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "idlib/plants/stage6/kinematics.h"

namespace lpvid::stage6 {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix68d = Eigen::Matrix<double, 6, 8>;

constexpr double kGravity_m_per_s2 = 9.8;  // seed 001, section 3.5

// Physical values (docs/assumptions.md gives the reason for each).
struct StageParameters {
  double mass_kg = 5.47;  // seed 001, section 3.5
  // Inertia about the centre of mass in body axes (symmetric, positive definite).
  Eigen::Matrix3d inertia_kgm2 = Eigen::Vector3d(0.029, 0.029, 0.057).asDiagonal();
  // Lever arm [a_i b_i c_i] (body axes, m) from the centre of mass to the force
  // centre of magnet array i (eq 29), one column per motor 1..4.
  Eigen::Matrix<double, 3, 4> lever_arms_m = default_lever_arms();
  // Motor force constant k_f at the reference gap (N/A): f_h = k_f α i_q,
  // f_z = k_f α i_d (docs/math.md, derived from eq 24).
  double force_constant_N_per_A = 20.0;
  // α(z) = exp(-γ (z_gap - z_ref)) with γ = 2π/pitch (eq 20 for a sinusoidal
  // magnet array); α(z_ref) = 1.
  double magnet_pitch_m = 0.0256;
  double reference_gap_m = 350e-6;  // the operating point q_r of section 3.5
  // d-q winding model (eq 25): resistance, inductance (dL/dz = 0 assumed), and
  // the proportional current-amplifier gain that closes the current loop.
  double resistance_ohm = 1.5;
  double inductance_H = 5e-3;
  double current_loop_gain_V_per_A = 3.5;  // τ_e = L/(R + k_c) = 1 ms

  static Eigen::Matrix<double, 3, 4> default_lever_arms();
  double gamma_per_m() const;
  // Electrical time constant of the closed current loop, L/(R + k_c) (s).
  double electrical_time_constant_s() const;
  // @throws InputError naming the first non-finite or non-positive value, or a
  //   non-symmetric / non-positive-definite inertia.
  void validate() const;
};

// ---- kinematics (eqs 1, 4; the templates in idlib/plants/stage6/kinematics.h) ----
// R = J₁ of eq 1 at the angles of q (rotation_zyx); W: ω = W [ψ̇ θ̇ φ̇] is
// angular_velocity_map(θ, φ).
inline Eigen::Matrix3d rotation(const Vector6d& q) { return rotation_zyx<double>(q(3), q(4), q(5)); }
// G(q) (6×6): u = G w, block diagonal [R, Wᵀ].
Matrix6d wrench_to_generalized(const Vector6d& q);

// ---- dynamics (eqs 5–9) ----
// M(q) = blockdiag(m I₃, Wᵀ H W)  (eq 5's J₂⁻ᵀ H J₂⁻¹ with J₂⁻¹ = W).
Matrix6d mass_matrix(const StageParameters& p, const Vector6d& q);
// h₁ = [0 0 m g 0 0 0]ᵀ (V = m g z, eq 6).
Vector6d gravity_term(const StageParameters& p);
// h₂(q, q̇) = [0; Wᵀ(H Ẇ q̇_a + ω × H ω)]: Coriolis and centrifugal terms of the
// Lagrange equations (eq 8); q̇_a = [ψ̇ θ̇ φ̇].  Equal to Ṁq̇ − ½∂(q̇ᵀMq̇)/∂q.
Vector6d coriolis_term(const StageParameters& p, const Vector6d& q, const Vector6d& qd);
// q̈ = M⁻¹(u − h₁ − h₂)  (eq 9 solved for q̈).
Vector6d acceleration(const StageParameters& p, const Vector6d& q, const Vector6d& qd, const Vector6d& u);
// T + V of eqs 5–6 (J); conserved when u = 0.
double total_energy(const StageParameters& p, const Vector6d& q, const Vector6d& qd);

// ---- allocation (eqs 27–30) ----
// A (6×8): w = A f derived from F = Σ f_i, τ = Σ r_i × f_i (DESIGN.md item 6) is
// allocation_matrix(lever_arms_m) of kinematics.h.
// Eq 30 exactly as printed (τ_Z row with −a₄ in the f4y column), for comparison.
Matrix68d printed_eq30_matrix(const Eigen::Matrix<double, 3, 4>& lever_arms_m);
// The minimum-norm forces for a desired wrench: f = A⁺ w = Aᵀ(AAᵀ)⁻¹ w.
// @throws InputError when A has rank < 6 (a degenerate geometry).
Eigen::Matrix<double, 8, 6> allocation_pseudo_inverse(const Eigen::Matrix<double, 3, 4>& lever_arms_m);

// ---- where the sensors look (the centre-of-mass offset) ----
// The stage's dynamics are those of its centre of mass; the sensors
// (interferometers, probes) look at the platen's reference point, the point the
// designed lever arms r_i are measured from.  With the centre of mass at c from
// the reference point (body axes), the reference point is at p_cm − R c.
// The configuration the sensors see for a centre-of-mass configuration q_cm:
// [p_cm − R c; the same angles].
Vector6d sensed_configuration(const Vector6d& q_cm, const Eigen::Vector3d& com_offset_m);
// Its rate: [ṗ_cm − R (ω × c); the same angle rates].
Vector6d sensed_velocity(const Vector6d& q_cm, const Vector6d& qd_cm, const Eigen::Vector3d& com_offset_m);
// The inverse of sensed_configuration: [p_ref + R c; angles].
Vector6d centre_of_mass_configuration(const Vector6d& q_sensed, const Eigen::Vector3d& com_offset_m);

// ---- motors (eqs 20–26) ----
// α(z_gap) = exp(-γ (z_gap - z_ref)).
double gap_factor(const StageParameters& p, double gap_m);
// Gap of the magnet array of motor i (0..3) when the platen's REFERENCE POINT is at
// q (the sensed configuration; the designed arms r_i are from that point):
// z + ((R − I) r_i)_z.
double motor_gap_m(const StageParameters& p, const Vector6d& q, int motor);
// Velocity of a magnet array (body axes, m/s) whose centre is at `arm_m` from the
// centre of mass (r_i − c), for a centre-of-mass configuration q and rate q̇:
// Rᵀ ṗ + ω × arm, ω = W q̇_a.  Its component along each of the array's forces is
// the velocity in that motor's back-EMF (eq 25 in the motor's own coordinates).
Eigen::Vector3d array_velocity(const Vector6d& q, const Vector6d& qd, const Eigen::Vector3d& arm_m);
// Forces of motor i from its d-q currents at gap z (eq 24 in d-q form with a
// sinusoidal magnet array; eq 26 prints f_x and f_z swapped):
//   horizontal = k_f α(z) i_q,   vertical = k_f α(z) i_d.
Eigen::Vector2d motor_forces(const StageParameters& p, double i_d_A, double i_q_A, double gap_m);
// The currents [i_d, i_q] that give [horizontal, vertical] forces at gap z.
Eigen::Vector2d motor_currents(const StageParameters& p, double horizontal_N, double vertical_N, double gap_m);
// d-q current derivatives (eq 25 with dL/dz = 0 and the current amplifier
// v = R i_cmd + k_c (i_cmd − i)), back-EMF from the array's own velocity
// (array_velocity) along its drive axis (body x for motors 1, 3; y for 2, 4) and
// along body z:
//   L di_q/dt = (R + k_c)(i_q,cmd − i_q) − k_e α ẋ_h
//   L di_d/dt = (R + k_c)(i_d,cmd − i_d) − k_e α ż,   k_e = k_f (V·s/m).
Eigen::Vector2d current_derivative(const StageParameters& p, const Eigen::Vector2d& i_dq,
                                   const Eigen::Vector2d& i_cmd_dq, double drive_velocity_m_per_s,
                                   double vertical_velocity_m_per_s, double gap_m);

}  // namespace lpvid::stage6
