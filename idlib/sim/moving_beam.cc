#include "idlib/sim/moving_beam.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

void require_finite(double v, const char* what) {
  if (!std::isfinite(v)) throw InputError(fmt::format("beam trajectory: {} = {}; it must be finite", what, v));
}

// Everything of the plant that does not depend on x_b.
struct PlantConstants {
  Eigen::Matrix3d K, D;
  double mb, zb, g;
};

// One frozen piece: exact ZOH of A(x_b, x_b'), B(x_b) over h.
struct FrozenPiece {
  Eigen::Matrix<double, 6, 6> Phi;
  Eigen::Matrix<double, 6, 3> Gamma;
};

FrozenPiece discretise_frozen(const PlatformParameters& params, const PlantConstants& c, double xb, double vb,
                              bool velocity_terms, double h) {
  const Eigen::Matrix3d M = mass_matrix(params, xb);  // checks the stroke
  Eigen::Matrix3d Dg = c.D;
  if (velocity_terms) {
    Dg(1, 1) += 2.0 * c.mb * vb * xb;
    Dg(2, 1) += c.mb * vb;
  }
  // The same construction as platform_model + discretize_zoh, so that a beam at
  // rest reproduces the LTI model to rounding.
  const Eigen::LLT<Eigen::Matrix3d> llt(M);
  Eigen::Matrix<double, 9, 9> aug = Eigen::Matrix<double, 9, 9>::Zero();
  aug.block<3, 3>(0, 3).setIdentity();
  aug.block<3, 3>(3, 0) = -llt.solve(c.K);
  aug.block<3, 3>(3, 3) = -llt.solve(Dg);
  aug.block<3, 3>(3, 6) = llt.solve(Eigen::Matrix3d::Identity());
  aug *= h;
  const Eigen::Matrix<double, 9, 9> E = aug.exp();
  return {E.topLeftCorner<6, 6>(), E.topRightCorner<6, 3>()};
}

Eigen::Vector3d beam_wrench(const PlantConstants& c, const MovingBeamEffects& effects, const BeamState& b) {
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  if (effects.beam_reaction) w(1) += c.mb * c.zb * b.acceleration_m_per_s2;
  if (effects.gravity_moment) w(1) -= c.mb * c.g * b.position_m;
  return w;
}

void check_controller(const StateSpace& controller, double sample_period_s) {
  controller.validate();
  if (!controller.is_discrete())
    throw InputError(fmt::format(
        "moving-beam simulation: the controller is continuous (ts = 0); discretise it at {} s first", sample_period_s));
  if (controller.num_inputs() != 3 || controller.num_outputs() != 3)
    throw InputError(fmt::format(
        "moving-beam simulation: the controller has {} inputs and {} outputs; it must have 3 (e) and 3 (u_c)",
        controller.num_inputs(), controller.num_outputs()));
  // Same rule as simulate_excitation: agreeing to 1e-9 is the same rate.
  constexpr double kSamplePeriodRelTolerance = 1e-9;
  if (std::abs(controller.sample_period_s - sample_period_s) > kSamplePeriodRelTolerance * sample_period_s)
    throw InputError(fmt::format(
        "moving-beam simulation: the controller has ts = {} s but the run samples at {} s; give a controller at the "
        "log's sample period",
        controller.sample_period_s, sample_period_s));
}

Index sample_count(const BeamTrajectory& traj, double Ts) {
  // A relative 1e-9 of a sample absorbs the rounding of t_end = start + (N-1)·Ts.
  constexpr double kEndSlack = 1e-9;
  const double n = std::floor((traj.end_s() - traj.start_s()) / Ts + kEndSlack) + 1.0;
  if (!(n >= 1.0) || !(n <= ExcitationOptions::kMaxSamples))
    throw InputError(fmt::format(
        "moving-beam simulation: the trajectory spans {} s, giving {} samples at {} s; it must give 1 to {} samples",
        traj.end_s() - traj.start_s(), n, Ts, ExcitationOptions::kMaxSamples));
  return static_cast<Index>(n);
}

