#include "idlib/stage6/stage6_fit.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace lpvid::stage6 {

std::string StageFitModel::name() const {
  std::string s = "base";
  if (com_offset) s += "+com";
  if (gap_dependence) s += "+gap";
  if (electrical_lag) s += "+lag";
  return s;
}

namespace {

// Torque rows are scaled by one lever arm so that both kinds of row weigh alike.
constexpr double kTorqueScale_m = 0.075;

struct Sample {
  Eigen::Matrix3d R, W, Wt;
  Eigen::Vector3d qdd_t, qdd_a, wdot_qd, omega;  // omega = W q̇_a, wdot_qd = Ẇ q̇_a
  Vector8d f_bar;                                // triangular-average motor forces
  Eigen::Vector4d gap_minus_ref_m;               // gap_i − z_ref
  // Velocity of each array along body axes, Rᵀ q̇_t + ω × r_i (back-EMF of the lag
  // effect): the reference point's q̇_t with the designed arm r_i equals the centre
  // of mass's velocity with the true arm r_i − c, so c does not enter.
  Eigen::Matrix<double, 3, 4> array_velocity;
};

struct Residual {
  const Sample* s;
  const Eigen::Matrix<double, 3, 4>* r;
  double force_scale, torque_scale;

  // base = [m, Hx, Hy, Hz, κ], com = [cx, cy, cz], gap = [γ], emf = [b] (N·s/m).
  template <typename T>
  bool operator()(const T* base, const T* com, const T* gap, const T* emf, T* out) const {
    using V3 = Eigen::Matrix<T, 3, 1>;
    const T m = base[0];
    const V3 H(base[1], base[2], base[3]);
    const T kappa = base[4];
    // Forces with the gap factor, then the wrench about the (offset) centre of mass.
    V3 F = V3::Zero(), tau = V3::Zero();
    for (int i = 0; i < 4; ++i) {
      const T alpha = exp(-gap[0] * T(s->gap_minus_ref_m(i)));
      V3 fi = V3::Zero();
      const int h = i % 2 == 0 ? 0 : 1;  // drive axis of motor i
      fi(h) = alpha * (T(s->f_bar(2 * i)) - emf[0] * T(s->array_velocity(h, i)));
      fi(2) = alpha * (T(s->f_bar(2 * i + 1)) - emf[0] * T(s->array_velocity(2, i)));
      const V3 ri(T((*r)(0, i)) - com[0], T((*r)(1, i)) - com[1], T((*r)(2, i)) - com[2]);
      F += fi;
      tau += ri.cross(fi);
    }
    F *= kappa;
    tau *= kappa;
    const V3 wdot = (s->W * s->qdd_a + s->wdot_qd).cast<T>();
    const V3 omega = s->omega.cast<T>();
    // Translational rows: m p̈_cm + m g e_z − R F, the centre of mass being at the
    // sensed reference point plus R c: p̈_cm = q̈_t + R (ω̇ × c + ω × (ω × c)).
    const V3 c(com[0], com[1], com[2]);
    const V3 acc_cm = s->qdd_t.cast<T>() + s->R.cast<T>() * V3(wdot.cross(c) + omega.cross(V3(omega.cross(c))));
    const V3 trans = m * acc_cm + V3(T(0), T(0), m * T(kGravity_m_per_s2)) - s->R.cast<T>() * F;
    // Rotational rows: Wᵀ(H(W q̈_a + Ẇ q̇_a) + ω × Hω − τ).
    const V3 Hwdot = H.cwiseProduct(wdot), Hw = H.cwiseProduct(omega);
    const V3 rot = s->Wt.cast<T>() * (Hwdot + omega.cross(Hw) - tau);
    for (int c = 0; c < 3; ++c) {
      out[c] = trans(c) * T(force_scale);
      out[3 + c] = rot(c) * T(torque_scale);
    }
    return true;
  }
};

// Triangular averages f̄_k (rows 1..N−2) of ZOH forces f_j through a first-order
// lag τ (τ = 0: no lag): docs/math.md.
Eigen::MatrixXd triangular_force_average(const Eigen::MatrixXd& f, double Ts, double tau) {
  const Eigen::Index N = f.rows();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(N, 8);
  if (tau <= 0) {
    for (Eigen::Index k = 1; k + 1 < N; ++k) out.row(k) = 0.5 * (f.row(k - 1) + f.row(k));
    return out;
  }
  const double a = std::exp(-Ts / tau);
  const double I1 = (tau * Ts - tau * tau * (1 - a)) / (Ts * Ts);   // ∫₀^Ts (Ts−s) e^{−s/τ} ds / Ts²
  const double I2 = (tau * tau * (1 - a) - tau * Ts * a) / (Ts * Ts);  // ∫₀^Ts s e^{−s/τ} ds / Ts²
  Eigen::MatrixXd y(N, 8);  // filter output at t_j; starts settled on f_0
  y.row(0) = f.row(0);
  for (Eigen::Index j = 0; j + 1 < N; ++j) y.row(j + 1) = f.row(j) + a * (y.row(j) - f.row(j));
  for (Eigen::Index k = 1; k + 1 < N; ++k)
    out.row(k) = 0.5 * f.row(k - 1) + I2 * (y.row(k - 1) - f.row(k - 1)) + 0.5 * f.row(k) + I1 * (y.row(k) - f.row(k));
  return out;
}

struct Problem {
  const StageParameters& nominal;
  std::vector<Sample> samples;
  Eigen::MatrixXd f;  // N × 8 allocated forces
  double Ts;
};

StageFitResult solve(Problem& P, const StageFitModel& model, double tau, const StageFitOptions& options) {
  const Eigen::MatrixXd fbar = triangular_force_average(P.f, P.Ts, tau);
  for (std::size_t k = 0; k < P.samples.size(); ++k) P.samples[k].f_bar = fbar.row(static_cast<Eigen::Index>(k) + 1);

  double base[5] = {P.nominal.mass_kg, P.nominal.inertia_kgm2(0, 0), P.nominal.inertia_kgm2(1, 1),
                    P.nominal.inertia_kgm2(2, 2), 1.0};
  double com[3] = {0, 0, 0};
  double gap[1] = {model.gap_dependence ? P.nominal.gamma_per_m() : 0.0};
  double emf[1] = {0.0};
  ceres::Problem problem;
  const double force_scale = 1.0 / (P.nominal.mass_kg * kGravity_m_per_s2);
  for (const Sample& s : P.samples) {
    auto* cost = new ceres::AutoDiffCostFunction<Residual, 6, 5, 3, 1, 1>(
        new Residual{&s, &P.nominal.lever_arms_m, force_scale, force_scale / kTorqueScale_m});
    problem.AddResidualBlock(cost, nullptr, base, com, gap, emf);
  }
  for (int i = 0; i < 5; ++i) problem.SetParameterLowerBound(base, i, 1e-9);
  problem.SetManifold(base, new ceres::SubsetManifold(5, {options.fix_mass ? 0 : 4}));
  if (!model.com_offset) problem.SetParameterBlockConstant(com);
  if (!model.gap_dependence) problem.SetParameterBlockConstant(gap);
  if (!model.electrical_lag) problem.SetParameterBlockConstant(emf);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.gradient_tolerance = 1e-16;
  so.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable())
    throw NumericalError("stage fit: Ceres found no usable solution (" + summary.message +
                         "); check that the log excites all six axes");

