// The stage's model-error loop (issue 13) through the program, on a log from the
// INDEPENDENT stage simulator (tests/support/independent_stage.h: the paper's
// physics written apart from idlib/stage6, with its own drawn mass, lever arms,
// inertias, force constant, controller gains and noise): the documented session
// (samples/stage6-loop.sh) `frf --input` -> `model init --base stage6 --set` (the
// weighed mass and the design arms, which a user knows) -> `fit` -> `diagnose`.
// The truth is the simulator's drawn stage, not lpvid's model.  Cheaper than the
// trial script (tests/support/stage_loop_trial.sh: 60 s logs, 1024 lines, every
// effect over several seeds): a 30 s log and 256 lines, one draw per case.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <string>

#include "tests/support/independent_stage.h"
#include "tests/support/run_lpvid.h"
#include "tests/support/statistics.h"

namespace lpvid {
namespace indep_stage_loop_test {

using testing::run_lpvid;
using testing::slurp;
using testing::TempDir;

struct LoopCase {
  indep_stage::Hidden hidden;
  std::uint64_t seed;
  bool operator==(const LoopCase& o) const { return hidden == o.hidden && seed == o.seed; }
};

class IndepStageLoop : public ::testing::TestWithParam<LoopCase> {};

TEST_P(IndepStageLoop, DiagnoseNamesTheHiddenEffect) {
  const LoopCase c = GetParam();
  // The draw as indep_stage_sim makes it (redrawn while it does not hover).
  indep_stage::HoveringRun hr;
  ASSERT_TRUE(indep_stage::run_hovering(
      c.seed, c.hidden, -1, [](indep_stage::Draw& d) { d.experiment.duration_s = 30; }, &hr, nullptr));
  const indep_stage::Draw& d = hr.draw;
  const indep_stage::Log& log = hr.log;
  TempDir dir("indep_stage_loop");
  indep_stage::write_log_csv(dir / "exp_stage6.csv", log);
  const std::string cd = dir.path().string();
  auto ok = [&](const std::string& args) {
    const auto r = run_lpvid(args, "", cd);
    EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.err;
    return r;
  };
  ok("frf --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,q2,q3,q4,q5,q6 --quantity P "
     "--segment 512 --out P.csv exp_stage6.csv");
  std::string sets = " --set mass_kg=" + std::to_string(d.stage.mass_kg);
  const char* axis[3] = {"x", "y", "z"};
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a)
      sets += " --set lever_arm_" + std::to_string(i + 1) + "_" + axis[a] + "_m=" + std::to_string(d.stage.arms_m(a, i));
  ok("model init --base stage6 --out model.json" + sets);
  ok("fit --model model.json --data P.csv@0 --rate-hz 1000 --out fit1.json");
  const auto r = ok("diagnose --model fit1.json --data P.csv@0 --rate-hz 1000 --json");
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const double e0 = j["baseline"]["error"], floor = j["effective_floor"];
  const std::string missing = j["missing"].is_null() ? "" : j["missing"].get<std::string>();
  std::printf("%s\n", d.description.c_str());
  std::printf("diagnose: missing '%s', error %.3g %%, floor %.3g %%\n", missing.c_str(), 100 * e0, 100 * floor);
  if (c.hidden == indep_stage::Hidden::kNone) {
    EXPECT_EQ(missing, "") << "false alarm on a clean independent stage";
    return;
  }
  const char* want = c.hidden == indep_stage::Hidden::kGap     ? "gap_dependence"
                     : c.hidden == indep_stage::Hidden::kLag   ? "electrical_lag"
                     : c.hidden == indep_stage::Hidden::kCom   ? "com_offset"
                                                               : "input_delay";
  EXPECT_EQ(missing, want);
  const double after = j["candidates"][0]["error"];
  const double variance_floor = j["noise_floor"].is_null() ? 0.0 : j["noise_floor"].get<double>();
  std::printf("candidate %s: error %.3g %% (%.3gx lower; variance floor %.3g %%)\n",
              j["candidates"][0]["effect"].dump().c_str(), 100 * after, e0 / after, 100 * variance_floor);
  // Issue 13's criterion: the error falls >= 10x or to within 1.5x the noise floor.
  EXPECT_TRUE(e0 / after >= 10 || after <= 1.5 * floor) << "error " << e0 << " -> " << after << ", floor " << floor;
  for (const auto& p : j["candidates"][0]["parameters"])
    std::printf("  %s = %.6g +- %.3g\n", p["name"].get<std::string>().c_str(), p["estimate"].get<double>(),
                p["std_error"].get<double>());
  // The documented next step: add the named effect and refit (model add restarts the
  // parameters fit1 left on bounds from the library's defaults); what the user keeps.
  ok("model add " + missing + " --model fit1.json --out start2.json");
  ok("fit --model start2.json --data P.csv@0 --rate-hz 1000 --out fit2.json");
  const nlohmann::json fit2 = nlohmann::json::parse(slurp(dir.path() / "fit2.json"));
  const auto& par = fit2["parameters"];
  auto value = [&](const char* name) { return par[name]["value"].get<double>(); };
  std::printf("refit: I = (%.6g, %.6g, %.6g) for (%.6g, %.6g, %.6g)\n", value("inertia_xx_kgm2"),
              value("inertia_yy_kgm2"), value("inertia_zz_kgm2"), d.stage.inertia_kgm2(0, 0), d.stage.inertia_kgm2(1, 1),
              d.stage.inertia_kgm2(2, 2));
  // The inertias against the drawn ones (truth from the simulator, not from lpvid):
  // measured within 0.1 % on 60 s logs at 1024 lines (trial script); 2 % leaves room
  // for the coarser 256 lines and 30 s here.
  EXPECT_NEAR(value("inertia_xx_kgm2") / d.stage.inertia_kgm2(0, 0), 1.0, 0.02);
  EXPECT_NEAR(value("inertia_yy_kgm2") / d.stage.inertia_kgm2(1, 1), 1.0, 0.02);
  EXPECT_NEAR(value("inertia_zz_kgm2") / d.stage.inertia_kgm2(2, 2), 1.0, 0.02);
  if (c.hidden == indep_stage::Hidden::kGap) {
    std::printf("refit: gamma %.6g for %.6g\n", value("gap_decay_per_m"), d.stage.gamma_per_m);
    // The decay rate against the drawn one; 5 %: the gap spring is undamped and Welch
    // at 256 lines smears it over a 12 rad/s bin (docs/model-error-walkthrough.md).
    EXPECT_NEAR(value("gap_decay_per_m") / d.stage.gamma_per_m, 1.0, 0.05);
  }
}

std::vector<LoopCase> cases() {
  using H = indep_stage::Hidden;
  // Seeds as the trial script numbers them (first seed 100).  lag and com were named
  // on none of 3 seeds until lpvid's back-EMF took each array's own velocity and its
  // sensors the reference point p_cm - R c (the independent simulator's physics,
  // which is the paper's; tests/cli/indep_stage_crosscheck_test.cc).  The delay's
  // seed 101 was named on no run until each Welch segment's mean was removed and an
  // entry larger than its diagonals was measured against itself (docs/math.md,
  // "Segment means", "Error figure"): one line's error had owned the figure.
  return testing::statistical_cases<LoopCase>(
      {{H::kGap, 100}, {H::kNone, 100}, {H::kLag, 100}, {H::kCom, 100}, {H::kDelay, 101}}, {{H::kGap, 100}});
}

INSTANTIATE_TEST_SUITE_P(Draws, IndepStageLoop, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<LoopCase>& i) {
                           return std::string(indep_stage::hidden_name(i.param.hidden)) + "_" +
                                  std::to_string(i.param.seed);
                         });

}  // namespace indep_stage_loop_test
}  // namespace lpvid
