// Independent simulator of the seed-000 platform (see the header for what is
// derived how).  Only Eigen; no lpvid code.
#include "tests/support/independent_platform.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

namespace indep {
namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

struct Sys {  // continuous or static pieces chained in series
  MatrixXd A, B, C, D;
};

// second after first: u -> first -> second -> y.
Sys series(const Sys& first, const Sys& second) {
  const Index n1 = first.A.rows(), n2 = second.A.rows();
  Sys s;
  s.A = MatrixXd::Zero(n1 + n2, n1 + n2);
  s.A.topLeftCorner(n1, n1) = first.A;
  s.A.bottomLeftCorner(n2, n1) = second.B * first.C;
  s.A.bottomRightCorner(n2, n2) = second.A;
  s.B = MatrixXd(n1 + n2, first.B.cols());
  s.B << first.B, second.B * first.D;
  s.C = MatrixXd(second.C.rows(), n1 + n2);
  s.C << second.D * first.C, second.C;
  s.D = second.D * first.D;
  return s;
}

Sys static_gain(const MatrixXd& K) {
  Sys s;
  s.A = MatrixXd::Zero(0, 0);
  s.B = MatrixXd::Zero(0, K.cols());
  s.C = MatrixXd::Zero(K.rows(), 0);
  s.D = K;
  return s;
}

// Coil positions (x, y) of the 3x3 grid with pitch r, in the numbering of eq 9.
Eigen::Matrix<double, 9, 2> coil_xy(double r) {
  Eigen::Matrix<double, 9, 2> xy;
  const double xs[3] = {r, 0.0, -r}, ys[3] = {r, 0.0, -r};
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) xy.row(3 * a + b) << xs[a], ys[b];
  return xy;
}

// W: generalised force of the nine vertical coil forces, columns (y_i, x_i, 1).
Eigen::Matrix<double, 3, 9> wrench_map(double r) {
  const auto xy = coil_xy(r);
  Eigen::Matrix<double, 3, 9> W;
  for (int i = 0; i < 9; ++i) W.col(i) << xy(i, 1), xy(i, 0), 1.0;
  return W;
}

Eigen::Matrix<double, 3, 9> transformation(double design_r) {
  const Eigen::Matrix<double, 3, 9> W = wrench_map(design_r);
  return (W * W.transpose()).inverse() * W;
}

Sys second_order_filter(const ChannelFilter& f) {
  Sys s;
  s.A = MatrixXd(2, 2);
  s.A << 0, 1, -f.a0, -f.a1;
  s.B = MatrixXd(2, 1);
  s.B << 0, 1;
  s.C = MatrixXd(1, 2);
  s.C << f.b0 - f.b2 * f.a0, f.b1 - f.b2 * f.a1;
  s.D = MatrixXd::Constant(1, 1, f.b2);
  return s;
}

// Block-diagonal embedding of per-channel filters on a 3-channel path.
Sys channel_filters(const std::vector<ChannelFilter>& filters, ChannelFilter::Kind kind) {
  Sys s = static_gain(MatrixXd::Identity(3, 3));
  for (const auto& f : filters) {
    if (f.kind != kind) continue;
    if (f.channel < 0 || f.channel > 2) throw std::invalid_argument("filter channel must be 0..2");
    const Sys one = second_order_filter(f);
    // identity on the other channels, the filter on f.channel
    Sys full;
    full.A = one.A;
    full.B = MatrixXd::Zero(2, 3);
    full.B.col(f.channel) = one.B;
    full.C = MatrixXd::Zero(3, 2);
    full.C.row(f.channel) = one.C;
    full.D = MatrixXd::Identity(3, 3);
    full.D(f.channel, f.channel) = one.D(0, 0);
    s = series(s, full);
  }
  return s;
}

