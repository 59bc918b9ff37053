#include "idlib/stage6/stage6_output_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>

#include "idlib/core/error.h"
#include "idlib/sim/stage6_sim.h"
#include "tests/support/statistics.h"

namespace lpvid::stage6 {
namespace stage6_output_error_test {

constexpr std::uint64_t kSeed = 6106;
constexpr double kTs = 1e-3;

// A truth different from the nominal values the equation-error start begins from.
StageParameters perturbed_truth() {
  StageParameters p;  // the mass stays the weighed 5.47 kg (fix_mass)
  p.inertia_kgm2 = Eigen::Vector3d(0.031, 0.027, 0.060).asDiagonal();
  return p;
}

// The experiment of `simulate stage6 --experiment` (cli/simulate_stage6.cc): a
// z step 250 → 350 µm with white excitation 2 N / 0.1 N·m on the allocated
// wrench, 2 s at 1 kHz, and with `noisy` that command's default sensor noise
// (1 nm, 1 nm, 10 nm, 0.1 µrad ×3).
Vector6d default_sensor_noise() {
  Vector6d s;
  s << 1e-9, 1e-9, 1e-8, 1e-7, 1e-7, 1e-7;
  return s;
}

StageRun experiment(const StageParameters& truth, const StageEffects& effects, bool noisy, std::uint64_t seed) {
  SimulationOptions sim;
  sim.duration_s = 2.0;
  sim.excitation_std << 2, 2, 2, 0.1, 0.1, 0.1;
  if (noisy) sim.sensor_noise_std = default_sensor_noise();
  sim.seed = seed;
  Vector6d q0 = Vector6d::Zero();
  q0(2) = 250e-6;
  return simulate_regulation(truth, effects, q0, paper_reference_configuration(), {}, sim);
}

Eigen::Matrix<double, kStageThetaSize, 1> theta_of(const StageParameters& p, const StageEffects& e) {
  Eigen::Matrix<double, kStageThetaSize, 1> t;
  t << p.mass_kg, p.inertia_kgm2.diagonal(), e.force_constant_scale, e.com_offset_m,
      e.gap_dependence ? p.gamma_per_m() : 0.0, p.electrical_time_constant_s(),
      e.electrical_lag ? p.force_constant_N_per_A * p.force_constant_N_per_A / (p.resistance_ohm + p.current_loop_gain_V_per_A)
                       : 0.0;
  return t;
}

void print(const StageOutputErrorResult& r, const Eigen::Matrix<double, kStageThetaSize, 1>& truth) {
  std::cout << r.model.name() << ": " << r.report.termination << "\n";
  for (int i = 0; i < kStageThetaSize; ++i)
    if (r.free[static_cast<std::size_t>(i)])
      std::cout << "  " << kStageThetaNames[static_cast<std::size_t>(i)] << " " << r.theta(i) << " ± " << r.std_error(i)
                << " (truth " << truth(i) << ", error " << (r.theta(i) - truth(i)) / r.std_error(i) << " σ)\n";
  std::cout << "  rms per channel " << r.rms_per_channel.transpose() << ", σ² " << r.sigma2 << "\n";
}

// Noise-free log with κ = 0.97 and a 3 mm centre-of-mass offset: the model is
// the simulator's (RK4 at one step per sample reproduces its 10 kHz RK4 to
// ~1e-14 m here), so every parameter is exact to rounding.  Measured: relative
// errors of H and κ below 1e-12, c within 2e-15 m; requirement 1 %.
TEST(Stage6OutputError, NoiseFreeLogRecoversEveryParameterWithin1Percent) {
  const StageParameters truth = perturbed_truth();
  StageEffects effects;
  effects.force_constant_scale = 0.97;
  effects.com_offset_m = Eigen::Vector3d(1e-3, -2e-3, 3e-3);
  const StageRun run = experiment(truth, effects, false, kSeed);
  StageFitModel model;  // base + com
  const StageOutputErrorResult r = fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, kTs, model);
  print(r, theta_of(truth, effects));
  constexpr double kRel = 0.01;  // the requirement
  EXPECT_DOUBLE_EQ(r.mass_kg, truth.mass_kg);  // held
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(r.inertia_diag_kgm2(i), truth.inertia_kgm2(i, i), kRel * truth.inertia_kgm2(i, i)) << i;
  EXPECT_NEAR(r.force_constant_scale, 0.97, kRel * 0.97);
  EXPECT_LT((r.com_offset_m - effects.com_offset_m).cwiseAbs().maxCoeff(), kRel * 3e-3);
  EXPECT_TRUE(r.report.usable);
  EXPECT_TRUE(r.report.warnings.empty());
  // Layout of the residual report.
  EXPECT_EQ(r.residual.rows(), run.q.rows());
  EXPECT_EQ(r.num_windows, 6);  // 2001 rows in windows of 300 (the last takes 501)
  ASSERT_EQ(r.window_start.size(), 6u);
  EXPECT_EQ(r.window_start[1], 300);
  EXPECT_EQ(r.rms_per_window.rows(), 6);
  EXPECT_EQ(r.num_parameters, 7);  // H (3), κ, c (3)
  // Noise-free: the output error is rounding (measured ≤ 4.2e-14 m and rad).
  EXPECT_LT(r.rms_per_channel.maxCoeff(), 1e-12);

