#include "idlib/plants/platform/platform.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

void require_positive(double value, const char* name, const char* what) {
  if (!std::isfinite(value) || !(value > 0.0))
    throw InputError(fmt::format("platform parameters: {} = {}; it must be finite and > 0; give {}", name, value, what));
}

void require_non_negative(double value, const char* name, const char* what) {
  if (!std::isfinite(value) || !(value >= 0.0))
    throw InputError(fmt::format("platform parameters: {} = {}; it must be finite and >= 0; give {}", name, value, what));
}

void require_finite(double value, const char* name, const char* what) {
  if (!std::isfinite(value))
    throw InputError(fmt::format("platform parameters: {} = {}; it must be finite; give {}", name, value, what));
}

void require_beam_position(const PlatformParameters& params, double beam_position_m) {
  if (!std::isfinite(beam_position_m) || std::abs(beam_position_m) > params.beam_stroke_m)
    throw InputError(fmt::format(
        "beam position x_b = {} m is outside the stroke |x_b| <= beam_stroke_m = {} m; give x_b in metres "
        "(e.g. -0.1, 0, 0.1) or raise beam_stroke_m",
        beam_position_m, params.beam_stroke_m));
}

// The ψ/θ sign pattern of eq 9 on the 3×3 grid, coils 1..9 (see CoilLayout).
constexpr std::array<double, 9> kGridXSign = {1, 1, 1, 0, 0, 0, -1, -1, -1};
constexpr std::array<double, 9> kGridYSign = {1, 0, -1, 1, 0, -1, 1, 0, -1};

}  // namespace

PlatformParameters PlatformParameters::defaults() { return PlatformParameters{}; }

void PlatformParameters::validate() const {
  require_positive(J_psi_kgm2, "J_psi_kgm2", "the moment of inertia about x in kg·m²");
  require_positive(J_theta_kgm2, "J_theta_kgm2", "the moment of inertia about y in kg·m²");
  require_finite(J_psitheta_kgm2, "J_psitheta_kgm2", "the product of inertia in kg·m²");
  if (!(std::abs(J_psitheta_kgm2) < std::sqrt(J_psi_kgm2 * J_theta_kgm2)))
    throw InputError(fmt::format(
        "platform parameters: J_psitheta_kgm2 = {}; |J_psitheta| must be < sqrt(J_psi·J_theta) = {} for a "
        "positive-definite inertia; check the value and its unit (kg·m²)",
        J_psitheta_kgm2, std::sqrt(J_psi_kgm2 * J_theta_kgm2)));
  require_positive(platform_mass_kg, "platform_mass_kg", "the platform mass in kg");
  require_positive(beam_mass_kg, "beam_mass_kg", "the beam mass in kg");
  require_finite(beam_height_m, "beam_height_m", "the height of the beam above the origin in m");
  require_positive(beam_stroke_m, "beam_stroke_m", "the largest |x_b| in m");
  require_positive(coil_arm_m, "coil_arm_m", "the coil pitch r_vc in m");
  require_non_negative(coil_damping_Ns_per_m, "coil_damping_Ns_per_m", "the damping of one coil in N·s/m");
  require_non_negative(k_linear_N_per_m, "k_linear_N_per_m", "the vertical rod stiffness in N/m");
  require_non_negative(k_torque_low_Nm_per_rad, "k_torque_low_Nm_per_rad", "the rod bending stiffness in N·m/rad");
  require_non_negative(k_torque_high_Nm_per_rad, "k_torque_high_Nm_per_rad", "the rod twist stiffness in N·m/rad");
  for (std::size_t j = 0; j < rod_axis_angles_rad.size(); ++j)
    if (!std::isfinite(rod_axis_angles_rad[j]))
      throw InputError(fmt::format(
          "platform parameters: rod_axis_angles_rad[{}] = {}; it must be finite; give the rod direction in rad", j,
          rod_axis_angles_rad[j]));
  require_finite(com_x_m, "com_x_m", "the centre-of-mass offset in x in m");
  require_finite(com_y_m, "com_y_m", "the centre-of-mass offset in y in m");
  require_non_negative(gravity_m_per_s2, "gravity_m_per_s2", "the gravitational acceleration in m/s²");
}

Eigen::Matrix3d mass_matrix(const PlatformParameters& params, double beam_position_m) {
  params.validate();
  require_beam_position(params, beam_position_m);
  double m[3][3];
  platform_mass_matrix(params.J_psi_kgm2, params.J_theta_kgm2, params.J_psitheta_kgm2, params.platform_mass_kg,
                       params.beam_mass_kg, params.beam_height_m, params.com_x_m, params.com_y_m, beam_position_m, m);
  Eigen::Matrix3d M;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) M(i, j) = m[i][j];
  if (Eigen::LLT<Eigen::Matrix3d>(M).info() != Eigen::Success)
    throw InputError(fmt::format(
        "platform parameters: the mass matrix at x_b = {} m is not positive definite (com_x_m = {}, com_y_m = {}); "
        "the centre-of-mass offsets are too large for the inertias — check their values and units",
        beam_position_m, params.com_x_m, params.com_y_m));
  return M;
}

