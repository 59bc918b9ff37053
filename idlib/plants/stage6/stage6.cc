#include "idlib/plants/stage6/stage6.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <numbers>

#include "idlib/core/error.h"

namespace lpvid::stage6 {

Eigen::Matrix<double, 3, 4> StageParameters::default_lever_arms() {
  // Pinwheel layout of four magnet arrays on a 0.25 m platen (docs/assumptions.md):
  // array centres 75 mm from the centre along both axes, 15 mm below the
  // centre of mass.  Columns: motors 1 (x), 2 (y), 3 (x), 4 (y).
  Eigen::Matrix<double, 3, 4> r;
  r << 0.075, -0.075, -0.075, 0.075,  //
      0.075, 0.075, -0.075, -0.075,   //
      -0.015, -0.015, -0.015, -0.015;
  return r;
}

double StageParameters::gamma_per_m() const { return 2.0 * std::numbers::pi / magnet_pitch_m; }

double StageParameters::electrical_time_constant_s() const {
  return inductance_H / (resistance_ohm + current_loop_gain_V_per_A);
}

void StageParameters::validate() const {
  auto positive = [](double v, const char* name) {
    if (!std::isfinite(v) || v <= 0)
      throw InputError(fmt::format("stage parameter {} = {}: must be a positive finite number", name, v));
  };
  positive(mass_kg, "mass_kg");
  positive(force_constant_N_per_A, "force_constant_N_per_A");
  positive(magnet_pitch_m, "magnet_pitch_m");
  positive(resistance_ohm, "resistance_ohm");
  positive(inductance_H, "inductance_H");
  if (!std::isfinite(current_loop_gain_V_per_A) || current_loop_gain_V_per_A < 0)
    throw InputError(fmt::format("stage parameter current_loop_gain_V_per_A = {}: must be >= 0",
                                 current_loop_gain_V_per_A));
  if (!std::isfinite(reference_gap_m))
    throw InputError("stage parameter reference_gap_m: must be finite");
  if (!lever_arms_m.allFinite()) throw InputError("stage lever arms: every entry must be finite");
  if (!inertia_kgm2.allFinite() || (inertia_kgm2 - inertia_kgm2.transpose()).norm() > 1e-12 * inertia_kgm2.norm())
    throw InputError("stage inertia_kgm2: must be a finite symmetric 3x3 matrix");
  Eigen::LLT<Eigen::Matrix3d> llt(inertia_kgm2);
  if (llt.info() != Eigen::Success)
    throw InputError("stage inertia_kgm2: must be positive definite (a rigid body's inertia)");
}

namespace {
// Ẇ q̇_a with Ẇ = ∂W/∂θ θ̇ + ∂W/∂φ φ̇.
Eigen::Vector3d w_dot_times(double theta, double phi, const Eigen::Vector3d& qa_dot) {
  const double cth = std::cos(theta), sth = std::sin(theta);
  const double cph = std::cos(phi), sph = std::sin(phi);
  const double td = qa_dot(1), pd = qa_dot(2);
  Eigen::Matrix3d Wd;
  Wd << -cth * td, 0.0, 0.0,  //
      -sth * sph * td + cth * cph * pd, -sph * pd, 0.0,  //
      -sth * cph * td - cth * sph * pd, -cph * pd, 0.0;
  return Wd * qa_dot;
}
}  // namespace

Matrix6d wrench_to_generalized(const Vector6d& q) {
  Matrix6d G = Matrix6d::Zero();
  G.topLeftCorner<3, 3>() = rotation(q);
  G.bottomRightCorner<3, 3>() = angular_velocity_map(q(4), q(5)).transpose();
  return G;
}

Matrix6d mass_matrix(const StageParameters& p, const Vector6d& q) {
  const Eigen::Matrix3d W = angular_velocity_map(q(4), q(5));
  Matrix6d M = Matrix6d::Zero();
  M.topLeftCorner<3, 3>() = p.mass_kg * Eigen::Matrix3d::Identity();
  M.bottomRightCorner<3, 3>() = W.transpose() * p.inertia_kgm2 * W;
  return M;
}

Vector6d gravity_term(const StageParameters& p) {
  Vector6d h = Vector6d::Zero();
  h(2) = p.mass_kg * kGravity_m_per_s2;
  return h;
}

Vector6d coriolis_term(const StageParameters& p, const Vector6d& q, const Vector6d& qd) {
  const Eigen::Matrix3d W = angular_velocity_map(q(4), q(5));
  const Eigen::Vector3d qa_dot = qd.tail<3>();
  const Eigen::Vector3d omega = W * qa_dot;
  const Eigen::Vector3d Hw = p.inertia_kgm2 * omega;
  Vector6d h = Vector6d::Zero();
  h.tail<3>() = W.transpose() * (p.inertia_kgm2 * w_dot_times(q(4), q(5), qa_dot) + omega.cross(Hw));
  return h;
}

Vector6d acceleration(const StageParameters& p, const Vector6d& q, const Vector6d& qd, const Vector6d& u) {
  const Vector6d rhs = u - gravity_term(p) - coriolis_term(p, q, qd);
  Vector6d qdd;
  qdd.head<3>() = rhs.head<3>() / p.mass_kg;
  const Eigen::Matrix3d W = angular_velocity_map(q(4), q(5));
  qdd.tail<3>() = (W.transpose() * p.inertia_kgm2 * W).partialPivLu().solve(rhs.tail<3>());
  return qdd;
}

double total_energy(const StageParameters& p, const Vector6d& q, const Vector6d& qd) {
  const Eigen::Vector3d omega = angular_velocity_map(q(4), q(5)) * qd.tail<3>();
  return 0.5 * p.mass_kg * qd.head<3>().squaredNorm() + 0.5 * omega.dot(p.inertia_kgm2 * omega) +
         p.mass_kg * kGravity_m_per_s2 * q(2);
}

Matrix68d printed_eq30_matrix(const Eigen::Matrix<double, 3, 4>& r) {
  const auto a = [&](int i) { return r(0, i - 1); };
  const auto b = [&](int i) { return r(1, i - 1); };
  const auto c = [&](int i) { return r(2, i - 1); };
  Matrix68d A;
  // Transcribed from seed 001, eq 30 (columns f1x f1z f2y f2z f3x f3z f4y f4z).
  A << 1, 0, 0, 0, 1, 0, 0, 0,  //
      0, 0, 1, 0, 0, 0, 1, 0,  //
      0, 1, 0, 1, 0, 1, 0, 1,  //
      0, b(1), -c(2), b(2), 0, b(3), -c(4), b(4),  //
      c(1), -a(1), 0, -a(2), c(3), -a(3), 0, -a(4),  //
      -b(1), 0, a(2), 0, -b(3), 0, -a(4), 0;
  return A;
}

Eigen::Matrix<double, 8, 6> allocation_pseudo_inverse(const Eigen::Matrix<double, 3, 4>& r) {
  const Matrix68d A = allocation_matrix(r);
  const Matrix6d AAt = A * A.transpose();
  Eigen::FullPivLU<Matrix6d> lu(AAt);
  // Relative threshold: a geometry whose AAᵀ is singular to 1e-10 of its size
  // cannot produce some wrench with bounded forces.
  lu.setThreshold(1e-10);
  if (lu.rank() < 6)
    throw InputError(fmt::format(
        "stage lever arms give a force allocation of rank {} < 6: some wrench cannot be produced; "
        "place the four magnet arrays off the centre of mass and not on one line",
        lu.rank()));
  return A.transpose() * lu.inverse();
}

Vector6d sensed_configuration(const Vector6d& q_cm, const Eigen::Vector3d& c) {
  Vector6d q = q_cm;
  q.head<3>() -= rotation(q_cm) * c;
  return q;
}

Vector6d sensed_velocity(const Vector6d& q_cm, const Vector6d& qd_cm, const Eigen::Vector3d& c) {
  const Eigen::Vector3d omega = angular_velocity_map(q_cm(4), q_cm(5)) * qd_cm.tail<3>();
  Vector6d qd = qd_cm;
  qd.head<3>() -= rotation(q_cm) * omega.cross(c);
  return qd;
}

Vector6d centre_of_mass_configuration(const Vector6d& q_sensed, const Eigen::Vector3d& c) {
  Vector6d q = q_sensed;
  q.head<3>() += rotation(q_sensed) * c;
  return q;
}

Eigen::Vector3d array_velocity(const Vector6d& q, const Vector6d& qd, const Eigen::Vector3d& arm_m) {
  const Eigen::Vector3d omega = angular_velocity_map(q(4), q(5)) * qd.tail<3>();
  return rotation(q).transpose() * qd.head<3>() + omega.cross(arm_m);
}

double gap_factor(const StageParameters& p, double gap_m) {
  return std::exp(-p.gamma_per_m() * (gap_m - p.reference_gap_m));
}

double motor_gap_m(const StageParameters& p, const Vector6d& q, int motor) {
  LPVID_ASSERT(motor >= 0 && motor < 4);
  const Eigen::Vector3d r = p.lever_arms_m.col(motor);
  return q(2) + (rotation(q) * r - r)(2);
}

Eigen::Vector2d motor_forces(const StageParameters& p, double i_d_A, double i_q_A, double gap_m) {
  const double k = p.force_constant_N_per_A * gap_factor(p, gap_m);
  return {k * i_q_A, k * i_d_A};
}

Eigen::Vector2d motor_currents(const StageParameters& p, double horizontal_N, double vertical_N, double gap_m) {
  const double k = p.force_constant_N_per_A * gap_factor(p, gap_m);
  return {vertical_N / k, horizontal_N / k};
}

Eigen::Vector2d current_derivative(const StageParameters& p, const Eigen::Vector2d& i_dq,
                                   const Eigen::Vector2d& i_cmd_dq, double drive_velocity_m_per_s,
                                   double vertical_velocity_m_per_s, double gap_m) {
  const double gain = p.resistance_ohm + p.current_loop_gain_V_per_A;
  const double ke_alpha = p.force_constant_N_per_A * gap_factor(p, gap_m);
  return {(gain * (i_cmd_dq(0) - i_dq(0)) - ke_alpha * vertical_velocity_m_per_s) / p.inductance_H,
          (gain * (i_cmd_dq(1) - i_dq(1)) - ke_alpha * drive_velocity_m_per_s) / p.inductance_H};
}

}  // namespace lpvid::stage6