// exp(Z h) by RK4 on X' = Z X: the degree-4 Taylor polynomial per substep, with
// substeps so that ||Z||_1 h_sub <= 0.05 and h_sub <= Ts / 16.
MatrixXd rk4_propagator(const MatrixXd& Z, double h, double Ts) {
  const Index n = Z.rows();
  if (h <= 0) return MatrixXd::Identity(n, n);
  double norm = 0;
  for (Index j = 0; j < n; ++j) norm = std::max(norm, Z.col(j).cwiseAbs().sum());
  const int steps = std::max({1, static_cast<int>(std::ceil(norm * h / 0.05)), static_cast<int>(std::ceil(16 * h / Ts))});
  const MatrixXd Y = Z * (h / steps);
  const MatrixXd I = MatrixXd::Identity(n, n);
  const MatrixXd Y2 = Y * Y;
  const MatrixXd step = I + Y + Y2 / 2.0 + Y2 * Y / 6.0 + Y2 * Y2 / 24.0;
  MatrixXd E = I;
  for (int k = 0; k < steps; ++k) E = step * E;
  return E;
}

}  // namespace

std::vector<Rod> Plant::symmetric_rods(double k_vert, double k_bend, double k_twist) {
  std::vector<Rod> rods;
  const double R = 0.12;
  for (int j = 0; j < 3; ++j) {
    const double phi = M_PI / 2 + j * 2 * M_PI / 3;  // attachment angle
    Rod r;
    r.x_m = R * std::cos(phi);
    r.y_m = R * std::sin(phi);
    r.axis_rad = phi + M_PI / 2;  // tangent
    r.k_vert_N_per_m = k_vert;
    r.k_bend_Nm_per_rad = k_bend;
    r.k_twist_Nm_per_rad = k_twist;
    rods.push_back(r);
  }
  return rods;
}

Plant Plant::nominal() {
  Plant p;
  p.m_p_kg = 5.3;
  p.J_psi_kgm2 = 0.043;
  p.J_theta_kgm2 = 0.058;
  p.m_b_kg = 1.4;
  p.z_b_m = 0.06;
  p.pitch_m = 0.11;
  p.design_pitch_m = 0.11;
  p.coil_damping_Ns_per_m = VectorXd::Constant(9, 24.0);
  // vertical 550 N/m per rod (1650 N/m together), bending 35 N·m/rad per rod
  p.rods = symmetric_rods(550.0, 35.0, 0.0);
  p.extra_k_theta_Nm_per_rad = 18.0;  // cables along x: psi and theta differ
  return p;
}

Eigen::Matrix3d mass_matrix(const Plant& p, double x_b) {
  Eigen::Matrix3d M;
  M << p.J_psi_kgm2, p.J_pt_kgm2, p.m_p_kg * p.c_y_m,  //
      p.J_pt_kgm2, p.J_theta_kgm2, p.m_p_kg * p.c_x_m,  //
      p.m_p_kg * p.c_y_m, p.m_p_kg * p.c_x_m, p.m_p_kg;
  // beam: point mass at (x_b, 0, z_b); velocity (-z_b th', -z_b psi', z' + x_b th')
  const double mb = p.m_b_kg, zb = p.z_b_m;
  M(0, 0) += mb * zb * zb;
  M(1, 1) += mb * (zb * zb + x_b * x_b);
  M(1, 2) += mb * x_b;
  M(2, 1) += mb * x_b;
  M(2, 2) += mb;
  return M;
}

Eigen::Matrix3d stiffness_matrix(const Plant& p) {
  Eigen::Matrix3d K = Eigen::Matrix3d::Zero();
  for (const Rod& r : p.rods) {
    const Eigen::Vector3d a(r.y_m, r.x_m, 1.0);  // vertical displacement of the attachment
    K += r.k_vert_N_per_m * a * a.transpose();
    // rotation about a horizontal unit vector e: psi e_x - theta e_y
    const Eigen::Vector2d axis(std::cos(r.axis_rad), std::sin(r.axis_rad));
    const Eigen::Vector2d bend(-axis.y(), axis.x());  // e_z x a
    const Eigen::Vector3d s_twist(axis.x(), -axis.y(), 0.0), s_bend(bend.x(), -bend.y(), 0.0);
    K += r.k_twist_Nm_per_rad * s_twist * s_twist.transpose();
    K += r.k_bend_Nm_per_rad * s_bend * s_bend.transpose();
  }
  K(0, 0) += p.extra_k_psi_Nm_per_rad;
  K(1, 1) += p.extra_k_theta_Nm_per_rad;
  if (p.beam_gravity) {
    K(0, 0) -= p.m_b_kg * p.g_m_per_s2 * p.z_b_m;
    K(1, 1) -= p.m_b_kg * p.g_m_per_s2 * p.z_b_m;
  }
  return K;
}