  // With κ known (held at 1) the mass is fitted instead.
  StageOutputErrorOptions o;
  o.fix_mass = false;
  StageParameters start;
  start.mass_kg = 5.0;  // 9 % off
  const StageRun run2 = experiment(truth, {}, false, kSeed);
  const StageOutputErrorResult r2 =
      fit_stage_output_error(start, run2.wrench, run2.q_measured, kTs, StageFitModel{false}, o);
  EXPECT_NEAR(r2.mass_kg, truth.mass_kg, kRel * truth.mass_kg);
  EXPECT_DOUBLE_EQ(r2.force_constant_scale, 1.0);
  EXPECT_GT(r2.std_error(0), 0.0);
  EXPECT_EQ(r2.std_error(4), 0.0);
}

// The bias test, with the default sensor noise of `simulate stage6
// --experiment` over 5 seeds.  The equation error attenuates every inertia
// (docs/math.md: −1.2 %, −0.9 %, −4.2 % for H_xx, H_yy, H_zz); the output error
// must be within 3 of its own σ of the truth on every seed and axis, and its
// mean error over the seeds within 1 σ.  Measured (seeds 6106..6110, 0.3 s
// windows): equation error ratios 0.986–0.989, 0.988–0.993, 0.954–0.959;
// output error |z| ≤ 1.5 (σ ≈ 2–3e-6 relative for H_xx, H_yy, 1e-5 for H_zz),
// mean z over the seeds −0.72, +0.45, −0.62 (H_xx, H_yy, H_zz) and −0.45 (κ);
// rms output error per channel = the noise level to 3 %; σ² = 0.994–0.999.
TEST(Stage6OutputError, DefaultSensorNoiseRemovesTheEquationErrorBiasOverFiveSeeds) {
  const StageParameters truth = perturbed_truth();
  StageEffects effects;
  effects.force_constant_scale = 0.97;
  StageFitModel model;
  model.com_offset = false;
  // Sanitizer build: two seeds, each still held to 3σ; the mean over them is no
  // statistical evidence and is not tested (tests/support/statistics.h).
  constexpr int kSeeds = testing::kFullStatistics ? 5 : 2;
  // An attenuation above 0.5 % on every axis (the law gives ≥ 0.9 % here).
  constexpr double kEquationErrorBiasAtLeast = 0.005;
  constexpr double kMaxZ = 3.0, kMaxMeanZ = 1.0;
  // rms output error against the noise level: 2000 samples give ±1.6 % (1σ) on
  // an rms; 5 % is 3σ.
  constexpr double kNoiseLevelTolerance = 0.05;
  Eigen::Vector4d mean_z = Eigen::Vector4d::Zero();
  for (int s = 0; s < kSeeds; ++s) {
    const StageRun run = experiment(truth, effects, true, kSeed + static_cast<std::uint64_t>(s));
    const StageOutputErrorResult r =
        fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, kTs, model);
    print(r, theta_of(truth, effects));
    std::cout << "  equation error H/truth "
              << (r.start.inertia_diag_kgm2.array() / truth.inertia_kgm2.diagonal().array()).transpose() << "\n";
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT(r.start.inertia_diag_kgm2(i), (1 - kEquationErrorBiasAtLeast) * truth.inertia_kgm2(i, i)) << s << " " << i;
      const double z = (r.inertia_diag_kgm2(i) - truth.inertia_kgm2(i, i)) / r.std_error(1 + i);
      EXPECT_LT(std::abs(z), kMaxZ) << s << " " << i;
      mean_z(i) += z / kSeeds;
    }
    const double zk = (r.force_constant_scale - 0.97) / r.std_error(4);
    EXPECT_LT(std::abs(zk), kMaxZ) << s;
    mean_z(3) += zk / kSeeds;
    for (int c = 0; c < 6; ++c)
      EXPECT_NEAR(r.rms_per_channel(c), default_sensor_noise()(c), kNoiseLevelTolerance * default_sensor_noise()(c)) << c;
    EXPECT_NEAR(r.sigma2, 1.0, 0.05);
  }
  std::cout << "mean error over seeds in σ (H_xx H_yy H_zz κ): " << mean_z.transpose() << "\n";
  if (testing::kFullStatistics) {
    EXPECT_LT(mean_z.cwiseAbs().maxCoeff(), kMaxMeanZ);
  }
}

