// Checks of the INDEPENDENT stage simulator (tests/support/independent_stage.h)
// against physics that does not come from it or from lpvid: conservation laws of a
// free rigid body, free fall, the hover equilibrium, the power balance of the motors'
// back-EMF, and its small-signal behaviour against closed-form derivatives.  These
// make the simulator a trustworthy truth for the stage loop's tests
// (tests/cli/indep_stage_loop_test.cc).
#include <gtest/gtest.h>

#include <cmath>

#include "tests/support/independent_stage.h"

namespace indep_stage {
namespace independent_stage_test {

using I8 = Eigen::Matrix<double, 8, 1>;

Stage asymmetric_stage() {
  Stage s;
  s.arms_m = pinwheel_arms(0.075, 0.07, 0.015);
  s.inertia_kgm2 << 0.025, 0.002, -0.001,  //
      0.002, 0.035, 0.0015,                //
      -0.001, 0.0015, 0.06;
  return s;
}

// A torque-free, force-free rigid body (no gravity, no currents) tumbling about all
// three axes: energy, angular momentum (inertial) and linear momentum are conserved.
// RK4 at 50 us over 5 s with |w| ~ 10 rad/s: local error ~ (h w)^5 = 1e-17 per step,
// so 1e-9 relative is a loose bound that still catches any wrong sign in w x Hw or in
// the quaternion kinematics (those change the energy at order 1).
TEST(IndependentStage, FreeRigidBodyConservesEnergyAndMomentum) {
  Stage s = asymmetric_stage();
  s.gravity = 0;
  State x = hover_state(s, 0);
  x.segment<3>(3) = Vec3(0.01, -0.02, 0.005);
  x.segment<3>(10) = Vec3(3.0, -7.0, 5.0);
  const double E0 = energy(s, x);
  const Vec3 L0 = angular_momentum_inertial(s, x);
  const Vec3 p0 = x.segment<3>(0);
  for (int k = 0; k < 100000; ++k) x = rk4_step(s, x, I8::Zero(), 5e-5);
  EXPECT_NEAR(energy(s, x) / E0, 1.0, 1e-9);
  EXPECT_LT((angular_momentum_inertial(s, x) - L0).norm() / L0.norm(), 1e-9);
  EXPECT_LT((x.segment<3>(0) - p0 - 5.0 * Vec3(0.01, -0.02, 0.005)).norm(), 1e-12);
  EXPECT_NEAR(x.segment<4>(6).norm(), 1.0, 1e-12);
}

// Free fall: z(t) = z0 - g t^2 / 2 (RK4 is exact on a quadratic).
TEST(IndependentStage, FreeFall) {
  Stage s = asymmetric_stage();
  State x = hover_state(s, 0.001);
  for (int k = 0; k < 1000; ++k) x = rk4_step(s, x, I8::Zero(), 1e-4);
  EXPECT_NEAR(configuration(s, x)(2), 0.001 - 0.5 * 9.8 * 0.01, 1e-12);
}

// At hover the allocated weight (allocation about the TRUE centre of mass) holds the
// stage still, with every effect on: accelerations at rounding level.
TEST(IndependentStage, HoverIsAnEquilibrium) {
  Stage s = asymmetric_stage();
  s.gap = true;
  s.lag = true;
  s.com_offset_m = Vec3(1e-4, -2e-4, 1e-3);
  const Eigen::Matrix<double, 6, 8> A = allocation(s.arms_m, s.com_offset_m);
  const Vec6 w0 = (Vec6() << 0, 0, s.mass_kg * s.gravity, 0, 0, 0).finished();
  const I8 i0 = A.transpose() * (A * A.transpose()).inverse() * w0 / s.force_constant_N_per_A;
  State x = hover_state(s, s.z_ref_m);
  x.segment<8>(13) = i0;
  const State dx = derivative(s, x, i0);
  EXPECT_LT(dx.segment<3>(3).norm(), 1e-12);   // m/s^2
  EXPECT_LT(dx.segment<3>(10).norm(), 1e-10);  // rad/s^2
  EXPECT_LT(dx.segment<8>(13).norm(), 1e-9);   // A/s
  EXPECT_LT((configuration(s, x).head<3>() - Vec3(0, 0, s.z_ref_m)).norm(), 1e-15);
}

// The back-EMF is the motors' power conjugate (eq 25 with the coenergy of eq 14):
// with i_ref = i the current loop sees only -e, and the electrical power sum e_k i_k
// equals the mechanical power of the motor forces on the moving platen.
TEST(IndependentStage, BackEmfPowerBalance) {
  Stage s = asymmetric_stage();
  s.lag = true;
  s.gap = true;
  s.com_offset_m = Vec3(2e-4, 1e-4, -1e-3);
  State x = hover_state(s, 4e-4);
  x.segment<4>(6) = Eigen::Vector4d(1, 0.002, -0.003, 0.001).normalized();
  x.segment<3>(3) = Vec3(0.02, -0.01, 0.003);
  x.segment<3>(10) = Vec3(0.3, -0.2, 0.5);
  I8 i;
  i << 0.1, 0.7, -0.2, 0.6, 0.05, 0.8, 0.3, 0.65;
  x.segment<8>(13) = i;
  const State dx = derivative(s, x, i);
  const double p_elec = -(s.inductance_H * dx.segment<8>(13)).dot(i);  // sum e_k i_k
  // Mechanical power: d/dt of the kinetic + potential energy minus gravity's share = F.v + tau.w
  Stage s0 = s;
  const double dt = 1e-7;
  State xp = x + dt * dx, xm = x - dt * dx;
  const double p_mech = (energy(s0, xp) - energy(s0, xm)) / (2 * dt);
  EXPECT_NEAR(p_elec, p_mech, 1e-6 * std::abs(p_mech) + 1e-9) << "p_elec " << p_elec << " p_mech " << p_mech;
}

// Small-signal: finite differences of the nonlinear derivative at hover against the
// closed forms of the linearisation (gap spring gamma m g on z, gamma m g a_y^2 on
// roll, gamma m g a_x^2 on pitch; the lift tilting with the platen, x'' = g theta,
// y'' = -g phi; force-constant gain kappa alpha k_f / m; back-EMF damping b / m on z).
TEST(IndependentStage, LinearisationMatchesClosedForms) {
  Stage s;
  s.arms_m = pinwheel_arms(0.08, 0.07, 0.01);
  s.gap = true;
  s.gamma_per_m = 250;
  s.kappa = 1.01;
  const Eigen::Matrix<double, 6, 8> A = allocation(s.arms_m, Vec3::Zero());
  const Vec6 w0 = (Vec6() << 0, 0, s.mass_kg * s.gravity, 0, 0, 0).finished();
  const I8 i0 = A.transpose() * (A * A.transpose()).inverse() * w0 / (s.kappa * s.force_constant_N_per_A);
  const State x0 = hover_state(s, s.z_ref_m);
  auto d_dstate = [&](const State& dir, double eps) {
    return State((derivative(s, x0 + eps * dir, i0) - derivative(s, x0 - eps * dir, i0)) / (2 * eps));
  };
  const double mg = s.mass_kg * s.gravity;
  // z: vz' = -gamma g (per m of height)
  State dz = State::Zero();
  dz(2) = 1;
  // central differences at eps 1e-7 m: truncation (gamma eps)^2 ~ 1e-9 relative
  EXPECT_NEAR(d_dstate(dz, 1e-7)(5), -s.gamma_per_m * s.gravity, 1e-6 * s.gamma_per_m * s.gravity);
  // Roll phi (about x): quaternion (1, phi/2, 0, 0): w_x' = -gamma m g a_y^2 / I_xx,
  // and the tilted lift y'' = -g phi.
  State droll = State::Zero();
  droll(7) = 0.5;
  const State r = d_dstate(droll, 1e-7);
  const double ay = 0.07, ax = 0.08;
  EXPECT_NEAR(r(10), -s.gamma_per_m * mg * ay * ay / s.inertia_kgm2(0, 0), 1e-5 * s.gamma_per_m * mg * ay * ay / 0.029);
  EXPECT_NEAR(r(4), -s.gravity, 1e-7);
  State dpitch = State::Zero();
  dpitch(8) = 0.5;
  const State p = d_dstate(dpitch, 1e-7);
  EXPECT_NEAR(p(11), -s.gamma_per_m * mg * ax * ax / s.inertia_kgm2(1, 1), 1e-5 * s.gamma_per_m * mg * ax * ax / 0.029);
  EXPECT_NEAR(p(3), s.gravity, 1e-7);
  // Input gain: one unit of every vertical current lifts 4 kappa k_f / m.
  I8 dv = I8::Zero();
  dv << 0, 1, 0, 1, 0, 1, 0, 1;
  const State du = (derivative(s, x0, i0 + 1e-3 * dv) - derivative(s, x0, i0 - 1e-3 * dv)) / 2e-3;
  EXPECT_NEAR(du(5), 4 * s.kappa * s.force_constant_N_per_A / s.mass_kg, 1e-9);
  // Back-EMF damping on z with the current loop: di_v/dt per m/s of z' = -kappa k_f / L.
  Stage sl = s;
  sl.gap = false;
  sl.lag = true;
  State xl = hover_state(sl, sl.z_ref_m);
  xl.segment<8>(13) = i0;
  State dvz = State::Zero();
  dvz(5) = 1;
  const State dl = (derivative(sl, xl + 1e-4 * dvz, i0) - derivative(sl, xl - 1e-4 * dvz, i0)) / 2e-4;
  for (int m = 0; m < 4; ++m) {
    EXPECT_NEAR(dl(13 + 2 * m + 1), -sl.kappa * sl.force_constant_N_per_A / sl.inductance_H, 1e-6);
    EXPECT_NEAR(dl(13 + 2 * m), 0.0, 1e-9);
  }
}

// The closed loop (paper's sliding-mode law) hovers: a noise-free, excitation-free run
// of the design stage settles within the law's static error at the reference.
TEST(IndependentStage, ClosedLoopHovers) {
  Stage s;
  s.arms_m = pinwheel_arms(0.075, 0.075, 0.015);
  Controller c;
  c.arms_m = s.arms_m;
  Experiment e;
  e.duration_s = 2;
  e.noise_std.setZero();
  e.excitation_std.setZero();
  const Log log = run(s, c, e);
  const Vec6 last = log.q_true.bottomRows(1).transpose();
  // kappa = 1, no effect: the weight is compensated exactly, nothing pushes: rest at q_r.
  EXPECT_LT((last - e.q_ref).cwiseAbs().maxCoeff(), 1e-12);
  // 2 % too weak a force constant: the law's linear region holds it at the static error
  // (1 - kappa) m g / (rho m Lambda K / delta) (boundary layer |sigma| << delta? no:
  // sigma_z = Lambda e_z is comparable to delta, so |sigma| enters: solved below).
  s.kappa = 0.98;
  e.duration_s = 5;  // e^(-Lambda t) = 3e-7 of the transient left
  const Log l2 = run(s, c, e);
  const double ez = l2.q_true(l2.q_true.rows() - 1, 2) - e.q_ref(2);
  // Static balance: kappa m g + rho m K sigma/(|sigma| + delta) ... with sigma = Lambda e_z
  // (only z is off): -(kappa - 1) g = -rho K (Lambda e_z)/(|Lambda e_z| + delta) / kappa'.
  // The force reaching the stage is kappa times the commanded.
  const double lam = c.lambda, K = c.gain_K, d = c.delta, rho = c.inertia_ratio;
  // kappa (g - rho K sig/(|sig|+d)) = g  =>  sig/(|sig|+d) = (1 - 1/kappa) g / (rho K)
  const double ratio = (1 - 1 / s.kappa) * s.gravity / (rho * K);
  const double sig = ratio * d / (1 - std::abs(ratio));
  EXPECT_NEAR(ez, sig / lam, 1e-3 * std::abs(sig / lam));
}

}  // namespace independent_stage_test
}  // namespace indep_stage