  StageFitResult r;
  r.model = model;
  r.mass_kg = base[0];
  r.inertia_diag_kgm2 = Eigen::Vector3d(base[1], base[2], base[3]);
  r.force_constant_scale = base[4];
  if (model.com_offset) r.com_offset_m = Eigen::Vector3d(com[0], com[1], com[2]);
  if (model.gap_dependence) r.gamma_per_m = gap[0];
  if (model.electrical_lag) r.electrical_time_constant_s = tau, r.back_emf_damping_Ns_per_m = emf[0];
  r.num_parameters = 4 + (model.com_offset ? 3 : 0) + (model.gap_dependence ? 1 : 0) + (model.electrical_lag ? 2 : 0);
  r.num_residuals = static_cast<Eigen::Index>(P.samples.size()) * 6;
  r.residual.resize(static_cast<Eigen::Index>(P.samples.size()), 6);
  for (std::size_t k = 0; k < P.samples.size(); ++k) {
    const Residual res{&P.samples[k], &P.nominal.lever_arms_m, force_scale, force_scale / kTorqueScale_m};
    double row[6];
    res(base, com, gap, emf, row);
    for (int c = 0; c < 6; ++c) r.residual(static_cast<Eigen::Index>(k), c) = row[c];
  }
  if (r.residual.rows() > 0)
    r.rms_per_row = (r.residual.colwise().squaredNorm() / static_cast<double>(r.residual.rows())).cwiseSqrt().transpose();
  const double n = static_cast<double>(r.num_residuals);
  const double rss = 2.0 * summary.final_cost;
  r.rms_residual = std::sqrt(rss / n);
  r.bic = n * std::log(std::max(rss, 1e-300) / n) + r.num_parameters * std::log(n);
  r.report.usable = true;
  r.report.termination = fmt::format("Ceres {} after {} iterations: {}", summary.termination_type == ceres::CONVERGENCE ? "converged" : "stopped",
                                     summary.iterations.size(), summary.message);
  if (summary.termination_type != ceres::CONVERGENCE)
    r.report.warnings.push_back("stage fit did not meet its tolerances: " + summary.message);
  return r;
}

}  // namespace