Eigen::Matrix3d stiffness_matrix(const PlatformParameters& params) {
  params.validate();
  double tilt[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
  for (const double phi : params.rod_axis_angles_rad)
    add_rod_tilt_stiffness(phi, params.k_torque_high_Nm_per_rad, params.k_torque_low_Nm_per_rad, tilt);
  const double gravity_term = -params.beam_height_m * params.beam_mass_kg * params.gravity_m_per_s2;
  Eigen::Matrix3d K = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) K(i, j) = tilt[i][j];
  K(0, 0) += gravity_term;
  K(1, 1) += gravity_term;
  K(2, 2) = params.k_linear_N_per_m;
  return K + params.stiffness_extra;
}

Eigen::Matrix3d damping_matrix(const PlatformParameters& params) {
  params.validate();
  if ((params.damping_override.diagonal().array() > 0.0).all()) return params.damping_override;
  const double d = params.coil_damping_Ns_per_m;
  const double r = params.coil_arm_m;
  return Eigen::Vector3d(6.0 * r * r * d, 6.0 * r * r * d, 9.0 * d).asDiagonal();
}

StateSpace platform_model(const PlatformParameters& params, double beam_position_m) {
  const Eigen::Matrix3d M = mass_matrix(params, beam_position_m);
  const Eigen::Matrix3d K = stiffness_matrix(params);
  const Eigen::Matrix3d D = damping_matrix(params);
  const Eigen::LLT<Eigen::Matrix3d> llt(M);
  const Eigen::Matrix3d M_inv = llt.solve(Eigen::Matrix3d::Identity());

  StateSpace sys;
  sys.A = Eigen::MatrixXd::Zero(6, 6);
  sys.A.topRightCorner(3, 3).setIdentity();
  sys.A.bottomLeftCorner(3, 3) = -llt.solve(K);
  sys.A.bottomRightCorner(3, 3) = -llt.solve(D);
  sys.B = Eigen::MatrixXd::Zero(6, 3);
  sys.B.bottomRows(3) = M_inv;
  sys.C = Eigen::MatrixXd::Zero(3, 6);
  sys.C.leftCols(3).setIdentity();
  sys.D = Eigen::MatrixXd::Zero(3, 3);
  sys.sample_period_s = 0.0;
  sys.input_names = {"T_psi", "T_theta", "F_z"};
  sys.output_names = {"psi", "theta", "z"};
  return sys;
}

// ---------------------------------------------------------------------------

CoilLayout CoilLayout::regular_grid(double coil_arm_m) {
  if (!std::isfinite(coil_arm_m) || !(coil_arm_m > 0.0))
    throw InputError(fmt::format("coil layout: coil_arm_m = {}; it must be finite and > 0; give the coil pitch r_vc in m",
                                 coil_arm_m));
  CoilLayout layout;
  for (std::size_t i = 0; i < 9; ++i)
    layout.position_m[i] = Eigen::Vector2d(kGridXSign[i] * coil_arm_m, kGridYSign[i] * coil_arm_m);
  return layout;
}

void CoilLayout::validate() const {
  for (std::size_t i = 0; i < position_m.size(); ++i)
    if (!position_m[i].allFinite())
      throw InputError(fmt::format("coil layout: coil {} is at ({}, {}); positions must be finite, in m", i + 1,
                                   position_m[i].x(), position_m[i].y()));
  // The wrench map has full row rank iff the coils are not all on one line,
  // i.e. the centred positions have a 2-D spread.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : position_m) mean += p;
  mean /= 9.0;
  Eigen::Matrix2d spread = Eigen::Matrix2d::Zero();
  for (const auto& p : position_m) spread += (p - mean) * (p - mean).transpose();
  const Eigen::Vector2d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(spread).eigenvalues();
  // Relative rank tolerance: coils collinear to 1e-9 of the layout's size count as a line.
  constexpr double kCollinearTolerance = 1e-18;
  if (!(ev(0) > kCollinearTolerance * std::max(ev(1), 1e-300)))
    throw InputError(
        "coil layout: the nine coils lie on one line, so no tilt about that line can be produced or measured; "
        "give positions that span the plane");
}

Eigen::Matrix<double, 3, 9> wrench_map(const CoilLayout& layout) {
  layout.validate();
  Eigen::Matrix<double, 3, 9> W;
  for (int i = 0; i < 9; ++i) {
    const auto& p = layout.position_m[static_cast<std::size_t>(i)];
    W(0, i) = p.y();
    W(1, i) = p.x();
    W(2, i) = 1.0;
  }
  return W;
}

