#include "idlib/plants/stage6/stage6.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <random>

#include "idlib/core/error.h"

namespace lpvid::stage6 {
namespace stage6_test {

constexpr std::uint64_t kSeed = 6001;

Eigen::Matrix<double, 3, 4> random_geometry(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  Eigen::Matrix<double, 3, 4> r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j) r(i, j) = u(rng);
  return r;
}

// The allocation is, by definition, F = Σ f_i and τ = Σ r_i × f_i with the
// force vectors of eq 27 (motors 1, 3: x and z; motors 2, 4: y and z).
TEST(Stage6Allocation, MatchesCrossProductsOnRandomGeometries) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> n(0.0, 10.0);
  for (int trial = 0; trial < 50; ++trial) {
    const auto r = random_geometry(rng);
    Vector8d f;
    for (int i = 0; i < 8; ++i) f(i) = n(rng);
    Eigen::Vector3d F = Eigen::Vector3d::Zero(), tau = Eigen::Vector3d::Zero();
    for (int i = 0; i < 4; ++i) {
      Eigen::Vector3d fi(0, 0, f(2 * i + 1));
      fi(i % 2 == 0 ? 0 : 1) = f(2 * i);
      F += fi;
      tau += Eigen::Vector3d(r.col(i)).cross(fi);
    }
    const Vector6d w = allocation_matrix(r) * f;
    // Sums of 8 products of O(0.2 m · 10 N): 1e-12 is ~1e3 ulps of the terms.
    constexpr double kTol = 1e-12;
    EXPECT_LT((w.head<3>() - F).norm(), kTol) << trial;
    EXPECT_LT((w.tail<3>() - tau).norm(), kTol) << trial;
  }
}

// Printed eq 30 agrees with r × f everywhere except the τ_Z entry of f4y, which
// it prints as −a₄ where the cross product (and eq 28) give +a₄ (DESIGN.md 6).
TEST(Stage6Allocation, PrintedEq30DiffersOnlyInTheTauZSignOfA4) {
  std::mt19937_64 rng(kSeed + 1);
  for (int trial = 0; trial < 20; ++trial) {
    const auto r = random_geometry(rng);
    const Matrix68d diff = printed_eq30_matrix(r) - allocation_matrix(r);
    Matrix68d expected = Matrix68d::Zero();
    expected(5, 6) = -2.0 * r(0, 3);  // printed −a₄ minus true +a₄
    EXPECT_EQ(diff, expected) << trial;  // entries are copies of the same doubles
  }
}

TEST(Stage6Allocation, PseudoInverseReproducesEveryWrench) {
  const auto r = StageParameters::default_lever_arms();
  const Eigen::Matrix<double, 8, 6> P = allocation_pseudo_inverse(r);
  // A A⁺ = I to rounding of a 6×6 inverse with condition ~ (1/0.015 m)².
  constexpr double kTol = 1e-10;
  EXPECT_LT((allocation_matrix(r) * P - Matrix6d::Identity()).norm(), kTol);
}

TEST(Stage6Allocation, DegenerateGeometryIsAnInputError) {
  Eigen::Matrix<double, 3, 4> r = Eigen::Matrix<double, 3, 4>::Zero();  // all arrays at the centre of mass
  EXPECT_THROW(allocation_pseudo_inverse(r), InputError);
}

// h₂ must equal the Lagrange terms Ṁ q̇ − ½ ∂(q̇ᵀ M q̇)/∂q of eq 8, evaluated
// here by central differences of M(q).
// kinematics.h's templates against definitions they do not use: R as the product of
// the three elementary rotations (Eigen's AngleAxis), its derivatives as central
// differences of R, and W⁻¹ω as a linear solve with W.  Random angles within ±1.2 rad.
TEST(Stage6Kinematics, RotationItsDerivativesAndTheEulerRatesMatchTheirDefinitions) {
  std::mt19937_64 rng(kSeed);
  std::uniform_real_distribution<double> a(-1.2, 1.2);
  for (int trial = 0; trial < 50; ++trial) {
    const double psi = a(rng), theta = a(rng), phi = a(rng);
    const Eigen::Matrix3d R = rotation_zyx(psi, theta, phi);
    const Eigen::Matrix3d product = (Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()) *
                                     Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitY()) *
                                     Eigen::AngleAxisd(phi, Eigen::Vector3d::UnitX()))
                                        .toRotationMatrix();
    EXPECT_LT((R - product).norm(), 1e-14);  // rounding of products of sines
    const auto dR = rotation_zyx_derivatives(psi, theta, phi);
    constexpr double h = 1e-6;
    const Eigen::Matrix3d fd[3] = {
        (rotation_zyx(psi + h, theta, phi) - rotation_zyx(psi - h, theta, phi)) / (2 * h),
        (rotation_zyx(psi, theta + h, phi) - rotation_zyx(psi, theta - h, phi)) / (2 * h),
        (rotation_zyx(psi, theta, phi + h) - rotation_zyx(psi, theta, phi - h)) / (2 * h)};
    // central differences: O(h²) truncation (1e-12) and 1e-16/h rounding (1e-10)
    for (int k = 0; k < 3; ++k) EXPECT_LT((dR[static_cast<std::size_t>(k)] - fd[k]).norm(), 1e-9) << k;
    const Eigen::Vector3d omega(a(rng), a(rng), a(rng));
    const Eigen::Vector3d rates = euler_rates(theta, phi, omega);
    const Eigen::Vector3d solved = angular_velocity_map(theta, phi).partialPivLu().solve(omega);
    EXPECT_LT((rates - solved).norm(), 1e-12 * (1.0 + omega.norm()) / std::cos(theta));
  }
}