StageFitResult fit_stage(const StageParameters& nominal, const Eigen::MatrixXd& u, const Eigen::MatrixXd& q,
                         double sample_period_s, const StageFitModel& model, const StageFitOptions& options) {
  nominal.validate();
  if (u.cols() != 6 || q.cols() != 6 || u.rows() != q.rows())
    throw InputError(fmt::format("stage fit: u and q must both be N x 6, got {}x{} and {}x{}", u.rows(), u.cols(),
                                 q.rows(), q.cols()));
  if (u.rows() < 10) throw InputError(fmt::format("stage fit: {} samples; need at least 10", u.rows()));
  if (!u.allFinite() || !q.allFinite()) throw InputError("stage fit: the log has non-finite values");
  if (!(sample_period_s > 0) || !std::isfinite(sample_period_s))
    throw InputError(fmt::format("stage fit: sample period {} s must be positive", sample_period_s));
  // A column that never changes carries no information: a wrench channel that
  // is never driven, or an axis that never moves, leaves the mass and inertia of
  // that axis undetermined, and the fit would only return its start values.
  for (int c = 0; c < 6; ++c)
    for (const auto& [m, name] : {std::pair<const Eigen::MatrixXd*, char>{&u, 'u'}, {&q, 'q'}})
      if (!(m->col(c).array() != (*m)(0, c)).any())
        throw InputError(fmt::format("stage fit: {}{} is {} throughout the log, so it carries no information about the "
                                     "stage's mass and inertia; give a closed-loop log with excitation (lpvid simulate "
                                     "stage6 --experiment writes one)",
                                     name, c + 1, (*m)(0, c)));

  Problem P{nominal, {}, {}, sample_period_s};
  const Eigen::Matrix<double, 8, 6> A_pinv = allocation_pseudo_inverse(nominal.lever_arms_m);
  P.f = u * A_pinv.transpose();
  const double Ts = sample_period_s;
  const Eigen::Index N = u.rows();
  P.samples.resize(static_cast<std::size_t>(N - 2));
  for (Eigen::Index k = 1; k + 1 < N; ++k) {
    Sample& s = P.samples[static_cast<std::size_t>(k - 1)];
    const Vector6d qk = q.row(k).transpose();
    const Vector6d qdd = (q.row(k + 1) - 2 * q.row(k) + q.row(k - 1)).transpose() / (Ts * Ts);
    const Vector6d qd = (q.row(k + 1) - q.row(k - 1)).transpose() / (2 * Ts);
    s.R = rotation(qk);
    s.W = angular_velocity_map(qk(4), qk(5));
    s.Wt = s.W.transpose();
    s.qdd_t = qdd.head<3>();
    s.qdd_a = qdd.tail<3>();
    s.omega = s.W * qd.tail<3>();
    for (int i = 0; i < 4; ++i)
      s.array_velocity.col(i) = s.R.transpose() * qd.head<3>() + s.omega.cross(Eigen::Vector3d(nominal.lever_arms_m.col(i)));
    // Ẇ q̇_a from the difference of W along the motion (exact to O(Ts²)).
    Vector6d qp = qk + qd * 1e-6, qm = qk - qd * 1e-6;
    s.wdot_qd = (angular_velocity_map(qp(4), qp(5)) - angular_velocity_map(qm(4), qm(5))) / 2e-6 * qd.tail<3>();
    for (int i = 0; i < 4; ++i) s.gap_minus_ref_m(i) = motor_gap_m(nominal, qk, i) - nominal.reference_gap_m;
  }

  if (!model.electrical_lag) return solve(P, model, 0.0, options);
  // Golden-section search on log τ with the inner fit.
  const double phi = (std::sqrt(5.0) - 1) / 2;
  double a = std::log(options.lag_min_s), b = std::log(options.lag_max_s);
  double c = b - phi * (b - a), d = a + phi * (b - a);
  StageFitResult rc = solve(P, model, std::exp(c), options), rd = solve(P, model, std::exp(d), options);
  while (b - a > options.lag_log_tolerance) {
    if (rc.rms_residual < rd.rms_residual) {
      b = d, d = c, rd = rc;
      c = b - phi * (b - a);
      rc = solve(P, model, std::exp(c), options);
    } else {
      a = c, c = d, rc = rd;
      d = a + phi * (b - a);
      rd = solve(P, model, std::exp(d), options);
    }
  }
  return rc.rms_residual < rd.rms_residual ? rc : rd;
}

StageDiagnosis diagnose_stage_from(const StageFitModel& current, const StageParameters& nominal,
                                   const Eigen::MatrixXd& u, const Eigen::MatrixXd& q, double sample_period_s,
                                   const StageFitOptions& options) {
  StageDiagnosis d;
  d.base = fit_stage(nominal, u, q, sample_period_s, current, options);
  for (int c = 0; c < 3; ++c) {
    StageFitModel m = current;
    bool& flag = c == 0 ? m.com_offset : (c == 1 ? m.gap_dependence : m.electrical_lag);
    if (flag) continue;  // already in the model
    flag = true;
    d.candidates.push_back(fit_stage(nominal, u, q, sample_period_s, m, options));
  }
  std::sort(d.candidates.begin(), d.candidates.end(),
            [](const StageFitResult& x, const StageFitResult& y) { return x.bic < y.bic; });
  return d;
}

StageDiagnosis diagnose_stage(const StageParameters& nominal, const Eigen::MatrixXd& u, const Eigen::MatrixXd& q,
                              double sample_period_s, const StageFitOptions& options) {
  StageFitModel base;
  base.com_offset = false;
  return diagnose_stage_from(base, nominal, u, q, sample_period_s, options);
}

}  // namespace lpvid::stage6