Eigen::Matrix<double, 3, 9> transformation_from_layout(const CoilLayout& layout) {
  const Eigen::Matrix<double, 3, 9> W = wrench_map(layout);
  const Eigen::Matrix3d WWt = W * W.transpose();
  return WWt.ldlt().solve(W);
}

Eigen::Matrix<double, 3, 9> printed_transformation(double coil_arm_m) {
  if (!std::isfinite(coil_arm_m) || !(coil_arm_m > 0.0))
    throw InputError(fmt::format(
        "printed transformation: coil_arm_m = {}; it must be finite and > 0; give the coil pitch r_vc in m", coil_arm_m));
  Eigen::Matrix<double, 3, 9> T;
  for (int i = 0; i < 9; ++i) {
    const auto s = static_cast<std::size_t>(i);
    T(0, i) = kGridYSign[s] / (6.0 * coil_arm_m);
    T(1, i) = kGridXSign[s] / (6.0 * coil_arm_m);
    T(2, i) = 1.0 / 6.0;
  }
  return T;
}

// ---------------------------------------------------------------------------

StateSpace discrete_pi_controller(const std::array<PiGains, 3>& gains, double sample_period_s) {
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0))
    throw InputError(fmt::format(
        "PI controller: sample_period_s = {}; it must be finite and > 0; give the controller's sample period in s",
        sample_period_s));
  static const char* const kAxis[3] = {"psi", "theta", "z"};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!std::isfinite(gains[i].kp) || !(gains[i].kp >= 0.0) || !std::isfinite(gains[i].ki) || !(gains[i].ki >= 0.0))
      throw InputError(fmt::format(
          "PI controller: gains for {} are kp = {}, ki = {}; both must be finite and >= 0 (the loop feeds back e = -q)",
          kAxis[i], gains[i].kp, gains[i].ki));
  }
  StateSpace c;
  c.A = Eigen::MatrixXd::Identity(3, 3);
  c.B = Eigen::MatrixXd::Zero(3, 3);
  c.C = Eigen::MatrixXd::Identity(3, 3);
  c.D = Eigen::MatrixXd::Zero(3, 3);
  for (int i = 0; i < 3; ++i) {
    const auto& g = gains[static_cast<std::size_t>(i)];
    c.B(i, i) = g.ki * sample_period_s;
    c.D(i, i) = g.kp + g.ki * sample_period_s;
  }
  c.sample_period_s = sample_period_s;
  c.input_names = {"e_psi", "e_theta", "e_z"};
  c.output_names = {"u_psi", "u_theta", "u_z"};
  return c;
}

std::array<PiGains, 3> default_pi_gains(const PlatformParameters& params) {
  params.validate();
  if (!(params.coil_damping_Ns_per_m > 0.0))
    throw InputError(fmt::format(
        "default PI gains: coil_damping_Ns_per_m = {}; a PI loop on an undamped plant cannot be stabilised "
        "(stability needs d·(k + kp) > m·ki > 0); give a positive damping or supply your own controller",
        params.coil_damping_Ns_per_m));
  const Eigen::Matrix3d M = mass_matrix(params, kBeamMiddle_m);
  const Eigen::Matrix3d K = stiffness_matrix(params);
  const Eigen::Matrix3d D = damping_matrix(params);
  // Integrator pole at 0.4·d/m leaves the pair a real part of 0.3·d/m: the two
  // equal-ish decay rates maximise the slowest one while keeping Routh margin
  // d(k+kp) - m·ki = m²·(d/m)·(...) comfortably positive.
  constexpr double kIntegratorPoleFraction = 0.4;
  // Pair natural frequency 1.2× the open-loop resonance: the loop stiffens the
  // plant a little (kp > 0) without pushing crossover toward 400 rad/s.
  constexpr double kPairOverOpenLoopFrequency = 1.2;
  // At least twice the pair's decay rate: damping ratio at most 0.5, so that a
  // soft (or gravity-unstable) axis still gets a proper P action.
  constexpr double kPairMinFrequencyOverDecay = 2.0;
  std::array<PiGains, 3> gains{};
  for (int i = 0; i < 3; ++i) {
    const double m = M(i, i);
    const double d = D(i, i);
    const double k = K(i, i);
    const double a = kIntegratorPoleFraction * d / m;
    const double decay = 0.5 * (d / m - a);
    const double omega_p = std::max(kPairOverOpenLoopFrequency * std::sqrt(std::max(k, 0.0) / m),
                                    kPairMinFrequencyOverDecay * decay);
    const double c = omega_p * omega_p;
    auto& g = gains[static_cast<std::size_t>(i)];
    g.kp = m * (a * (d / m - a) + c) - k;
    g.ki = m * a * c;
  }
  return gains;
}

}  // namespace lpvid
