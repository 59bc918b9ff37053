// diagnose on the INDEPENDENT platform (tests/support/independent_*, written from
// the physics apart from idlib/physical): the acceptance of issue 10, "the
// model-error loop on a plant that is not lpvid's own simulator".  Plants are drawn
// over tests/idlib/diagnose/independent_data.h's ranges (masses ±30 %, psi/theta
// stiffness differing by up to ~30 %, per-coil damping ±10 %, coil pitch 8–13 cm,
// a PID loop with closed-loop damping 0.1–0.5); one effect is hidden at a time with
// its parameters drawn from tests/support/independent_draw.h; the data are what a
// user gets — a stepped-sine analyzer's S with coherence and averages, or lpvid's
// frf on 60 s white-noise logs; the start is `model init` with the design values a
// user knows (the rods' tilt stiffness within ±25 %).
//
// Criteria (issue 10, "What must hold"): each hidden effect named first and the
// error falls >= 10x or to within 1.5x the noise floor; a clean plant: nothing
// significant; an effect no library contains (a sensor resonance in the theta row):
// never explained, and described where and what it is.
//
// Seeds.  The normal build runs every seed below: that is the acceptance.  The
// sanitizer build runs each test on the subset named beside its seeds (every hidden
// effect, both data routes, a fitted start, an out-of-library effect, clean plants
// on both routes; tests/support/statistics.h picks it), so that CI checks memory
// and UB on these code paths within its budget; the subset is no statistical
// evidence.
#include "idlib/diagnose/diagnose.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <ostream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "idlib/core/error.h"
#include "tests/idlib/diagnose/independent_data.h"
#include "tests/support/statistics.h"

namespace lpvid {
namespace diagnose_test {

using indep::HiddenEffect;
using testing::LoopCase;
using testing::Route;

// "falls >= 10x or to within 1.5x the noise floor" (issue 10)
constexpr double kFallFactor = 10.0;
constexpr double kWithinFloor = 1.5;

struct LoopRun {
  LoopCase c;
  Diagnosis d;
};

LoopRun diagnose_case(std::uint64_t seed, HiddenEffect hidden, Route route, Progress* progress = nullptr) {
  LoopRun r{testing::make_loop_case(seed, hidden, route), {}};
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(r.c);
  o.progress = progress;
  r.d = diagnose(r.c.start, r.c.data, o);
  return r;
}

// Keeps every progress report (from diagnose's threads too).
class Recorder final : public Progress {
 public:
  struct Seen {
    std::string task, step, detail;
    Index index = 0, count = 0;
    double fraction = 0;
  };
  void report(const ProgressStep& s) noexcept override {
    std::lock_guard<std::mutex> lock(m_);
    seen.push_back({std::string(s.task), std::string(s.step), std::string(s.detail), s.index, s.count, s.fraction});
  }
  std::vector<Seen> seen;

