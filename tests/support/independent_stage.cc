// The independent 6-DOF stage simulator (independent_stage.h says what it models
// and where each piece comes from).  Eigen only; no lpvid code.
#include "tests/support/independent_stage.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace indep_stage {

const char* hidden_name(Hidden h) {
  switch (h) {
    case Hidden::kNone: return "none";
    case Hidden::kGap: return "gap";
    case Hidden::kLag: return "lag";
    case Hidden::kCom: return "com";
    case Hidden::kDelay: return "delay";
  }
  return "";
}

bool parse_hidden(const std::string& s, Hidden* h) {
  for (Hidden c : {Hidden::kNone, Hidden::kGap, Hidden::kLag, Hidden::kCom, Hidden::kDelay})
    if (s == hidden_name(c)) {
      *h = c;
      return true;
    }
  return false;
}

Eigen::Matrix<double, 3, 4> pinwheel_arms(double ax, double ay, double depth) {
  Eigen::Matrix<double, 3, 4> r;
  r << ax, -ax, -ax, ax,  //
      ay, ay, -ay, -ay,   //
      -depth, -depth, -depth, -depth;
  return r;
}

namespace {

constexpr int kP = 0, kV = 3, kQ = 6, kW = 10, kI = 13;

// Horizontal push direction of motor i (body): x for motors 1 and 3, y for 2 and 4 (eq 27).
Vec3 push_dir(int i) { return (i % 2 == 0) ? Vec3::UnitX() : Vec3::UnitY(); }

Mat3 rot_of(const State& x) {
  Eigen::Quaterniond q(x(kQ), x(kQ + 1), x(kQ + 2), x(kQ + 3));
  return q.normalized().toRotationMatrix();
}

// Z-Y-X Euler angles (psi, theta, phi) of R = Rz(psi) Ry(theta) Rx(phi) (eq 1).
Vec3 euler_of(const Mat3& R) {
  return Vec3(std::atan2(R(1, 0), R(0, 0)), -std::asin(std::clamp(R(2, 0), -1.0, 1.0)), std::atan2(R(2, 1), R(2, 2)));
}

Mat3 rot_from_euler(double psi, double theta, double phi) {
  return (Eigen::AngleAxisd(psi, Vec3::UnitZ()) * Eigen::AngleAxisd(theta, Vec3::UnitY()) *
          Eigen::AngleAxisd(phi, Vec3::UnitX()))
      .toRotationMatrix();
}

// omega_body = W(eta) eta' for eta = (psi, theta, phi) (eq 4, reordered).
Mat3 euler_rate_matrix(double theta, double phi) {
  Mat3 W;
  W << -std::sin(theta), 0, 1,                          //
      std::cos(theta) * std::sin(phi), std::cos(phi), 0,  //
      std::cos(theta) * std::cos(phi), -std::sin(phi), 0;
  return W;
}

double alpha_of(const Stage& s, const State& x, const Mat3& R, int i) {
  if (!s.gap) return 1.0;
  const Vec3 p_ref = x.segment<3>(kP) - R * s.com_offset_m;
  const double z_array = p_ref(2) + (R * s.arms_m.col(i))(2);
  const double level = s.z_ref_m + s.arms_m(2, i);
  return std::exp(-s.gamma_per_m * (z_array - level));
}

}  // namespace

Eigen::Matrix<double, 6, 8> allocation(const Eigen::Matrix<double, 3, 4>& arms, const Vec3& about) {
  Eigen::Matrix<double, 6, 8> A;
  for (int i = 0; i < 4; ++i) {
    const Vec3 r = arms.col(i) - about;
    const Vec3 dh = push_dir(i), dv = Vec3::UnitZ();
    A.block<3, 1>(0, 2 * i) = dh;
    A.block<3, 1>(3, 2 * i) = r.cross(dh);
    A.block<3, 1>(0, 2 * i + 1) = dv;
    A.block<3, 1>(3, 2 * i + 1) = r.cross(dv);
  }
  return A;
}

State hover_state(const Stage& s, double z_m) {
  State x = State::Zero();
  x.segment<3>(kP) = Vec3(0, 0, z_m) + s.com_offset_m;
  x(kQ) = 1;
  return x;
}

