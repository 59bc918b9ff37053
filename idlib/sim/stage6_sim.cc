#include "idlib/sim/stage6_sim.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "idlib/core/error.h"

namespace lpvid::stage6 {

void SlidingModeOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!std::isfinite(v) || v <= 0)
      throw InputError(fmt::format("sliding-mode option {} = {}: must be a positive finite number", name, v));
  };
  positive(lambda_per_s, "lambda_per_s");
  positive(gain_K, "gain_K");
  positive(boundary_layer, "boundary_layer (delta)");
  positive(inertia_scale, "inertia_scale");
  positive(control_rate_hz, "control_rate_hz");
}

void SimulationOptions::validate(const SlidingModeOptions& smc) const {
  if (!std::isfinite(duration_s) || duration_s <= 0)
    throw InputError(fmt::format("simulation duration_s = {}: must be positive", duration_s));
  if (!std::isfinite(integration_step_s) || integration_step_s <= 0)
    throw InputError(fmt::format("integration_step_s = {}: must be positive", integration_step_s));
  const double period = 1.0 / smc.control_rate_hz;
  const double ratio = period / integration_step_s;
  if (ratio < 1.0 - 1e-9 || std::abs(ratio - std::round(ratio)) > 1e-9 * ratio)
    throw InputError(fmt::format(
        "integration_step_s = {} does not divide the control period {} s; choose e.g. {}", integration_step_s,
        period, period / std::max(1.0, std::ceil(ratio))));
  if (duration_s * smc.control_rate_hz > 1e7)
    throw InputError(fmt::format("simulation of {} s at {} Hz is more than 1e7 control periods; shorten it",
                                 duration_s, smc.control_rate_hz));
  if (!(sensor_noise_std.array() >= 0).all() || !sensor_noise_std.allFinite())
    throw InputError("sensor_noise_std: every entry must be finite and >= 0");
  if (!(excitation_std.array() >= 0).all() || !excitation_std.allFinite())
    throw InputError("excitation_std: every entry must be finite and >= 0");
  if (excitation_samples.size() != 0) {
    const double needed = std::round(duration_s * smc.control_rate_hz) + 1;
    if (excitation_samples.cols() != 6 || static_cast<double>(excitation_samples.rows()) < needed ||
        !excitation_samples.allFinite())
      throw InputError(fmt::format("excitation_samples is {} x {}; it must be at least {} x 6 (one row per control "
                                   "period of the run) of finite values",
                                   excitation_samples.rows(), excitation_samples.cols(), needed));
  }
}

Vector6d paper_initial_configuration() {
  Vector6d q;
  q << 0, 0, 250e-6, 0.1, 0.2, 0.3;
  return q;
}

Vector6d paper_reference_configuration() {
  Vector6d q;
  q << 0, 0, 350e-6, 0, 0, 0;
  return q;
}

namespace {

// The plant: state x = [q (6), q̇ (6), i_dq (8, only with electrical lag)], q the
// configuration of the centre of mass (the sensors see sensed_configuration).
struct Plant {
  const StageParameters& truth;
  const StageEffects& effects;
  Eigen::Matrix<double, 3, 4> arms_from_cm;  // r_i − c
  Matrix68d A_true;
  int n;

  Plant(const StageParameters& p, const StageEffects& e)
      : truth(p), effects(e), n(e.electrical_lag ? 20 : 12) {
    arms_from_cm = p.lever_arms_m;
    arms_from_cm.colwise() -= e.com_offset_m;
    A_true = allocation_matrix(arms_from_cm);
  }

  // The gaps follow the reference point, which the designed arms are measured from.
  double gap(const Vector6d& q_cm, int motor) const {
    return effects.gap_dependence ? motor_gap_m(truth, sensed_configuration(q_cm, effects.com_offset_m), motor)
                                  : truth.reference_gap_m;
  }

  // ẋ for motor-current commands i_cmd (8: [i_d, i_q] per motor).
  Eigen::VectorXd derivative(const Eigen::VectorXd& x, const Vector8d& i_cmd) const {
    const Vector6d q = x.head<6>(), qd = x.segment<6>(6);
    Vector8d f;
    Eigen::VectorXd dx(n);
    for (int i = 0; i < 4; ++i) {
      const double g = gap(q, i);
      Eigen::Vector2d current = i_cmd.segment<2>(2 * i);
      if (effects.electrical_lag) {
        current = x.segment<2>(12 + 2 * i);
        // Back-EMF from the array's own velocity: the centre of mass's plus ω × (r_i − c).
        const Eigen::Vector3d v = array_velocity(q, qd, arms_from_cm.col(i));
        const double drive_velocity = (i % 2 == 0) ? v(0) : v(1);
        dx.segment<2>(12 + 2 * i) = current_derivative(truth, current, i_cmd.segment<2>(2 * i), drive_velocity,
                                                       v(2), g);
      }
      const Eigen::Vector2d hv = effects.force_constant_scale * motor_forces(truth, current(0), current(1), g);
      f(2 * i) = hv(0);
      f(2 * i + 1) = hv(1);
    }
    const Vector6d u = wrench_to_generalized(q) * (A_true * f);
    dx.head<6>() = qd;
    dx.segment<6>(6) = acceleration(truth, q, qd, u);
    return dx;
  }
};

}  // namespace

