#include "idlib/stage6/stage6_output_error.h"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <memory>

namespace lpvid::stage6 {

const std::array<const char*, kStageThetaSize> kStageThetaNames = {
    "mass_kg",        "inertia_xx_kgm2", "inertia_yy_kgm2", "inertia_zz_kgm2",
    "force_constant_scale", "com_offset_x_m", "com_offset_y_m", "com_offset_z_m",
    "gamma_per_m",    "electrical_time_constant_s", "back_emf_damping_Ns_per_m"};
const std::array<const char*, 6> kStageChannelNames = {"x", "y", "z", "psi", "theta", "phi"};

void StageOutputErrorOptions::validate() const {
  if (!std::isfinite(window_s) || window_s <= 0)
    throw InputError(fmt::format("output-error option window_s = {}: must be a positive number of seconds", window_s));
  if (rk4_substeps < 0 || rk4_substeps > 100)
    throw InputError(fmt::format("output-error option rk4_substeps = {}: must be 0 (automatic) to 100", rk4_substeps));
  if (lag_warmup_samples < 0)
    throw InputError(fmt::format("output-error option lag_warmup_samples = {}: must be >= 0", lag_warmup_samples));
  if (max_iterations < 1)
    throw InputError(fmt::format("output-error option max_iterations = {}: must be >= 1", max_iterations));
}

namespace {

// The first pass's channel scales: 1 nm, and 1 nm at one lever arm for the angles.
constexpr double kFirstPassScale_m = 1e-9;
constexpr double kLeverArm_m = 0.075;
// A channel whose rms output error after the first pass is below this (m or rad)
// is a noise-free channel fitted to rounding; its weight is capped there.
constexpr double kScaleFloor = 1e-14;
// State sizes: q (6), ṗ (3), ω (3), and with the lag effect its states y (8).
// The size is a template parameter so that the rigid model's Jets carry no
// unused lag states.
constexpr int kRigidStates = 12, kLagStates = 20;

template <typename T, int NX>
using State = Eigen::Matrix<T, NX, 1>;

// R(ψ, θ, φ) of a state (eq 1).
template <typename T, int NX>
Eigen::Matrix<T, 3, 3> rotation_of(const State<T, NX>& x) {
  return rotation_zyx<T>(x(3), x(4), x(5));
}

// The centre-of-mass offset c = θ[5..7].
template <typename T>
Eigen::Matrix<T, 3, 1> com_of(const T* th) {
  return Eigen::Matrix<T, 3, 1>(th[5], th[6], th[7]);
}

// α of motor i's array: its gap follows the reference point p − R c and the
// designed arm r_i (gap − z_ref = z_ref_point + (R r_i)_z − r_iz − z_ref).
template <typename T, int NX>
T gap_alpha(const T* th, const State<T, NX>& x, const Eigen::Matrix<T, 3, 3>& R, const Eigen::Vector3d& ri,
            double z_ref) {
  using std::exp;
  const Eigen::Matrix<T, 3, 1> c = com_of(th);
  const T z_point = x(2) - (R(2, 0) * c(0) + R(2, 1) * c(1) + R(2, 2) * c(2));
  const T gap_minus_ref = z_point + R(2, 0) * ri(0) + R(2, 1) * ri(1) + R(2, 2) * ri(2) - ri(2) - z_ref;
  return exp(-th[8] * gap_minus_ref);
}

// ẋ of the model in the header comment; th = θ (kStageThetaNames order); x's
// position is the centre of mass's.
template <typename T, int NX>
State<T, NX> derivative(const T* th, const State<T, NX>& x, const Vector8d& f, const Eigen::Matrix<double, 3, 4>& r,
                        double z_ref) {
  constexpr bool lag = NX == kLagStates;
  using V3 = Eigen::Matrix<T, 3, 1>;
  const Eigen::Matrix<T, 3, 3> R = rotation_of(x);
  const V3 v = x.template segment<3>(6), w = x.template segment<3>(9);
  const V3 c = com_of(th);
  State<T, NX> dx;
  V3 F = V3::Zero(), tau = V3::Zero();
  [[maybe_unused]] const V3 v_body = R.transpose() * v;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d ri = r.col(i);
    const T alpha = gap_alpha(th, x, R, ri, z_ref);
    const int h = drive_axis(i);        // body x for motors 1, 3; y for 2, 4
    const V3 arm = ri.cast<T>() - c;    // from the centre of mass
    T fh, fz;
    if constexpr (lag) {
      // Back-EMF from the array's own velocity in body axes: Rᵀ ṗ + ω × (r_i − c).
      const V3 va = v_body + w.cross(arm);
      const T yh = x(12 + 2 * i), yz = x(12 + 2 * i + 1);
      dx(12 + 2 * i) = (T(f(2 * i)) - yh - th[10] * alpha * va(h)) / th[9];
      dx(12 + 2 * i + 1) = (T(f(2 * i + 1)) - yz - th[10] * alpha * va(2)) / th[9];
      fh = alpha * yh;
      fz = alpha * yz;
    } else {
      fh = alpha * T(f(2 * i));
      fz = alpha * T(f(2 * i + 1));
    }
    V3 fi = V3::Zero();
    fi(h) = fh;
    fi(2) = fz;
    F += fi;
    tau += arm.cross(fi);
  }
  const V3 H(th[1], th[2], th[3]);
  const V3 acc = R * F * (th[4] / th[0]) - V3(T(0), T(0), T(kGravity_m_per_s2));
  const V3 wdot = (tau * th[4] - w.cross(V3(H.cwiseProduct(w)))).cwiseQuotient(H);
  // q̇_a = W⁻¹ ω (W of eq 4, columns ψ̇ θ̇ φ̇).
  dx.template head<3>() = v;
  dx.template segment<3>(3) = euler_rates<T>(x(4), x(5), w);
  dx.template segment<3>(6) = acc;
  dx.template segment<3>(9) = wdot;
  return dx;
}

struct Log {
  Eigen::MatrixXd f;  // N × 8 allocated motor forces
  Eigen::MatrixXd q;  // N × 6 measured
  double Ts = 0;
  Eigen::Matrix<double, 3, 4> r;
  double z_ref = 0;
};

// One window's output error: parameter blocks x_w (12) and θ (11).
struct WindowResidual {
  const Log* log;
  Eigen::Index k0, len;
  int substeps, warmup;
  bool lag;
  Vector6d inv_scale;