Eigen::Matrix3d damping_matrix(const Plant& p) {
  const auto W = wrench_map(p.pitch_m);
  Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 9; ++i) D += p.coil_damping_Ns_per_m(i) * W.col(i) * W.col(i).transpose();
  return D;
}

Continuous continuous_plant(const Plant& p, double x_b) {
  const Eigen::Matrix3d M = mass_matrix(p, x_b), K = stiffness_matrix(p), D = damping_matrix(p);
  const Eigen::Matrix3d Mi = M.inverse();
  const Eigen::Matrix<double, 3, 9> W = wrench_map(p.pitch_m);
  const Eigen::Matrix<double, 3, 9> T = transformation(p.design_pitch_m);
  const Index nm = static_cast<Index>(p.modes.size());
  // body: input coil forces F (9), output sensor readings y (9)
  Sys body;
  const Index nb = 6 + 2 * nm;
  body.A = MatrixXd::Zero(nb, nb);
  body.B = MatrixXd::Zero(nb, 9);
  body.C = MatrixXd::Zero(9, nb);
  body.D = MatrixXd::Zero(9, 9);
  body.A.block(0, 3, 3, 3).setIdentity();
  body.A.block(3, 0, 3, 3) = -Mi * K;
  body.A.block(3, 3, 3, 3) = -Mi * D;
  body.B.block(3, 0, 3, 9) = Mi * W;
  body.C.leftCols(3) = W.transpose();
  for (Index k = 0; k < nm; ++k) {
    const Mode& m = p.modes[static_cast<std::size_t>(k)];
    if (m.shape.size() != 9) throw std::invalid_argument("mode shape needs 9 values");
    const Index i = 6 + 2 * k;
    body.A(i, i + 1) = 1;
    body.A(i + 1, i) = -m.omega_rad_s * m.omega_rad_s;
    body.A(i + 1, i + 1) = -2 * m.zeta * m.omega_rad_s;
    body.B.row(i + 1) = m.shape.transpose();
    body.C.col(i) = m.shape;
  }
  Sys chain = channel_filters(p.filters, ChannelFilter::kInput);
  chain = series(chain, static_gain(p.input_gain * T.transpose()));  // wrench command -> coil forces
  if (p.coil_lag_s > 0) {
    Sys lag;
    lag.A = -MatrixXd::Identity(9, 9) / p.coil_lag_s;
    lag.B = MatrixXd::Identity(9, 9) / p.coil_lag_s;
    lag.C = MatrixXd::Identity(9, 9);
    lag.D = MatrixXd::Zero(9, 9);
    chain = series(chain, lag);
  }
  chain = series(chain, body);
  chain = series(chain, static_gain(T));  // sensor readings -> q
  chain = series(chain, channel_filters(p.filters, ChannelFilter::kOutput));
  if (chain.D.norm() != 0) throw std::logic_error("plant has feedthrough");
  return {chain.A, chain.B, chain.C};
}

