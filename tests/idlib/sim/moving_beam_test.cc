#include "idlib/sim/moving_beam.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"
#include "idlib/validate/time_fit.h"

namespace lpvid {
namespace moving_beam_test {

using ::testing::HasSubstr;

constexpr double kTs = 1e-3;
// Named seed of the random tests in this file.
constexpr std::uint64_t kSeed = 20261123;

StateSpace pi_controller(const PlatformParameters& p) { return discrete_pi_controller(default_pi_gains(p), kTs); }

StateSpace open_loop_controller() {
  StateSpace c;
  c.A.resize(0, 0);
  c.B.resize(0, 3);
  c.C.resize(3, 0);
  c.D = Eigen::MatrixXd::Zero(3, 3);
  c.sample_period_s = kTs;
  return c;
}

double max_abs(const Eigen::MatrixXd& m) { return m.cwiseAbs().maxCoeff(); }

TEST(MovingBeam, BeamAtRestReproducesTheLtiSimulationToRounding) {
  const PlatformParameters p;
  const double xb = kBeamRight_m;
  ExcitationOptions ex;
  ex.duration_s = 2.0;
  ex.excited_input = -1;
  ex.seed = kSeed;
  const SimulatedLog lti = simulate_excitation(discretize_zoh(platform_model(p, xb), kTs), pi_controller(p), ex);

  MovingBeamOptions o;
  o.excitation_std = ex.excitation_std;
  o.sensor_noise_std = ex.sensor_noise_std;
  o.seed = kSeed;
  const Index N = lti.data.rows();
  const SimulatedLog mb =
      simulate_moving_beam(p, pi_controller(p), BeamTrajectory::constant(xb, 0.0, (N - 1) * kTs), o);
  ASSERT_EQ(mb.data.rows(), N);
  // Same ZOH model and the same loop: the outputs agree to a few ulps of their
  // size (1e-12 relative leaves room for a different Eigen kernel order).
  constexpr double kRoundingRel = 1e-12;
  const Eigen::MatrixXd q_lti = lti.data.middleCols(7, 3), q_mb = mb.data.middleCols(7, 3);
  EXPECT_LE(max_abs(q_mb - q_lti), kRoundingRel * max_abs(q_lti));
  EXPECT_EQ(mb.data.col(0), lti.data.col(0));
  EXPECT_EQ(mb.data.middleCols(1, 3), lti.data.middleCols(1, 3));  // same random excitation
  // Started in equilibrium, the theta integrator holds the gravity moment of the
  // beam: u_theta differs from the LTI run (no gravity) by +m_b g x_b exactly.
  const double hold = p.beam_mass_kg * p.gravity_m_per_s2 * xb;
  const Eigen::VectorXd du = mb.data.col(5) - lti.data.col(5);
  EXPECT_LE((du.array() - hold).abs().maxCoeff(), kRoundingRel * max_abs(lti.data.middleCols(4, 3)) + 1e-12 * hold);
  EXPECT_LE(max_abs(mb.data.col(4) - lti.data.col(4)), kRoundingRel * max_abs(lti.data.middleCols(4, 3)));
  EXPECT_TRUE((mb.data.col(10).array() == xb).all());
}

TEST(MovingBeam, OpenLoopStaticTiltIsStiffnessInverseTimesGravityMoment) {
  const PlatformParameters p;
  const double xb = kBeamRight_m;
  MovingBeamOptions o;
  o.sensor_noise_std.setZero();
  o.start = MovingBeamOptions::Start::rest;
  // 4 s: the slowest open-loop pole (z, about -6.7 1/s) decays by e^-27.
  const SimulatedLog log = simulate_moving_beam(p, open_loop_controller(), BeamTrajectory::constant(xb, 0, 4.0), o);
  const Eigen::Vector3d w(0.0, -p.beam_mass_kg * p.gravity_m_per_s2 * xb, 0.0);
  const Eigen::Vector3d expected = stiffness_matrix(p).lu().solve(w);
  const Eigen::Vector3d last = log.data.block<1, 3>(log.data.rows() - 1, 7).transpose();
  EXPECT_LT(expected(1), 0.0);  // beam on the +x side: that side goes down (h = z + x·theta)
  // e^-27 of the initial error, plus rounding.
  constexpr double kSettledRel = 1e-9;
  EXPECT_LE((last - expected).norm(), kSettledRel * expected.norm());
}

TEST(MovingBeam, ClosedLoopFromRestIntegratorsTakeOverTheGravityMoment) {
  const PlatformParameters p;
  const double xb = kBeamLeft_m;
  MovingBeamOptions o;
  o.sensor_noise_std.setZero();
  o.start = MovingBeamOptions::Start::rest;
  // 6 s: slowest closed-loop decay 0.3 d/m ~ 7 1/s (platform.h) -> e^-42.
  const SimulatedLog log = simulate_moving_beam(p, pi_controller(p), BeamTrajectory::constant(xb, 0, 6.0), o);
  const Index last = log.data.rows() - 1;
  const double moment = p.beam_mass_kg * p.gravity_m_per_s2 * std::abs(xb);
  // A transient tilt of order moment / (k + kp) appears, then the integrator removes it.
  EXPECT_GT(log.data.col(8).maxCoeff(), 1e-4);  // beam on the left: theta > 0 transiently
  constexpr double kSettledAbs = 1e-12;         // rad: e^-42 of a ~3 mrad transient
  EXPECT_LE((log.data.block<1, 3>(last, 7).cwiseAbs().maxCoeff()), kSettledAbs);
  EXPECT_NEAR(log.data(last, 5), p.beam_mass_kg * p.gravity_m_per_s2 * xb, 1e-9 * moment);
}

TEST(MovingBeam, MidpointRuleConvergesAtSecondOrderInTheStep) {
  const PlatformParameters p;
  MovingBeamOptions o;
  o.sensor_noise_std.setZero();
  const BeamTrajectory traj = BeamTrajectory::sweep({}, 2.0);  // one 0.6 s move
  auto run = [&](int substeps) {
    o.substeps = substeps;
    return Eigen::MatrixXd(simulate_moving_beam(p, pi_controller(p), traj, o).data.middleCols(7, 3));
  };
  const Eigen::MatrixXd q1 = run(1), q2 = run(2), q8 = run(8);
  const double e1 = max_abs(q1 - q8), e2 = max_abs(q2 - q8);
  // Second order: halving h divides the error by 4; against the h/8 reference
  // the ratio is (1 - 1/64)/(1/4 - 1/64) = 4.2.  [3, 5.5] allows higher-order terms.
  EXPECT_GT(e1 / e2, 3.0);
  EXPECT_LT(e1 / e2, 5.5);
  // One step per sample is accurate to 1e-4 of the response (measured 3.8e-5).
  EXPECT_LT(e1, 1e-4 * max_abs(q8));
}

TEST(BeamTrajectory, SweepIsMinimumJerkWithConsistentDerivatives) {
  const BeamTrajectory::Sweep s;
  const BeamTrajectory traj = BeamTrajectory::sweep(s, 6.0);
  EXPECT_EQ(traj.at(0.5).position_m, s.left_m);
  EXPECT_NEAR(traj.at(s.first_dwell_s + s.move_s).position_m, s.right_m, 1e-12);
  EXPECT_NEAR(traj.at(s.first_dwell_s + 2 * s.move_s + s.dwell_s).position_m, s.left_m, 1e-12);
  // Peak acceleration of a minimum-jerk move: 10/sqrt(3) · Δ / T².
  const double delta = s.right_m - s.left_m;
  double peak = 0.0;
  for (double t = 0; t < 6.0; t += 1e-4) peak = std::max(peak, std::abs(traj.at(t).acceleration_m_per_s2));
  EXPECT_NEAR(peak, 10.0 / std::sqrt(3.0) * delta / (s.move_s * s.move_s), 1e-4 * peak);  // grid of 1e-4 s
  // Central differences (step 1e-5 s) agree with the analytic derivatives to O(step²).
  for (double t : {1.1, 1.3, 1.55, 3.2}) {
    const double h = 1e-5;
    const BeamState a = traj.at(t - h), b = traj.at(t), c = traj.at(t + h);
    EXPECT_NEAR((c.position_m - a.position_m) / (2 * h), b.velocity_m_per_s, 1e-7);
    EXPECT_NEAR((c.velocity_m_per_s - a.velocity_m_per_s) / (2 * h), b.acceleration_m_per_s2, 1e-6);
  }
}

TEST(BeamTrajectory, SplineThroughSampledSweepRecoversItsAcceleration) {
  const BeamTrajectory truth = BeamTrajectory::sweep({}, 3.0);
  const Index n = 3001;
  Eigen::VectorXd t(n), x(n);
  for (Index k = 0; k < n; ++k) {
    t(k) = k * kTs;
    x(k) = truth.at(t(k)).position_m;
  }
  const BeamTrajectory spline = BeamTrajectory::from_samples(t, x);
  double worst = 0.0;
  for (double tt = 0.0005; tt < 2.999; tt += 0.0137)
    worst = std::max(worst, std::abs(spline.at(tt).acceleration_m_per_s2 - truth.at(tt).acceleration_m_per_s2));
  // Cubic-spline acceleration error O(h²·x''''): 1e-6 s² · ~1e3 m/s⁴ = 1e-3 m/s²,
  // against a 3.2 m/s² peak; a sweep's jerk is discontinuous at move ends, so allow 1e-2.
  EXPECT_LT(worst, 1e-2);
}

TEST(BeamTrajectory, BadSamplesAreRejectedWithTheSampleIndex) {
  Eigen::VectorXd t(3), x(3);
  t << 0, 0.001, 0.001;
  x << 0, 0, 0;
  EXPECT_THAT([&] { BeamTrajectory::from_samples(t, x); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("t[2] = 0.001 s is not after t[1]")));
  t << 0, 0.001, 0.002;
  x << 0, std::nan(""), 0;
  EXPECT_THAT([&] { BeamTrajectory::from_samples(t, x); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("sample 1 is")));
}

TEST(MovingBeam, BeamOutsideTheStrokeIsAnInputError) {
  const PlatformParameters p;
  MovingBeamOptions o;
  EXPECT_THAT([&] { simulate_moving_beam(p, pi_controller(p), BeamTrajectory::constant(0.3, 0, 0.1), o); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("outside the stroke")));
}

// ---------------------------------------------------------------------------
// Prediction of a measured moving-beam run (issue 4, Fig. 14)

struct MeasuredRun {
  SimulatedLog log;
  Eigen::MatrixXd q, v;
  BeamTrajectory traj = BeamTrajectory::constant(0, 0, 1);
};

MeasuredRun measure(const PlatformParameters& truth, double duration_s) {
  MovingBeamOptions o;
  o.seed = kSeed;
  o.excitation_std = Eigen::Vector3d(0.01, 0.01, 0.2);  // a little white excitation, for the cross test
  MeasuredRun run;
  run.log = simulate_moving_beam(truth, pi_controller(truth), BeamTrajectory::sweep({}, duration_s), o);
  run.q = run.log.data.middleCols(7, 3);
  run.v = run.log.data.middleCols(1, 3);
  // The model sees the logged x_b samples, as a user would.
  run.traj = BeamTrajectory::from_samples(run.log.data.col(0), run.log.data.col(10));
  return run;
}

TimeFitResult predict_and_fit(const MeasuredRun& run, const PlatformParameters& model, const MovingBeamEffects& fx) {
  MovingBeamOptions o;
  o.effects = fx;
  // The model's loop uses the controller designed for the truth (the known controller).
  const PlatformParameters truth;
  const MovingBeamPrediction pr = predict_moving_beam(model, pi_controller(truth), run.traj, 0.0, run.v, o);
  const Eigen::MatrixXd open_loop =
      predict_moving_beam_from_input(model, run.traj, 0.0, run.log.data.middleCols(4, 3), o);
  Eigen::MatrixXd inputs(run.v.rows(), 4);
  inputs << run.v, run.log.data.col(10);
  return time_fit(run.q, pr.q, inputs, 0.0, kTs, TimeFitOptions{}, open_loop);
}

TEST(MovingBeamPrediction, TrueParametersFitThetaAndZAbove95PercentAndPassTheResidualTests) {
  const PlatformParameters truth;
  const MeasuredRun run = measure(truth, 8.0);
  const TimeFitResult r = predict_and_fit(run, truth, {});
  // Issue 4: fit >= 95 % on theta and z when the model lacks nothing; the
  // remainder is the sensor noise seen through the loop.
  EXPECT_GE(r.fit_percent(1), 95.0);
  EXPECT_GE(r.fit_percent(2), 95.0);
  EXPECT_TRUE(r.failures.empty()) << r.failures.size() << " failing windows";
  for (const auto& t : r.cross) EXPECT_TRUE(t.pass) << "residual " << t.channel << " vs input " << t.input;
  for (const auto& t : r.whiteness) EXPECT_TRUE(t.pass) << "channel " << t.channel << " worst " << t.worst_ratio;
}

TEST(MovingBeamPrediction, MissingGravityMomentDropsTheFitAndIsLocatedInTheMoves) {
  const PlatformParameters truth;
  const MeasuredRun run = measure(truth, 8.0);
  MovingBeamEffects fx;
  fx.gravity_moment = false;
  const TimeFitResult r = predict_and_fit(run, truth, fx);
  const TimeFitResult good = predict_and_fit(run, truth, {});
  EXPECT_LT(r.fit_percent(1), good.fit_percent(1) - 20.0);
  EXPECT_FALSE(r.whiteness[1].pass);
  bool theta_in_a_move = false;
  for (const auto& w : r.failures)
    if (w.channel == 1 && w.t_start_s <= 1.6 && w.t_end_s >= 1.0) theta_in_a_move = true;  // first move: 1.0–1.6 s
  EXPECT_TRUE(theta_in_a_move);
}

TEST(MovingBeamPrediction, TwentyPercentHeavierBeamDropsTheFit) {
  const PlatformParameters truth;
  const MeasuredRun run = measure(truth, 8.0);
  PlatformParameters wrong = truth;
  wrong.beam_mass_kg *= 1.2;
  const TimeFitResult r = predict_and_fit(run, wrong, {});
  const TimeFitResult good = predict_and_fit(run, truth, {});
  EXPECT_LT(r.fit_percent(1), good.fit_percent(1) - 5.0);
  EXPECT_FALSE(r.failures.empty());
}

TEST(MovingBeamPrediction, TwentyPercentMoreInertiaFailsTheWhitenessTest) {
  const PlatformParameters truth;
  const MeasuredRun run = measure(truth, 8.0);
  PlatformParameters wrong = truth;
  wrong.J_theta_kgm2 *= 1.2;
  const TimeFitResult r = predict_and_fit(run, wrong, {});
  const TimeFitResult good = predict_and_fit(run, truth, {});
  // The inertia shows mainly in the fast part of theta (excitation, reaction
  // torque), not in the slow gravity moment, so the fit drops less than for the
  // beam mass; the residual tests see it clearly.
  EXPECT_LT(r.fit_percent(1), good.fit_percent(1) - 0.5);
  EXPECT_FALSE(r.whiteness[1].pass);
}

}  // namespace moving_beam_test
}  // namespace lpvid
