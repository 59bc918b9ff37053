// Closed-loop simulation of the 6-DOF maglev stage (seed 001): the sliding-mode
// configuration controller (eqs 31–42 with the boundary layer of section 3.5,
// DESIGN.md item 8), the allocation to eight motor forces, optional motor
// effects (gap-dependent force constant α(z), d-q electrical lag), a fixed-step
// RK4 integrator with the control held (ZOH) over each control period, the
// closed-loop identification experiment, and the linearisation about hover.
// Coordinates and orderings: idlib/plants/stage6/stage6.h.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/plants/stage6/stage6.h"

namespace lpvid::stage6 {

// Sliding-mode law (DESIGN.md item 8):
//   e = q − q_r,  σ = ė + Λ e,
//   v = M⁰(q)(q̈_r − Λ ė − K σ/(‖σ‖ + δ)),   u = v + h₁   (generalised force)
// with M⁰ = inertia_scale · M(q) (the paper's "40 % of the real value") and h₁
// the true gravity term (the paper's gravity compensation).  q_r is constant
// (regulation), so q̇_r = q̈_r = 0.  ‖σ‖ mixes m/s and rad/s as the paper's does.
struct SlidingModeOptions {
  double lambda_per_s = 3.0;        // Λ = λ·I₆, seed 001 section 3.5
  double gain_K = 2.0;              // K, in the units of q̈ (m/s², rad/s²)
  double boundary_layer = 0.01;     // δ > 0, in the units of σ (m/s, rad/s)
  double inertia_scale = 0.4;       // M⁰ = inertia_scale · M
  double control_rate_hz = 1000.0;  // the controller runs (and holds u) at this rate
  // @throws InputError naming the field when a value is not finite and positive.
  void validate() const;
};

// Effects present in the simulated stage but not in the controller's model.
struct StageEffects {
  bool gap_dependence = false;  // forces scale by α(gap of each motor), eq 20
  bool electrical_lag = false;  // d-q current dynamics (eq 25) between command and force
  // Centre-of-mass offset c (body axes, m) from the reference point that the
  // designed arms r_i are measured from and the sensors look at: every true lever
  // arm is r_i − c while the controller allocates with the nominal r_i, and the
  // sensors see p_cm − R c (sensed_configuration).
  Eigen::Vector3d com_offset_m = Eigen::Vector3d::Zero();
  // Multiplies every true force constant (the controller assumes 1).
  double force_constant_scale = 1.0;
  // The motor commands reach the amplifiers this long after the controller computed
  // them (computation and communication); rounded to whole integration steps.
  double input_delay_s = 0.0;
};

struct SimulationOptions {
  double duration_s = 8.0;
  double integration_step_s = 1e-4;  // RK4 step; must divide the control period
  // Sensor noise (std per q channel: m, m, m, rad, rad, rad) seen by the
  // controller and logged; 0 = noise-free.
  Vector6d sensor_noise_std = Vector6d::Zero();
  // White excitation (std per body-wrench channel, N and N·m) added to the
  // allocated wrench every control period; 0 = none.
  Vector6d excitation_std = Vector6d::Zero();
  // A designed excitation (e.g. from lpvid excite), at least N x 6 with N the
  // run's samples (duration_s x control rate + 1), used sample for sample
  // instead of the white excitation when not empty (excitation_std is then not
  // used; the noise draws are unchanged).
  Eigen::MatrixXd excitation_samples;
  std::uint64_t seed = 1;
  // @throws InputError naming the field (non-positive duration or step, a step
  //   that does not divide the control period to 1e-9, negative stds, more
  //   than 1e7 control periods, excitation_samples not N x 6 finite values).
  void validate(const SlidingModeOptions& smc) const;
};

// A simulated run sampled at the control rate: row k is t_k = k/control_rate_hz,
// the state at t_k and the control held over [t_k, t_k+1).
struct StageRun {
  Eigen::VectorXd t_s;        // N
  Eigen::MatrixXd q;          // N × 6, true configuration the sensors look at (the reference point)
  Eigen::MatrixXd q_measured; // N × 6, q plus sensor noise (what the controller saw)
  Eigen::MatrixXd qd;         // N × 6, true rate of q
  Eigen::MatrixXd sigma;      // N × 6, σ computed by the controller
  Eigen::MatrixXd u;          // N × 6, generalised force commanded (eq 42)
  Eigen::MatrixXd wrench;     // N × 6, body wrench sent to allocation (incl. excitation)
  Eigen::MatrixXd excitation; // N × 6, the excitation part of wrench
  Eigen::MatrixXd forces;     // N × 8, allocated motor force commands f = A⁺ wrench
};

// Runs the sliding-mode controller from (q0, q̇ = 0) towards q_r.
// @throws InputError  options or parameters invalid.
// @throws NumericalError  the state becomes non-finite or |θ| reaches 1.5 rad
//   (the Euler angles' singularity at 90°): the loop diverged.
StageRun simulate_regulation(const StageParameters& truth, const StageEffects& effects, const Vector6d& q0,
                             const Vector6d& q_ref, const SlidingModeOptions& smc, const SimulationOptions& sim);

// The regulation run of seed 001 section 3.5: q₀ = (0, 0, 250 µm, 0.1, 0.2,
// 0.3 rad) and q_r = (0, 0, 350 µm, 0, 0, 0) (angles read as rad).
Vector6d paper_initial_configuration();
Vector6d paper_reference_configuration();

// The closed-loop identification log in the usual CSV layout: columns
// t, v1..v6, u1..u6, q1..q6 with v the excitation, u the body wrench sent to
// allocation (controller + excitation), q the measured configuration.
struct StageLog {
  std::vector<std::string> names;
  Eigen::MatrixXd data;  // N × 19
};
StageLog experiment_log(const StageRun& run);

// The air gaps of the four motor arrays over a run (motor_gap_m at the true
// configuration, every control sample): the smallest and largest, where and
// when. A gap at or below 0 is a touch-down the simulation does not model (no
// contact forces): the run is then not a physical experiment.
struct GapExcursion {
  double min_gap_m = 0, max_gap_m = 0;
  int min_motor = 0;   // 0-based array of the smallest gap
  double min_t_s = 0;  // when it occurred
};
GapExcursion gap_excursion(const StageParameters& p, const StageRun& run);

// An identification experiment the stage can fly. An operator starts at the
// design level and lowers it until the stage stays well inside its gap: with
// `back_off`, the white excitation (sim.excitation_std) is halved, up to
// kMaxExcitationHalvings times, until every motor gap stays within
// [kSafeGapFraction.first, kSafeGapFraction.second] x the reference gap.
// Without it (a level the user chose, or a designed excitation), the run is
// returned as it is. `scale` is the factor applied to excitation_std.
inline constexpr int kMaxExcitationHalvings = 6;
inline constexpr std::pair<double, double> kSafeGapFraction = {0.25, 3.0};
struct ExperimentRun {
  StageRun run;
  GapExcursion gaps;
  double scale = 1.0;
  GapExcursion first_gaps;  // of the design level, when it was lowered
};
ExperimentRun simulate_experiment_in_gap(const StageParameters& truth, const StageEffects& effects, const Vector6d& q0,
                                         const Vector6d& q_ref, const SlidingModeOptions& smc, SimulationOptions sim,
                                         bool back_off);

// Linearisation about hover at q = (0, 0, z0, 0, 0, 0), q̇ = 0 with the body
// wrench w = w₀ + δw (w₀ = [0 0 m g 0 0 0]) as input and q as output:
//   x = [q − q₀; q̇] (12),  ẋ = A x + B δw,  y = C x.
// A = [0 I; K 0] with the tilt-of-thrust terms ẍ = g θ, ÿ = −g φ; B = [0; M⁻¹G].
// Continuous time (sample_period_s = 0); names: inputs F_x F_y F_z tau_x tau_y
// tau_z, outputs x y z psi theta phi.
StateSpace linearize_hover(const StageParameters& p, double z0_m);

}  // namespace lpvid::stage6