// Each effect, present in the simulated stage (with the default sensor noise),
// is fitted: its parameters within 3σ and 1 % of the truth.  Measured (seed
// 6106): c = (1, −2, 3) mm within 2.2σ (σ ≤ 1.1e-9 m); γ = 245.436 ± 0.0007
// for 245.437 1/m; τ_e = 1.00003 ± 0.00002 ms, b = 80.0001 ± 0.00007 N·s/m.
TEST(Stage6OutputError, EachEffectIsFittedWhenPresent) {
  const StageParameters truth = perturbed_truth();
  for (int e = 0; e < 3; ++e) {
    StageEffects effects;
    effects.force_constant_scale = 0.97;
    StageFitModel model;
    model.com_offset = e == 0;
    if (e == 0) effects.com_offset_m = Eigen::Vector3d(1e-3, -2e-3, 3e-3);
    if (e == 1) effects.gap_dependence = model.gap_dependence = true;
    if (e == 2) effects.electrical_lag = model.electrical_lag = true;
    const StageRun run = experiment(truth, effects, true, kSeed);
    const StageOutputErrorResult r = fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, kTs, model);
    const auto t = theta_of(truth, effects);
    print(r, t);
    std::vector<int> check = {1, 2, 3, 4};
    if (e == 0) check.insert(check.end(), {5, 6, 7});
    if (e == 1) check.push_back(8);
    if (e == 2) check.insert(check.end(), {9, 10});
    for (int i : check) {
      EXPECT_TRUE(r.free[static_cast<std::size_t>(i)]) << kStageThetaNames[static_cast<std::size_t>(i)];
      EXPECT_LT(std::abs(r.theta(i) - t(i)), 3 * r.std_error(i)) << kStageThetaNames[static_cast<std::size_t>(i)];
      // 1 % of the value (of the largest component, 3 mm, for the offset).
      EXPECT_LT(std::abs(r.theta(i) - t(i)), 0.01 * (i >= 5 && i <= 7 ? 3e-3 : std::abs(t(i))))
          << kStageThetaNames[static_cast<std::size_t>(i)];
    }
  }
}

// A hidden α(z) left out of the model shows where it fails: in the z channel's
// output error, far above its noise, and in the BIC.
TEST(Stage6OutputError, AMissingGapEffectShowsInTheZResidualAndTheBic) {
  StageEffects effects;
  effects.gap_dependence = true;
  const StageRun run = experiment(perturbed_truth(), effects, true, kSeed);
  StageFitModel base;
  base.com_offset = false;
  StageFitModel gap = base;
  gap.gap_dependence = true;
  // The wrong model converges slowly (its windows drift apart from the data);
  // 10 iterations are enough to tell, and keep the test short.
  StageOutputErrorOptions few;
  few.max_iterations = 10;
  const StageOutputErrorResult rb =
      fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, kTs, base, few);
  const StageOutputErrorResult rg = fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, kTs, gap);
  std::cout << "rms without gap " << rb.rms_per_channel.transpose() << " BIC " << rb.bic << "\nrms with gap    "
            << rg.rms_per_channel.transpose() << " BIC " << rg.bic << "\n";
  constexpr double kSignificantDeltaBic = 10.0;  // as lpvid diagnose
  EXPECT_LT(rg.bic, rb.bic - kSignificantDeltaBic);
  Eigen::Index worst;
  (rb.rms_per_channel.array() / default_sensor_noise().array()).maxCoeff(&worst);
  EXPECT_EQ(worst, 2);  // z
  EXPECT_GT(rb.rms_per_channel(2), 3 * default_sensor_noise()(2));
  EXPECT_NEAR(rg.rms_per_channel(2), default_sensor_noise()(2), 0.05 * default_sensor_noise()(2));
}