StageRun simulate_regulation(const StageParameters& truth, const StageEffects& effects, const Vector6d& q0,
                             const Vector6d& q_ref, const SlidingModeOptions& smc, const SimulationOptions& sim) {
  truth.validate();
  smc.validate();
  sim.validate(smc);
  if (!q0.allFinite() || !q_ref.allFinite()) throw InputError("initial and reference configurations must be finite");
  if (!effects.com_offset_m.allFinite() || !(effects.force_constant_scale > 0))
    throw InputError("stage effects: com_offset_m must be finite and force_constant_scale positive");
  if (!(effects.input_delay_s >= 0.0 && effects.input_delay_s <= 0.1))
    throw InputError(fmt::format("stage effects: input delay {} s; give 0 to 0.1 s", effects.input_delay_s));

  const double period = 1.0 / smc.control_rate_hz;
  const int substeps = static_cast<int>(std::llround(period / sim.integration_step_s));
  const double h = period / substeps;
  const Eigen::Index N = static_cast<Eigen::Index>(std::llround(sim.duration_s * smc.control_rate_hz)) + 1;

  // The controller's model: nominal geometry, force constant, α = 1.
  const Eigen::Matrix<double, 8, 6> A_pinv = allocation_pseudo_inverse(truth.lever_arms_m);
  const Plant plant(truth, effects);

  StageRun run;
  run.t_s.resize(N);
  for (auto* m : {&run.q, &run.q_measured, &run.qd, &run.sigma, &run.u, &run.wrench, &run.excitation})
    m->resize(N, 6);
  run.forces.resize(N, 8);

  std::mt19937_64 rng(sim.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  Eigen::VectorXd x = Eigen::VectorXd::Zero(plant.n);
  x.head<6>() = centre_of_mass_configuration(q0, effects.com_offset_m);
  Vector6d noise_prev = Vector6d::Zero();
  bool currents_initialised = false;
  // Every command so far (the input delay reaches back into them).
  std::vector<Vector8d> commands;
  const Index delay_steps = static_cast<Index>(std::llround(effects.input_delay_s / h));
  for (Eigen::Index k = 0; k < N; ++k) {
    // What the sensors look at: the reference point (the centre of mass less R c).
    const Vector6d q = sensed_configuration(x.head<6>(), effects.com_offset_m);
    const Vector6d qd = sensed_velocity(x.head<6>(), x.segment<6>(6), effects.com_offset_m);
    Vector6d noise, excitation;
    for (int c = 0; c < 6; ++c) noise(c) = sim.sensor_noise_std(c) * normal(rng);
    for (int c = 0; c < 6; ++c) excitation(c) = sim.excitation_std(c) * normal(rng);
    if (sim.excitation_samples.size() != 0) excitation = sim.excitation_samples.row(k).transpose();
    if (k == 0) noise_prev = noise;
    // What the controller sees: measured q, and a velocity that is exact but for
    // the difference of the sensor noise over one period (the noise a backward
    // difference of q would add, without its half sample of lag).
    const Vector6d q_meas = q + noise;
    const Vector6d qd_meas = qd + (noise - noise_prev) / period;
    noise_prev = noise;

    const Vector6d e = q_meas - q_ref;
    const Vector6d sigma = qd_meas + smc.lambda_per_s * e;
    const Vector6d accel = -smc.lambda_per_s * qd_meas - smc.gain_K * sigma / (sigma.norm() + smc.boundary_layer);
    const Vector6d u = smc.inertia_scale * (mass_matrix(truth, q_meas) * accel) + gravity_term(truth);
    // Body wrench from the generalised force: F_b = Rᵀ u_t, τ_b = W⁻ᵀ u_a.
    Vector6d w;
    w.head<3>() = rotation(q_meas).transpose() * u.head<3>();
    w.tail<3>() = angular_velocity_map(q_meas(4), q_meas(5)).transpose().partialPivLu().solve(u.tail<3>());
    w += excitation;
    const Vector8d f = A_pinv * w;
    Vector8d i_cmd;
    for (int i = 0; i < 4; ++i)
      i_cmd.segment<2>(2 * i) = motor_currents(truth, f(2 * i), f(2 * i + 1), truth.reference_gap_m);

    run.t_s(k) = static_cast<double>(k) * period;
    run.q.row(k) = q.transpose();
    run.q_measured.row(k) = q_meas.transpose();
    run.qd.row(k) = qd.transpose();
    run.sigma.row(k) = sigma.transpose();
    run.u.row(k) = u.transpose();
    run.wrench.row(k) = w.transpose();
    run.excitation.row(k) = excitation.transpose();
    run.forces.row(k) = f.transpose();
    if (k == N - 1) break;

    if (effects.electrical_lag && !currents_initialised) {
      x.tail<8>() = i_cmd;  // the current loop starts settled on the first command
      currents_initialised = true;
    }
    commands.push_back(i_cmd);
    for (int s = 0; s < substeps; ++s) {
      // The command in force during this step: computed delay_steps steps ago (the
      // first command before that: the stage starts settled on it).
      const Index since = static_cast<Index>(commands.size() - 1) * substeps + s - delay_steps;
      const Vector8d& applied = commands[static_cast<std::size_t>(std::max<Index>(0, since) / substeps)];
      const Eigen::VectorXd k1 = plant.derivative(x, applied);
      const Eigen::VectorXd k2 = plant.derivative(x + 0.5 * h * k1, applied);
      const Eigen::VectorXd k3 = plant.derivative(x + 0.5 * h * k2, applied);
      const Eigen::VectorXd k4 = plant.derivative(x + h * k3, applied);
      x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    if (!x.allFinite() || std::abs(x(4)) >= 1.5)
      throw NumericalError(fmt::format(
          "stage simulation diverged at t = {:.4g} s (state not finite or pitch near 90 deg); "
          "raise the control rate, lower K/delta, or check the parameters",
          static_cast<double>(k + 1) * period));
  }
  return run;
}

StageLog experiment_log(const StageRun& run) {
  StageLog log;
  log.names = {"t"};
  for (const char* prefix : {"v", "u", "q"})
    for (int c = 1; c <= 6; ++c) log.names.push_back(fmt::format("{}{}", prefix, c));
  const Eigen::Index N = run.t_s.size();
  log.data.resize(N, 19);
  log.data.col(0) = run.t_s;
  log.data.middleCols(1, 6) = run.excitation;
  log.data.middleCols(7, 6) = run.wrench;
  log.data.middleCols(13, 6) = run.q_measured;
  return log;
}

GapExcursion gap_excursion(const StageParameters& p, const StageRun& run) {
  LPVID_ASSERT(run.q.rows() == run.t_s.size() && run.q.rows() > 0 && run.q.cols() == 6);
  GapExcursion g;
  g.min_gap_m = std::numeric_limits<double>::infinity();
  g.max_gap_m = -std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 0; k < run.q.rows(); ++k) {
    const Vector6d q = run.q.row(k).transpose();
    for (int i = 0; i < 4; ++i) {
      const double gap = motor_gap_m(p, q, i);
      if (gap < g.min_gap_m) g = {gap, g.max_gap_m, i, run.t_s(k)};
      g.max_gap_m = std::max(g.max_gap_m, gap);
    }
  }
  return g;
}

ExperimentRun simulate_experiment_in_gap(const StageParameters& truth, const StageEffects& effects, const Vector6d& q0,
                                         const Vector6d& q_ref, const SlidingModeOptions& smc, SimulationOptions sim,
                                         bool back_off) {
  const double low = kSafeGapFraction.first * truth.reference_gap_m;
  const double high = kSafeGapFraction.second * truth.reference_gap_m;
  // Halving does nothing to a designed excitation or to none.
  back_off = back_off && sim.excitation_samples.size() == 0 && !sim.excitation_std.isZero();
  ExperimentRun e;
  for (int halvings = 0;; ++halvings) {
    e.run = simulate_regulation(truth, effects, q0, q_ref, smc, sim);
    e.gaps = gap_excursion(truth, e.run);
    if (halvings == 0) e.first_gaps = e.gaps;
    const bool inside = e.gaps.min_gap_m >= low && e.gaps.max_gap_m <= high;
    if (!back_off || inside || halvings == kMaxExcitationHalvings) return e;
    sim.excitation_std *= 0.5;
    e.scale *= 0.5;
  }
}

StateSpace linearize_hover(const StageParameters& p, double z0_m) {
  p.validate();
  if (!std::isfinite(z0_m)) throw InputError("linearize_hover: z0_m must be finite");
  Vector6d q0 = Vector6d::Zero();
  q0(2) = z0_m;
  StateSpace ss;
  ss.A = Eigen::MatrixXd::Zero(12, 12);
  ss.A.topRightCorner(6, 6).setIdentity();
  // Tilt of the body-frame lift m g: ẍ = g θ, ÿ = −g φ (∂(R e_z)/∂θ = e_x, ∂/∂φ = −e_y at 0).
  ss.A(6, 4) = kGravity_m_per_s2;
  ss.A(7, 5) = -kGravity_m_per_s2;
  ss.B = Eigen::MatrixXd::Zero(12, 6);
  ss.B.bottomRows(6) = mass_matrix(p, q0).inverse() * wrench_to_generalized(q0);
  ss.C = Eigen::MatrixXd::Zero(6, 12);
  ss.C.leftCols(6).setIdentity();
  ss.D = Eigen::MatrixXd::Zero(6, 6);
  ss.input_names = {"F_x", "F_y", "F_z", "tau_x", "tau_y", "tau_z"};
  ss.output_names = {"x", "y", "z", "psi", "theta", "phi"};
  return ss;
}

}  // namespace lpvid::stage6