// The loop shared by simulation and prediction.  excitation: N × 3 or empty
// (then drawn from rng with options.excitation_std); noise drawn when draw_noise.
void run_loop(const PlatformParameters& params, const StateSpace& controller, const BeamTrajectory& traj,
              double start_s, Index N, const MovingBeamOptions& options, const Eigen::MatrixXd* excitation,
              Eigen::MatrixXd& v_out, Eigen::MatrixXd& u_out, Eigen::MatrixXd& q_out) {
  params.validate();
  const PlantConstants c{stiffness_matrix(params), damping_matrix(params), params.beam_mass_kg, params.beam_height_m,
                         params.gravity_m_per_s2};
  const double Ts = options.sample_period_s;
  const int S = options.substeps;
  const double h = Ts / S;
  const Index nc = controller.order();
  const Eigen::MatrixXd Ac = controller.A, Bc = controller.B, Cc = controller.C;
  const Eigen::Matrix3d Dc = controller.D;

  Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::VectorXd xc = Eigen::VectorXd::Zero(nc);
  if (options.start == MovingBeamOptions::Start::equilibrium) {
    // Static loop with w0 = w(t_0):  K q = w0 + C_c x_c - D_c q,  x_c = A_c x_c - B_c q.
    const Eigen::Vector3d w0 = beam_wrench(c, options.effects, traj.at(start_s));
    mass_matrix(params, traj.at(start_s).position_m);  // stroke check at t_0
    Eigen::MatrixXd S_mat = Eigen::MatrixXd::Zero(3 + nc, 3 + nc);
    S_mat.topLeftCorner(3, 3) = c.K + Dc;
    S_mat.topRightCorner(3, nc) = -Cc;
    S_mat.bottomLeftCorner(nc, 3) = -Bc;
    S_mat.bottomRightCorner(nc, nc) = Ac - Eigen::MatrixXd::Identity(nc, nc);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 + nc);
    rhs.head(3) = w0;
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(S_mat);
    if (!lu.isInvertible())
      throw InputError(
          "moving-beam simulation: the static closed loop is singular (no unique equilibrium for the beam's start "
          "position: a controller without integral action on an axis with zero stiffness?); start from rest instead");
    const Eigen::VectorXd z = lu.solve(rhs);
    x.head<3>() = z.head(3);
    xc = z.tail(nc);
  }

  Eigen::Vector3d v_mask = options.excitation_std;
  const Eigen::Vector3d n_scale = excitation ? Eigen::Vector3d::Zero() : options.sensor_noise_std;
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  FrozenPiece piece{Eigen::Matrix<double, 6, 6>::Zero(), Eigen::Matrix<double, 6, 3>::Zero()};
  double cached_x = std::numeric_limits<double>::quiet_NaN(), cached_v = cached_x;
  Eigen::Matrix<double, 6, 1> x_next;
  Eigen::VectorXd xc_next(nc);
  for (Index k = 0; k < N; ++k) {
    const double t_k = start_s + static_cast<double>(k) * Ts;
    Eigen::Vector3d v, n;
    if (excitation) {
      v = excitation->row(k).transpose();
      n.setZero();
    } else {
      for (int i = 0; i < 3; ++i) v(i) = normal(rng);
      for (int i = 0; i < 3; ++i) n(i) = normal(rng);
      v = v.cwiseProduct(v_mask);
      n = n.cwiseProduct(n_scale);
    }
    const Eigen::Vector3d q_meas = x.head<3>() + n;
    const Eigen::Vector3d e = -q_meas;
    Eigen::Vector3d u = Dc * e + v;
    if (nc > 0) u += Cc * xc;
    if (v_out.size() > 0) v_out.row(k) = v.transpose();
    u_out.row(k) = u.transpose();
    q_out.row(k) = q_meas.transpose();

    for (int s = 0; s < S; ++s) {
      const BeamState b = traj.at(t_k + (s + 0.5) * h);
      const double vb = options.effects.velocity_terms ? b.velocity_m_per_s : 0.0;
      // Reuse the frozen piece while (x_b, x_b') moves by less than 1e-12 m and
      // 1e-12 m/s: M changes by ~1e-13 relative then, far below the model's
      // accuracy, and a spline at rest (whose ringing decays to ~1e-20, not to
      // exactly 0) costs no exponentials.
      constexpr double kReuseTolerance = 1e-12;
      if (!(std::abs(b.position_m - cached_x) <= kReuseTolerance && std::abs(vb - cached_v) <= kReuseTolerance)) {
        piece = discretise_frozen(params, c, b.position_m, vb, options.effects.velocity_terms, h);
        cached_x = b.position_m;
        cached_v = vb;
      }
      const Eigen::Vector3d drive = u + beam_wrench(c, options.effects, b);
      x_next.noalias() = piece.Phi * x;
      x_next.noalias() += piece.Gamma * drive;
      x.swap(x_next);
    }
    if (nc > 0) {
      xc_next.noalias() = Ac * xc;
      xc_next.noalias() += Bc * e;
      xc.swap(xc_next);
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------

BeamTrajectory BeamTrajectory::from_samples(const Eigen::VectorXd& time_s, const Eigen::VectorXd& position_m) {
  const Index n = time_s.size();
  if (n < 2 || position_m.size() != n)
    throw InputError(fmt::format(
        "beam trajectory: {} time stamps and {} positions; give at least 2 samples of each, equally many", n,
        position_m.size()));
  for (Index j = 0; j < n; ++j) {
    if (!std::isfinite(time_s(j)) || !std::isfinite(position_m(j)))
      throw InputError(fmt::format("beam trajectory: sample {} is (t = {}, x_b = {}); every value must be finite", j,
                                   time_s(j), position_m(j)));
    if (j > 0 && !(time_s(j) > time_s(j - 1)))
      throw InputError(fmt::format(
          "beam trajectory: t[{}] = {} s is not after t[{}] = {} s; time must be strictly increasing", j, time_s(j),
          j - 1, time_s(j - 1)));
  }
  // Natural cubic spline: second derivatives m_j from the tridiagonal system
  // h_{j-1} m_{j-1} + 2(h_{j-1} + h_j) m_j + h_j m_{j+1} = 6 (s_j - s_{j-1}),
  // m_0 = m_{n-1} = 0 (Thomas algorithm; diagonally dominant, so stable).
  std::vector<double> h(static_cast<std::size_t>(n - 1)), slope(static_cast<std::size_t>(n - 1));
  for (Index j = 0; j + 1 < n; ++j) {
    h[j] = time_s(j + 1) - time_s(j);
    slope[j] = (position_m(j + 1) - position_m(j)) / h[j];
  }
  std::vector<double> m(static_cast<std::size_t>(n), 0.0);
  if (n > 2) {
    const Index k = n - 2;  // interior unknowns m_1..m_{n-2}
    std::vector<double> diag(k), upper(k), rhs(k);
    for (Index i = 0; i < k; ++i) {
      diag[i] = 2.0 * (h[i] + h[i + 1]);
      upper[i] = h[i + 1];
      rhs[i] = 6.0 * (slope[i + 1] - slope[i]);
    }
    for (Index i = 1; i < k; ++i) {
      const double f = h[i] / diag[i - 1];
      diag[i] -= f * upper[i - 1];
      rhs[i] -= f * rhs[i - 1];
    }
    m[k] = rhs[k - 1] / diag[k - 1];
    for (Index i = k - 2; i >= 0; --i) m[i + 1] = (rhs[i] - upper[i] * m[i + 2]) / diag[i];
  }
  BeamTrajectory traj;
  traj.breaks_.assign(time_s.data(), time_s.data() + n);
  traj.coeffs_.resize(static_cast<std::size_t>(n - 1));
  for (Index j = 0; j + 1 < n; ++j) {
    auto& cf = traj.coeffs_[j];
    cf = {position_m(j), slope[j] - h[j] * (2.0 * m[j] + m[j + 1]) / 6.0, 0.5 * m[j], (m[j + 1] - m[j]) / (6.0 * h[j]),
          0.0, 0.0};
  }
  return traj;
}

BeamTrajectory BeamTrajectory::sweep(const Sweep& spec, double duration_s) {
  for (double v : {spec.left_m, spec.right_m, spec.first_dwell_s, spec.move_s, spec.dwell_s, duration_s})
    require_finite(v, "a sweep value");
  if (!(spec.move_s > 0.0) || spec.first_dwell_s < 0.0 || spec.dwell_s < 0.0 || !(duration_s > 0.0))
    throw InputError(fmt::format(
        "beam trajectory: sweep with move_s = {}, dwells {} and {}, duration {} s; moves and the duration must be > 0, "
        "dwells >= 0",
        spec.move_s, spec.first_dwell_s, spec.dwell_s, duration_s));
  BeamTrajectory traj;
  double t = 0.0, x = spec.left_m, target = spec.right_m;
  traj.breaks_.push_back(0.0);
  auto add = [&](double length, const std::array<double, 6>& cf) {
    if (!(length > 0.0) || t >= duration_s) return;
    traj.coeffs_.push_back(cf);
    t = std::min(t + length, duration_s);
    traj.breaks_.push_back(t);
  };
  add(spec.first_dwell_s, {x, 0, 0, 0, 0, 0});
  while (t < duration_s) {
    const double d = target - x, T = spec.move_s;
    add(T, {x, 0, 0, 10.0 * d / (T * T * T), -15.0 * d / (T * T * T * T), 6.0 * d / (T * T * T * T * T)});
    x = target;
    target = target == spec.right_m ? spec.left_m : spec.right_m;
    add(spec.dwell_s, {x, 0, 0, 0, 0, 0});
  }
  return traj;
}

BeamTrajectory BeamTrajectory::constant(double position_m, double start_s, double end_s) {
  require_finite(position_m, "x_b");
  if (!std::isfinite(start_s) || !std::isfinite(end_s) || !(end_s > start_s))
    throw InputError(fmt::format("beam trajectory: span [{}, {}] s; it must be finite with end > start", start_s, end_s));
  BeamTrajectory traj;
  traj.breaks_ = {start_s, end_s};
  traj.coeffs_ = {{position_m, 0, 0, 0, 0, 0}};
  return traj;
}

BeamState BeamTrajectory::at(double t_s) const {
  const auto it = std::upper_bound(breaks_.begin() + 1, breaks_.end() - 1, t_s);
  const std::size_t j = static_cast<std::size_t>(it - breaks_.begin()) - 1;
  const auto& c = coeffs_[j];
  const double tau = t_s - breaks_[j];
  BeamState s;
  s.position_m = c[0] + tau * (c[1] + tau * (c[2] + tau * (c[3] + tau * (c[4] + tau * c[5]))));
  s.velocity_m_per_s = c[1] + tau * (2 * c[2] + tau * (3 * c[3] + tau * (4 * c[4] + tau * 5 * c[5])));
  s.acceleration_m_per_s2 = 2 * c[2] + tau * (6 * c[3] + tau * (12 * c[4] + tau * 20 * c[5]));
  return s;
}

// ---------------------------------------------------------------------------

void MovingBeamOptions::validate() const {
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format(
        "moving-beam options: sample_period_s = {}; it must be finite and > 0 (1 kHz = 1e-3)", sample_period_s));
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(excitation_std(i)) || excitation_std(i) < 0.0)
      throw InputError(fmt::format("moving-beam options: excitation_std[{}] = {}; it must be finite and >= 0", i,
                                   excitation_std(i)));
    if (!std::isfinite(sensor_noise_std(i)) || sensor_noise_std(i) < 0.0)
      throw InputError(fmt::format("moving-beam options: sensor_noise_std[{}] = {}; it must be finite and >= 0", i,
                                   sensor_noise_std(i)));
  }
  if (substeps < 1 || substeps > 1000)
    throw InputError(fmt::format("moving-beam options: substeps = {}; it must be 1 to 1000", substeps));
}

