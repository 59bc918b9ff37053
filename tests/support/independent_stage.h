// Test support: an INDEPENDENT simulator of the 6-DOF maglev stage of seed 001
// (Nam et al., ICCAS 2003), written from the paper apart from idlib/plants, idlib/stage6 and
// idlib/physical (it includes none of them and shares no code with them), so that the
// stage's model-error loop is not tried only on data from lpvid's own simulator.
//
// What it is, and where each piece comes from:
// - Rigid body (eqs 1-9): position of the centre of mass in the inertial frame,
//   attitude as a unit QUATERNION (not Euler angles), body angular velocity;
//   Newton-Euler m a = R f_b - m g e_z, H w' + w x H w = tau_b (about the centre of
//   mass).  The log reports the configuration q = [x y z psi theta phi] of the
//   platen's reference point (where the interferometers and probes look: the design
//   centre, which differs from the centre of mass by the hidden offset c), with the
//   Z-Y-X Euler angles of eq 1 (psi yaw, theta pitch, phi roll) extracted from R.
// - Four magnet arrays / linear motors (eqs 27-30): motor i sits at r_i (body frame,
//   from the reference point); motors 1 and 3 push along body x, 2 and 4 along body
//   y, all four lift along body z.  The body wrench about the centre of mass is
//   sum_i (r_i - c) x f_i.
// - Force constant (eqs 20, 24, 26): f = kappa * alpha(gap_i) * k_f * i with the
//   Halbach-array field decay alpha = exp(-gamma (gap_i - z_ref)), gap_i the height
//   of array i (z of its point in the inertial frame minus its level height), only
//   when the gap effect is on (otherwise alpha = 1).
// - Electrical dynamics (eqs 10-13, 23, 25), when the lag effect is on: per motor two
//   current components (horizontal, vertical) with L di/dt = v - R i - e, back-EMF
//   e = kappa k_f alpha * (velocity of ARRAY i along that force; centre-of-mass
//   velocity plus w x (r_i - c), the motor's own coordinates in eq 25), driven by a
//   current amplifier v = R i_ref + k_c (i_ref - i) (resistance feed-forward plus
//   proportional gain: tau_e = L / (R + k_c)).  Otherwise i = i_ref.
// - Input delay: the motor currents' references switch D after each control sample.
// - Controller (eqs 31-42 with the smoothing of section 3.5): in generalised
//   coordinates q, u = M0 (q_r'' - Lambda e' - K sigma / (|sigma| + delta)) + h1,
//   M0 = rho * blockdiag(m I3, W^T H W) (rho = 0.4 in the paper), h1 = the weight,
//   the velocity by backward difference of the measured q at the control rate, then
//   converted to the body wrench (F_b = R^T F, tau_b = W^-T Q) that the log's u1..u6
//   record (F_x F_y F_z tau_x tau_y tau_z), plus the white excitation v1..v6 added to
//   it, and allocated to the eight motor forces with the pseudo-inverse of the
//   DESIGNED allocation (arms r_i about the reference point, c = 0, alpha = 1).
// - Integration: classical RK4 with a fixed substep (default 1/20 of the control
//   period), split at the delayed switching instant; quaternion renormalised.
//
// Only Eigen is used.  Units SI; angles rad.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <functional>
#include <string>