  template <typename T>
  bool operator()(const T* x0, const T* th, T* res) const {
    return lag ? simulate<T, kLagStates>(x0, th, res) : simulate<T, kRigidStates>(x0, th, res);
  }

  template <typename T, int NX>
  bool simulate(const T* x0, const T* th, T* res) const {
    State<T, NX> x;
    for (int i = 0; i < 12; ++i) x(i) = x0[i];
    if constexpr (NX == kLagStates) init_lag(x, th);
    const double h = log->Ts / substeps;
    const Eigen::Matrix<T, 3, 1> c_off = com_of(th);
    for (Eigen::Index j = 0; j < len; ++j) {
      const Eigen::Index k = k0 + j;
      // The sensors see the reference point p − R c and the angles.
      const Eigen::Matrix<T, 3, 1> Rc = rotation_of(x) * c_off;
      for (int c = 0; c < 3; ++c) res[6 * j + c] = (x(c) - Rc(c) - T(log->q(k, c))) * T(inv_scale(c));
      for (int c = 3; c < 6; ++c) res[6 * j + c] = (x(c) - T(log->q(k, c))) * T(inv_scale(c));
      if (j + 1 == len) break;
      const Vector8d f = log->f.row(k).transpose();
      for (int s = 0; s < substeps; ++s) {
        using S = State<T, NX>;
        const S k1 = derivative<T, NX>(th, x, f, log->r, log->z_ref);
        const S k2 = derivative<T, NX>(th, S(x + (0.5 * h) * k1), f, log->r, log->z_ref);
        const S k3 = derivative<T, NX>(th, S(x + (0.5 * h) * k2), f, log->r, log->z_ref);
        const S k4 = derivative<T, NX>(th, S(x + h * k3), f, log->r, log->z_ref);
        x += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      }
      // A window that diverges (a model missing a stiffness, a trial step too
      // far): tell Ceres the point is not evaluable (it then shortens the step,
      // without printing a warning over the user's terminal).
      if (!finite_value(x(0)) || !finite_value(x(2)) || !finite_value(x(4))) return false;
    }
    return true;
  }