SimulatedLog simulate_moving_beam(const PlatformParameters& params, const StateSpace& discrete_controller,
                                  const BeamTrajectory& trajectory, const MovingBeamOptions& options) {
  options.validate();
  params.validate();
  check_controller(discrete_controller, options.sample_period_s);
  const Index N = sample_count(trajectory, options.sample_period_s);
  Eigen::MatrixXd v(N, 3), u(N, 3), q(N, 3);
  run_loop(params, discrete_controller, trajectory, trajectory.start_s(), N, options, nullptr, v, u, q);
  SimulatedLog log;
  log.names = {"t", "v1", "v2", "v3", "u1", "u2", "u3", "q1", "q2", "q3", "x_b"};
  log.data.resize(N, 11);
  for (Index k = 0; k < N; ++k) {
    const double t = trajectory.start_s() + static_cast<double>(k) * options.sample_period_s;
    log.data(k, 0) = t;
    log.data(k, 10) = trajectory.at(t).position_m;
  }
  log.data.middleCols(1, 3) = v;
  log.data.middleCols(4, 3) = u;
  log.data.middleCols(7, 3) = q;
  return log;
}

MovingBeamPrediction predict_moving_beam(const PlatformParameters& params, const StateSpace& discrete_controller,
                                         const BeamTrajectory& trajectory, double start_s,
                                         const Eigen::MatrixXd& excitation, const MovingBeamOptions& options) {
  options.validate();
  params.validate();
  check_controller(discrete_controller, options.sample_period_s);
  if (excitation.cols() != 3 || excitation.rows() < 1 || !excitation.allFinite())
    throw InputError(fmt::format(
        "moving-beam prediction: the excitation is {} × {}; it must be N × 3 (v1 v2 v3), N >= 1, every entry finite",
        excitation.rows(), excitation.cols()));
  require_finite(start_s, "start time");
  const Index N = excitation.rows();
  MovingBeamPrediction p;
  p.q.resize(N, 3);
  p.u.resize(N, 3);
  Eigen::MatrixXd none;
  run_loop(params, discrete_controller, trajectory, start_s, N, options, &excitation, none, p.u, p.q);
  return p;
}

