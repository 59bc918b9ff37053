// The model-error loop through the program, on analyzer data with a hidden
// effect: simulate platform --truth-model (a 1 ms input delay the start model
// lacks) -> fit -> diagnose names input_delay -> model add -> fit -> the error
// falls -> history lists both fits -> diagnose finds nothing more.  Plus the
// bad-input paths of diagnose.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace diagnose_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

class DiagnoseLoop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("diagnose");
    const TempDir& d = *dir_;
    ASSERT_EQ(run_lpvid("model init --out " + (d / "truth.json")).exit_code, 0);
    ASSERT_EQ(run_lpvid("model add input_delay --model " + (d / "truth.json")).exit_code, 0);
    // The truth: a one-sample (1 ms) computation delay (the user edits the file).
    auto truth = nlohmann::json::parse(slurp(d / "truth.json"));
    truth["parameters"]["input_delay_s"]["value"] = 1e-3;
    std::ofstream(d / "truth.json") << truth.dump(2);
    // 16 averages, 4 s per frequency: ~0.12 % noise on S (idlib/sim/analyzer.h).
    const auto sim = run_lpvid("simulate platform --out " + (d / "data") +
                               " --truth-model " + (d / "truth.json") +
                               " --duration-s 1 --analyzer --analyzer-averages 16 --analyzer-integration-s 4 --seed 5");
    ASSERT_EQ(sim.exit_code, 0) << sim.err;
    ASSERT_EQ(run_lpvid("model init --out " + (d / "start.json")).exit_code, 0);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string data_args() {
    std::string args = " --target S --controller " + (*dir_ / "data/middle_1000hz/controller.json");
    const char* pos[3][2] = {{"left", "-0.1"}, {"middle", "0"}, {"right", "0.1"}};
    for (const auto& p : pos) {
      const std::string f = *dir_ / (std::string("data/") + p[0] + "_1000hz/S_v");
      args += " --data " + f + "1.csv," + f + "2.csv," + f + "3.csv@" + p[1];
    }
    return args;
  }
  static TempDir* dir_;
};
TempDir* DiagnoseLoop::dir_ = nullptr;

TEST_F(DiagnoseLoop, NamesTheHiddenDelayThenTheErrorFallsAndNothingIsLeft) {
  const TempDir& d = *dir_;
  const auto fit1 = run_lpvid("fit --model " + (d / "start.json") + data_args() + " --out " + (d / "m1.json"));
  ASSERT_EQ(fit1.exit_code, 0) << fit1.err;

  const auto diag = run_lpvid("diagnose --model " + (d / "m1.json") + data_args() + " --averages 16 --json");
  ASSERT_EQ(diag.exit_code, 0) << diag.err;
  const auto j = nlohmann::json::parse(diag.out);
  EXPECT_TRUE(j["explained"].get<bool>());
  EXPECT_EQ(j["missing"], "input_delay");
  const auto& best = j["candidates"][0];
  // The delay estimate within 1 % of the truth's 1 ms (its σ is ~0.4 µs here).
  EXPECT_NEAR(best["parameters"][0]["estimate"].get<double>(), 1e-3, 1e-5);
  EXPECT_GT(j["baseline_failures"].size(), 0u);
  EXPECT_EQ(j["remaining_failures"].size(), 0u);
  // The error falls at least 10x (issue 5; the noise floor is ~0.1 % of S).
  EXPECT_LT(best["error"].get<double>(), j["baseline"]["error"].get<double>() / 10.0);

  ASSERT_EQ(run_lpvid("model add input_delay --model " + (d / "m1.json")).exit_code, 0);
  const auto fit2 = run_lpvid("fit --model " + (d / "m1.json") + data_args() + " --out " + (d / "m2.json"));
  ASSERT_EQ(fit2.exit_code, 0) << fit2.err;

  const auto hist = run_lpvid("history --model " + (d / "m2.json") + " --json");
  ASSERT_EQ(hist.exit_code, 0) << hist.err;
  const auto h = nlohmann::json::parse(hist.out);
  ASSERT_EQ(h["fits"].size(), 2u);  // the start's fit carried over, then this one
  EXPECT_LT(h["fits"][1]["error_mean"].get<double>(), h["fits"][0]["error_mean"].get<double>() / 10.0);

  // Nothing is left: --out has no model to hold, so it is not written and the run says
  // so; the report asked for is still written and the run succeeds (as the time route).
  const auto again = run_lpvid("diagnose --model " + (d / "m2.json") + data_args() + " --averages 16 --json --out " +
                               (d / "m3.json") + " --report " + (d / "again.json"));
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const auto k = nlohmann::json::parse(again.out);
  EXPECT_FALSE(k["explained"].get<bool>());
  EXPECT_EQ(k["baseline_failures"].size(), 0u);
  EXPECT_FALSE(k["out_written"].get<bool>());
  EXPECT_FALSE(std::filesystem::exists(d / "m3.json"));
  EXPECT_FALSE(std::filesystem::exists(d / "m3.json.history.jsonl"));
  EXPECT_EQ(nlohmann::json::parse(slurp(d / "again.json"))["summary"], k["summary"]);
  const auto text = run_lpvid("diagnose --model " + (d / "m2.json") + data_args() + " --averages 16 --out " +
                              (d / "m3.json"));
  ASSERT_EQ(text.exit_code, 0) << text.err;
  EXPECT_THAT(text.out, HasSubstr("nothing named: " + (d / "m3.json") + " not written (no candidate is significant"));
  // standard output asked for the model: nothing to print in its place, so the run fails
  // with one line and writes nothing
  const auto piped = run_lpvid("diagnose --model " + (d / "m2.json") + data_args() + " --averages 16 --out - --report " +
                               (d / "never.json"));
  EXPECT_EQ(piped.exit_code, 1);
  EXPECT_THAT(piped.err, HasSubstr("no candidate is significant, so there is no model to write to --out -"));
  EXPECT_EQ(std::count(piped.err.begin(), piped.err.end(), '\n'), 1) << piped.err;
  EXPECT_TRUE(piped.out.empty()) << piped.out;
  EXPECT_FALSE(std::filesystem::exists(d / "never.json"));
}

