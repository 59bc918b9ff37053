// diagnose on the 6-DOF maglev stage (issue 13): the same framework, fit and
// diagnosis as the platform's, on data a user gets from the stage — a 60 s
// closed-loop log of the NONLINEAR sliding-mode simulation (idlib/sim/stage6_sim,
// RK4 of the Lagrange equations with Euler angles; a different code from the base's
// linearised matrices), reduced to the plant by estimate_plant_frf (P = S_qv S_uv⁻¹
// with its variance).  Plants are drawn over documented ranges: inertias ±30 % of
// seed 001's, force constant ±2 % (make_case_once says why); one effect hidden at a time with its parameter
// drawn (gap dependence: magnet pitch 20–40 mm; electrical lag: inductance 3–8 mH,
// tau_e 0.6–1.6 ms, a draw whose loop diverges redrawn; centre-of-mass offset:
// 0.05–0.2 mm horizontally and 0.5–2 mm vertically, random signs (make_case_once says
// why); input delay: 0.3–1.5 ms).  The start is `model init --base stage6`: the design values
// (seed 001's inertias, force-constant scale 1).
//
// Criteria (issue 13, "What must hold"): the hidden effect named first and the error
// falls >= 10x or to within 1.5x the noise floor; a clean stage: nothing significant
// in >= 9 of 10 seeds.  Sanitizer build: two hidden effects and one clean seed
// (tests/support/statistics.h); no statistical evidence.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include <fmt/format.h>

#include "idlib/core/error.h"
#include "idlib/diagnose/diagnose.h"
#include "idlib/signal/frf.h"
#include "idlib/sim/stage6_sim.h"
#include "tests/support/statistics.h"

