// lpvid fit and lpvid model through the program: simulated data with known truth.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "formats/io/frd_csv.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "idlib/fit/fit.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/evaluate.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"
#include "tests/cli/effect_fixture.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace fit_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

constexpr double kRecovery = 0.01;  // the issue's 1 % on noise-free data

PhysicalModel truth_model() {
  PhysicalModel m = platform_defaults_model();
  m.parameter("com_x_m").value = 0.006;
  m.parameter("com_y_m").value = -0.004;
  return m;
}

// Plant FRD files (ZOH at 1 kHz) at the paper's three positions; returns the --data arguments.
std::string write_plant_frds(const TempDir& dir, const PhysicalModel& truth) {
  const Eigen::VectorXd w = log_frequency_grid(2.0, 600.0, 100);
  std::string args;
  const char* names[3] = {"P_left.csv", "P_mid.csv", "P_right.csv"};
  for (int i = 0; i < 3; ++i) {
    FrequencyResponse f;
    f.omega_rad_s = w;
    f.response = physical_response(truth, kPaperBeamPositions_m[static_cast<std::size_t>(i)], w, 1e-3);
    f.input_names = {"T_psi", "T_theta", "F_z"};
    f.output_names = {"psi", "theta", "z"};
    write_frd_csv(dir / names[i], f, "P");
    args += fmt::format(" --data {}@{}", dir / names[i], kPaperBeamPositions_m[static_cast<std::size_t>(i)]);
  }
  return args;
}

PhysicalModel two_times_off(const PhysicalModel& truth) {
  PhysicalModel m = truth;
  int k = 0;
  for (auto& p : m.parameters)
    if (p.free) p.value = std::clamp(k++ % 2 == 0 ? 2.0 * p.value : 0.5 * p.value, p.lower, p.upper);
  return m;
}

