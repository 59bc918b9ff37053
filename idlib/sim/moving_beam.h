// The 3-DOF platform with the manipulator beam moving along x_b(t) (seed 000,
// Fig. 14): the time-varying closed loop whose measurement the LPV model must
// predict.  Derivation from the Lagrangian in docs/math.md ("Moving beam").
//
// Equations (coordinates and signs of idlib/plants/platform/platform.h; q = [psi theta z]):
//
//   M(x_b) q'' + (D + G(x_b, x_b')) q' + K q = tau + w(t)
//
//   G = m_b x_b' [[0 0 0], [0 2 x_b 0], [0 1 0]]        (from M' and dL/dtheta)
//   w = [0,  m_b z_b x_b''  -  m_b g x_b,  0]            (beam reaction, gravity moment)
//
// M, D, K are those of platform.h (mass_matrix, damping_matrix, stiffness_matrix).
// The constant weights (m_p + m_b) g on z are taken as compensated (the paper's
// "zero working point"); the x_b-dependent moment is not, so it disturbs theta.
//
// Discretisation (stated error): per sample [t_k, t_k + Ts] split into `substeps`
// equal pieces of length h, the coefficients are frozen at each piece's midpoint
// (x_b, x_b', x_b'' at t_mid) and the piece is integrated exactly by ZOH:
//   x ← Φ(t_mid) x + Γ(t_mid) (u_k + w(t_mid)),  [[Φ Γ];[0 I]] = exp([[A B];[0 0]] h)
// (the exponential midpoint rule).  With x_b constant this is exactly the LTI
// ZOH model that simulate_excitation uses (tests pin it to rounding); with x_b
// moving the error is second order in h (measured in tests: substeps 1 vs 8).
// The matrix exponential is recomputed only when (x_b, x_b') at the midpoint
// moves by more than 1e-12 (m, m/s) from the last one computed, so a beam at
// rest costs one product per sample.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"

namespace lpvid {

// Beam position, velocity and acceleration at one instant (m, m/s, m/s²).
struct BeamState {
  double position_m = 0.0;
  double velocity_m_per_s = 0.0;
  double acceleration_m_per_s2 = 0.0;
};

// x_b(t) as a piecewise polynomial (degree <= 5 per segment) so that position,
// velocity and acceleration are exact derivatives of one function.
class BeamTrajectory {
 public:
  // Natural cubic spline through samples (t_j, x_j): C² (continuous
  // acceleration, piecewise linear), x'' = 0 at both ends.  Use it on a
  // reference trajectory: the acceleration of a spline through noisy samples
  // amplifies the noise by 1/Δt².
  // @throws InputError  fewer than 2 samples; sizes differ; a value not finite;
  //   t not strictly increasing (message names the sample index).
  static BeamTrajectory from_samples(const Eigen::VectorXd& time_s, const Eigen::VectorXd& position_m);

  // The built-in profile "sweep": rest at left_m for first_dwell_s, then
  // minimum-jerk moves (Flash & Hogan: x = x0 + Δ(10s³ - 15s⁴ + 6s⁵),
  // s = τ/move_s) to right_m, rest dwell_s, back to left_m, rest dwell_s, ...
  // until duration_s; the last piece is cut at duration_s.  Peak acceleration of
  // a move 5.77·|Δ|/move_s².  Defaults: ±0.1 m (the paper's left/right,
  // docs/assumptions.md), 0.6 s moves (peak 3.2 m/s², 0.26 N·m of reaction on
  // theta), 1.4 s rests: one period 4 s.
  struct Sweep {
    double left_m = kBeamLeft_m;
    double right_m = kBeamRight_m;
    double first_dwell_s = 1.0;
    double move_s = 0.6;
    double dwell_s = 1.4;
  };
  // @throws InputError  a value not finite; move_s <= 0; a dwell < 0; duration_s <= 0.
  static BeamTrajectory sweep(const Sweep& spec, double duration_s);

  // x_b held at position_m over [start_s, end_s].
  static BeamTrajectory constant(double position_m, double start_s, double end_s);

  // Evaluates the segment holding t (the first/last segment's polynomial
  // extrapolates outside [start_s, end_s]).
  BeamState at(double t_s) const;
  double start_s() const { return breaks_.front(); }
  double end_s() const { return breaks_.back(); }