TEST(Stage6OutputError, BadInputsAreInputErrors) {
  const Eigen::MatrixXd u = Eigen::MatrixXd::Random(500, 6), q = Eigen::MatrixXd::Random(500, 6);
  auto fit = [&](const Eigen::MatrixXd& uu, const Eigen::MatrixXd& qq, double Ts, StageOutputErrorOptions o = {}) {
    return fit_stage_output_error(StageParameters{}, uu, qq, Ts, {}, o);
  };
  EXPECT_THROW(fit(u.topRows(5), q.topRows(5), kTs), InputError);          // too short
  EXPECT_THROW(fit(u, q.leftCols(5), kTs), InputError);                    // shape
  EXPECT_THROW(fit(u, q.topRows(400), kTs), InputError);                   // rows differ
  EXPECT_THROW(fit(u, q, 0.0), InputError);                                // sample period
  EXPECT_THROW(fit(u, q, std::nan("")), InputError);
  Eigen::MatrixXd bad = q;
  bad(7, 2) = std::nan("");
  EXPECT_THROW(fit(u, bad, kTs), InputError);                              // non-finite
  EXPECT_THROW(fit(u.topRows(150), q.topRows(150), kTs), InputError);      // shorter than a window
  try {
    fit(u.topRows(150), q.topRows(150), kTs);
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "stage output-error fit: the log has 150 rows, fewer than one window of 300 rows "
                           "(window_s = 0.3 s); give a longer log or a shorter window");
  }
  Eigen::MatrixXd still = q;
  still.col(3).setZero();
  EXPECT_THROW(fit(u, still, kTs), InputError);                            // an axis that never moves
  StageOutputErrorOptions o;
  o.window_s = 0;
  EXPECT_THROW(fit(u, q, kTs, o), InputError);
  o = {};
  o.rk4_substeps = -1;
  EXPECT_THROW(fit(u, q, kTs, o), InputError);
  o = {};
  o.max_iterations = 0;
  EXPECT_THROW(fit(u, q, kTs, o), InputError);
  // A start fitted with another model.
  StageFitResult start;
  start.model.gap_dependence = true;
  EXPECT_THROW(fit_stage_output_error(StageParameters{}, u, q, kTs, StageFitModel{}, {}, &start), InputError);
}

// stage_output_error_at (compare --log): at the simulator's true parameters the
// held-parameter output error is the sensor noise alone (rms per channel within
// 10 % of the simulated noise level: 2000 samples give a sampling scatter of ~2 %,
// the 12 free states per window take a little of it), and with the inertias 20 %
// off it is far above (the model error); nothing is estimated.
TEST(Stage6OutputError, HeldParametersGiveTheNoiseAtTheTruthAndMoreAwayFromIt) {
  const StageParameters truth = perturbed_truth();
  StageEffects effects;
  effects.gap_dependence = true;
  const StageRun run = experiment(truth, effects, /*noisy=*/true, kSeed + 7);
  StageFitModel model;
  model.com_offset = false;
  model.gap_dependence = true;
  const auto theta = theta_of(truth, effects);
  const StageOutputErrorResult at = stage_output_error_at(truth, run.wrench, run.q_measured, kTs, model, theta);
  EXPECT_EQ(at.num_parameters, 0);
  for (int c = 0; c < 6; ++c) EXPECT_NEAR(at.rms_per_channel(c), default_sensor_noise()(c), 0.1 * default_sensor_noise()(c)) << c;
  auto off = theta;
  off.segment<3>(1) *= 1.2;
  const StageOutputErrorResult wrong = stage_output_error_at(truth, run.wrench, run.q_measured, kTs, model, off);
  for (int c = 3; c < 6; ++c) EXPECT_GT(wrong.rms_per_channel(c), 5 * default_sensor_noise()(c)) << c;
  off(1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(stage_output_error_at(truth, run.wrench, run.q_measured, kTs, model, off), InputError);
}

}  // namespace stage6_output_error_test
}  // namespace lpvid::stage6