Eigen::MatrixXd predict_moving_beam_from_input(const PlatformParameters& params, const BeamTrajectory& trajectory,
                                               double start_s, const Eigen::MatrixXd& plant_input,
                                               const MovingBeamOptions& options) {
  options.validate();
  params.validate();
  if (plant_input.cols() != 3 || plant_input.rows() < 1 || !plant_input.allFinite())
    throw InputError(fmt::format(
        "moving-beam prediction: the plant input is {} × {}; it must be N × 3 (u1 u2 u3), N >= 1, every entry finite",
        plant_input.rows(), plant_input.cols()));
  require_finite(start_s, "start time");
  StateSpace open_loop;
  open_loop.A.resize(0, 0);
  open_loop.B.resize(0, 3);
  open_loop.C.resize(3, 0);
  open_loop.D = Eigen::MatrixXd::Zero(3, 3);
  open_loop.sample_period_s = options.sample_period_s;
  const Index N = plant_input.rows();
  Eigen::MatrixXd none, u(N, 3), q(N, 3);
  MovingBeamOptions from_rest = options;
  from_rest.start = MovingBeamOptions::Start::rest;
  run_loop(params, open_loop, trajectory, start_s, N, from_rest, &plant_input, none, u, q);
  return q;
}

}  // namespace lpvid