 private:
  std::vector<double> breaks_;                 // segment j spans [breaks_[j], breaks_[j+1]]
  std::vector<std::array<double, 6>> coeffs_;  // x = Σ c_i (t - breaks_[j])^i
};

// Which beam effects act on the platform (each a term of the equation above).
// Switching one off gives a model that lacks it (for tests and diagnosis).
struct MovingBeamEffects {
  bool gravity_moment = true;  // -m_b g x_b on theta
  bool beam_reaction = true;   // +m_b z_b x_b'' on theta
  bool velocity_terms = true;  // G(x_b, x_b') q'
};

struct MovingBeamOptions {
  double sample_period_s = 1e-3;  // must equal the controller's Ts
  // Independent white excitation per plant input [T_psi T_theta F_z] (N·m, N·m, N);
  // zero = not excited (the default: the beam alone disturbs, as in Fig. 14).
  Eigen::Vector3d excitation_std = Eigen::Vector3d::Zero();
  // White sensor noise per output (rad, rad, m); default as ExcitationOptions.
  Eigen::Vector3d sensor_noise_std{1.2e-6, 1.2e-6, 1.0e-7};
  std::uint64_t seed = 1;
  int substeps = 1;  // pieces per sample, 1..1000
  // equilibrium: the loop has been at rest with the beam at x_b(t_0): q' = 0 and
  //   plant and controller states solve the static loop with w(t_0) (for the PI
  //   controller: q = 0, integrators holding -w).  rest: all states zero.
  enum class Start { equilibrium, rest };
  Start start = Start::equilibrium;
  MovingBeamEffects effects;

  // @throws InputError naming the field (sample period not finite/positive, a
  //   std negative or not finite, substeps outside 1..1000).
  void validate() const;
};

// Simulates the closed loop over the trajectory: samples t_k = start_s + k·Ts,
// k = 0..N-1, N = floor((end_s - start_s)/Ts) + 1 (1 <= N <= kMaxSamples).
// Per sample, as simulate_excitation: q_meas = q + n, e = -q_meas,
// u = C_c x_c + D_c e + v, log, advance plant (above) and controller.
// Random numbers as simulate_excitation (v1 v2 v3 n1 n2 n3 per sample from
// mt19937_64(seed)).  Result columns: t, v1..v3, u1..u3, q1..q3, x_b (N × 11);
// t is the trajectory's time.
//
// | argument            | requirement |
// |---------------------|-------------|
// | discrete_controller | discrete, order n_c >= 0, 3 inputs (e), 3 outputs (u_c), Ts = options' |
//
// A controller of order 0 with D = 0 runs the plant open loop.
// @throws InputError  parameters or options invalid; controller of the wrong
//   shape or sample period; x_b(t) outside the stroke at a sample or midpoint
//   (mass_matrix's message); Start::equilibrium when the static loop is
//   singular (a controller without integral action on an axis with K = 0).
SimulatedLog simulate_moving_beam(const PlatformParameters& params, const StateSpace& discrete_controller,
                                  const BeamTrajectory& trajectory, const MovingBeamOptions& options);

// The model's prediction of a measured run: the same loop, driven by the
// measured excitation (N × 3, row k at t_k = start_s + k·Ts) instead of random
// numbers, without sensor noise.  Returns q (N × 3) and u (N × 3).
struct MovingBeamPrediction {
  Eigen::MatrixXd q;
  Eigen::MatrixXd u;
};
// @throws InputError  as simulate_moving_beam; excitation not N × 3 or not finite.
MovingBeamPrediction predict_moving_beam(const PlatformParameters& params, const StateSpace& discrete_controller,
                                         const BeamTrajectory& trajectory, double start_s,
                                         const Eigen::MatrixXd& excitation, const MovingBeamOptions& options);

// The open-loop prediction from the measured plant input u (N × 3, row k at
// t_k = start_s + k·Ts): q̂ = the plant (with the beam's effects) driven by u,
// no controller, no noise, starting at rest at q = 0, q' = 0 (where a logged run
// that starts in closed-loop equilibrium has its plant, whatever the model; the
// constant moment of the beam before t_0 was held by u, which the log holds).
// options.start is not used.  For a correct model the residual q_meas - q̂ is
// the sensor noise alone (white), whereas the closed-loop prediction's residual
// is that noise fed back through the loop (coloured by the sensitivity): the
// residual tests (idlib/validate/time_fit.h) belong on this residual.
// Needs a stable open-loop plant (K positive definite, D > 0).
// @throws InputError  as predict_moving_beam.
Eigen::MatrixXd predict_moving_beam_from_input(const PlatformParameters& params, const BeamTrajectory& trajectory,
                                               double start_s, const Eigen::MatrixXd& plant_input,
                                               const MovingBeamOptions& options);

}  // namespace lpvid