TEST(FitCli, FrdAtThreePositionsRecoversTruthAndWritesModelPlotAndBands) {
  TempDir dir("fit");
  const PhysicalModel truth = truth_model();
  const std::string data = write_plant_frds(dir, truth);
  write_physical_model(dir / "start.json", two_times_off(truth));
  const auto r = run_lpvid(fmt::format("fit --model {} {} --rate-hz 1000 --out {} --plot {} --bands {}",
                                       dir / "start.json", data, dir / "fitted.json", dir / "fit.png",
                                       dir / "bands.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("parameter"));
  EXPECT_THAT(r.out, HasSubstr("per-channel relative rms error"));
  const PhysicalModel fitted = read_physical_model(dir / "fitted.json");
  for (const auto& p : fitted.parameters)
    if (p.free) {
      EXPECT_NEAR(p.value, truth.parameter(p.name).value, kRecovery * std::max(std::abs(p.value), 1e-3)) << p.name;
    }
  const std::string text = lpvid::testing::slurp(dir / "fitted.json");
  EXPECT_THAT(text, HasSubstr("\"fit\""));
  EXPECT_THAT(text, HasSubstr("\"std_error\""));
  EXPECT_GT(std::filesystem::file_size(dir / "fit.png"), 10000u);
  const std::string bands = lpvid::testing::slurp(dir / "bands.csv");
  EXPECT_THAT(bands, HasSubstr("x_b_m,freq_hz,output,input,magnitude,magnitude_sigma"));
}

TEST(FitCli, ClosedLoopSensitivityTargetThroughTheController) {
  TempDir dir("fit_s");
  const PhysicalModel truth = truth_model();
  FitOptions o;
  o.target = FitTarget::kInputSensitivity;
  o.sample_period_s = 1e-3;
  o.controller = discrete_pi_controller(default_pi_gains(platform_parameters(truth)), 1e-3);
  write_state_space(dir / "C.json", *o.controller);
  const Eigen::VectorXd w = log_frequency_grid(2.0, 600.0, 100);
  std::string data;
  for (double xb : kPaperBeamPositions_m) {
    const auto path = dir / fmt::format("S_{}.csv", xb);
    write_frd_csv(path, target_response(truth, xb, w, o), "S");
    data += fmt::format(" --data {}@{}", path, xb);
  }
  write_physical_model(dir / "start.json", two_times_off(truth));
  // The ZOH rate comes from the discrete controller.
  const auto r = run_lpvid(fmt::format("fit --model {} {} --target S --controller {} --out {} --json",
                                       dir / "start.json", data, dir / "C.json", dir / "fitted.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("\"sample_period_s\": 0.001"));
  EXPECT_THAT(r.out, HasSubstr("\"target\": \"S\""));
  const PhysicalModel fitted = read_physical_model(dir / "fitted.json");
  for (const auto& p : fitted.parameters)
    if (p.free) {
      EXPECT_NEAR(p.value, truth.parameter(p.name).value, kRecovery * std::max(std::abs(p.value), 1e-3)) << p.name;
    }
}

// The controller's measured response (FRD) on exactly the data's lines stands in for the
// model: C.csv holds the state-space controller's own response on those lines, written
// with round-trip precision, so fit and compare must agree with the model route (the
// existing, independently tested one: S data through C(e^{jωTs}) of the model).
// S data of the sampled loop (ZOH at 1 kHz, the discrete PI controllers) at the paper's
// positions on the lines w, with the controller as C.json and as its FRD C.csv on w;
// returns the --data arguments.
std::string write_sampled_loop_s_data(const TempDir& dir, const PhysicalModel& truth, const Eigen::VectorXd& w) {
  FitOptions o;
  o.target = FitTarget::kInputSensitivity;
  o.sample_period_s = 1e-3;
  const StateSpace c = discrete_pi_controller(default_pi_gains(platform_parameters(truth)), 1e-3);
  o.controller = c;
  write_state_space(dir / "C.json", c);
  write_frd_csv(dir / "C.csv", frequency_response(c, w), "C");
  std::string data;
  for (double xb : kPaperBeamPositions_m) {
    const auto path = dir / fmt::format("S_{}.csv", xb);
    write_frd_csv(path, target_response(truth, xb, w, o), "S");
    data += fmt::format(" --data {}@{}", path, xb);
  }
  return data;
}

TEST(FitCli, MeasuredControllerOnTheDataLinesGivesTheModelControllersFit) {
  TempDir dir("fit_cfrd");
  const PhysicalModel truth = truth_model();
  const Eigen::VectorXd w = log_frequency_grid(2.0, 600.0, 40);
  const std::string data = write_sampled_loop_s_data(dir, truth, w);
  Eigen::VectorXd shifted = w;
  shifted(17) *= 1.0 + 1e-6;  // one line off by 1e-6 relative (> the 1e-9 allowed)
  write_frd_csv(dir / "C_off.csv",
                frequency_response(discrete_pi_controller(default_pi_gains(platform_parameters(truth)), 1e-3), shifted),
                "C");
  PhysicalModel start = truth;
  for (auto& p : start.parameters)
    if (p.free) p.value = std::clamp(1.2 * p.value, p.lower, p.upper);
  write_physical_model(dir / "start.json", start);
  // A measured controller carries no sample period: --rate-hz gives it (to both runs).
  auto fit = [&](const char* controller, const char* out) {
    return run_lpvid(fmt::format("fit --model {} {} --target S --controller {} --rate-hz 1000 --no-global --out {}",
                                 dir / "start.json", data, dir / controller, dir / out));
  };
  const auto model_run = fit("C.json", "by_model.json");
  ASSERT_EQ(model_run.exit_code, 0) << model_run.err;
  const auto frd_run = fit("C.csv", "by_frd.json");
  ASSERT_EQ(frd_run.exit_code, 0) << frd_run.err;
  const PhysicalModel by_model = read_physical_model(dir / "by_model.json");
  const PhysicalModel by_frd = read_physical_model(dir / "by_frd.json");
  Index free = 0;
  for (const auto& p : by_model.parameters)
    if (p.free) {
      ++free;
      // The two controllers differ only by the CSV round trip (~1e-16 relative), so the
      // fits agree to round-off; 1e-9 leaves room for LM's path through that round-off.
      // Parameters whose truth is 0 (stiffness centre, damping couplings) end at ~1e-12 in
      // both runs: relative to their bounds' span there (all finite on this base).
      const double span = p.upper - p.lower;
      EXPECT_NEAR(by_frd.parameter(p.name).value, p.value,
                  1e-9 * std::max(std::abs(p.value), std::isfinite(span) ? span : 0.0))
          << p.name;
      // And both recover the truth (noise-free data; the 1 % of the issue).
      EXPECT_NEAR(p.value, truth.parameter(p.name).value, kRecovery * std::max(std::abs(p.value), 1e-3)) << p.name;
    }
  EXPECT_GT(free, 0);

  // compare --model ... --target S --controller C.csv: the same error figure as with C.json.
  auto compare = [&](const char* controller) {
    const auto r = run_lpvid(fmt::format("compare --model {} {} --target S --controller {} --rate-hz 1000 "
                                         "--noise-level 0.01 --json",
                                         dir / "start.json", data, dir / controller));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.exit_code == 0 ? nlohmann::json::parse(r.out).at("error").get<double>() : -1.0;
  };
  const double e_model = compare("C.json"), e_frd = compare("C.csv");
  EXPECT_GT(e_model, 0.0);  // the start is 20 % off: a visible error
  EXPECT_NEAR(e_frd, e_model, 1e-9 * e_model);

  // diagnose through either controller: the same report (the fitted model is within the
  // noise; one candidate keeps this cheap).
  auto diagnose = [&](const char* controller) {
    const auto r = run_lpvid(fmt::format("diagnose --model {} {} --target S --controller {} --rate-hz 1000 "
                                         "--noise-level 0.01 --candidates input_delay",
                                         dir / "by_model.json", data, dir / controller));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out;
  };
  const std::string d_model = diagnose("C.json");
  EXPECT_THAT(d_model, HasSubstr("input_delay"));
  EXPECT_EQ(diagnose("C.csv"), d_model);

  // A controller measured on other lines is refused before anything is written.
  const auto off = fit("C_off.csv", "off.json");
  EXPECT_EQ(off.exit_code, 2);
  EXPECT_THAT(off.err, HasSubstr("C_off.csv: line 18 is"));
  EXPECT_THAT(off.err, HasSubstr("measure the controller at the data's frequency lines"));
  EXPECT_EQ(std::count(off.err.begin(), off.err.end(), '\n'), 1) << off.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "off.json"));
  const auto off_compare = run_lpvid(fmt::format("compare --model {} {} --target S --controller {} --rate-hz 1000 "
                                                 "--noise-level 0.01 --out {}",
                                                 dir / "start.json", data, dir / "C_off.csv", dir / "cmp.json"));
  EXPECT_EQ(off_compare.exit_code, 2);
  EXPECT_THAT(off_compare.err, HasSubstr("line 18"));
  EXPECT_FALSE(std::filesystem::exists(dir / "cmp.json"));
}