  static bool finite_value(double v) { return std::isfinite(v); }
  template <typename J>
  static bool finite_value(const J& v) {
    return std::isfinite(v.a) && v.v.allFinite();
  }

  // Lag states at the window start: the exact ZOH response of τ_e ẏ = f − y − bαv
  // to the commands before the window, with α of the window's initial state
  // and v over each sample from the measured q (first differences: the mean
  // velocity over the sample; noise enters as bα·√2σ/Ts, 1e-4 N for 1 nm).
  template <typename T>
  void init_lag(State<T, kLagStates>& x, const T* th) const {
    using std::exp;
    if (k0 == 0) {  // settled on the first command (the simulator's start)
      for (int i = 0; i < 8; ++i) x(12 + i) = T(log->f(0, i));
      return;
    }
    const Eigen::Index n = std::min<Eigen::Index>(warmup, k0);
    const T a = exp(-T(log->Ts) / th[9]);
    // bα_i at the window's initial state.
    const Eigen::Matrix<T, 3, 3> R = rotation_of(x);
    std::array<T, 4> b_alpha;
    for (int i = 0; i < 4; ++i)
      b_alpha[static_cast<std::size_t>(i)] = th[10] * gap_alpha(th, x, R, Eigen::Vector3d(log->r.col(i)), log->z_ref);
    for (int i = 0; i < 8; ++i) {
      // The array's velocity along force i over sample j from the measured q: the
      // reference point's Rᵀ ṗ + ω × r_i with the designed arm (equal to the centre
      // of mass's velocity with the true arm r_i − c).
      const int motor = i / 2;
      const int axis = i % 2 == 1 ? 2 : (motor % 2 == 0 ? 0 : 1);  // z for the vertical forces
      const T& ba = b_alpha[static_cast<std::size_t>(motor)];
      auto target = [&](Eigen::Index j) {
        const Vector6d qj = log->q.row(j).transpose();
        const Vector6d dq = (log->q.row(j + 1) - log->q.row(j)).transpose() / log->Ts;
        const Eigen::Vector3d v = array_velocity(qj, dq, log->r.col(motor));
        return T(log->f(j, i)) - ba * T(v(axis));
      };
      T y = target(k0 - n);
      for (Eigen::Index j = k0 - n; j < k0; ++j) {
        const T t = target(j);
        y = t + a * (y - t);
      }
      x(12 + i) = y;
    }
  }
};

void check_log(const Eigen::MatrixXd& u, const Eigen::MatrixXd& q, double Ts) {
  if (u.cols() != 6 || q.cols() != 6 || u.rows() != q.rows())
    throw InputError(fmt::format("stage output-error fit: u and q must both be N x 6, got {}x{} and {}x{}", u.rows(),
                                 u.cols(), q.rows(), q.cols()));
  if (u.rows() < 10) throw InputError(fmt::format("stage output-error fit: {} samples; need at least 10", u.rows()));
  if (!u.allFinite() || !q.allFinite()) throw InputError("stage output-error fit: the log has non-finite values");
  if (!(Ts > 0) || !std::isfinite(Ts))
    throw InputError(fmt::format("stage output-error fit: sample period {} s must be positive", Ts));
}

// Initial state of a window from the measurements: q at its first row, and the
// velocity from the first difference corrected by half a sample of the start
// model's acceleration under the held command: (q₁ − q₀)/Ts = q̇₀ + q̈₀ Ts/2.
// The state's position is the centre of mass's: the reference point's plus R c,
// its velocity plus R (ω × c).
Eigen::Matrix<double, 12, 1> initial_state(const Log& log, Eigen::Index k0, const double* th) {
  Eigen::Matrix<double, 12, 1> x0;
  const Eigen::Vector3d c(th[5], th[6], th[7]);
  const Vector6d q0 = centre_of_mass_configuration(log.q.row(k0).transpose(), c),
                 q1 = centre_of_mass_configuration(log.q.row(k0 + 1).transpose(), c);
  State<double, kRigidStates> x = State<double, kRigidStates>::Zero();
  x.head<6>() = q0;
  const State<double, kRigidStates> dx =
      derivative<double, kRigidStates>(th, x, log.f.row(k0).transpose(), log.r, log.z_ref);
  const Eigen::Matrix3d W = angular_velocity_map(q0(4), q0(5));
  Vector6d qd = (q1 - q0) / log.Ts;
  qd.head<3>() -= 0.5 * log.Ts * dx.segment<3>(6);
  qd.tail<3>() -= 0.5 * log.Ts * W.partialPivLu().solve(dx.segment<3>(9));
  x0.head<6>() = q0;
  x0.segment<3>(6) = qd.head<3>();
  x0.segment<3>(9) = W * qd.tail<3>();
  return x0;
}

using Theta = Eigen::Matrix<double, kStageThetaSize, 1>;
using WindowCost = ceres::AutoDiffCostFunction<WindowResidual, ceres::DYNAMIC, 12, kStageThetaSize>;

}  // namespace