 private:
  std::mutex m_;
};

std::string report(const Diagnosis& d) {
  std::string s;
  for (const auto& line : d.summary) s += line + "\n";
  for (const auto& c : d.ranked)
    s += fmt::format("  {:<18} error {:.4f} % share {:.2f} bands {:.2f}: {}\n", c.effect, 100 * c.error,
                     c.excess_share, c.band_share, c.verdict);
  return s;
}

const char* expected_name(HiddenEffect e) {
  switch (e) {
    case HiddenEffect::kMode: return "structural_mode";
    case HiddenEffect::kDelay: return "input_delay";
    case HiddenEffect::kCoilLag: return "actuator_lag";
    case HiddenEffect::kComOffset: return "com_offset";
    case HiddenEffect::kRodTwist: return "rod_twist";
    default: return "";
  }
}

struct HiddenCase {
  HiddenEffect effect;
  std::uint64_t seed;
  Route route;
  bool operator==(const HiddenCase&) const = default;
};

// gtest prints the parameter beside the test name (ctest's listing): say what it is.
void PrintTo(const HiddenCase& h, std::ostream* os) {
  *os << indep::hidden_name(h.effect) << " seed " << h.seed << (h.route == Route::kAnalyzer ? " analyzer" : " frf");
}

std::string case_name(const ::testing::TestParamInfo<HiddenCase>& info) {
  return fmt::format("{}_seed{}_{}", indep::hidden_name(info.param.effect), info.param.seed,
                     info.param.route == Route::kAnalyzer ? "analyzer" : "frf");
}

class HiddenEffectIsNamed : public ::testing::TestWithParam<HiddenCase> {};

TEST_P(HiddenEffectIsNamed, FirstAndTheErrorFallsTenfoldOrToTheNoise) {
  const HiddenCase& h = GetParam();
  const LoopRun r = diagnose_case(h.seed, h.effect, h.route);
  const Diagnosis& d = r.d;
  const std::string why = report(d) + r.c.draw.description;
  ASSERT_EQ(d.missing, expected_name(h.effect)) << why;
  const double e1 = d.ranked.front().error;
  std::printf("%s seed %llu %s: %s, error %.4f %% -> %.4f %% (%.1fx; floor %.4f %%)\n", indep::hidden_name(h.effect),
              static_cast<unsigned long long>(h.seed), h.route == Route::kAnalyzer ? "analyzer" : "frf",
              d.missing.c_str(), 100 * d.baseline_error, 100 * e1, d.baseline_error / e1, 100 * d.effective_floor);
  EXPECT_TRUE(e1 * kFallFactor <= d.baseline_error || e1 <= kWithinFloor * d.effective_floor) << why;
  EXPECT_TRUE(d.explained) << why;
}

// Every effect on analyzer data of seeds 201-203 and on frf from the logs of seed
// 211.  Reduced (sanitizer) build: every effect once, both routes among them — the
// frf route for the two effects whose frf case is cheap (coil_lag, com_offset), the
// analyzer route for the others (their frf cases take 30-50 s in Release).
std::vector<HiddenCase> hidden_cases() {
  std::vector<HiddenCase> full;
  for (HiddenEffect e : {HiddenEffect::kMode, HiddenEffect::kDelay, HiddenEffect::kCoilLag, HiddenEffect::kComOffset,
                         HiddenEffect::kRodTwist}) {
    for (std::uint64_t s : {201, 202, 203}) full.push_back({e, s, Route::kAnalyzer});
    full.push_back({e, 211, Route::kFrfFromLogs});
  }
  const std::vector<HiddenCase> subset = {{HiddenEffect::kMode, 201, Route::kAnalyzer},
                                          {HiddenEffect::kDelay, 201, Route::kAnalyzer},
                                          {HiddenEffect::kCoilLag, 211, Route::kFrfFromLogs},
                                          {HiddenEffect::kComOffset, 211, Route::kFrfFromLogs},
                                          {HiddenEffect::kRodTwist, 201, Route::kAnalyzer}};
  return testing::statistical_cases(full, subset);
}

INSTANTIATE_TEST_SUITE_P(IndependentPlant, HiddenEffectIsNamed, ::testing::ValuesIn(hidden_cases()), case_name);

// The user's order: fit the start model first, then diagnose the FITTED model (the
// walkthrough's fit1.json).  A rod twist that makes the tilts 3-6x stiffer than the
// design cannot be followed by the base (its bending tolerance is 0.5-2x): the fit
// runs inertias and bending scales to their bounds, and a candidate refitted from
// those values stays in that basin unless it also starts from the library defaults
// (found by tests/support/loop_trial.sh, seed 1001: nothing named, error 36 %).
class FromTheFittedModel : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(FromTheFittedModel, RodTwistIsStillNamedAndTheErrorFalls) {
  const LoopCase c = testing::make_loop_case(GetParam(), HiddenEffect::kRodTwist, Route::kAnalyzer);
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  const FitResult first = fit_physical_model(c.start, c.data, o.fit);
  bool distorted = false;
  for (const ParameterEstimate& p : first.parameters) distorted = distorted || p.at_bound;
  const Diagnosis d = diagnose(first.model, c.data, o);
  ASSERT_EQ(d.missing, "rod_twist") << report(d) << c.draw.description;
  const double e1 = d.ranked.front().error;
  std::printf("rod_twist seed %llu from the fitted model (%s): error %.4f %% -> %.4f %% (floor %.4f %%)\n",
              static_cast<unsigned long long>(GetParam()), distorted ? "a parameter on a bound" : "no bound",
              100 * d.baseline_error, 100 * e1, 100 * d.effective_floor);
  EXPECT_TRUE(e1 * kFallFactor <= d.baseline_error || e1 <= kWithinFloor * d.effective_floor) << report(d);
}

// Reduced (sanitizer) build: seed 204.
INSTANTIATE_TEST_SUITE_P(IndependentPlant, FromTheFittedModel,
                         ::testing::ValuesIn(testing::statistical_cases<std::uint64_t>({201, 202, 203, 204}, {204})));

// Two effects missing at once (issue 25): the product of inertia and centre-of-mass
// offset (com_offset) with a second library effect, drawn together.  Both must be
// named — as a pair in one diagnosis, or the second after adding the first (the
// user's next round) — and the error must end within 1.5x the floor with both.
struct PairCase {
  HiddenEffect first, second;
  std::uint64_t seed;
  bool operator==(const PairCase&) const = default;
};

void PrintTo(const PairCase& p, std::ostream* os) {
  *os << indep::hidden_name(p.first) << "+" << indep::hidden_name(p.second) << " seed " << p.seed;
}

class TwoHiddenEffects : public ::testing::TestWithParam<PairCase> {};

TEST_P(TwoHiddenEffects, BothAreNamedAndTheErrorEndsWithinTheFloor) {
  const PairCase& p = GetParam();
  const LoopCase c = testing::make_loop_case(p.seed, {p.first, p.second}, Route::kAnalyzer);
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  const Diagnosis d = diagnose(c.start, c.data, o);
  std::vector<std::string> named = d.missing_effects;
  std::string why = report(d);
  for (const auto& k : d.combinations)
    why += fmt::format("  {:<30} error {:.4f} % share {:.2f}: {}\n", k.effect, 100 * k.error, k.excess_share, k.verdict);
  double e_end = d.winner() != nullptr ? d.winner()->error : d.baseline_error;
  bool explained = d.explained;
  std::string rounds = d.missing.empty() ? "nothing" : d.missing;
  if (!d.missing.empty() && !d.explained && d.missing_effects.size() == 1) {
    // the user's next round: diagnose the model with what was named
    const Diagnosis d2 = diagnose(d.winner()->fit.model, c.data, o);
    why += "round 2:\n" + report(d2);
    for (const std::string& e : d2.missing_effects) named.push_back(e);
    if (d2.winner() != nullptr) e_end = d2.winner()->error;
    explained = d2.explained;
    rounds += ", then " + (d2.missing.empty() ? std::string("nothing") : d2.missing);
  }
  std::printf("%s + %s seed %llu: %s; error %.4f %% -> %.4f %% (floor %.4f %%)\n", indep::hidden_name(p.first),
              indep::hidden_name(p.second), static_cast<unsigned long long>(p.seed), rounds.c_str(),
              100 * d.baseline_error, 100 * e_end, 100 * d.effective_floor);
  why += c.draw.description;
  EXPECT_THAT(named, ::testing::Contains(expected_name(p.first))) << why;
  EXPECT_THAT(named, ::testing::Contains(expected_name(p.second))) << why;
  EXPECT_TRUE(explained) << why;
  EXPECT_LE(e_end, kWithinFloor * d.effective_floor) << why;
}

// com_offset with a coil lag, a delay, a flexible mode (seeds 221, 222) and a rod
// twist (seed 222).  Seed 222's twist is 3.9x / 2.8x the bending (issue 25's "design
// values far off": the base ends on its bending bounds, rod_twist alone stops at
// 19.8 % and the pair's own refits at 18.7 %): the pair is found through the triple
// with input_delay idle at 0 (candidates.cc, pairs_from_idle_members).  The rod twist
// of seed 221, the easier draw (35.7 % -> 0.0530 % for a 0.0529 % floor, measured
// 2026-12-02), gave its place to it for CI's time (docs/dev/CI.md).
std::vector<PairCase> pair_cases() {
  std::vector<PairCase> full;
  for (HiddenEffect e : {HiddenEffect::kCoilLag, HiddenEffect::kDelay, HiddenEffect::kMode})
    for (std::uint64_t s : {221, 222}) full.push_back({HiddenEffect::kComOffset, e, s});
  full.push_back({HiddenEffect::kComOffset, HiddenEffect::kRodTwist, 222});
  const std::vector<PairCase> subset = {{HiddenEffect::kComOffset, HiddenEffect::kCoilLag, 221}};
  return testing::statistical_cases(full, subset);
}

std::string pair_name(const ::testing::TestParamInfo<PairCase>& info) {
  return fmt::format("{}_{}_seed{}", indep::hidden_name(info.param.first), indep::hidden_name(info.param.second),
                     info.param.seed);
}

INSTANTIATE_TEST_SUITE_P(IndependentPlant, TwoHiddenEffects, ::testing::ValuesIn(pair_cases()), pair_name);

// Design values far off (issue 25): from lpvid's default rods (k_torque_low 45
// N·m/rad) on a plant whose rods also twist (each tilt 2-5x stiffer), the base ends
// on its bending bounds.  The report must name the design value that is off and
// what it should be: the refit with the bounds widened wants a bending scale whose
// product with the design is the plant's tilt stiffness per 1.5 rods (three rods
// 120° apart: K_tilt = 1.5 k_torque_low × scale), which the draw states.
TEST(DesignValuesFarOff, TheReportNamesTheDesignValueAndTheValueTheDataWant) {
  LoopCase c = testing::make_loop_case(201, HiddenEffect::kRodTwist, Route::kAnalyzer);
  c.start = PhysicalModel::initial("platform");
  c.start.parameter("beam_height_m").value = c.draw.plant.z_b_m;
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  o.candidates = {"rod_twist"};  // the guidance does not depend on the candidates
  const Diagnosis d = diagnose(c.start, c.data, o);
  ASSERT_FALSE(d.design_hints.empty()) << report(d);
  const std::string& desc = c.draw.description;
  auto drawn = [&](const std::string& key) { return std::stod(desc.substr(desc.find(key + " = ") + key.size() + 3)); };
  const double truth[2] = {drawn("K_psipsi_with_twist") / 1.5, drawn("K_thth_with_twist") / 1.5};
  int checked = 0;
  for (const DesignHint& h : d.design_hints) {
    if (h.design.empty()) continue;
    EXPECT_EQ(h.design, "k_torque_low_Nm_per_rad");
    const double want = h.parameter == "bending_scale_psi" ? truth[0] : truth[1];
    std::printf("%s on its bound %g: the data want %.4g, so k_torque_low ≈ %.4g (the plant's %.4g; design %.4g)\n",
                h.parameter.c_str(), h.bound, h.wanted, h.suggested, want, h.design_value);
    // within 15 %: the widened base still lacks the twist's exact split between the
    // axes and the coupling the bending_coupling bound (±0.5) allows
    EXPECT_NEAR(h.suggested / want, 1.0, 0.15) << report(d);
    ++checked;
  }
  EXPECT_GT(checked, 0) << report(d);
  bool said = false;
  for (const std::string& line : d.summary) said = said || line.find("lpvid model init --out model.json --set k_torque_low_Nm_per_rad=") != std::string::npos;
  EXPECT_TRUE(said) << report(d);
}

// An effect that stood in for another (issue 25, "delay vs lag"): a model with both a
// coil lag and an input delay, on a plant whose only dynamic beyond the base is a
// delay (seed 201).  The lag is idle: refitted without it the error does not rise and
// BIC improves; the delay is not (without it the lag cannot follow a 1-sample-scale
// delay at high frequency).  The report says which to remove, and how.
TEST(IdleEffects, ALagBesideTheDelayItStoodInForIsReportedIdle) {
  LoopCase c = testing::make_loop_case(201, HiddenEffect::kDelay, Route::kAnalyzer);
  c.start.add_effect("input_delay");
  c.start.add_effect("actuator_lag");
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  o.candidates = {"sensor_gain"};  // the idle check does not depend on the candidates
  const Diagnosis d = diagnose(c.start, c.data, o);  // its baseline is the fit of both
  std::vector<std::string> idle;
  for (const IdleEffect& e : d.idle_effects) {
    idle.push_back(e.effect);
    std::printf("idle: %s (%s): error %.4f %% without, %.4f %% with; dBIC %+.1f\n", e.effect.c_str(),
                e.why_tried.c_str(), 100 * e.error_without, 100 * d.baseline_error, e.delta_bic);
    EXPECT_LE(e.error_without, d.baseline_error * 1.001) << report(d);
    EXPECT_LT(e.delta_bic, o.significance_delta_bic) << report(d);
  }
  EXPECT_EQ(idle, std::vector<std::string>{"actuator_lag"}) << report(d) << c.draw.description;
  bool said = false;
  for (const std::string& line : d.summary)
    said = said || line.find("lpvid model remove actuator_lag --model MODEL") != std::string::npos;
  EXPECT_TRUE(said) << report(d);
}

// Issue 25, confounded pairs: a force constant common to all coils (indep
// HiddenEffect::kGain, here 0.80) is exactly a scaling of M, D and K on S: the base
// fits it within the noise with every mass 1/0.80 too heavy, and gain_error adds
// nothing the data can see (reported as such, with what would reveal it).  A weighed
// platform and beam (priors at the drawn masses, ±10 g) break the tie: the posterior's
// ΔBIC names a gain and the estimates return to their priors.  Which gain, actuator or
// sensor, S cannot say for a uniform one: they are reported as indistinguishable.
TEST(ConfoundedPairs, AGainIsAMassScalingUntilAWeighedMassBreaksTheTie) {
  LoopCase c = testing::make_loop_case(1000, HiddenEffect::kGain, Route::kAnalyzer);
  const indep::Plant& p = c.draw.plant;
  ASSERT_TRUE(std::abs(p.input_gain - 1) > 0.1) << c.draw.description;
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  o.candidates = {"gain_error", "sensor_gain", "rod_twist"};
  const Diagnosis without = diagnose(c.start, c.data, o);
  for (const auto& k : without.ranked) EXPECT_FALSE(k.significant) << report(without);
  const double mass = without.baseline.model.parameter("platform_mass_kg").value;
  std::printf("without a prior: platform mass %.4g kg for the plant's %.4g (gain %.4g)\n", mass, p.m_p_kg, p.input_gain);
  EXPECT_NEAR(mass * p.input_gain / p.m_p_kg, 1.0, 0.02) << report(without);  // the scaling took it
  bool noted = false;
  for (const std::string& line : without.summary) noted = noted || line.find("cannot tell an input gain") != std::string::npos;
  EXPECT_TRUE(noted) << report(without);

  PhysicalModel weighed = without.baseline.model;
  for (auto [name, value] : {std::pair<const char*, double>{"platform_mass_kg", p.m_p_kg}, {"beam_mass_kg", p.m_b_kg}}) {
    weighed.parameter(name).prior_mean = value;
    weighed.parameter(name).prior_sigma = 0.01;
  }
  const Diagnosis with = diagnose(weighed, c.data, o);
  const CandidateOutcome* w = with.winner();
  ASSERT_NE(w, nullptr) << report(with);
  EXPECT_TRUE(w->effect == "gain_error" || w->effect == "sensor_gain") << report(with);
  for (const ParameterEstimate& e : w->effect_parameters)  // the drawn gain, to 1 %
    EXPECT_NEAR(e.estimate / p.input_gain, 1.0, 0.01) << e.name << "\n" << report(with);
  EXPECT_NEAR(w->fit.model.parameter("platform_mass_kg").value / p.m_p_kg, 1.0, 0.01) << report(with);
  EXPECT_LT(w->delta_bic, -100) << report(with);
  bool tie = false;
  for (const std::string& name : with.indistinguishable) tie = tie || name == "gain_error" || name == "sensor_gain";
  EXPECT_TRUE(tie) << report(with);
  // rod_twist fits the data within the noise too, but only with the masses far from
  // their weighed values: the priors separate it (not a tie).
  for (const std::string& name : with.indistinguishable) EXPECT_NE(name, "rod_twist") << report(with);
  std::printf("separated by the priors: %zu candidate(s)%s%s\n", with.separated_by_priors.size(),
              with.separated_by_priors.empty() ? "" : ", first ",
              with.separated_by_priors.empty() ? "" : with.separated_by_priors.front().c_str());
  bool returned = false;
  for (const std::string& line : with.summary)
    returned = returned || line.find("with it the estimates return to their priors") != std::string::npos;
  EXPECT_TRUE(returned) << report(with);
  std::printf("with a weighed mass: %s, ΔBIC %.1f, %s = %.4f, platform mass %.4g kg\n", w->effect.c_str(),
              w->delta_bic, w->effect_parameters.front().name.c_str(), w->effect_parameters.front().estimate,
              w->fit.model.parameter("platform_mass_kg").value);
}

// Issue 25, confounded pairs: a delay and a first-order lag are the same phase
// lag, ωτ, where ωτ << 1.  Seed 1000 hides a 0.547 ms delay; an analyzer's S up to
// 2 Hz (ωτ <= 0.007) cannot tell which: both leave only noise and the data's BIC
// differs by less than the margin (measured: 3.6).  A datasheet's coil time
// constant, L/R = 50 ± 50 us, given before actuator_lag is added (a design value
// of an absent effect), breaks the tie: the lag would need 0.55 ms, ten sigma off,
// so the priors separate it and the delay stands.  Over the analyzer's full band
// (to 400 Hz, ωτ up to 1.4) the data separate them themselves: the lag still
// brings the error within the noise, but its likelihood is thousands worse, and
// that is said as such, not as a tie.
TEST(ConfoundedPairs, ADelayIsALagAtLowFrequencyUntilADatasheetTimeConstantBreaksTheTie) {
  constexpr double kLowBandHz = 2.0;
  LoopCase c = testing::make_loop_case(1000, HiddenEffect::kDelay, Route::kAnalyzer, 300, kLowBandHz);
  const double delay = c.draw.plant.input_delay_s;
  ASSERT_GT(delay, 0.0) << c.draw.description;
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  o.candidates = {"input_delay", "actuator_lag"};
  const Diagnosis without = diagnose(c.start, c.data, o);
  ASSERT_TRUE(without.explained) << report(without);
  const std::string other = without.missing == "input_delay" ? "actuator_lag" : "input_delay";
  EXPECT_THAT(without.indistinguishable, ::testing::ElementsAre(other)) << report(without);
  bool hinted = false;  // the hint names the lag's own parameter as one a prior can be given on
  for (const std::string& line : without.summary)
    hinted = hinted || (line.find("indistinguishable on these data") != std::string::npos &&
                        line.find("actuator_time_constant_s") != std::string::npos);
  EXPECT_TRUE(hinted) << report(without);

  PhysicalModel datasheet = c.start;
  PhysicalParameter& tau = datasheet.parameter_or_design_value("actuator_time_constant_s");
  tau.value = tau.prior_mean = 50e-6;
  tau.prior_sigma = 50e-6;
  const Diagnosis with = diagnose(datasheet, c.data, o);
  ASSERT_EQ(with.missing, "input_delay") << report(with);
  EXPECT_TRUE(with.indistinguishable.empty()) << report(with);
  EXPECT_THAT(with.separated_by_priors, ::testing::ElementsAre("actuator_lag")) << report(with);
  const CandidateOutcome* w = with.winner();
  ASSERT_NE(w, nullptr);
  // On 2 Hz the delay is seen through ωτ alone; its standard error says how well.
  const ParameterEstimate& d = w->effect_parameters.front();
  EXPECT_LT(std::abs(d.estimate - delay), 3 * d.std_error + 0.02 * delay) << report(with);
  std::printf("to %g Hz: without a prior %s named, %s indistinguishable; with L/R = 50 +- 50 us: input_delay %.4g s "
              "(+-%.2g; hidden %.4g), actuator_lag separated by the priors\n",
              kLowBandHz, without.missing.c_str(), other.c_str(), d.estimate, d.std_error, delay);

  const LoopCase full = testing::make_loop_case(1000, HiddenEffect::kDelay, Route::kAnalyzer);
  o.fit = testing::loop_fit_options(full);
  const Diagnosis wide = diagnose(full.start, full.data, o);
  ASSERT_EQ(wide.missing, "input_delay") << report(wide);
  EXPECT_TRUE(wide.indistinguishable.empty()) << report(wide);
  EXPECT_THAT(wide.also_explain, ::testing::ElementsAre("actuator_lag")) << report(wide);
}

// A clean plant (nothing hidden): nothing significant in at least 9 of 10 seeds
// (300-309).  Reduced (sanitizer) build: seeds 300-302 with the allowance scaled to
// them, floor(1 x 3 / 10) = 0 alarms — stricter than the full rate, and none of the
// three alarms in the full run.
TEST(IndependentPlantClean, NothingIsSignificantInAtLeastNineOfTenSeeds) {
  constexpr int kSeeds = 10, kAllowedFalseAlarms = 1, kSubsetSeeds = 3;
  constexpr int kRuns = testing::kFullStatistics ? kSeeds : kSubsetSeeds;
  constexpr int kAllowed = testing::scaled_allowance(kAllowedFalseAlarms, kSeeds, kRuns);
  static_assert(kAllowed < kRuns, "the criterion over the seeds run must be able to fail");
  if (!testing::kFullStatistics)
    std::printf("reduced statistics (sanitizer build): seeds 300-%d, at most %d alarms\n", 300 + kRuns - 1, kAllowed);
  int alarms = 0;
  std::string why;
  for (int s = 0; s < kRuns; ++s) {
    const LoopRun r = diagnose_case(300 + static_cast<std::uint64_t>(s), HiddenEffect::kNone, Route::kAnalyzer);
    bool any = false;
    for (const auto& c : r.d.ranked) any = any || c.significant;
    std::printf("clean seed %d: error %.4f %%, floor %.4f %%, %s\n", 300 + s, 100 * r.d.baseline_error,
                100 * r.d.effective_floor, any ? ("ALARM: " + r.d.missing).c_str() : "nothing significant");
    if (any) {
      ++alarms;
      why += report(r.d);
    }
  }
  EXPECT_LE(alarms, kAllowed) << why;
}

TEST(IndependentPlantClean, FrfFromLogsCallsNothingSignificant) {
  const LoopRun r = diagnose_case(311, HiddenEffect::kNone, Route::kFrfFromLogs);
  for (const auto& c : r.d.ranked) EXPECT_FALSE(c.significant) << report(r.d);
}

// An effect outside the library — a resonance of the theta sensor's mount, in the
// theta output row only — is never claimed explained, and the description finds its
// place (the theta output row) and its frequency.
class OutOfLibrary : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(OutOfLibrary, IsNeverExplainedAndIsDescribedInTheThetaRowAtItsFrequency) {
  Recorder progress;
  const LoopRun r = diagnose_case(GetParam(), HiddenEffect::kSensorResonance, Route::kAnalyzer, &progress);
  const Diagnosis& d = r.d;
  // Progress (idlib/core/progress.h): the baseline's fit first, then every candidate
  // started once (K counts the starts: 1..n, each name once), the bar reaching all
  // finished, then the residual's models.
  ASSERT_FALSE(progress.seen.empty());
  EXPECT_EQ(progress.seen.front().task, "diagnose baseline, fit");
  std::vector<std::string> started;
  Index last_start = 0;
  double finished = 0;
  bool residual = false;
  for (const auto& s : progress.seen) {
    if (s.step == "candidate") {
      EXPECT_EQ(s.count, static_cast<Index>(d.ranked.size()));
      if (s.index > last_start) {  // a start: its name is the newest running
        EXPECT_EQ(s.index, last_start + 1);
        started.push_back(s.detail.substr(0, s.detail.find(',')));
        last_start = s.index;
      }
      finished = std::max(finished, s.fraction);
    }
    residual = residual || s.step == "residual model";
  }
  std::vector<std::string> ranked;
  for (const auto& c : d.ranked) ranked.push_back(c.effect);
  std::sort(started.begin(), started.end());
  std::sort(ranked.begin(), ranked.end());
  EXPECT_EQ(started, ranked);
  EXPECT_EQ(finished, 1.0);
  EXPECT_TRUE(residual);
  EXPECT_FALSE(d.explained) << report(d);
  ASSERT_FALSE(d.descriptions.empty()) << report(d);
  const ResidualDescription& best = d.descriptions.front();
  EXPECT_EQ(best.side, "output");
  EXPECT_EQ(best.channel, "theta") << best.text;
  EXPECT_EQ(best.kind, "resonance") << best.text;
  // the drawn resonance frequency, from the draw's description "sensor_resonance_rad_s = ..."
  const std::string& desc = r.c.draw.description;
  const double truth = std::stod(desc.substr(desc.find("sensor_resonance_rad_s = ") + 25));
  const double found = best.effect.parameters[0].value;
  // within 2 %: the resonance is sharp (ζ 0.02–0.08) and the analyzer sees it at ~1 % line spacing
  constexpr double kFrequencyTolerance = 0.02;
  EXPECT_NEAR(found / truth, 1.0, kFrequencyTolerance) << best.text;
  std::printf("out of library, seed %llu: %s (truth %.1f rad/s)\n", static_cast<unsigned long long>(GetParam()),
              best.text.c_str(), truth);
}

// Reduced (sanitizer) build: seed 401.
INSTANTIATE_TEST_SUITE_P(IndependentPlant, OutOfLibrary,
                         ::testing::ValuesIn(testing::statistical_cases<std::uint64_t>({401, 402, 403}, {401})));

// ---- rules --------------------------------------------------------------------

TEST(DiagnoseRules, DataWithCoherenceButNoAveragesIsAnInputErrorNamingTheRemedy) {
  LoopCase c = testing::make_loop_case(201, HiddenEffect::kNone, Route::kAnalyzer, 40);
  for (auto& ds : c.data) ds.response.averages = 0;  // an export that does not state it
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  try {
    diagnose(c.start, c.data, o);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("give --averages N"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("coherence without the number of averages"));
  }
}

TEST(DiagnoseRules, UnknownOrPresentCandidatesAndBadOptionsAreInputErrors) {
  LoopCase c = testing::make_loop_case(201, HiddenEffect::kNone, Route::kAnalyzer, 40);
  DiagnoseOptions o;
  o.fit = testing::loop_fit_options(c);
  o.candidates = {"friction"};
  EXPECT_THROW(diagnose(c.start, c.data, o), InputError);
  o.candidates = {"beam_gravity"};
  EXPECT_THROW(diagnose(c.start, c.data, o), InputError);
  o.candidates.clear();
  o.min_excess_share = 0;
  EXPECT_THROW(o.validate(), InputError);
  o.min_excess_share = 0.5;
  o.explained_ratio = 0.5;
  EXPECT_THROW(o.validate(), InputError);
}

TEST(Phenomena, BandsAtOneFrequencyInOneRowAreOnePhenomenonSaidAsThatRow) {
  auto band = [](Index d, Index i, Index j, double w, double ratio) {
    FailingBand b;
    b.data_index = d;
    b.output = i;
    b.input = j;
    b.lo_rad_s = 0.9 * w;
    b.hi_rad_s = 1.1 * w;
    b.omega_at_max_rad_s = w;
    b.max_sigma_ratio = ratio;
    b.hint = "narrow peak";
    return b;
  };
  const std::vector<std::vector<FailingBand>> failures = {
      {band(0, 1, 0, 850, 40), band(0, 1, 1, 860, 90), band(0, 0, 0, 60, 30)},
      {band(1, 1, 2, 845, 50), band(1, 2, 2, 5, 20)}};
  const auto ph = group_phenomena(failures, {"psi", "theta", "z"}, {"T_psi", "T_theta", "F_z"});
  ASSERT_EQ(ph.size(), 3u);
  EXPECT_EQ(ph[0].bands.size(), 3u);  // the theta row near 850 rad/s, strongest first
  EXPECT_NEAR(ph[0].omega_rad_s, 860, 1e-9);
  EXPECT_THAT(ph[0].where, ::testing::StartsWith("the theta output row only"));
  EXPECT_EQ(ph[0].data_sets, (std::vector<Index>{0, 1}));
  EXPECT_EQ(ph[1].where, "psi <- T_psi");
}

}  // namespace diagnose_test
}  // namespace lpvid