namespace lpvid {
namespace stage6_diagnose_test {

constexpr double kFallFactor = 10.0;
constexpr double kWithinFloor = 1.5;
constexpr double kRate_hz = 1000.0;
constexpr double kDuration_s = 60.0;
constexpr Index kSegment = 512;  // 256 lines, Δω = 12.3 rad/s (the platform's analyzer: 500 lines)

enum class Hidden { kNone, kGap, kLag, kCom, kDelay };

const char* hidden_name(Hidden h) {
  switch (h) {
    case Hidden::kNone: return "none";
    case Hidden::kGap: return "gap_dependence";
    case Hidden::kLag: return "electrical_lag";
    case Hidden::kCom: return "com_offset";
    case Hidden::kDelay: return "input_delay";
  }
  return "";
}

struct StageCase {
  std::string description;
  std::vector<FitDataset> data;
};

StageCase make_case_once(std::uint64_t seed, Hidden hidden) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto within = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  stage6::StageParameters p;
  p.inertia_kgm2.diagonal() << p.inertia_kgm2(0, 0) * within(0.7, 1.3), p.inertia_kgm2(1, 1) * within(0.7, 1.3),
      p.inertia_kgm2(2, 2) * within(0.7, 1.3);
  stage6::StageEffects e;
  // A calibrated force constant (±2 %): the sliding-mode law has no integral
  // action, so a force-constant error leaves a static height error (~1–2 mm at 2 %),
  // which uses up the law's shared saturation ‖σ‖ (a centre-of-mass offset on top
  // then tips the stage over: measured at 3 %), and beyond ~8 % the loop cannot hold
  // the weight at all.  No lab would log those runs.
  e.force_constant_scale = within(0.98, 1.02);
  std::string what;
  switch (hidden) {
    case Hidden::kNone: break;
    case Hidden::kGap:
      e.gap_dependence = true;
      p.magnet_pitch_m = within(0.02, 0.04);
      what = fmt::format("gamma {:.1f} 1/m", p.gamma_per_m());
      break;
    case Hidden::kLag:
      e.electrical_lag = true;
      p.inductance_H = within(3e-3, 8e-3);
      what = fmt::format("tau_e {:.3f} ms", 1e3 * p.electrical_time_constant_s());
      break;
    case Hidden::kCom:
      // Horizontal offsets put the lift's torque m g c on the tilts, which the paper's
      // sliding-mode law holds only up to M⁰ K ≈ 0.023 N·m (c ≈ 0.4 mm): 0.05–0.2 mm;
      // the vertical offset moves the horizontal forces' torques (arm −15 mm): 0.5–2 mm
      // (with 1–4 mm, 6 of 8 drawn stages tipped over under the paper's law).
      for (int a = 0; a < 2; ++a) e.com_offset_m(a) = (u(rng) < 0.5 ? -1.0 : 1.0) * within(5e-5, 2e-4);
      e.com_offset_m(2) = (u(rng) < 0.5 ? -1.0 : 1.0) * within(5e-4, 2e-3);
      what = fmt::format("c = ({:.2f}, {:.2f}, {:.2f}) mm", 1e3 * e.com_offset_m(0), 1e3 * e.com_offset_m(1),
                         1e3 * e.com_offset_m(2));
      break;
    case Hidden::kDelay:
      e.input_delay_s = 1e-4 * std::round(within(3.0, 15.0));  // whole RK4 steps
      what = fmt::format("delay {:.1f} ms", 1e3 * e.input_delay_s);
      break;
  }
  stage6::SlidingModeOptions smc;
  smc.control_rate_hz = kRate_hz;
  stage6::SimulationOptions sim;
  sim.duration_s = kDuration_s;
  sim.seed = seed;
  // `simulate stage6 --experiment`'s defaults: sensor noise 1 nm (x, y), 10 nm (z),
  // 0.1 urad (tilts); excitation 2 N, 0.1 N·m.
  sim.sensor_noise_std << 1e-9, 1e-9, 1e-8, 1e-7, 1e-7, 1e-7;
  sim.excitation_std << 2, 2, 2, 0.1, 0.1, 0.1;
  const stage6::Vector6d qr = stage6::paper_reference_configuration();
  const stage6::StageRun run = stage6::simulate_regulation(p, e, qr, qr, smc, sim);
  // A lab logs a run that hovers: over its second half, tilts within 20 mrad and the
  // height within 3 mm of the reference (else the loop could not hold the stage).
  const Eigen::Index half = run.q.rows() / 2;
  const Eigen::VectorXd mean = run.q.bottomRows(run.q.rows() - half).colwise().mean().transpose();
  if (mean.tail(3).cwiseAbs().maxCoeff() > 2e-2 || std::abs(mean(2) - qr(2)) > 3e-3)
    throw NumericalError(fmt::format("seed {}: the stage did not hover (height {:.2f} mm, tilts {:.2f} {:.2f} {:.2f} mrad)",
                                     seed, 1e3 * (mean(2) - qr(2)), 1e3 * mean(3), 1e3 * mean(4), 1e3 * mean(5)));
  // The base's input order: F_x F_y F_z tau_z tau_y tau_x (stage6_base.h).
  const int order[6] = {0, 1, 2, 5, 4, 3};
  Eigen::MatrixXd v(run.t_s.size(), 6), z(run.t_s.size(), 12);
  for (int c = 0; c < 6; ++c) {
    v.col(c) = run.excitation.col(order[c]);
    z.col(c) = run.q_measured.col(c);
    z.col(6 + c) = run.wrench.col(order[c]);
  }
  FrfOptions fo;
  fo.sample_period_s = 1.0 / kRate_hz;
  fo.segment_length = kSegment;
  StageCase c;
  c.data.push_back({0.0, estimate_plant_frf({{v, z}}, fo), "stage"});
  c.description = fmt::format(
      "seed {}: I = ({:.4f}, {:.4f}, {:.4f}) kg·m², kappa {:.3f}; hidden {} {}; hovering {:.2f} mm above the "
      "reference, tilts ({:.2f}, {:.2f}, {:.2f}) mrad",
      seed, p.inertia_kgm2(0, 0), p.inertia_kgm2(1, 1), p.inertia_kgm2(2, 2), e.force_constant_scale,
      hidden_name(hidden), what, 1e3 * (mean(2) - qr(2)), 1e3 * mean(3), 1e3 * mean(4), 1e3 * mean(5));
  return c;
}

// A draw whose sliding-mode loop diverges (a slow current loop with a light
// inertia can make it unstable) or does not hover is redrawn, as a lab would not
// log that run.
StageCase make_case(std::uint64_t seed, Hidden hidden) {
  for (std::uint64_t k = 0;; ++k) {
    try {
      StageCase c = make_case_once(seed + 1000 * k, hidden);
      if (k > 0) c.description += fmt::format(" (redrawn {}x: the loop diverged or did not hover)", k);
      return c;
    } catch (const NumericalError& e) {
      std::printf("redraw: %s\n", e.what());
      if (k == 5) throw;
    }
  }
}

Diagnosis diagnose_stage(const StageCase& c) {
  DiagnoseOptions o;
  o.fit.sample_period_s = 1.0 / kRate_hz;
  return diagnose(PhysicalModel::initial("stage6"), c.data, o);
}

std::string report(const Diagnosis& d) {
  std::string s;
  for (const auto& line : d.summary) s += line + "\n";
  for (const auto& c : d.ranked)
    s += fmt::format("  {:<18} error {:.4f} % share {:.2f} bands {:.2f}: {}\n", c.effect, 100 * c.error,
                     c.excess_share, c.band_share, c.verdict);
  return s;
}

struct HiddenCase {
  Hidden effect;
  std::uint64_t seed;
  bool operator==(const HiddenCase&) const = default;
};

void PrintTo(const HiddenCase& h, std::ostream* os) { *os << hidden_name(h.effect) << " seed " << h.seed; }

class StageHiddenEffectIsNamed : public ::testing::TestWithParam<HiddenCase> {};

TEST_P(StageHiddenEffectIsNamed, FirstAndTheErrorFallsTenfoldOrToTheNoise) {
  const HiddenCase& h = GetParam();
  const StageCase c = make_case(h.seed, h.effect);
  const Diagnosis d = diagnose_stage(c);
  const std::string why = report(d) + c.description;
  ASSERT_EQ(d.missing, hidden_name(h.effect)) << why;
  const double e1 = d.ranked.front().error;
  std::printf("%s: %s, error %.4f %% -> %.4f %% (%.1fx; floor %.4f %%, %.4f %% with lpvid's resolution)\n",
              c.description.c_str(), d.missing.c_str(), 100 * d.baseline_error, 100 * e1, d.baseline_error / e1,
              100 * d.noise_floor, 100 * d.effective_floor);
  EXPECT_TRUE(e1 * kFallFactor <= d.baseline_error || e1 <= kWithinFloor * d.effective_floor) << why;
  EXPECT_TRUE(d.explained) << why;
}

std::vector<HiddenCase> hidden_cases() {
  std::vector<HiddenCase> full;
  for (Hidden e : {Hidden::kGap, Hidden::kLag, Hidden::kCom, Hidden::kDelay})
    for (std::uint64_t s : {501, 502, 503}) full.push_back({e, s});
  // Sanitizer build: two cases (each takes 70–90 s under ASan): the gap's
  // stiffness and the delay's fractional-sample path; the lag and the offset run
  // the same diagnose code.
  return testing::statistical_cases(full, {{Hidden::kGap, 501}, {Hidden::kDelay, 501}});
}

std::string case_name(const ::testing::TestParamInfo<HiddenCase>& info) {
  return fmt::format("{}_seed{}", hidden_name(info.param.effect), info.param.seed);
}

INSTANTIATE_TEST_SUITE_P(Stage6, StageHiddenEffectIsNamed, ::testing::ValuesIn(hidden_cases()), case_name);

TEST(Stage6Clean, NothingIsSignificantInAtLeastNineOfTenSeeds) {
  // Sanitizer build: one seed (three took 328 s under ASan), no alarm allowed.
  constexpr int kSeeds = 10, kAllowedFalseAlarms = 1, kSubsetSeeds = 1;
  constexpr int kRuns = testing::kFullStatistics ? kSeeds : kSubsetSeeds;
  constexpr int kAllowed = testing::scaled_allowance(kAllowedFalseAlarms, kSeeds, kRuns);
  static_assert(kAllowed < kRuns, "the criterion over the seeds run must be able to fail");
  int alarms = 0;
  std::string why;
  for (int s = 0; s < kRuns; ++s) {
    const StageCase c = make_case(600 + static_cast<std::uint64_t>(s), Hidden::kNone);
    const Diagnosis d = diagnose_stage(c);
    bool any = false;
    for (const auto& r : d.ranked) any = any || r.significant;
    std::printf("%s: error %.4f %%, floor %.4f %% (%.4f %% with lpvid's resolution), %s\n", c.description.c_str(),
                100 * d.baseline_error, 100 * d.noise_floor, 100 * d.effective_floor,
                any ? ("ALARM: " + d.missing).c_str() : "nothing significant");
    if (any) {
      ++alarms;
      why += c.description + "\n" + report(d);
    }
  }
  EXPECT_LE(alarms, kAllowed) << why;
}

}  // namespace stage6_diagnose_test
}  // namespace lpvid
