#include "idlib/physical/evaluate.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

Index at(const PhysicalModel& m, const char* name) { return m.index_of(name); }

}  // namespace

ModelLayout::ModelLayout(const PhysicalModel& model) {
  model.validate();
  J_psi = at(model, "J_psi_kgm2");
  J_theta = at(model, "J_theta_kgm2");
  m_p = at(model, "platform_mass_kg");
  m_b = at(model, "beam_mass_kg");
  z_b = at(model, "beam_height_m");
  stroke = at(model, "beam_stroke_m");
  r_vc = at(model, "coil_arm_m");
  d = at(model, "coil_damping_Ns_per_m");
  k_lin = at(model, "k_linear_N_per_m");
  k_low = at(model, "k_torque_low_Nm_per_rad");
  rod[0] = at(model, "rod_axis_angle_1_rad");
  rod[1] = at(model, "rod_axis_angle_2_rad");
  rod[2] = at(model, "rod_axis_angle_3_rad");
  k_high = at(model, "k_torque_high_Nm_per_rad");
  com_x = at(model, "com_x_m");
  com_y = at(model, "com_y_m");
  J_pt = at(model, "J_psitheta_kgm2");
  g = at(model, "gravity_m_per_s2");
  mode_w = at(model, "mode_frequency_rad_s");
  mode_zeta = at(model, "mode_damping");
  phi[0] = at(model, "mode_shape_psi");
  phi[1] = at(model, "mode_shape_theta");
  phi[2] = at(model, "mode_shape_z");
  delay = at(model, "input_delay_s");
  lag = at(model, "actuator_time_constant_s");
  gain[0] = at(model, "gain_psi");
  gain[1] = at(model, "gain_theta");
  gain[2] = at(model, "gain_z");
}

void check_beam_position(const PhysicalModel& model, double beam_position_m) {
  const double stroke = model.parameter("beam_stroke_m").value;
  if (!std::isfinite(beam_position_m) || std::abs(beam_position_m) > stroke)
    throw InputError(fmt::format(
        "beam position x_b = {} m is outside the stroke |x_b| <= beam_stroke_m = {} m; give x_b in metres "
        "(e.g. -0.1, 0, 0.1) or raise beam_stroke_m",
        beam_position_m, stroke));
}

PhysicalStateSpace physical_state_space(const PhysicalModel& model, double beam_position_m, double sample_period_s) {
  const ModelLayout layout(model);
  check_beam_position(model, beam_position_m);
  if (!std::isfinite(sample_period_s) || sample_period_s < 0.0)
    throw InputError(fmt::format("sample period {} s: it must be 0 (continuous) or a positive number of seconds",
                                 sample_period_s));
  const Eigen::VectorXd p = model.values();
  Eigen::MatrixXd A, B, C, D;
  if (!build_continuous<double>(layout, p.data(), beam_position_m, A, B, C, D))
    throw InputError(fmt::format(
        "the mass matrix at x_b = {} m is not positive definite; the centre-of-mass offsets or J_psitheta are too "
        "large for the inertias — check their values and units",
        beam_position_m));
  PhysicalStateSpace out;
  out.input_delay_s = layout.delay >= 0 ? p(layout.delay) : 0.0;
  StateSpace& s = out.system;
  s.input_names = {"T_psi", "T_theta", "F_z"};
  s.output_names = {"psi", "theta", "z"};
  if (sample_period_s == 0.0) {
    s.A = A;
    s.B = B;
    s.C = C;
    s.D = D;
    return out;
  }
  Eigen::MatrixXd Ad, Bd;
  zoh_discretize<double>(A, B, sample_period_s, Ad, Bd);
  const Index n = A.rows();
  const Index d = static_cast<Index>(std::llround(out.input_delay_s / sample_period_s));
  out.delay_samples = d;
  const Index nd = 3 * d;
  // Shift register per input: s_1[k+1] = u[k], s_i[k+1] = s_{i-1}[k]; the plant
  // is driven by s_d.  State order [x; s_1; ...; s_d] (each s_i 3 entries).
  s.A = Eigen::MatrixXd::Zero(n + nd, n + nd);
  s.B = Eigen::MatrixXd::Zero(n + nd, 3);
  s.C = Eigen::MatrixXd::Zero(3, n + nd);
  s.D = D;
  s.A.topLeftCorner(n, n) = Ad;
  s.C.leftCols(n) = C;
  if (d == 0) {
    s.B.topRows(n) = Bd;
  } else {
    s.A.block(0, n + nd - 3, n, 3) = Bd;
    s.B.block(n, 0, 3, 3).setIdentity();
    for (Index i = 1; i < d; ++i) s.A.block(n + 3 * i, n + 3 * (i - 1), 3, 3).setIdentity();
  }
  s.sample_period_s = sample_period_s;
  return out;
}

std::vector<Eigen::MatrixXcd> physical_response(const PhysicalModel& model, double beam_position_m,
                                                const Eigen::VectorXd& omega_rad_s, double sample_period_s) {
  const ModelLayout layout(model);
  check_beam_position(model, beam_position_m);
  if (!std::isfinite(sample_period_s) || sample_period_s < 0.0)
    throw InputError(fmt::format("sample period {} s: it must be 0 (continuous) or a positive number of seconds",
                                 sample_period_s));
  const Eigen::VectorXd p = model.values();
  Eigen::MatrixXd A, B, C, D;
  if (!build_continuous<double>(layout, p.data(), beam_position_m, A, B, C, D))
    throw InputError(fmt::format("the mass matrix at x_b = {} m is not positive definite; check the centre-of-mass "
                                 "offsets, J_psitheta and their units",
                                 beam_position_m));
  if (sample_period_s > 0.0) {
    Eigen::MatrixXd Ad, Bd;
    zoh_discretize<double>(A, B, sample_period_s, Ad, Bd);
    A = Ad;
    B = Bd;
  }
  const double tau = layout.delay >= 0 ? p(layout.delay) : 0.0;
  std::vector<Eigen::MatrixXcd> out;
  out.reserve(static_cast<std::size_t>(omega_rad_s.size()));
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s(k);
    if (!std::isfinite(w)) throw InputError(fmt::format("frequency {} rad/s is not finite", w));
    const Complex lambda = sample_period_s > 0.0 ? std::exp(Complex(0.0, w * sample_period_s)) : Complex(0.0, w);
    Eigen::MatrixXcd Z = -A.cast<Complex>();
    Z.diagonal().array() += lambda;
    const Eigen::MatrixXcd X = Z.partialPivLu().solve(B.cast<Complex>());
    out.push_back((C.cast<Complex>() * X + D.cast<Complex>()) * std::exp(Complex(0.0, -w * tau)));
  }
  return out;
}

}  // namespace lpvid
