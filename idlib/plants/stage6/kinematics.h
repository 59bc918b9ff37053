// The 6-DOF stage's kinematics and force allocation (seed 001, eqs 1, 4, 27–30),
// once, as templates on the scalar type: doubles for the simulator and the
// equation-error fit (idlib/plants/stage6/stage6.cc), ceres::Jet for the
// output-error fit (idlib/stage6/stage6_output_error.cc) and the linearised base
// (idlib/physical/stage6/stage6_base.h).  Conventions as in
// idlib/plants/stage6/stage6.h: Z-Y-X Euler angles yaw psi, pitch theta, roll phi;
// R = Rz(psi) Ry(theta) Rx(phi) maps body to inertial axes; the body angular
// velocity is omega = W(theta, phi) [psi' theta' phi'].  The allocation's columns are
// the forces f = [f1x f1z f2y f2z f3x f3z f4y f4z] (motors 1, 3 push along body x,
// motors 2, 4 along body y, all four lift along body z); its rows the body wrench
// [F_x F_y F_z tau_x tau_y tau_z].  The tests' independent stage
// (tests/support/independent_stage.cc) derives all of this separately.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>

namespace lpvid::stage6 {

template <class T>
using Matrix3 = Eigen::Matrix<T, 3, 3>;
template <class T>
using Vector3 = Eigen::Matrix<T, 3, 1>;

// R = Rz(psi) Ry(theta) Rx(phi) (eq 1's J₁).
template <class T>
Matrix3<T> rotation_zyx(const T& psi, const T& theta, const T& phi) {
  using std::cos;
  using std::sin;
  const T cps = cos(psi), sps = sin(psi), cth = cos(theta), sth = sin(theta), cph = cos(phi), sph = sin(phi);
  Matrix3<T> R;
  R << cps * cth, -sps * cph + cps * sth * sph, sps * sph + cps * cph * sth,  //
      sps * cth, cps * cph + sps * sth * sph, -cps * sph + sps * cph * sth,  //
      -sth, cth * sph, cth * cph;
  return R;
}

// dR/dpsi, dR/dtheta, dR/dphi (in that order).
template <class T>
std::array<Matrix3<T>, 3> rotation_zyx_derivatives(const T& psi, const T& theta, const T& phi) {
  using std::cos;
  using std::sin;
  const T zero(0.0), one(1.0);
  const T cps = cos(psi), sps = sin(psi), cth = cos(theta), sth = sin(theta), cph = cos(phi), sph = sin(phi);
  Matrix3<T> Rz, Ry, Rx, dRz, dRy, dRx;
  Rz << cps, -sps, zero, sps, cps, zero, zero, zero, one;
  Ry << cth, zero, sth, zero, one, zero, -sth, zero, cth;
  Rx << one, zero, zero, zero, cph, -sph, zero, sph, cph;
  dRz << -sps, -cps, zero, cps, -sps, zero, zero, zero, zero;
  dRy << -sth, zero, cth, zero, zero, zero, -cth, zero, -sth;
  dRx << zero, zero, zero, zero, -sph, -cph, zero, cph, -sph;
  return {dRz * Ry * Rx, Rz * dRy * Rx, Rz * Ry * dRx};
}

// W(theta, phi) of eq 4 with its columns in q's order [psi' theta' phi'] (eq 4
// multiplies [phi' theta' psi']): omega = W [psi' theta' phi'].
template <class T>
Matrix3<T> angular_velocity_map(const T& theta, const T& phi) {
  using std::cos;
  using std::sin;
  const T zero(0.0), one(1.0);
  const T cth = cos(theta), sth = sin(theta), cph = cos(phi), sph = sin(phi);
  Matrix3<T> W;
  W << -sth, zero, one,  //
      cth * sph, cph, zero,  //
      cth * cph, -sph, zero;
  return W;
}

// [psi' theta' phi'] = W⁻¹ omega (singular at theta = ±90°, the Euler angles' gimbal lock).
template <class T>
Vector3<T> euler_rates(const T& theta, const T& phi, const Vector3<T>& omega) {
  using std::cos;
  using std::sin;
  const T cth = cos(theta), sth = sin(theta), cph = cos(phi), sph = sin(phi);
  const T psid = (sph * omega(1) + cph * omega(2)) / cth;
  return Vector3<T>(psid, cph * omega(1) - sph * omega(2), omega(0) + sth * psid);
}

// The drive axis of motor i (0..3): body x for motors 1, 3 (i = 0, 2), y for 2, 4.
constexpr int drive_axis(int motor) { return motor % 2 == 0 ? 0 : 1; }

// A (6×8): w = A f, from F = Σ f_i and tau = Σ r_i × f_i with the lever arms r
// (one column per motor, body axes, from the point the moments are taken about).
// DESIGN.md item 6: eq 30 as printed has one sign wrong (printed_eq30_matrix).
template <class T>
Eigen::Matrix<T, 6, 8> allocation_matrix(const Eigen::Matrix<T, 3, 4>& r) {
  const T zero(0.0), one(1.0);
  Eigen::Matrix<T, 6, 8> A = Eigen::Matrix<T, 6, 8>::Constant(zero);
  for (int i = 0; i < 4; ++i) {
    const int h = drive_axis(i), ch = 2 * i, cv = 2 * i + 1;
    A(h, ch) = one;
    // r × e_x = (0, r_z, −r_y); r × e_y = (−r_z, 0, r_x)
    if (h == 0) {
      A(4, ch) = r(2, i);
      A(5, ch) = -r(1, i);
    } else {
      A(3, ch) = -r(2, i);
      A(5, ch) = r(0, i);
    }
    // r × e_z = (r_y, −r_x, 0)
    A(2, cv) = one;
    A(3, cv) = r(1, i);
    A(4, cv) = -r(0, i);
  }
  return A;
}

}  // namespace lpvid::stage6