State derivative(const Stage& s, const State& x, const Eigen::Matrix<double, 8, 1>& i_ref) {
  const Mat3 R = rot_of(x);
  const Vec3 w = x.segment<3>(kW);
  const Vec3 v_body = R.transpose() * x.segment<3>(kV);
  const Eigen::Matrix<double, 8, 1> cur = s.lag ? Eigen::Matrix<double, 8, 1>(x.segment<8>(kI)) : i_ref;
  Vec3 F = Vec3::Zero(), tau = Vec3::Zero();
  State dx = State::Zero();
  for (int i = 0; i < 4; ++i) {
    const double a = alpha_of(s, x, R, i);
    const double kf = s.kappa * a * s.force_constant_N_per_A;
    const Vec3 rho = s.arms_m.col(i) - s.com_offset_m;
    const Vec3 f = kf * cur(2 * i) * push_dir(i) + kf * cur(2 * i + 1) * Vec3::UnitZ();
    F += f;
    tau += rho.cross(f);
    if (s.lag) {
      const Vec3 v_arr = s.back_emf_at_array ? Vec3(v_body + w.cross(rho)) : Vec3(x.segment<3>(kV));
      const double e_h = kf * push_dir(i).dot(v_arr), e_v = kf * v_arr(2);
      const double g = s.resistance_ohm + s.amp_gain_V_per_A;
      // L di/dt = v - R i - e, v = R i_ref + k_c (i_ref - i)
      dx(kI + 2 * i) = (g * (i_ref(2 * i) - cur(2 * i)) - e_h) / s.inductance_H;
      dx(kI + 2 * i + 1) = (g * (i_ref(2 * i + 1) - cur(2 * i + 1)) - e_v) / s.inductance_H;
    }
  }
  dx.segment<3>(kP) = x.segment<3>(kV);
  dx.segment<3>(kV) = R * F / s.mass_kg - Vec3(0, 0, s.gravity);
  const Eigen::Quaterniond q(x(kQ), x(kQ + 1), x(kQ + 2), x(kQ + 3));
  const Eigen::Quaterniond qd = q * Eigen::Quaterniond(0, w(0), w(1), w(2));
  dx(kQ) = 0.5 * qd.w();
  dx(kQ + 1) = 0.5 * qd.x();
  dx(kQ + 2) = 0.5 * qd.y();
  dx(kQ + 3) = 0.5 * qd.z();
  dx.segment<3>(kW) = s.inertia_kgm2.ldlt().solve(tau - w.cross(s.inertia_kgm2 * w));
  return dx;
}

State rk4_step(const Stage& s, const State& x, const Eigen::Matrix<double, 8, 1>& i_ref, double h) {
  const State k1 = derivative(s, x, i_ref);
  const State k2 = derivative(s, x + 0.5 * h * k1, i_ref);
  const State k3 = derivative(s, x + 0.5 * h * k2, i_ref);
  const State k4 = derivative(s, x + h * k3, i_ref);
  State y = x + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
  y.segment<4>(kQ).normalize();
  return y;
}

Vec6 configuration(const Stage& s, const State& x) {
  const Mat3 R = rot_of(x);
  Vec6 q;
  q.head<3>() = x.segment<3>(kP) - (s.measure_at_reference ? Vec3(R * s.com_offset_m) : s.com_offset_m);
  q.tail<3>() = euler_of(R);
  return q;
}

double energy(const Stage& s, const State& x) {
  const Vec3 w = x.segment<3>(kW);
  return 0.5 * s.mass_kg * x.segment<3>(kV).squaredNorm() + 0.5 * w.dot(s.inertia_kgm2 * w) +
         s.mass_kg * s.gravity * x(kP + 2);
}

Vec3 angular_momentum_inertial(const Stage& s, const State& x) {
  return rot_of(x) * (s.inertia_kgm2 * x.segment<3>(kW));
}