// A measured controller (FRD) carries no sample period.  Without --rate-hz the model's
// continuous response stands in for a loop that ran sampled: one warning line on stderr
// then, and none when the rate is known (the flag, or a discrete controller model).  The
// truth behind the warning: S data of the sampled loop (ZOH at 1 kHz, the discrete PI
// controllers) against the TRUE model give an error figure near 0 with --rate-hz 1000
// and a clearly larger one without (the continuous response misses the ZOH's lag).
TEST(FitCli, MeasuredControllerWithoutRateWarnsOnceOnStderr) {
  TempDir dir("fit_cwarn");
  const PhysicalModel truth = truth_model();
  const std::string data = write_sampled_loop_s_data(dir, truth, log_frequency_grid(2.0, 2000.0, 30));
  write_physical_model(dir / "truth.json", truth);
  struct Run {
    std::string err;
    double error = -1.0;
  };
  auto compare = [&](const std::string& controller, const std::string& extra) {
    const auto r = run_lpvid(fmt::format("compare --model {} {} --target S --controller {} --noise-level 0.01 "
                                         "--json {}",
                                         dir / "truth.json", data, dir / controller, extra));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return Run{r.err, r.exit_code == 0 ? nlohmann::json::parse(r.out).at("error").get<double>() : -1.0};
  };
  const std::string warning = "is a measured response with no sample rate and no --rate-hz was given";
  const Run bare = compare("C.csv", "");
  EXPECT_THAT(bare.err, HasSubstr(warning));
  EXPECT_THAT(bare.err, HasSubstr("give --rate-hz with the controller's sample rate"));
  EXPECT_EQ(std::count(bare.err.begin(), bare.err.end(), '\n'), 1) << bare.err;
  const Run rated = compare("C.csv", "--rate-hz 1000");
  EXPECT_EQ(rated.err, "");
  const Run model = compare("C.json", "");  // the discrete model gives the rate
  EXPECT_EQ(model.err, "");
  // The truth with the right rate fits its own noise-free data (error figure ~ round-off);
  // the continuous response does not: 10x is far below the measured ratio (see docs).
  EXPECT_GT(bare.error, 10.0 * rated.error + 1e-6) << bare.error << " vs " << rated.error;
  std::fprintf(stderr, "[warning] compare error: continuous %.3g, --rate-hz 1000 %.3g\n", bare.error, rated.error);
  // fit warns the same way (one line, before its summary on stdout).
  const auto f = run_lpvid(fmt::format("fit --model {} {} --target S --controller {} --no-global --max-iterations 1 "
                                       "--out {}",
                                       dir / "truth.json", data, dir / "C.csv", dir / "fitted.json"));
  EXPECT_EQ(f.exit_code, 0) << f.err;
  EXPECT_EQ(std::count(f.err.begin(), f.err.end(), '\n'), 1) << f.err;
  EXPECT_THAT(f.err, HasSubstr(warning));
}