TEST(Stage6Dynamics, CoriolisTermEqualsTheLagrangeEquation) {
  StageParameters p;
  p.inertia_kgm2 << 0.03, 0.002, -0.001, 0.002, 0.028, 0.0015, -0.001, 0.0015, 0.055;
  std::mt19937_64 rng(kSeed + 2);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  for (int trial = 0; trial < 20; ++trial) {
    Vector6d q, qd;
    for (int i = 0; i < 6; ++i) q(i) = u(rng), qd(i) = 3 * u(rng);
    const double h = 1e-6;
    Matrix6d Mdot = Matrix6d::Zero();
    Vector6d grad = Vector6d::Zero();
    for (int j = 0; j < 6; ++j) {
      Vector6d dq = Vector6d::Zero();
      dq(j) = h;
      const Matrix6d dM = (mass_matrix(p, q + dq) - mass_matrix(p, q - dq)) / (2 * h);
      Mdot += dM * qd(j);
      grad(j) = 0.5 * qd.dot(dM * qd);
    }
    const Vector6d lagrange = Mdot * qd - grad;
    // Central differences with h = 1e-6: truncation ~h² and rounding ~1e-16/h
    // on terms of O(0.1 N·m): 1e-8 covers both with margin.
    EXPECT_LT((coriolis_term(p, q, qd) - lagrange).norm(), 1e-8) << trial;
  }
}

// Without control, with gravity, T + V is conserved (eqs 5–8); integrate with
// small RK4 steps from a tumbling state.
TEST(Stage6Dynamics, EnergyIsConservedWithoutInputs) {
  StageParameters p;
  Vector6d q, qd;
  q << 0, 0, 0, 0.1, 0.2, 0.3;
  qd << 0.1, -0.2, 0.3, 2.0, -1.5, 3.0;
  const double e0 = total_energy(p, q, qd);
  const double h = 1e-4;
  auto f = [&](const Vector6d& a, const Vector6d& b) { return acceleration(p, a, b, Vector6d::Zero()); };
  for (int k = 0; k < 10000; ++k) {  // 1 s
    const Vector6d k1q = qd, k1v = f(q, qd);
    const Vector6d k2q = qd + 0.5 * h * k1v, k2v = f(q + 0.5 * h * k1q, qd + 0.5 * h * k1v);
    const Vector6d k3q = qd + 0.5 * h * k2v, k3v = f(q + 0.5 * h * k2q, qd + 0.5 * h * k2v);
    const Vector6d k4q = qd + h * k3v, k4v = f(q + h * k3q, qd + h * k3v);
    q += h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q);
    qd += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
  }
  // RK4 energy drift ~ (ω h)⁴ per unit time with ω ~ 4 rad/s: ~1e-14 relative;
  // 1e-9 of the energy scale (~0.5 J) leaves room for rounding over 1e4 steps.
  EXPECT_NEAR(total_energy(p, q, qd), e0, 1e-9);
  // And the free fall of the centre of mass: z = v_z t − g t²/2.
  EXPECT_NEAR(q(2), 0.3 - 0.5 * kGravity_m_per_s2, 1e-9);
  EXPECT_NEAR(q(0), 0.1, 1e-12);
}

TEST(Stage6Dynamics, HoverNeedsTheWeightOnly) {
  StageParameters p;
  Vector6d q = Vector6d::Zero(), qd = Vector6d::Zero();
  const Vector6d qdd = acceleration(p, q, qd, gravity_term(p));
  EXPECT_LT(qdd.norm(), 1e-15);
}

// eq 24 in d-q form: the currents that give a force pair give it back, and the
// force falls with the gap as α(z) = exp(−2π (z − z_ref)/pitch).
TEST(Stage6Motor, CurrentsAndForcesAreInverseAndGapDependent) {
  StageParameters p;
  const Eigen::Vector2d i = motor_currents(p, 3.0, 13.0, p.reference_gap_m + 50e-6);
  const Eigen::Vector2d f = motor_forces(p, i(0), i(1), p.reference_gap_m + 50e-6);
  EXPECT_NEAR(f(0), 3.0, 1e-12);
  EXPECT_NEAR(f(1), 13.0, 1e-12);
  const double ratio = motor_forces(p, 1, 1, p.reference_gap_m + 100e-6)(1) / motor_forces(p, 1, 1, p.reference_gap_m)(1);
  EXPECT_NEAR(ratio, std::exp(-2 * M_PI * 100e-6 / p.magnet_pitch_m), 1e-14);
}

TEST(Stage6Parameters, InvalidValuesAreInputErrors) {
  StageParameters p;
  p.mass_kg = -1;
  EXPECT_THROW(p.validate(), InputError);
  p = StageParameters{};
  p.inertia_kgm2(0, 0) = -0.1;
  EXPECT_THROW(p.validate(), InputError);
}

}  // namespace stage6_test
}  // namespace lpvid::stage6