namespace {

// The log cut into windows, each with its own initial state, and the weighted output
// error of every window (the channel scales divide the residuals).
struct Windows {
  const Log& log;
  std::vector<Eigen::Index> k0, len;
  std::vector<Eigen::Matrix<double, 12, 1>> xs;
  int substeps;
  int lag_warmup_samples;
  bool electrical_lag;
  Vector6d scale;

  WindowResidual* functor(std::size_t w) const {
    return new WindowResidual{&log, k0[w], len[w], substeps, lag_warmup_samples, electrical_lag, scale.cwiseInverse()};
  }
  // The unweighted residual of every row at θ.
  Eigen::MatrixXd raw_residual(Eigen::Index N, const Theta& theta) const {
    Eigen::MatrixXd e(N, 6);
    for (std::size_t w = 0; w < xs.size(); ++w) {
      std::unique_ptr<WindowResidual> f(functor(w));
      Eigen::VectorXd r(6 * len[w]);
      (*f)(xs[w].data(), theta.data(), r.data());
      for (Eigen::Index j = 0; j < len[w]; ++j)
        e.row(k0[w] + j) = r.segment<6>(6 * j).cwiseProduct(scale).transpose();
    }
    return e;
  }
};

// θ at the start (the given values, or the equation-error fit's) and which entries
// the fit estimates (none with given values).
Theta start_theta(const StageParameters& nominal, const StageFitModel& model, const StageOutputErrorOptions& options,
                  const StageFitResult& s0, const Theta* given, StageOutputErrorResult& out) {
  Theta theta;
  if (given) {
    theta = *given;
  } else {
    theta << s0.mass_kg, s0.inertia_diag_kgm2, s0.force_constant_scale, s0.com_offset_m, s0.gamma_per_m,
        model.electrical_lag ? s0.electrical_time_constant_s : nominal.electrical_time_constant_s(),
        s0.back_emf_damping_Ns_per_m;
  }
  if (!model.com_offset) theta.segment<3>(5).setZero();
  if (!model.gap_dependence) theta(8) = 0;
  if (!model.electrical_lag) theta(10) = 0;
  out.free.fill(false);
  if (!given) {
    out.free[0] = !options.fix_mass;
    out.free[1] = out.free[2] = out.free[3] = true;
    out.free[4] = options.fix_mass;
    out.free[5] = out.free[6] = out.free[7] = model.com_offset;
    out.free[8] = model.gap_dependence;
    out.free[9] = out.free[10] = model.electrical_lag;
  }
  return theta;
}

// Multiple shooting: the window states and θ's free entries by Ceres (a second pass
// reweighted by the first's channel residuals when options.reweight).
ceres::Solver::Summary solve_windows(Windows& win, Theta& theta, const std::vector<int>& held, int p, Eigen::Index N,
                                     const StageOutputErrorOptions& options, int passes, StageOutputErrorResult& out) {
  ceres::Solver::Summary summary;
  for (int pass = 0; pass < passes; ++pass) {
    if (pass > 0) {
      const Eigen::MatrixXd e = win.raw_residual(N, theta);
      for (int c = 0; c < 6; ++c) win.scale(c) = std::max(kScaleFloor, std::sqrt(e.col(c).squaredNorm() / double(N)));
    }
    ceres::Problem problem;
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (std::size_t w = 0; w < win.xs.size(); ++w) {
      problem.AddResidualBlock(new WindowCost(win.functor(w), static_cast<int>(6 * win.len[w])), nullptr,
                               win.xs[w].data(), theta.data());
      ordering->AddElementToGroup(win.xs[w].data(), 0);
    }
    ordering->AddElementToGroup(theta.data(), 1);
    for (int i : {0, 1, 2, 3, 4}) problem.SetParameterLowerBound(theta.data(), i, 1e-9);
    // τ_e > 0 (it divides); 1 ns is far below any current loop.
    problem.SetParameterLowerBound(theta.data(), 9, 1e-9);
    if (p == 0)
      problem.SetParameterBlockConstant(theta.data());
    else
      problem.SetManifold(theta.data(), new ceres::SubsetManifold(kStageThetaSize, held));
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_SCHUR;
    so.linear_solver_ordering = ordering;
    so.max_num_iterations = options.max_iterations;
    so.function_tolerance = 1e-12;
    so.parameter_tolerance = 1e-12;
    so.gradient_tolerance = 1e-16;
    so.num_threads = 1;
    ceres::Solve(so, &problem, &summary);
    out.iterations += static_cast<int>(summary.iterations.size()) - 1;
    if (!summary.IsSolutionUsable())
      throw NumericalError("stage output-error fit: Ceres found no usable solution (" + summary.message +
                           "); check that the log excites all six axes and that the start is sensible");
  }
  return summary;
}

// Parameter covariance with the window states marginalised (Schur complement); sets
// sigma2, covariance and std_error; returns the factorisation (its health is reported).
Eigen::LDLT<Eigen::MatrixXd> marginal_covariance(const Windows& win, const Theta& theta,
                                                 const std::vector<int>& free_index, double n, double k_total,
                                                 StageOutputErrorResult& out) {
  const int p = static_cast<int>(free_index.size());
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(p, p);
  double rss = 0;
  for (std::size_t w = 0; w < win.xs.size(); ++w) {
    const Eigen::Index m = 6 * win.len[w];
    WindowCost cost(win.functor(w), static_cast<int>(m));
    Eigen::VectorXd r(m);
    Eigen::Matrix<double, Eigen::Dynamic, 12, Eigen::RowMajor> Jx(m, 12);
    Eigen::Matrix<double, Eigen::Dynamic, kStageThetaSize, Eigen::RowMajor> Jt(m, kStageThetaSize);
    const double* params[2] = {win.xs[w].data(), theta.data()};
    double* jac[2] = {Jx.data(), Jt.data()};
    if (!cost.Evaluate(params, r.data(), jac) || !Jt.allFinite() || !Jx.allFinite())
      throw NumericalError("stage output-error fit: the model is not finite at the solution");
    rss += r.squaredNorm();
    if (p == 0) continue;  // nothing estimated (Eigen's solve on a 12 × 0 block reads a null pointer)
    Eigen::MatrixXd Jf(m, p);
    for (int i = 0; i < p; ++i) Jf.col(i) = Jt.col(free_index[static_cast<std::size_t>(i)]);
    const Eigen::Matrix<double, 12, 12> A = Jx.transpose() * Jx;
    const Eigen::MatrixXd B = Jx.transpose() * Jf;
    S += Jf.transpose() * Jf - B.transpose() * A.ldlt().solve(B);
  }
  out.sigma2 = rss / std::max(1.0, n - k_total);
  // Nothing estimated (p = 0): no covariance (the 1 × 1 identity only keeps Eigen
  // off empty matrices).
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(p == 0 ? Eigen::MatrixXd(Eigen::MatrixXd::Identity(1, 1)) : S);
  out.covariance = p == 0 ? Eigen::MatrixXd(0, 0) : Eigen::MatrixXd(out.sigma2 * ldlt.solve(Eigen::MatrixXd::Identity(p, p)));
  for (int i = 0; i < p; ++i)
    out.std_error(free_index[static_cast<std::size_t>(i)]) = std::sqrt(std::max(0.0, out.covariance(i, i)));
  return ldlt;
}

// The fit (given == nullptr: θ from the equation-error start, its free entries
// estimated) or the output error of given parameters (every θ entry held, only the
// window states fitted).
StageOutputErrorResult output_error_impl(const StageParameters& nominal, const Eigen::MatrixXd& u,
                                         const Eigen::MatrixXd& q, double sample_period_s, const StageFitModel& model,
                                         const StageOutputErrorOptions& options, const StageFitResult* start,
                                         const Theta* given) {
  nominal.validate();
  options.validate();
  check_log(u, q, sample_period_s);
  const double Ts = sample_period_s;
  const Eigen::Index N = u.rows();
  const Eigen::Index L = std::max<Eigen::Index>(10, std::llround(options.window_s / Ts));
  if (N < L)
    throw InputError(fmt::format("stage output-error fit: the log has {} rows, fewer than one window of {} rows "
                                 "(window_s = {} s); give a longer log or a shorter window",
                                 N, L, options.window_s));
  if (start && (start->model.com_offset != model.com_offset || start->model.gap_dependence != model.gap_dependence ||
                start->model.electrical_lag != model.electrical_lag))
    throw InputError(fmt::format("stage output-error fit: the start was fitted with model {} but the fit asks for {}; "
                                 "start from an equation-error fit of the same model",
                                 start->model.name(), model.name()));

  StageOutputErrorResult out;
  out.model = model;
  if (given) {
    out.start.model = model;
  } else if (start) {
    out.start = *start;
  } else {
    StageFitOptions fo;  // also rejects constant columns
    fo.fix_mass = options.fix_mass;
    out.start = fit_stage(nominal, u, q, Ts, model, fo);
  }
  const StageFitResult& s0 = out.start;

  Log log;
  log.f = u * allocation_pseudo_inverse(nominal.lever_arms_m).transpose();
  log.q = q;
  log.Ts = Ts;
  log.r = nominal.lever_arms_m;
  log.z_ref = nominal.reference_gap_m;

  Theta theta = start_theta(nominal, model, options, s0, given, out);
  std::vector<int> held, free_index;
  for (int i = 0; i < kStageThetaSize; ++i) (out.free[static_cast<std::size_t>(i)] ? free_index : held).push_back(i);
  const int p = static_cast<int>(free_index.size());

  const Eigen::Index W = N / L;
  Windows win{log, std::vector<Eigen::Index>(static_cast<std::size_t>(W)),
              std::vector<Eigen::Index>(static_cast<std::size_t>(W)),
              std::vector<Eigen::Matrix<double, 12, 1>>(static_cast<std::size_t>(W)),
              options.rk4_substeps > 0 ? options.rk4_substeps : (model.electrical_lag ? 4 : 1),
              options.lag_warmup_samples, model.electrical_lag, Vector6d()};
  for (Eigen::Index w = 0; w < W; ++w) {
    win.k0[static_cast<std::size_t>(w)] = w * L;
    win.len[static_cast<std::size_t>(w)] = w + 1 < W ? L : N - w * L;
  }
  for (std::size_t w = 0; w < win.xs.size(); ++w) win.xs[w] = initial_state(log, win.k0[w], theta.data());
  win.scale << kFirstPassScale_m, kFirstPassScale_m, kFirstPassScale_m,
      Eigen::Vector3d::Constant(kFirstPassScale_m / kLeverArm_m);

  const int passes = options.reweight ? 2 : 1;
  const ceres::Solver::Summary summary = solve_windows(win, theta, held, p, N, options, passes, out);
  out.channel_scale = win.scale;

  // Residuals, per channel and per window.
  out.residual = win.raw_residual(N, theta);
  out.num_windows = static_cast<int>(W);
  out.num_parameters = p;
  out.num_residuals = 6 * N;
  out.window_start = win.k0;
  out.rms_per_window.resize(W, 6);
  for (std::size_t w = 0; w < win.xs.size(); ++w)
    out.rms_per_window.row(static_cast<Eigen::Index>(w)) =
        (out.residual.middleRows(win.k0[w], win.len[w]).colwise().squaredNorm() / double(win.len[w])).cwiseSqrt();
  out.rms_per_channel = (out.residual.colwise().squaredNorm() / double(N)).cwiseSqrt().transpose();
  const double n = 6.0 * double(N);
  const double k_total = p + 12.0 * double(W);
  out.bic = k_total * std::log(n);
  for (int c = 0; c < 6; ++c)
    out.bic += double(N) * std::log(std::max(out.residual.col(c).squaredNorm(), 1e-300) / double(N));

  const Eigen::LDLT<Eigen::MatrixXd> ldlt = marginal_covariance(win, theta, free_index, n, k_total, out);

  out.theta = theta;
  out.mass_kg = theta(0);
  out.inertia_diag_kgm2 = theta.segment<3>(1);
  out.force_constant_scale = theta(4);
  out.com_offset_m = theta.segment<3>(5);
  out.gamma_per_m = theta(8);
  if (model.electrical_lag) out.electrical_time_constant_s = theta(9), out.back_emf_damping_Ns_per_m = theta(10);
  out.report.usable = true;
  out.report.termination =
      fmt::format("Ceres {} after {} iterations ({} pass{}, {} windows of {} rows): {}",
                  summary.termination_type == ceres::CONVERGENCE ? "converged" : "stopped", out.iterations, passes,
                  passes > 1 ? "es" : "", W, L, summary.message);
  if (summary.termination_type != ceres::CONVERGENCE)
    out.report.warnings.push_back("stage output-error fit did not meet its tolerances: " + summary.message);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0).all())
    out.report.warnings.push_back(
        "the parameters' information matrix is singular: some parameter is not determined by this log, and its "
        "standard error is not meaningful");
  return out;
}

}  // namespace

StageOutputErrorResult fit_stage_output_error(const StageParameters& nominal, const Eigen::MatrixXd& u,
                                              const Eigen::MatrixXd& q, double sample_period_s,
                                              const StageFitModel& model, const StageOutputErrorOptions& options,
                                              const StageFitResult* start) {
  return output_error_impl(nominal, u, q, sample_period_s, model, options, start, nullptr);
}

StageOutputErrorResult stage_output_error_at(const StageParameters& nominal, const Eigen::MatrixXd& u,
                                             const Eigen::MatrixXd& q, double sample_period_s,
                                             const StageFitModel& model,
                                             const Eigen::Matrix<double, kStageThetaSize, 1>& theta,
                                             const StageOutputErrorOptions& options) {
  if (!theta.allFinite())
    throw InputError("stage output error: a parameter value is not finite; check the model file");
  return output_error_impl(nominal, u, q, sample_period_s, model, options, nullptr, &theta);
}

}  // namespace lpvid::stage6