TEST(FitCli, MissingXbTagIsExit2WithOneLineAndNoOutput) {
  TempDir dir("fit_bad");
  write_physical_model(dir / "start.json", platform_defaults_model());
  const auto r = run_lpvid(fmt::format("fit --model {} --data P.csv --out {}", dir / "start.json", dir / "out.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("missing @x_b tag"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(count_files(dir.path()), 1);
}

TEST(FitCli, BadModelFilesAreExit2WithFileLineColumn) {
  TempDir dir("fit_badmodel");
  const std::string good = physical_model_to_json(platform_defaults_model());
  const std::string data = write_plant_frds(dir, truth_model());
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"\"damping_z_Ns_per_m\"", "\"damping_z\""},                            // unknown parameter
      {"\"lower\": 0.001, \"upper\": 1000000.0", "\"lower\": 1000000, \"upper\": 0.001"},  // bounds reversed
      {"\"value\": 1500.0,", "\"value\": 1e9,"},                               // value outside bounds
  };
  for (const auto& [from, to] : cases) {
    std::string text = good;
    text.replace(text.find(from), from.size(), to);
    lpvid::testing::TempDir sub("m");
    {
      std::ofstream(sub / "bad.json") << text;
    }
    const auto r = run_lpvid(fmt::format("fit --model {} {} --out {}", sub / "bad.json", data, sub / "out.json"));
    EXPECT_EQ(r.exit_code, 2) << to;
    EXPECT_THAT(r.err, HasSubstr(sub / "bad.json:")) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(sub / "out.json"));
  }
}

TEST(FitCli, TargetSWithoutControllerIsExit2) {
  TempDir dir("fit_noc");
  write_physical_model(dir / "start.json", platform_defaults_model());
  const auto r = run_lpvid(fmt::format("fit --model {} --target S --data S.csv@0 --out {}", dir / "start.json",
                                       dir / "out.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--controller"));
}