Log run(const Stage& s, const Controller& c, const Experiment& e) {
  const double Ts = 1.0 / c.rate_hz;
  const long n_settle = std::lround(e.settle_s * c.rate_hz);
  const long n_log = e.replay_excitation.rows() > 0 ? static_cast<long>(e.replay_excitation.rows())
                                                    : std::lround(e.duration_s * c.rate_hz) + 1;
  const double h_max = Ts / e.substeps;
  std::mt19937_64 rng(e.seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  const Eigen::Matrix<double, 6, 8> A = allocation(c.arms_m, Vec3::Zero());
  // Minimum-norm allocation A^T (A A^T)^-1 (A has full row rank 6 for a pinwheel).
  const Eigen::Matrix<double, 8, 6> A_pinv = A.transpose() * (A * A.transpose()).inverse();
  Vec6 Lambda = Vec6::Constant(c.lambda);

  State x = hover_state(s, e.q_ref(2));
  // Hover currents (the weight, allocated) as the initial command.
  const Vec6 w0 = (Vec6() << 0, 0, c.mass_kg * s.gravity, 0, 0, 0).finished();
  Eigen::Matrix<double, 8, 1> i_hover = A_pinv * w0 / s.force_constant_N_per_A;
  if (s.lag) x.segment<8>(kI) = i_hover;

  const long m_delay = static_cast<long>(std::floor(s.input_delay_s / Ts + 1e-12));
  const double d_frac = s.input_delay_s - m_delay * Ts;
  std::vector<Eigen::Matrix<double, 8, 1>> cmd;  // command k issued at t_k
  cmd.reserve(n_settle + n_log);
  auto command = [&](long j) { return j < 0 ? i_hover : cmd[j]; };
  bool first_command = e.history_from_first_command;
  auto integrate = [&](double len, const Eigen::Matrix<double, 8, 1>& ir) {
    if (len <= 0) return;
    const int n = static_cast<int>(std::ceil(len / h_max - 1e-9));
    for (int k = 0; k < n; ++k) x = rk4_step(s, x, ir, len / n);
  };

  Log log;
  log.t.resize(n_log);
  log.v.resize(n_log, 6);
  log.u.resize(n_log, 6);
  log.q.resize(n_log, 6);
  log.q_true.resize(n_log, 6);
  Vec6 q_prev = Vec6::Zero();
  for (long k = 0; k < n_settle + n_log; ++k) {
    const Vec6 q_true = configuration(s, x);
    if (!q_true.allFinite() || std::abs(q_true(2) - e.q_ref(2)) > 5e-3 || q_true.tail<3>().cwiseAbs().maxCoeff() > 0.2)
      throw std::runtime_error("the stage left its hover range (|z - z_ref| > 5 mm or a tilt > 0.2 rad)");
    Vec6 q_meas = q_true;
    for (int j = 0; j < 6; ++j) q_meas(j) += e.noise_std(j) * normal(rng);
    Vec6 qdot = k == 0 ? Vec6::Zero() : Vec6((q_meas - q_prev) / Ts);
    if (c.true_velocity) {
      const Mat3 R = rot_of(x);
      const Vec3 w = x.segment<3>(kW);
      qdot.head<3>() = x.segment<3>(kV) - (s.measure_at_reference ? Vec3(R * w.cross(s.com_offset_m)) : Vec3::Zero());
      qdot.tail<3>() = euler_rate_matrix(q_true(4), q_true(5)).partialPivLu().solve(w);
    }
    q_prev = q_meas;
    Vec6 wrench = Vec6::Zero();
    if (c.enabled) {
      const Vec6 err = q_meas - e.q_ref;
      const Vec6 sigma = qdot + Lambda.cwiseProduct(err);
      const Mat3 W = euler_rate_matrix(q_meas(4), q_meas(5));
      Mat6 M0 = Mat6::Zero();
      M0.topLeftCorner<3, 3>() = c.mass_kg * Mat3::Identity();
      M0.bottomRightCorner<3, 3>() = W.transpose() * c.inertia_kgm2 * W;
      M0 *= c.inertia_ratio;
      Vec6 u_gen = M0 * (-Lambda.cwiseProduct(qdot) - c.gain_K * sigma / (sigma.norm() + c.delta));
      u_gen(2) += c.mass_kg * s.gravity;  // h1
      const Mat3 R = rot_from_euler(q_meas(3), q_meas(4), q_meas(5));
      wrench.head<3>() = R.transpose() * u_gen.head<3>();
      wrench.tail<3>() = W.transpose().partialPivLu().solve(u_gen.tail<3>());
    }
    Vec6 v = Vec6::Zero();
    const long kl = k - n_settle;
    if (kl >= 0) {
      if (e.replay_excitation.rows() > 0) v = e.replay_excitation.row(kl).transpose();
      else
        for (int j = 0; j < 6; ++j) v(j) = e.excitation_std(j) * normal(rng);
      wrench += v;
      log.t(kl) = kl * Ts;
      log.v.row(kl) = v.transpose();
      log.u.row(kl) = wrench.transpose();
      log.q.row(kl) = q_meas.transpose();
      log.q_true.row(kl) = q_true.transpose();
    }
    if (!c.enabled) wrench.setZero();
    cmd.push_back(A_pinv * wrench / s.force_constant_N_per_A);
    if (first_command) {
      i_hover = cmd.back();
      if (s.lag) x.segment<8>(kI) = i_hover;
      first_command = false;
    }
    // Over [t_k, t_k + Ts): command k - m - 1 until t_k + d, then command k - m.
    integrate(d_frac, command(k - m_delay - 1));
    integrate(Ts - d_frac, command(k - m_delay));
  }
  return log;
}

Draw draw(std::uint64_t seed, Hidden hidden, double noise_scale) {
  std::mt19937_64 rng(seed * 2654435761ULL + 17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto within = [&](double lo, double hi) { return lo + (hi - lo) * u01(rng); };
  auto sign = [&]() { return u01(rng) < 0.5 ? -1.0 : 1.0; };
  Draw d;
  Stage& s = d.stage;
  Controller& c = d.controller;
  Experiment& e = d.experiment;
  // Design values a user would know (and give lpvid): the weighed mass, the arms.
  const double mass = 5.47 * within(0.9, 1.1);
  const double ax = within(0.06, 0.09), ay = within(0.06, 0.09), depth = within(0.005, 0.025);
  const Vec3 I_design(0.029, 0.029, 0.057);
  s.mass_kg = mass;
  s.arms_m = pinwheel_arms(ax, ay, depth);
  s.inertia_kgm2 = Vec3(I_design(0) * within(0.7, 1.3), I_design(1) * within(0.7, 1.3), I_design(2) * within(0.7, 1.3))
                       .asDiagonal();
  s.force_constant_N_per_A = within(15, 25);
  s.kappa = within(0.985, 1.02);
  c.mass_kg = mass;
  c.arms_m = s.arms_m;
  c.inertia_kgm2 = I_design.asDiagonal();
  c.lambda = within(2.5, 4.0);
  c.gain_K = within(1.6, 2.6);
  c.delta = within(0.008, 0.014);
  c.inertia_ratio = within(0.35, 0.5);
  // Drawn always, so that --noise-scale changes the noise only, not the rest of the draw.
  const double ns_drawn = std::exp(within(std::log(0.5), std::log(2.0)));
  const double ns = noise_scale >= 0 ? noise_scale : ns_drawn;
  e.noise_std *= ns;
  e.excitation_std *= within(0.8, 1.25);
  e.seed = seed;
  std::ostringstream o;
  o.precision(9);
  switch (hidden) {
    case Hidden::kNone: break;
    case Hidden::kGap: {
      s.gap = true;
      const double pitch = within(0.018, 0.036);
      s.gamma_per_m = 2 * M_PI / pitch;
      o << "magnet_pitch_m = " << pitch << "\ngamma_per_m = " << s.gamma_per_m << "  # alpha = exp(-gamma (gap - z_ref))\n";
      break;
    }
    case Hidden::kLag: {
      s.lag = true;
      s.resistance_ohm = within(1.0, 2.0);
      s.inductance_H = within(2.5e-3, 7e-3);
      const double tau = within(0.5e-3, 1.5e-3);
      s.amp_gain_V_per_A = std::max(0.2, s.inductance_H / tau - s.resistance_ohm);
      o << "resistance_ohm = " << s.resistance_ohm << "\ninductance_H = " << s.inductance_H
        << "\namp_gain_V_per_A = " << s.amp_gain_V_per_A << "\ntau_e_s = " << s.tau_e()
        << "\nback_emf_damping_Ns_per_m = " << s.back_emf_damping() << "  # per force, at the array\n";
      break;
    }
    case Hidden::kCom: {
      s.com_offset_m = Vec3(sign() * within(5e-5, 1.8e-4), sign() * within(5e-5, 1.8e-4), sign() * within(4e-4, 1.8e-3));
      o << "com_x_m = " << s.com_offset_m(0) << "\ncom_y_m = " << s.com_offset_m(1) << "\ncom_z_m = " << s.com_offset_m(2)
        << "\n";
      break;
    }
    case Hidden::kDelay: {
      s.input_delay_s = within(0.25e-3, 1.4e-3);
      o << "input_delay_s = " << s.input_delay_s << "  # continuous (not whole samples)\n";
      break;
    }
  }
  std::ostringstream h;
  h.precision(9);
  h << "hidden = " << hidden_name(hidden) << "\nmass_kg = " << mass << "  # weighed: the controller's too\n"
    << "inertia_xx_kgm2 = " << s.inertia_kgm2(0, 0) << "\ninertia_yy_kgm2 = " << s.inertia_kgm2(1, 1)
    << "\ninertia_zz_kgm2 = " << s.inertia_kgm2(2, 2) << "\nforce_constant_scale = " << s.kappa
    << "\nforce_constant_N_per_A = " << s.force_constant_N_per_A << "\n";
  for (int i = 0; i < 4; ++i)
    h << "lever_arm_" << i + 1 << "_x_m = " << s.arms_m(0, i) << "\nlever_arm_" << i + 1 << "_y_m = " << s.arms_m(1, i)
      << "\nlever_arm_" << i + 1 << "_z_m = " << s.arms_m(2, i) << "\n";
  h << "z_ref_m = " << s.z_ref_m << "\ngravity_m_per_s2 = " << s.gravity << "\ncontrol_lambda = " << c.lambda
    << "\ncontrol_K = " << c.gain_K << "\ncontrol_delta = " << c.delta << "\ncontrol_inertia_ratio = " << c.inertia_ratio
    << "\nnoise_scale = " << ns << "  # on 1 nm (x, y), 10 nm (z), 0.1 urad (tilts)\nexcitation_std = "
    << e.excitation_std.transpose() << "\n"
    << o.str();
  d.description = h.str();
  return d;
}

bool run_hovering(std::uint64_t seed, Hidden hidden, double noise_scale, const std::function<void(Draw&)>& configure,
                  HoveringRun* out, std::string* notes) {
  for (int redraw = 0; redraw <= 10; ++redraw) {
    Draw d = draw(seed + 7777ULL * static_cast<std::uint64_t>(redraw), hidden, noise_scale);
    if (configure) configure(d);
    Log log;
    try {
      log = run(d.stage, d.controller, d.experiment);
    } catch (const std::runtime_error& e) {
      if (notes) *notes += "draw " + std::to_string(redraw) + " of seed " + std::to_string(seed) + ": " + e.what() + "; redrawn\n";
      continue;
    }
    const Eigen::Index half = log.q_true.rows() / 2;
    const Vec6 mean = log.q_true.bottomRows(log.q_true.rows() - half).colwise().mean().transpose();
    if (std::abs(mean(2) - d.experiment.q_ref(2)) > 3e-3 || mean.tail(3).cwiseAbs().maxCoeff() > 2e-2) {
      if (notes) *notes += "draw " + std::to_string(redraw) + " of seed " + std::to_string(seed) + " does not hover level; redrawn\n";
      continue;
    }
    out->draw = std::move(d);
    out->log = std::move(log);
    out->redraws = redraw;
    out->mean_q_second_half = mean;
    return true;
  }
  return false;
}

void write_log_csv(const std::string& path, const Log& log) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  std::fprintf(f, "t,v1,v2,v3,v4,v5,v6,u1,u2,u3,u4,u5,u6,q1,q2,q3,q4,q5,q6\n");
  for (Eigen::Index k = 0; k < log.t.size(); ++k) {
    std::fprintf(f, "%.6f", log.t(k));
    for (int j = 0; j < 6; ++j) std::fprintf(f, ",%.10g", log.v(k, j));
    for (int j = 0; j < 6; ++j) std::fprintf(f, ",%.10g", log.u(k, j));
    for (int j = 0; j < 6; ++j) std::fprintf(f, ",%.12g", log.q(k, j));
    std::fprintf(f, "\n");
  }
  std::fclose(f);
}

}  // namespace indep_stage
