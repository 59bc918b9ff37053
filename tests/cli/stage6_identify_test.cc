// lpvid stage6 fit / diagnose / history on a simulated closed-loop log of the
// 6-DOF stage with a hidden gap-dependent force constant alpha(z) (issue 6).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace stage6_identify_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

TEST(Stage6IdentifyCli, DiagnoseNamesTheHiddenGapDependenceAndTheHistoryShowsTheErrorFalling) {
  TempDir d("stage6id");
  // Noise-free log (the "within 1 % on noise-free logs" setting).
  auto r = run_lpvid("simulate stage6 --experiment --out " + (d / "exp") + " --effects gap --seed 3 --noise-scale 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = d / "exp/exp_stage6.csv";
  r = run_lpvid("stage6 diagnose --log " + log + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["explained"].get<bool>());
  EXPECT_EQ(j["missing"], "gap_dependence");
  // The issue: adding it makes the error fall >= 10x.
  EXPECT_LT(j["candidates"][0]["rms_residual"].get<double>(), j["baseline"]["rms_residual"].get<double>() / 10.0);
  // gamma = 2 pi / pitch = 2 pi / 0.0256 m (docs/assumptions.md) within 1 %.
  EXPECT_NEAR(j["candidates"][0]["gamma_per_m"].get<double>(), 2 * M_PI / 0.0256, 0.01 * 2 * M_PI / 0.0256);

  // The loop: fit without, then with the effect, into the same model file.
  ASSERT_EQ(run_lpvid("stage6 fit --log " + log + " --out " + (d / "stage.json")).exit_code, 0);
  r = run_lpvid("stage6 fit --log " + log + " --effects gap --out " + (d / "stage.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("history --model " + (d / "stage.json") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto h = nlohmann::json::parse(r.out);
  ASSERT_EQ(h["fits"].size(), 2u);
  EXPECT_LT(h["fits"][1]["error_mean"].get<double>(), h["fits"][0]["error_mean"].get<double>() / 10.0);
  // Nothing left once gap is in.
  r = run_lpvid("stage6 diagnose --log " + log + " --effects gap --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_FALSE(nlohmann::json::parse(r.out)["explained"].get<bool>());
}

// --method output / both on a log with the default sensor noise: the output
// error's inertias are within 3 of their σ of the truth (H = diag(0.029, 0.029,
// 0.057), docs/assumptions.md) where the equation error's are ≥ 0.5 % low, and
// the JSON carries standard errors and the residual per channel and window.
TEST(Stage6IdentifyCli, OutputErrorMethodRemovesTheInertiaBiasAndReportsStandardErrors) {
  TempDir d("stage6oe");
  auto r = run_lpvid("simulate stage6 --experiment --out " + (d / "exp") + " --effects gap --seed 3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = d / "exp/exp_stage6.csv";
  r = run_lpvid("stage6 fit --log " + log + " --effects gap --method both --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const double truth[3] = {0.029, 0.029, 0.057};
  ASSERT_TRUE(j.contains("output_error"));
  const auto& oe = j["output_error"];
  EXPECT_EQ(oe["method"], "output");
  EXPECT_EQ(oe["model"], "base+gap");
  EXPECT_EQ(oe["windows"].get<int>(), 6);
  EXPECT_EQ(oe["rms_per_window"].size(), 6u);
  EXPECT_DOUBLE_EQ(oe["rms_per_window"][1]["t_start_s"].get<double>(), 0.3);
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(j["inertia_diag_kgm2"][i].get<double>(), 0.995 * truth[i]) << i;
    const double se = oe["std_error"][std::string("inertia_") + "xyz"[i] + "xyz"[i] + "_kgm2"].get<double>();
    EXPECT_LT(std::abs(oe["inertia_diag_kgm2"][i].get<double>() - truth[i]), 3 * se) << i;
  }
  // The z channel's noise is 10 nm (simulate stage6 --experiment).
  EXPECT_NEAR(oe["rms_per_channel"]["z"].get<double>(), 1e-8, 0.05e-8);
  // --method output alone: its estimates on top, the start beside them, and the history.
  r = run_lpvid("stage6 fit --log " + log + " --effects gap --method output --out " + (d / "stage.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("output error"));
  // The alias writes a stage6 physical model file (as lpvid fit), the summary in its "fit" section.
  std::ifstream in(d / "stage.json");
  const auto s = nlohmann::json::parse(in);
  EXPECT_EQ(s["base"], "stage6");
  EXPECT_EQ(s["effects"], nlohmann::json::array({"gap_dependence"}));
  EXPECT_EQ(s["fit"]["method"], "output");
  EXPECT_EQ(s["fit"]["equation_error_start"]["model"], "base+gap");
  EXPECT_DOUBLE_EQ(s["parameters"]["inertia_zz_kgm2"]["value"].get<double>(),
                   oe["inertia_diag_kgm2"][2].get<double>());
  r = run_lpvid("stage6 fit --log " + log + " --method outptu");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--method outptu: use 'equation', 'output' or 'both'"));
}

// The time-domain route through the shared commands (issue 13): on a log with
// the default sensor noise and a hidden gap dependence, compare shows where the
// rigid-body model fails (failing windows on z and the tilts), diagnose --log
// names gap_dependence, fit --log (output error) brings gamma and the inertias
// to the truth within 3 of their standard errors, compare then finds no failing
// window and a residual at the noise (ratio to the noise floor ~1), and the
// history shows the error falling to its floor.  Truth: the simulator's
// parameters (docs/assumptions.md: H = diag(0.029, 0.029, 0.057) kg·m²,
// gamma = 2 pi / 0.0256 m), which the fit never sees.
TEST(Stage6IdentifyCli, TheTimeDomainRouteThroughFitDiagnoseCompareAndHistory) {
  TempDir d("stage6time");
  auto r = run_lpvid("simulate stage6 --experiment --out " + (d / "exp") + " --effects gap --seed 3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = d / "exp/exp_stage6.csv";
  ASSERT_EQ(run_lpvid("model init --base stage6 --out " + (d / "m.json")).exit_code, 0);

  r = run_lpvid("compare --model " + (d / "m.json") + " --log " + log + " --out-png " + (d / "rigid.png") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto c = nlohmann::json::parse(r.out);
  std::set<std::string> failing;
  for (const auto& f : c["failures"]) failing.insert(f["channel"].get<std::string>());
  EXPECT_TRUE(failing.count("z") && failing.count("theta") && failing.count("phi")) << c["failures"].dump();
  EXPECT_TRUE(std::filesystem::exists(d / "rigid.png"));
  EXPECT_FALSE(c["within_noise"].get<bool>()) << c["ratio_to_floor"];  // measured 8.0x

  r = run_lpvid("diagnose --model " + (d / "m.json") + " --log " + log + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto named = nlohmann::json::parse(r.out);
  EXPECT_EQ(named["missing"], "gap_dependence");
  // Judged against the noise floor, as the frequency route: the rigid body's output error
  // is far above it (measured 8.9x), the model with the gap effect within 1.5x (0.99x).
  EXPECT_GT(named["baseline"]["output_error"]["ratio_to_floor"].get<double>(), 3.0) << named["baseline"].dump();
  EXPECT_TRUE(named["explained"].get<bool>()) << named["with_missing_output_error"].dump();
  EXPECT_LT(named["with_missing_output_error"]["ratio_to_floor"].get<double>(), 1.5);

  ASSERT_EQ(run_lpvid("fit --model " + (d / "m.json") + " --log " + log + " --method equation --out " +
                      (d / "fit.json")).exit_code, 0);
  ASSERT_EQ(run_lpvid("model add gap_dependence --model " + (d / "fit.json") + " --out " + (d / "m2.json")).exit_code,
            0);
  r = run_lpvid("fit --model " + (d / "m2.json") + " --log " + log + " --out " + (d / "fit2.json") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["method"], "output");
  std::ifstream in(d / "fit2.json");
  const auto m = nlohmann::json::parse(in);
  const double gamma = 2 * M_PI / 0.0256;
  EXPECT_NEAR(m["parameters"]["gap_decay_per_m"]["value"].get<double>(), gamma,
              3 * m["fit"]["std_errors"]["gap_decay_per_m"].get<double>());
  const char* H[3] = {"inertia_xx_kgm2", "inertia_yy_kgm2", "inertia_zz_kgm2"};
  const double truth[3] = {0.029, 0.029, 0.057};
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(m["parameters"][H[i]]["value"].get<double>(), truth[i], 3 * m["fit"]["std_errors"][H[i]].get<double>())
        << H[i];

  r = run_lpvid("compare --params " + (d / "fit2.json") + " --log " + log + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  c = nlohmann::json::parse(r.out);
  EXPECT_TRUE(c["failures"].empty()) << c["failures"].dump();
  // White noise of level sigma: rms(e) / (rms(Δe)/√2) = 1 within its sampling
  // scatter (2000 samples: a few %); a model error makes it grow (rigid: 7–15).
  for (const auto& ch : c["channels"]) EXPECT_LT(ch["ratio_to_noise"].get<double>(), 1.1) << ch.dump();
  EXPECT_TRUE(c["within_noise"].get<bool>()) << c["ratio_to_floor"];  // measured 0.99x
  const double compared_error = c["error"].get<double>();

  r = run_lpvid("history --model " + (d / "fit2.json") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto h = nlohmann::json::parse(r.out)["fits"];
  ASSERT_EQ(h.size(), 2u);
  EXPECT_LT(h[1]["error"].get<double>(), 1.5 * h[1]["noise_floor"].get<double>());
  // compare --log reports the history's figure for the model it wrote: the same windows
  // and weights, the window states refitted at the written parameters (measured equal
  // to 3 digits; 1 %: the refitted states' convergence).
  EXPECT_NEAR(compared_error, h[1]["error"].get<double>(), 0.01 * h[1]["error"].get<double>());

  // Nothing is left: diagnose's --out has no model to hold, so it is not written and the
  // report says so (as on the frequency route).
  r = run_lpvid("diagnose --model " + (d / "fit2.json") + " --log " + log + " --json --out " + (d / "none.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto none = nlohmann::json::parse(r.out);
  EXPECT_FALSE(none["explained"].get<bool>()) << none["missing"].dump();
  EXPECT_TRUE(none["baseline_within_noise"].get<bool>()) << none["baseline"].dump();
  EXPECT_TRUE(none["missing"].is_null());
  EXPECT_FALSE(none["out_written"].get<bool>());
  EXPECT_FALSE(std::filesystem::exists(d / "none.json"));
}

// Two hidden effects at once (the gap dependence and the motors' electrical lag, seed
// 5, the default sensor noise): from the rigid body, diagnose --log names one of them
// but says the error with it is still above the noise floor (more is missing); from
// the model with that one, it names the other and the error is then within the floor;
// with both, nothing is missing.  Truth: the simulator's effects, which the fits never
// see; the floor: the residual's sample-to-sample part, the simulator's white sensor
// noise (1 nm, 1 nm, 10 nm, 0.1 urad x3).  Measured: 13.5x -> 19x (lag added; its
// output-error fit stops at its iteration cap far from the floor) and 19x -> 1.0x.
TEST(Stage6IdentifyCli, TheTimeRouteSaysWhenMoreIsMissingAndTheLoopEndsAtTheFloor) {
  TempDir d("stage6two");
  auto r = run_lpvid("simulate stage6 --experiment --out " + (d / "exp") + " --effects gap,lag --seed 5");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = d / "exp/exp_stage6.csv";
  r = run_lpvid("stage6 diagnose --log " + log + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto first = nlohmann::json::parse(r.out);
  ASSERT_TRUE(first["named"].get<bool>()) << r.out;
  const std::string one = first["missing"].get<std::string>();
  EXPECT_TRUE(one == "gap_dependence" || one == "electrical_lag") << one;
  EXPECT_FALSE(first["explained"].get<bool>());
  EXPECT_GT(first["with_missing_output_error"]["ratio_to_floor"].get<double>(), 1.5);
  const std::string other = one == "gap_dependence" ? "electrical_lag" : "gap_dependence";
  const std::string flag = one == "gap_dependence" ? "gap" : "lag";
  r = run_lpvid("stage6 diagnose --log " + log + " --effects " + flag + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto second = nlohmann::json::parse(r.out);
  EXPECT_EQ(second["missing"], other);
  EXPECT_TRUE(second["explained"].get<bool>()) << second["with_missing_output_error"].dump();
  r = run_lpvid("stage6 diagnose --log " + log + " --effects gap,lag --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto last = nlohmann::json::parse(r.out);
  EXPECT_TRUE(last["baseline_within_noise"].get<bool>()) << last["baseline"].dump();
  EXPECT_TRUE(last["missing"].is_null());
  for (const auto& c : last["candidates"]) EXPECT_FALSE(c["significant"].get<bool>()) << c.dump();
}

TEST(Stage6IdentifyCli, TheTimeDomainRouteRefusesWhatItCannotSimulate) {
  TempDir d("stage6timebad");
  auto r = run_lpvid("simulate stage6 --experiment --out " + (d / "exp") + " --duration-s 0.5 --seed 3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = d / "exp/exp_stage6.csv";
  ASSERT_EQ(run_lpvid("model init --base stage6 --out " + (d / "m.json")).exit_code, 0);
  ASSERT_EQ(run_lpvid("model add input_delay --model " + (d / "m.json") + " --out " + (d / "md.json")).exit_code, 0);
  r = run_lpvid("fit --model " + (d / "md.json") + " --log " + log + " --out " + (d / "f.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("effect input_delay of the model has no time-domain form"));
  EXPECT_FALSE(std::filesystem::exists(d / "f.json"));
  ASSERT_EQ(run_lpvid("model init --out " + (d / "p.json")).exit_code, 0);
  r = run_lpvid("diagnose --model " + (d / "p.json") + " --log " + log);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("is for models of base stage6, and this model's base is 'platform'"));
  r = run_lpvid("fit --model " + (d / "m.json") + " --log " + log + " --data x.csv@0 --out " + (d / "f.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("either --log (time domain) or --data/--datasets"));
  r = run_lpvid("fit --model " + (d / "m.json") + " --log " + log + " --out " + (d / "m.json"));
  EXPECT_EQ(r.exit_code, 2);
  r = run_lpvid("compare --model " + (d / "m.json") + " --log " + log + " --controller " + (d / "m.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("no controller is needed"));
}

TEST(Stage6IdentifyCli, BadInputsGiveOneLineAndExitTwo) {
  TempDir d("stage6bad");
  auto r = run_lpvid("stage6 fit --log " + (d / "missing.csv") + " --out " + (d / "s.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("missing.csv"));
  EXPECT_FALSE(std::filesystem::exists(d / "s.json"));
  r = run_lpvid("stage6 diagnose --log " + (d / "missing.csv") + " --effects warp");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown stage effect 'warp'"));
}

}  // namespace stage6_identify_test
}  // namespace lpvid

namespace lpvid {
namespace stage6_identify_test {

// The stage through the SAME commands as the platform (issue 13): the plant from
// one closed-loop log by `frf --input`, `model init --base stage6`, `diagnose`
// names the hidden gap dependence, `model add` + `fit` bring the error to the noise,
// `compare` against the simulator's truth model finds nothing beyond the noise.
TEST(Stage6LoopCli, TheSharedCommandsNameTheHiddenGapDependenceAndTheErrorFallsToTheNoise) {
  TempDir d("stage6loop");
  auto r = run_lpvid("simulate stage6 --experiment --hover --duration-s 30 --effects gap --seed 4 --out " +
                     (d / "rig"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("frf --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,q2,q3,q4,q5,q6 "
                "--quantity P --segment 512 --out " + (d / "P.csv") + " " + (d / "rig/exp_stage6.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string data = " --data " + (d / "P.csv") + "@0 --rate-hz 1000";
  ASSERT_EQ(run_lpvid("model init --base stage6 --out " + (d / "model.json")).exit_code, 0);
  r = run_lpvid("diagnose --model " + (d / "model.json") + data + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["missing"], "gap_dependence") << r.out.substr(0, 2000);
  EXPECT_TRUE(j["explained"].get<bool>());
  ASSERT_EQ(run_lpvid("model add gap_dependence --model " + (d / "model.json") + " --out " + (d / "start2.json"))
                .exit_code,
            0);
  r = run_lpvid("fit --model " + (d / "start2.json") + data + " --out " + (d / "fit2.json") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto f = nlohmann::json::parse(r.out);
  // Within the noise: the weighted cost per real residual (a χ² per degree of
  // freedom when the noise is known) near 1 (the sample: 0.96).
  EXPECT_LT(f["cost_final"].get<double>() / f["residuals"].get<double>(), 1.5) << r.out.substr(0, 2000);
  r = run_lpvid("compare --model " + (d / "rig/truth_model.json") + data);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("no failing band"));
}

// Issue 25: the stage's noise floor from Welch is driven by its lowest lines
// (leakage near the closed-loop poles) and hides model errors of a few percent. On
// the walkthrough's rig (samples/stage6-loop.sh: 60 s, gap hidden) the Local
// Polynomial Method on the whole record estimates the same plant with a floor 5.8x
// lower (measured 3.43 % Welch, 0.591 % LPM, both over 3-3142 rad/s), and the stage
// with its gap dependence, fitted from the simulator's truth, sits within the LPM
// floor (0.606 %: 1.03x).  Asserted: the LPM floor below 1 % and at least 3x below
// Welch's (room for the noise draw), the fit within 1.5x the LPM floor (the
// project's "within the noise").
TEST(Stage6LoopCli, TheLocalPolynomialMethodGivesAFloorThatHidesNothingAtTheLowestLines) {
  TempDir d("stage6lpm");
  auto r = run_lpvid("simulate stage6 --experiment --hover --duration-s 60 --effects gap --inertia-kgm2 "
                     "0.034,0.025,0.061 --force-constant-scale 1.04 --seed 3 --out " + (d / "rig"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string channels = " --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 "
                               "--output q1,q2,q3,q4,q5,q6 --quantity P ";
  r = run_lpvid("frf" + channels + "--segment 2048 --out " + (d / "P.csv") + " " + (d / "rig/exp_stage6.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("frf --method lpm --lpm-stride 8" + channels + "--out " + (d / "P_lpm.csv") + " " +
                (d / "rig/exp_stage6.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto fit = [&](const std::string& data) {
    const auto f = run_lpvid("fit --model " + (d / "rig/truth_model.json") + " --data " + (d / data) +
                             "@0 --rate-hz 1000 --band-min 3 --out " + (d / ("fit_" + data + ".json")) + " --json");
    EXPECT_EQ(f.exit_code, 0) << f.err;
    return nlohmann::json::parse(f.out);
  };
  const auto welch = fit("P.csv"), lpm = fit("P_lpm.csv");
  const double fw = welch["noise_floor"].get<double>(), fl = lpm["noise_floor"].get<double>();
  std::printf("floor: Welch %.3f %%, LPM %.3f %%; fitted error on LPM %.3f %%\n", 100 * fw, 100 * fl,
              100 * lpm["error"].get<double>());
  EXPECT_LT(fl, 0.01);
  EXPECT_LT(3 * fl, fw);
  EXPECT_LT(lpm["error"].get<double>(), 1.5 * fl) << lpm.dump().substr(0, 2000);
}

}  // namespace stage6_identify_test
}  // namespace lpvid