namespace indep_stage {

using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;

enum class Hidden { kNone, kGap, kLag, kCom, kDelay };
const char* hidden_name(Hidden h);                 // none, gap, lag, com, delay
bool parse_hidden(const std::string& s, Hidden* h);  // false if unknown

struct Stage {
  double mass_kg = 5.47;
  Mat3 inertia_kgm2 = Eigen::Vector3d(0.029, 0.029, 0.057).asDiagonal();  // about the centre of mass, body axes
  double gravity = 9.8;
  Eigen::Matrix<double, 3, 4> arms_m;  // r_i, body frame, from the reference point (set by default_arms)
  double force_constant_N_per_A = 20;  // k_f as designed (the controller's)
  double kappa = 1;                    // true force constant over the designed one
  double z_ref_m = 350e-6;             // the gap where alpha = 1 (the operating point)
  // Effects (hidden from the controller)
  bool gap = false;
  double gamma_per_m = 245;  // 2 pi / magnet pitch
  bool lag = false;
  double resistance_ohm = 1.5, inductance_H = 5e-3, amp_gain_V_per_A = 3.5;
  Vec3 com_offset_m = Vec3::Zero();  // centre of mass relative to the reference point, body frame
  double input_delay_s = 0;
  // Back-EMF velocity: the array's own velocity along each force, in the body frame
  // (true, default: eq 25 written in each motor's coordinates), or the centre of
  // mass's inertial x', y', z' (false: what lpvid's simulator did until 2026-11-24;
  // to measure what that physics missed).
  bool back_emf_at_array = true;
  // Where the sensors look: the reference point p_cm - R c (true, default), or the
  // centre of mass shifted by the constant c, p_cm - c (false: what lpvid's simulator
  // logged until 2026-11-24; to measure what that physics missed).
  bool measure_at_reference = true;
  double tau_e() const { return inductance_H / (resistance_ohm + amp_gain_V_per_A); }
  double back_emf_damping() const {
    return kappa * kappa * force_constant_N_per_A * force_constant_N_per_A / (resistance_ohm + amp_gain_V_per_A);
  }
};

// The paper's layout as assumed in docs/assumptions.md is NOT used: the default is a
// pinwheel with the given half-pitches and depth (motor 1 (+a,+b), 2 (-a,+b), 3 (-a,-b),
// 4 (+a,-b)).
Eigen::Matrix<double, 3, 4> pinwheel_arms(double ax_m, double ay_m, double depth_m);

struct Controller {
  double rate_hz = 1000;
  double lambda = 3;         // Lambda = lambda I (paper: 3)
  double gain_K = 2;         // K
  double delta = 0.01;       // boundary layer
  double inertia_ratio = 0.4;  // M0 = ratio * M (paper: 40 %)
  double mass_kg = 5.47;     // the weighed mass (gravity compensation and M0)
  Mat3 inertia_kgm2 = Eigen::Vector3d(0.029, 0.029, 0.057).asDiagonal();  // designed
  Eigen::Matrix<double, 3, 4> arms_m;  // designed arms for the allocation
  bool enabled = true;
  // The velocity the law uses: false (default, a real controller): the backward
  // difference of the measured q; true: the exact q' of the state at the sample (what
  // lpvid's simulator does when noise-free; only for the cross-check).
  bool true_velocity = false;
};

struct Experiment {
  double duration_s = 60;
  double settle_s = 2;  // simulated before the log starts (no excitation)
  double substeps = 20;  // RK4 steps per control period
  Vec6 excitation_std = (Vec6() << 2, 2, 2, 0.1, 0.1, 0.1).finished();  // N, N·m, per sample, body wrench
  Vec6 noise_std = (Vec6() << 1e-9, 1e-9, 1e-8, 1e-7, 1e-7, 1e-7).finished();  // m, rad
  Vec6 q_ref = (Vec6() << 0, 0, 350e-6, 0, 0, 0).finished();
  std::uint64_t seed = 1;
  // If non-empty: replay this excitation (rows = samples, 6 columns in wrench order)
  // instead of drawing it (cross-checks against another simulator).
  Eigen::MatrixXd replay_excitation;
  // What the motors had before t = 0 (the delay line, the currents): the hover
  // command (default) or the first command (only for matching another simulator).
  bool history_from_first_command = false;
};

// One run: t, v (6), u (6), q measured (6), plus the true q (6), N rows.
struct Log {
  Eigen::VectorXd t;
  Eigen::MatrixXd v, u, q, q_true;
};

// Runs the closed loop.  Throws std::runtime_error if the state leaves a sane range
// (|z - z_ref| > 5 mm, tilts > 0.2 rad, non-finite).
Log run(const Stage& s, const Controller& c, const Experiment& e);

// Low-level access for the checks: the full state
// x = [p(3) v(3) quat(4: w x y z) omega(3) currents(8)] and its derivative for given
// current references (8, the motor forces commanded divided by k_f) with the
// controller out of the loop.
using State = Eigen::Matrix<double, 21, 1>;
State hover_state(const Stage& s, double z_m);
State derivative(const Stage& s, const State& x, const Eigen::Matrix<double, 8, 1>& i_ref);
Vec6 configuration(const Stage& s, const State& x);  // q of the reference point
double energy(const Stage& s, const State& x);       // kinetic + potential (no magnetic energy)
Vec3 angular_momentum_inertial(const Stage& s, const State& x);  // about the centre of mass
// The designed allocation matrix A (6 x 8: wrench [F; tau] of the 8 forces f1h f1v
// ... f4h f4v about the point `about` with unit force constant).
Eigen::Matrix<double, 6, 8> allocation(const Eigen::Matrix<double, 3, 4>& arms, const Vec3& about);
State rk4_step(const Stage& s, const State& x, const Eigen::Matrix<double, 8, 1>& i_ref, double h);

// A draw over documented ranges for a seed and hidden effect (inertias ±30 %, mass
// ±10 %, arms, kappa ±2 %, controller gains, effect size); `description` lists every
// drawn value as "name = value  # unit" lines.
struct Draw {
  Stage stage;
  Controller controller;
  Experiment experiment;
  std::string description;
};
Draw draw(std::uint64_t seed, Hidden hidden, double noise_scale = -1);  // noise_scale < 0: drawn 0.5-2

// A draw that hovers: draws `seed`, then seed + 7777 k (k = 1..10) until the run
// stays in range and, over its second half, hovers within 3 mm of the reference
// height with tilts below 20 mrad.  `configure` adjusts each draw before it runs
// (duration, switches).  Returns false when no draw hovered; `notes` gets one line
// per redraw (why).
struct HoveringRun {
  Draw draw;
  Log log;
  int redraws = 0;
  Vec6 mean_q_second_half = Vec6::Zero();  // of the true q
};
bool run_hovering(std::uint64_t seed, Hidden hidden, double noise_scale, const std::function<void(Draw&)>& configure,
                  HoveringRun* out, std::string* notes);

// Writes the log in the layout of `lpvid simulate stage6 --experiment`
// (t, v1..v6, u1..u6, q1..q6).
void write_log_csv(const std::string& path, const Log& log);

}  // namespace indep_stage