Discrete sampled_plant(const Plant& p, double x_b, double Ts) {
  const Continuous c = continuous_plant(p, x_b);
  const Index n = c.A.rows(), m = c.B.cols();
  const double delay_samples = p.input_delay_s / Ts;
  const Index k0 = static_cast<Index>(std::floor(delay_samples + 1e-12));
  double f = delay_samples - static_cast<double>(k0);
  if (f < 1e-12) f = 0;
  // augmented [x; u_old; u_new]; phase 1 (f Ts) driven by u_old, phase 2 by u_new
  MatrixXd Z1 = MatrixXd::Zero(n + 2 * m, n + 2 * m), Z2 = Z1;
  Z1.block(0, 0, n, n) = c.A;
  Z1.block(0, n, n, m) = c.B;
  Z2.block(0, 0, n, n) = c.A;
  Z2.block(0, n + m, n, m) = c.B;
  const MatrixXd P = rk4_propagator(Z2, (1 - f) * Ts, Ts) * rk4_propagator(Z1, f * Ts, Ts);
  const MatrixXd Phi = P.block(0, 0, n, n), G_old = P.block(0, n, n, m), G_new = P.block(0, n + m, n, m);
  // buffer b_i = u[k - i], i = 1..L
  const Index L = k0 + (f > 0 ? 1 : 0);
  Discrete d;
  d.Ts = Ts;
  const Index N = n + L * m;
  d.A = MatrixXd::Zero(N, N);
  d.B = MatrixXd::Zero(N, m);
  d.C = MatrixXd::Zero(3, N);
  d.D = MatrixXd::Zero(3, m);
  d.A.topLeftCorner(n, n) = Phi;
  d.C.leftCols(n) = c.C;
  auto add_input_term = [&](Index lag, const MatrixXd& G) {  // x[k+1] += G u[k - lag]
    if (lag == 0)
      d.B.topRows(n) += G;
    else
      d.A.block(0, n + (lag - 1) * m, n, m) += G;
  };
  add_input_term(k0, G_new);
  if (f > 0) add_input_term(k0 + 1, G_old);
  if (L > 0) {
    d.B.block(n, 0, m, m).setIdentity();
    for (Index i = 1; i < L; ++i) d.A.block(n + i * m, n + (i - 1) * m, m, m).setIdentity();
  }
  return d;
}

Eigen::MatrixXcd Discrete::response(double omega) const {
  const std::complex<double> z = std::exp(std::complex<double>(0, omega * Ts));
  const Index n = A.rows();
  Eigen::MatrixXcd Zm = -A.cast<std::complex<double>>();
  Zm.diagonal().array() += z;
  return C.cast<std::complex<double>>() * Zm.partialPivLu().solve(B.cast<std::complex<double>>()) +
         D.cast<std::complex<double>>();
  (void)n;
}

Discrete pid_controller(const Plant& p, const PidDesign& design, double Ts) {
  const Eigen::Matrix3d M = mass_matrix(p, 0.0), K = stiffness_matrix(p), D = damping_matrix(p);
  Discrete c;
  c.Ts = Ts;
  c.A = MatrixXd::Zero(6, 6);
  c.B = MatrixXd::Zero(6, 3);
  c.C = MatrixXd::Zero(3, 6);
  c.D = MatrixXd::Zero(3, 3);
  for (int i = 0; i < 3; ++i) {
    const double m = M(i, i), d = D(i, i), k = K(i, i);
    const double w = design.bandwidth_rad_s[i], z = design.damping[i], a = 1.0 / design.integral_time_s[i];
    const double kd = m * (2 * z * w + a) - d, kp = m * (w * w + 2 * z * w * a) - k, ki = m * w * w * a;
    const double wf = design.derivative_filter_factor * w;
    // continuous: integrator x1' = e, filter x2' = -wf x2 + e; u = ki x1 - kd wf^2 x2 + (kp + kd wf) e
    Eigen::Matrix2d Ac;
    Ac << 0, 0, 0, -wf;
    const Eigen::Vector2d Bc(1, 1);
    const Eigen::RowVector2d Cc(ki, -kd * wf * wf);
    const double Dc = kp + kd * wf;
    // Tustin: Ad = (I - A T/2)^-1 (I + A T/2), Bd = (I - A T/2)^-1 B sqrt(T),
    //         Cd = sqrt(T) C (I - A T/2)^-1, Dd = D + C (I - A T/2)^-1 B T/2
    const Eigen::Matrix2d I = Eigen::Matrix2d::Identity();
    const Eigen::Matrix2d Minv = (I - Ac * Ts / 2).inverse();
    c.A.block<2, 2>(2 * i, 2 * i) = Minv * (I + Ac * Ts / 2);
    c.B.block<2, 1>(2 * i, i) = Minv * Bc * std::sqrt(Ts);
    c.C.block<1, 2>(i, 2 * i) = std::sqrt(Ts) * Cc * Minv;
    c.D(i, i) = Dc + (Cc * Minv * Bc)(0) * Ts / 2;
  }
  return c;
}

namespace {
Eigen::Matrix3d q_noise_covariance(const Plant& p, const Noise& noise) {
  const Eigen::Matrix<double, 3, 9> T = transformation(p.design_pitch_m);
  return noise.sensor_std_m * noise.sensor_std_m * T * T.transpose();
}
}  // namespace