// The next step keeps the promise (issue 25): `model add EFFECT --from-diagnosis
// REPORT.json` starts every parameter where diagnose's refit of that candidate
// ended, so the user's `fit` reaches (within 5 %) the error diagnose reported; a
// report without the candidate, or made on another model, is refused in one line.
TEST_F(DiagnoseLoop, ModelAddFromTheDiagnosisReachesTheErrorDiagnoseReported) {
  const TempDir& d = *dir_;
  ASSERT_EQ(run_lpvid("fit --model " + (d / "start.json") + data_args() + " --out " + (d / "p1.json")).exit_code, 0);
  const auto diag = run_lpvid("diagnose --model " + (d / "p1.json") + data_args() + " --averages 16 --json --out " +
                              (d / "p1d.json"));
  ASSERT_EQ(diag.exit_code, 0) << diag.err;
  std::ofstream(d / "report.json") << diag.out;
  const auto j = nlohmann::json::parse(diag.out);
  ASSERT_EQ(j["missing"], "input_delay");
  // diagnose --out continues the lineage: p1's fit, then the winner's refit.
  const auto hist = run_lpvid("history --model " + (d / "p1d.json") + " --json");
  ASSERT_EQ(hist.exit_code, 0) << hist.err;
  const auto fits = nlohmann::json::parse(hist.out)["fits"];
  ASSERT_EQ(fits.size(), 2u) << hist.out;
  EXPECT_EQ(fits[1]["model"], d / "p1d.json");
  EXPECT_NEAR(fits[1]["error"].get<double>(), j["candidates"][0]["error"].get<double>(), 1e-12);
  const double promised = j["candidates"][0]["error"].get<double>();

  const auto add = run_lpvid("model add input_delay --model " + (d / "p1.json") + " --from-diagnosis " +
                             (d / "report.json") + " --out " + (d / "p2.json"));
  ASSERT_EQ(add.exit_code, 0) << add.err;
  EXPECT_THAT(add.out, HasSubstr("every parameter from"));
  const auto m = nlohmann::json::parse(slurp(d / "p2.json"));
  EXPECT_NEAR(m["parameters"]["input_delay_s"]["value"].get<double>(),
              j["candidates"][0]["values"]["input_delay_s"].get<double>(), 1e-15);
  const auto fit = run_lpvid("fit --model " + (d / "p2.json") + data_args() + " --out " + (d / "p3.json") + " --json");
  ASSERT_EQ(fit.exit_code, 0) << fit.err;
  const double reached = nlohmann::json::parse(fit.out)["error"].get<double>();
  std::printf("diagnose promised %.5f %%, the refit from its values reached %.5f %%\n", 100 * promised, 100 * reached);
  EXPECT_LE(reached, 1.05 * promised);

  // no such candidate: the report's are listed; nothing written
  auto r = run_lpvid("model add input_delay,actuator_lag --model " + (d / "p1.json") + " --from-diagnosis " +
                     (d / "report.json") + " --out " + (d / "never.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("no candidate 'input_delay + actuator_lag' in this report (it has: "));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(std::filesystem::exists(d / "never.json"));
  // made on another model (this one has rod_twist too)
  ASSERT_EQ(run_lpvid("model add rod_twist --model " + (d / "p1.json") + " --out " + (d / "other.json")).exit_code, 0);
  r = run_lpvid("model add input_delay --model " + (d / "other.json") + " --from-diagnosis " + (d / "report.json") +
                " --out " + (d / "never.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("was fitted on another model (it lacks twist_stiffness_psi_Nm_per_rad"));
  EXPECT_FALSE(std::filesystem::exists(d / "never.json"));
  // not a report
  r = run_lpvid("model add input_delay --model " + (d / "p1.json") + " --from-diagnosis " + (d / "p1.json") +
                " --out " + (d / "never.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("not a diagnose report"));
  EXPECT_FALSE(std::filesystem::exists(d / "never.json"));
}

TEST_F(DiagnoseLoop, BadInputsGiveOneLineAndExitTwoAndWriteNothing) {
  const TempDir& d = *dir_;
  const std::string out = d / "never.json";
  auto r = run_lpvid("diagnose --model " + (d / "start.json") + data_args() + " --candidates warp_drive --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown effect 'warp_drive'"));
  r = run_lpvid("diagnose --model " + (d / "start.json") + " --data " + (d / "data/left_1000hz/S_v1.csv") +
                " --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("missing @x_b tag"));
  r = run_lpvid("diagnose --model " + (d / "start.json") + data_args() + " --candidates beam_gravity --out " + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("already has effect 'beam_gravity'"));
  r = run_lpvid("diagnose --model " + (d / "start.json") + data_args() + " --out " + (d / "start.json"));
  EXPECT_EQ(r.exit_code, 2);  // the output would overwrite the input
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace diagnose_test
}  // namespace lpvid