TEST(ModelCli, InitAddEffectsAndExport) {
  TempDir dir("model");
  ASSERT_EQ(run_lpvid(fmt::format("model init --out {}", dir / "m.json")).exit_code, 0);
  const auto add = run_lpvid(fmt::format("model add input_delay --model {}", dir / "m.json"));
  ASSERT_EQ(add.exit_code, 0) << add.err;
  EXPECT_TRUE(read_physical_model(dir / "m.json").has_effect("input_delay"));
  const auto unknown = run_lpvid(fmt::format("model add friction --model {}", dir / "m.json"));
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_THAT(unknown.err, HasSubstr("unknown effect 'friction'"));
  const auto effects = run_lpvid("model effects");
  EXPECT_EQ(effects.exit_code, 0);
  EXPECT_THAT(effects.out, HasSubstr("structural_mode"));
  const auto exp = run_lpvid(fmt::format("model export --model {} --xb 0.05 --rate-hz 1000 --out {}", dir / "m.json",
                                         dir / "ss.json"));
  ASSERT_EQ(exp.exit_code, 0) << exp.err;
  const StateSpace ss = read_state_space(dir / "ss.json");
  // Default delay 0.5 ms at 1 kHz: half a sample, the input switching mid-sample: one
  // register per input (u[k-1]) beside the 6 rigid-body states.
  EXPECT_EQ(ss.order(), 9);
  EXPECT_EQ(ss.sample_period_s, 1e-3);
  const auto out_of_stroke =
      run_lpvid(fmt::format("model export --model {} --xb 0.5 --out {}", dir / "m.json", dir / "x.json"));
  EXPECT_EQ(out_of_stroke.exit_code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
}

TEST(ModelCli, AddAndRemoveToANewFileKeepTheLineageAndInitTakesDesignValues) {
  TempDir dir("model_lineage");
  ASSERT_EQ(run_lpvid(fmt::format("model init --out {} --set k_torque_low_Nm_per_rad=45 --set beam_height_m=0.06",
                                  dir / "m.json"))
                .exit_code,
            0);
  const PhysicalModel m = read_physical_model(dir / "m.json");
  EXPECT_EQ(m.parameter("k_torque_low_Nm_per_rad").value, 45.0);
  EXPECT_EQ(m.parameter("beam_height_m").value, 0.06);
  // a fitted model with a history, then add to a new file: the history continues
  const std::string history =
      "{\"timestamp\":\"2026-11-23T12:00:00Z\",\"model\":\"m.json\",\"effects\":[],\"free_parameters\":3,"
      "\"cost\":1,\"error_mean\":0.01,\"error_max\":0.02}\n";
  { std::ofstream(dir / "m.json.history.jsonl") << history; }
  const auto add = run_lpvid(fmt::format("model add input_delay --model {} --out {}", dir / "m.json", dir / "m2.json"));
  ASSERT_EQ(add.exit_code, 0) << add.err;
  EXPECT_FALSE(read_physical_model(dir / "m.json").has_effect("input_delay"));  // the source is unchanged
  EXPECT_TRUE(read_physical_model(dir / "m2.json").has_effect("input_delay"));
  EXPECT_EQ(lpvid::testing::slurp(dir / "m2.json.history.jsonl"), history);
  const auto rem = run_lpvid(fmt::format("model remove input_delay --model {}", dir / "m2.json"));
  ASSERT_EQ(rem.exit_code, 0) << rem.err;
  EXPECT_FALSE(read_physical_model(dir / "m2.json").has_effect("input_delay"));
  const auto again = run_lpvid(fmt::format("model remove input_delay --model {}", dir / "m2.json"));
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_THAT(again.err, HasSubstr("no effect 'input_delay' to remove"));
  const auto bad_set = run_lpvid(fmt::format("model init --out {} --set beam_height_m=9", dir / "x.json"));
  EXPECT_EQ(bad_set.exit_code, 2);
  EXPECT_THAT(bad_set.err, HasSubstr("outside the bounds"));
  EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
}

// Priors (issue 25): NAME=VALUE±SIGMA (or +-) in init and set, kept in the file,
// bad ones refused with the file unchanged.
TEST(ModelCli, SetGivesDesignValuesWithPriorsAndRefusesBadOnesLeavingTheFile) {
  TempDir dir("model_prior");
  ASSERT_EQ(run_lpvid(fmt::format("model init --out {} --set platform_mass_kg=5.3±0.05", dir / "m.json")).exit_code, 0);
  PhysicalModel m = read_physical_model(dir / "m.json");
  EXPECT_EQ(m.parameter("platform_mass_kg").value, 5.3);
  EXPECT_EQ(m.parameter("platform_mass_kg").prior_mean, 5.3);
  EXPECT_EQ(m.parameter("platform_mass_kg").prior_sigma, 0.05);
  EXPECT_FALSE(m.parameter("beam_mass_kg").has_prior());
  const auto set = run_lpvid(fmt::format("model set --model {} --set beam_mass_kg=0.8+-0.01 --set beam_height_m=0.05",
                                         dir / "m.json"));
  ASSERT_EQ(set.exit_code, 0) << set.err;
  EXPECT_THAT(set.out, HasSubstr("beam_mass_kg = 0.8 kg (prior 0.8 ± 0.01)"));
  m = read_physical_model(dir / "m.json");
  EXPECT_EQ(m.parameter("beam_mass_kg").prior_sigma, 0.01);
  EXPECT_EQ(m.parameter("platform_mass_kg").prior_sigma, 0.05);  // kept
  EXPECT_EQ(m.parameter("beam_height_m").value, 0.05);
  const std::string before = lpvid::testing::slurp(dir / "m.json");
  for (const char* bad : {"beam_mass_kg=0.8±", "beam_mass_kg=0.8±-1", "beam_mass_kg=0.8±x", "beam_mass_kg=0.8±0"}) {
    const auto r = run_lpvid(fmt::format("model set --model {} --set {}", dir / "m.json", bad));
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_THAT(r.err, HasSubstr("is not a number > 0; write NAME=VALUE±SIGMA")) << bad;
  }
  EXPECT_EQ(lpvid::testing::slurp(dir / "m.json"), before);
  // --fix / --free: the free flag, as the error messages of fit tell a user to set it
  const auto fix = run_lpvid(fmt::format("model set --model {} --fix beam_mass_kg,beam_height_m --out {}", dir / "m.json",
                                         dir / "fixed.json"));
  ASSERT_EQ(fix.exit_code, 0) << fix.err;
  EXPECT_THAT(fix.out, HasSubstr("fixed beam_mass_kg, beam_height_m"));
  m = read_physical_model(dir / "fixed.json");
  EXPECT_FALSE(m.parameter("beam_mass_kg").free);
  EXPECT_FALSE(m.parameter("beam_height_m").free);
  EXPECT_EQ(m.parameter("beam_mass_kg").value, 0.8);  // the value kept
  ASSERT_EQ(run_lpvid(fmt::format("model set --model {} --free beam_mass_kg", dir / "fixed.json")).exit_code, 0);
  EXPECT_TRUE(read_physical_model(dir / "fixed.json").parameter("beam_mass_kg").free);
  const std::string fixed_before = lpvid::testing::slurp(dir / "fixed.json");
  for (const std::string bad : {"--fix no_such_parameter", "--fix beam_mass_kg --free beam_mass_kg", ""}) {
    const auto r = run_lpvid(fmt::format("model set --model {} {}", dir / "fixed.json", bad));
    EXPECT_EQ(r.exit_code, 2) << bad;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  EXPECT_EQ(lpvid::testing::slurp(dir / "fixed.json"), fixed_before);
  // a prior with sigma <= 0 in the file itself: positioned, with the form to write
  {
    std::string text = before;
    const std::string key = "\"prior\": {\"mean\": 0.8, \"sigma\": 0.01}";
    const size_t at = text.find(key);
    ASSERT_NE(at, std::string::npos) << text;
    text.replace(at, key.size(), "\"prior\": {\"mean\": 0.8, \"sigma\": 0}");
    std::ofstream(dir / "bad.json") << text;
  }
  const auto read_bad = run_lpvid(fmt::format("model export --model {} --xb 0 --out {}", dir / "bad.json", dir / "P.json"));
  EXPECT_EQ(read_bad.exit_code, 2);
  EXPECT_THAT(read_bad.err, HasSubstr("bad.json:"));
  EXPECT_THAT(read_bad.err, HasSubstr("sigma > 0"));
  EXPECT_FALSE(std::filesystem::exists(dir / "P.json"));
  // a design value of an effect the model does not have yet: kept for `model add`
  const auto lag = run_lpvid(fmt::format("model set --model {} --set actuator_time_constant_s=5e-5±5e-5 --out {}",
                                         dir / "m.json", dir / "lag.json"));
  ASSERT_EQ(lag.exit_code, 0) << lag.err;
  EXPECT_THAT(lag.out, HasSubstr("(a design value, used when its effect is added)"));
  EXPECT_EQ(read_physical_model(dir / "lag.json").index_of("actuator_time_constant_s"), -1);
  ASSERT_EQ(run_lpvid(fmt::format("model add actuator_lag --model {}", dir / "lag.json")).exit_code, 0);
  m = read_physical_model(dir / "lag.json");
  EXPECT_EQ(m.parameter("actuator_time_constant_s").value, 5e-5);
  EXPECT_EQ(m.parameter("actuator_time_constant_s").prior_sigma, 5e-5);
  EXPECT_TRUE(m.design_values.empty());
  const auto unknown = run_lpvid(fmt::format("model set --model {} --set no_such_s=1", dir / "m.json"));
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_THAT(unknown.err, HasSubstr("no effect it could add has one"));
  EXPECT_EQ(lpvid::testing::slurp(dir / "m.json"), before);
}

TEST(ModelCli, DefineAddsAUserDefinedEffectFromAFile) {
  TempDir dir("model_define");
  ASSERT_EQ(run_lpvid(fmt::format("model init --out {}", dir / "m.json")).exit_code, 0);
  {
    std::ofstream(dir / "mount.json") << testing::kMountEffect;
  }
  const auto def = run_lpvid(fmt::format("model define --model {} --from {} --add", dir / "m.json", dir / "mount.json"));
  ASSERT_EQ(def.exit_code, 0) << def.err;
  const PhysicalModel m = read_physical_model(dir / "m.json");
  EXPECT_TRUE(m.has_effect("theta_mount"));
  EXPECT_EQ(m.parameter("wp_rad_s").value, 800);
  // a definition on a channel the base lacks: exit 2, the file unchanged
  const std::string before = lpvid::testing::slurp(dir / "m.json");
  {
    std::string text = lpvid::testing::slurp(dir / "mount.json");
    text.replace(text.find("\"theta\""), 7, "\"phi\"");
    text.replace(text.find("theta_mount"), 11, "phi_mount");
    std::ofstream(dir / "bad.json") << text;
  }
  const auto bad = run_lpvid(fmt::format("model define --model {} --from {}", dir / "m.json", dir / "bad.json"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr("channel 'phi' is not an output"));
  EXPECT_EQ(lpvid::testing::slurp(dir / "m.json"), before);
}

TEST(FitCli, DatasetManifestGivesTheDataOnceAndItsErrorsArePositioned) {
  TempDir dir("fit_manifest");
  const PhysicalModel truth = truth_model();
  write_plant_frds(dir, truth);
  write_physical_model(dir / "start.json", two_times_off(truth));
  {
    std::ofstream(dir / "data.json") << R"({"format": "lpvid-datasets", "rate_hz": 1000, "noise_level": 0.001,
 "datasets": [{"beam_position_m": -0.1, "files": ["P_left.csv"]},
              {"beam_position_m": 0, "files": ["P_mid.csv"]},
              {"beam_position_m": 0.1, "files": ["P_right.csv"]}]})";
  }
  const auto r = run_lpvid(fmt::format("fit --model {} --datasets {} --out {} --json", dir / "start.json",
                                       dir / "data.json", dir / "fitted.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr(R"("noise_source": "noise level 0.1 %")"));
  const PhysicalModel fitted = read_physical_model(dir / "fitted.json");
  EXPECT_NEAR(fitted.parameter("J_psi_kgm2").value, truth.parameter("J_psi_kgm2").value, 1e-3 * 0.05);
  {
    std::ofstream(dir / "bad.json") << "{\"format\": \"lpvid-datasets\",\n \"datasets\": [{\"files\": [\"P_mid.csv\"]}]}";
  }
  const auto bad = run_lpvid(fmt::format("fit --model {} --datasets {} --out {}", dir / "start.json", dir / "bad.json",
                                         dir / "o.json"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.err, HasSubstr(dir / "bad.json:2:2: each data set is"));
  EXPECT_FALSE(std::filesystem::exists(dir / "o.json"));
  const auto both = run_lpvid(fmt::format("fit --model {} --datasets {} --data {}@0 --out {}", dir / "start.json",
                                          dir / "data.json", dir / "P_mid.csv", dir / "o.json"));
  EXPECT_EQ(both.exit_code, 2);
  EXPECT_THAT(both.err, HasSubstr("not both"));
}

}  // namespace fit_test
}  // namespace lpvid