double closed_loop_spectral_radius(const Discrete& P, const Discrete& C) {
  const Index np = P.order(), nc = C.order();
  MatrixXd A(np + nc, np + nc);
  A << P.A - P.B * C.D * P.C, P.B * C.C, -C.B * P.C, C.A;
  return A.eigenvalues().cwiseAbs().maxCoeff();
}

Eigen::MatrixXd simulate_log(const Discrete& P, const Discrete& C, const Plant& physical, const Noise& noise,
                             const double excitation_std[3], int excited, Index N, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Matrix<double, 3, 9> T = transformation(physical.design_pitch_m);
  VectorXd xp = VectorXd::Zero(P.order()), xc = VectorXd::Zero(C.order());
  MatrixXd log(N, 10);
  for (Index k = 0; k < N; ++k) {
    Eigen::Vector3d v = Eigen::Vector3d::Zero(), w;
    for (int i = 0; i < 3; ++i) {
      const double g = gauss(rng);
      if (excited < 0 || excited == i) v(i) = excitation_std[i] * g;
    }
    Eigen::Matrix<double, 9, 1> ns;
    for (int i = 0; i < 9; ++i) ns(i) = noise.sensor_std_m * gauss(rng);
    for (int i = 0; i < 3; ++i) w(i) = noise.force_std[i] * gauss(rng);
    const Eigen::Vector3d q = P.C * xp + T * ns;
    const Eigen::Vector3d e = -q;
    const Eigen::Vector3d u = C.C * xc + C.D * e + v;
    log(k, 0) = static_cast<double>(k) * P.Ts;
    log.block<1, 3>(k, 1) = v.transpose();
    log.block<1, 3>(k, 4) = u.transpose();
    log.block<1, 3>(k, 7) = q.transpose();
    xp = P.A * xp + P.B * (u + w);
    xc = C.A * xc + C.B * e;
  }
  return log;
}

AnalyzerData analyzer_S(const Discrete& P, const Discrete& C, const Plant& physical, const Noise& noise,
                        const VectorXd& omega, const double amplitude[3], int K, Index Nb, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Matrix3d Sn = q_noise_covariance(physical, noise);
  // per real part the DFT noise of a block has covariance (2 / Nb) Sn
  const Eigen::LLT<Eigen::Matrix3d> chol((2.0 / static_cast<double>(Nb)) * Sn +
                                         1e-300 * Eigen::Matrix3d::Identity());
  const Eigen::Matrix3d L = chol.matrixL();
  AnalyzerData out;
  out.omega_rad_s = omega;
  out.averages = K;
  for (Index f = 0; f < omega.size(); ++f) {
    const Eigen::Matrix3cd Pz = P.response(omega(f)), Cz = C.response(omega(f));
    const Eigen::Matrix3cd S = (Eigen::Matrix3cd::Identity() + Cz * Pz).inverse();
    const Eigen::Matrix3cd SC = S * Cz;
    Eigen::Matrix3cd est = Eigen::Matrix3cd::Zero();
    Eigen::Matrix3d coh;
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3cd sum = Eigen::Vector3cd::Zero();
      Eigen::Vector3d sum_abs2 = Eigen::Vector3d::Zero();
      for (int b = 0; b < K; ++b) {
        Eigen::Vector3d re, im;
        for (int i = 0; i < 3; ++i) re(i) = gauss(rng);
        for (int i = 0; i < 3; ++i) im(i) = gauss(rng);
        const Eigen::Vector3cd n = (L * re).cast<std::complex<double>>() +
                                   std::complex<double>(0, 1) * (L * im).cast<std::complex<double>>();
        const Eigen::Vector3cd U = S.col(j) * amplitude[j] - SC * n;
        sum += U;
        sum_abs2 += U.cwiseAbs2();
      }
      est.col(j) = sum / (static_cast<double>(K) * amplitude[j]);
      for (int i = 0; i < 3; ++i)
        coh(i, j) = std::min(1.0, std::norm(sum(i)) / (static_cast<double>(K) * sum_abs2(i)));
    }
    out.S.push_back(est);
    out.truth.push_back(S);
    out.coherence.push_back(coh);
  }
  return out;
}