// The significance test on its own (issue 25, "a verdict never contradicts the
// error"): the numbers are the cases the issue measured.
namespace diagnose_test {

lpvid::CandidateEvidence evidence(double e0, double e, double floor, double delta_bic, double band_share) {
  lpvid::CandidateEvidence ev;
  ev.floor = floor;
  ev.baseline_error = e0;
  ev.error = e;
  ev.global_excess = e0 > 1.5 * floor;
  ev.has_band_points = true;
  ev.something = true;
  ev.delta_bic = delta_bic;
  const double excess2 = e0 * e0 - floor * floor;
  ev.excess_share = excess2 > 0 ? (e0 * e0 - e * e) / excess2 : 0.0;
  ev.band_share = band_share;
  return ev;
}

TEST(CandidateJudgement, ACandidateThatRaisesTheErrorIsNeverSignificantWhateverItsBic) {
  // The stage's out-of-library platen mode: gain_error, ΔBIC far below −10, took the
  // error from 5.09 % to 5.23 % inside 1.5x a 5 % floor (the excess test waived).
  const lpvid::CandidateJudgement j =
      lpvid::judge_candidate(evidence(0.0509, 0.0523, 0.05, -3.8e5, 0.9), lpvid::DiagnoseOptions{});
  EXPECT_FALSE(j.significant);
  EXPECT_THAT(j.verdict, testing::HasSubstr("raises the error figure from 5.09 % to 5.23 %")) << j.verdict;
}

TEST(CandidateJudgement, BringingTheErrorToTheFloorIsNotVetoedByTheResidualBands) {
  // The out-of-library platform case: com_offset took 0.30 % to 0.088 % against a
  // 0.092 % floor (all the excess) yet removed only 39 % of the failing-band points.
  const lpvid::CandidateJudgement j =
      lpvid::judge_candidate(evidence(0.0030, 0.00088, 0.00092, -400.0, 0.39), lpvid::DiagnoseOptions{});
  EXPECT_TRUE(j.significant) << j.verdict;
  // Halfway to the floor, the bands still decide.
  const lpvid::CandidateJudgement half =
      lpvid::judge_candidate(evidence(0.0030, 0.0016, 0.00092, -400.0, 0.39), lpvid::DiagnoseOptions{});
  EXPECT_FALSE(half.significant);
  EXPECT_THAT(half.verdict, testing::HasSubstr("removes 39 % of the failing-band points")) << half.verdict;
}

TEST(CandidateJudgement, TheOtherTestsInOrder) {
  const lpvid::DiagnoseOptions o;
  lpvid::CandidateEvidence ev = evidence(0.0030, 0.0010, 0.00092, -5.0, 0.9);
  EXPECT_THAT(lpvid::judge_candidate(ev, o).verdict, testing::HasSubstr("ΔBIC -5.0 above −10"));
  ev = evidence(0.0030, 0.0028, 0.00092, -50.0, 0.9);
  EXPECT_THAT(lpvid::judge_candidate(ev, o).verdict, testing::HasSubstr("of the excess (needs 50 %)"));
  ev.pinned = {"tau = 0.01 at its upper bound"};
  EXPECT_THAT(lpvid::judge_candidate(ev, o).verdict, testing::HasSubstr("tau = 0.01 at its upper bound (used as a patch)"));
  ev = evidence(0.0010, 0.0009, 0.00092, -50.0, 0.9);
  ev.something = false;
  EXPECT_THAT(lpvid::judge_candidate(ev, o).verdict, testing::HasSubstr("nothing beyond the noise"));
  // A localized phenomenon (no global excess): judged by its bands.
  ev.something = true;
  EXPECT_TRUE(lpvid::judge_candidate(ev, o).significant);
  ev.band_share = 0.2;
  EXPECT_FALSE(lpvid::judge_candidate(ev, o).significant);
}

// One of several modes (a base that offers several, diagnose.h): the F-16's torsion mode,
// ΔBIC −1608, took a model with no mode from 79.2 % to 62.9 % against a 1.48 % floor —
// 37 % of the excess, and no failing-band point removed while the other modes are missing.
TEST(CandidateJudgement, OneOfSeveralModesNeedsATenthOfTheExcessAndNoBands) {
  const lpvid::DiagnoseOptions o;
  lpvid::CandidateEvidence ev = evidence(0.792, 0.629, 0.0148, -1608.0, 0.0);
  EXPECT_FALSE(lpvid::judge_candidate(ev, o).significant);  // any other effect: half the excess
  ev.one_of_several = true;
  const lpvid::CandidateJudgement j = lpvid::judge_candidate(ev, o);
  EXPECT_TRUE(j.significant) << j.verdict;
  EXPECT_THAT(j.verdict, testing::HasSubstr("one of several modes (explains 37 % of the excess; more is missing)"));
  // the other tests still hold: a mode that raises the error, or explains too little
  EXPECT_FALSE(lpvid::judge_candidate(evidence(0.563, 0.993, 0.0148, -1315.0, 0.0), o).significant);
  ev = evidence(0.792, 0.78, 0.0148, -200.0, 0.0);  // 3 % of the excess
  ev.one_of_several = true;
  EXPECT_THAT(lpvid::judge_candidate(ev, o).verdict, testing::HasSubstr("of the excess (needs 10 %)"));
  // the last mode, to the floor: plain "significant"
  ev = evidence(0.05, 0.02, 0.0148, -500.0, 0.0);
  ev.one_of_several = true;
  EXPECT_EQ(lpvid::judge_candidate(ev, o).verdict, "significant");
}

}  // namespace diagnose_test