void write_log_csv(const std::string& path, const MatrixXd& log) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  std::fprintf(f, "t,v1,v2,v3,u1,u2,u3,q1,q2,q3\n");
  for (Index k = 0; k < log.rows(); ++k) {
    for (Index j = 0; j < log.cols(); ++j) std::fprintf(f, j ? ",%.17g" : "%.17g", log(k, j));
    std::fprintf(f, "\n");
  }
  std::fclose(f);
}

namespace {
void write_matrix(FILE* f, const char* key, const MatrixXd& X, bool last) {
  std::fprintf(f, "  \"%s\": [", key);
  for (Index i = 0; i < X.rows(); ++i) {
    std::fprintf(f, "%s[", i ? ", " : "");
    for (Index j = 0; j < X.cols(); ++j) std::fprintf(f, j ? ", %.17g" : "%.17g", X(i, j));
    std::fprintf(f, "]");
  }
  std::fprintf(f, "]%s\n", last ? "" : ",");
}
void write_names(FILE* f, const char* key, const std::vector<std::string>& names) {
  std::fprintf(f, "  \"%s\": [", key);
  for (std::size_t i = 0; i < names.size(); ++i) std::fprintf(f, "%s\"%s\"", i ? ", " : "", names[i].c_str());
  std::fprintf(f, "],\n");
}
}  // namespace

void write_state_space_json(const std::string& path, const Discrete& sys, const std::vector<std::string>& inputs,
                            const std::vector<std::string>& outputs) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path);
  std::fprintf(f, "{\n  \"type\": \"state_space\",\n  \"ts\": %.17g,\n", sys.Ts);
  write_names(f, "inputs", inputs);
  write_names(f, "outputs", outputs);
  if (sys.A.rows() == 0) {
    std::fprintf(f, "  \"A\": [],\n  \"B\": [],\n  \"C\": [");
    for (Index i = 0; i < sys.D.rows(); ++i) std::fprintf(f, "%s[]", i ? ", " : "");
    std::fprintf(f, "],\n");
  } else {
    write_matrix(f, "A", sys.A, false);
    write_matrix(f, "B", sys.B, false);
    write_matrix(f, "C", sys.C, false);
  }
  write_matrix(f, "D", sys.D, true);
  std::fprintf(f, "}\n");
  std::fclose(f);
}

void write_controller_json(const std::string& path, const Discrete& controller) {
  write_state_space_json(path, controller, {"e1", "e2", "e3"}, {"uc1", "uc2", "uc3"});
}

void write_analyzer_csv(const std::string& dir, const AnalyzerData& d, bool write_averages) {
  for (int j = 0; j < 3; ++j) {
    const std::string path = dir + "/S_v" + std::to_string(j + 1) + ".csv";
    FILE* f = std::fopen(path.c_str(), "w");
    if (!f) throw std::runtime_error("cannot write " + path);
    std::fprintf(f, "# independent analyzer export, stepped sine\n");
    if (write_averages) std::fprintf(f, "# averages: %d\n", d.averages);
    std::fprintf(f, "# outputs: u1,u2,u3\n# inputs: v%d\nfreq_hz", j + 1);
    for (int i = 0; i < 3; ++i) std::fprintf(f, ",S_u%d_v%d_re,S_u%d_v%d_im", i + 1, j + 1, i + 1, j + 1);
    for (int i = 0; i < 3; ++i) std::fprintf(f, ",coh_u%d_v%d", i + 1, j + 1);
    std::fprintf(f, "\n");
    for (Index k = 0; k < d.omega_rad_s.size(); ++k) {
      std::fprintf(f, "%.17g", d.omega_rad_s(k) / (2 * M_PI));
      for (int i = 0; i < 3; ++i) std::fprintf(f, ",%.17g,%.17g", d.S[k](i, j).real(), d.S[k](i, j).imag());
      for (int i = 0; i < 3; ++i) std::fprintf(f, ",%.17g", d.coherence[k](i, j));
      std::fprintf(f, "\n");
    }
    std::fclose(f);
  }
}

}  // namespace indep
