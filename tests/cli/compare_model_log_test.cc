// compare --log with a state-space model (issue 24: "compare --log for any state-space
// model against any log"): a positioning axis with a pure integrator under a PD
// controller (tests/support/positioning_axis.h: the truth is the axis written there,
// simulated there by its own recursion).  The figures a correct model must reach come
// from the log's own noise, known to the test: the fit of the truth is
// 100 (1 - ||q - q_clean|| / ||q - mean q||), q_clean the same experiment without the
// sensor noise.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "tests/support/positioning_axis.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace compare_model_log_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;
using namespace lpvid::testing::positioning_axis;

// Column `name` of a CSV log written by write_files (a header line, then numbers).
std::vector<double> column(const std::string& path, const std::string& name) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::stringstream h(line);
    for (std::string cell; std::getline(h, cell, ',');) header.push_back(cell);
  }
  const auto at = std::find(header.begin(), header.end(), name);
  EXPECT_NE(at, header.end()) << name;
  const auto k = static_cast<std::size_t>(at - header.begin());
  std::vector<double> out;
  while (std::getline(in, line)) {
    std::stringstream row(line);
    std::string cell;
    for (std::size_t c = 0; c <= k; ++c) std::getline(row, cell, ',');
    out.push_back(std::stod(cell));
  }
  return out;
}

// 100 (1 - ||y - reference|| / ||y - mean y||): the fit of a prediction equal to `reference`.
double fit_against(const std::vector<double>& y, const std::vector<double>& reference) {
  double mean = 0;
  for (double v : y) mean += v / static_cast<double>(y.size());
  double err = 0, spread = 0;
  for (std::size_t k = 0; k < y.size(); ++k) {
    err += (y[k] - reference[k]) * (y[k] - reference[k]);
    spread += (y[k] - mean) * (y[k] - mean);
  }
  return 100.0 * (1.0 - std::sqrt(err / spread));
}

// truth.json with every entry of B scaled (a gain error of the same factor).
void write_scaled_model(const TempDir& dir, double gain, const std::string& name) {
  nlohmann::json m = nlohmann::json::parse(lpvid::testing::slurp(dir / "truth.json"));
  for (auto& row : m["B"])
    for (auto& v : row) v = v.get<double>() * gain;
  std::ofstream(dir / name) << m.dump();
}

TEST(CompareModelLog, TheTrueAxisReachesTheNoiseCeilingInClosedLoopAndAGainErrorIsCaught) {
  TempDir dir("cmp_axis");
  write_files(dir.path(), 1.0, "axis.csv");
  write_files(dir.path(), 0.0, "clean.csv");  // the same references, no sensor noise
  const std::vector<double> q = column(dir / "axis.csv", "q");
  const double ceiling = fit_against(q, column(dir / "clean.csv", "q"));
  const std::string loop = " --log " + (dir / "axis.csv") + " --controller " + (dir / "controller.json") +
                           " --excitation r --excitation-at reference --input u --json";
  const auto r = run_lpvid("compare --model " + (dir / "truth.json") + loop + " --out-png " + (dir / "ov.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const double fit = j["fit_percent"]["q"].get<double>();
  std::printf("axis in closed loop: truth fits %.4f %% ('z' %.4f %%), the noise allows %.4f %%\n", fit,
              j["fit_zero_state_percent"]["q"].get<double>(), ceiling);
  // The model's loop, driven by v = C (r - r°), is the noise-free loop up to a
  // constant (the operating point: the fitted offset, 5 mm) and a decaying start (the
  // fitted initial state): 4 values fitted to 30 000 samples can raise the fit above the
  // ceiling by about sqrt(4 / 30000) of the noise's share (0.01 of ~0.3 points), and a
  // correct model cannot fall below it by more than that.
  EXPECT_NEAR(fit, ceiling, 0.01);
  // From rest the loop's response to the step r(0) - mean r is missing (it decays at the
  // loop's ~100 rad/s within 0.05 s of the 30 s): measured 0.002 points below.
  EXPECT_NEAR(j["fit_zero_state_percent"]["q"].get<double>(), ceiling, 0.01);
  // (The offset is not checked: with an integrator a constant is also a free response,
  // so x(0) and the offset share it.)
  EXPECT_EQ(j["stable"], false);  // the integrator: a pole at z = 1
  // With --input u the residual tests run on the open-loop prediction from the logged
  // force: the sensor noise alone, white and uncorrelated with r.
  EXPECT_THAT(j["residual_tests_on"].get<std::string>(), HasSubstr("open-loop prediction from the logged plant input u"));
  EXPECT_EQ(j["whiteness"][0]["pass"], true) << j["whiteness"].dump();
  EXPECT_EQ(j["cross_correlation"][0]["pass"], true) << j["cross_correlation"].dump();
  EXPECT_TRUE(j["failures"].empty()) << j["failures"].dump();
  EXPECT_TRUE(std::filesystem::exists(dir / "ov.png"));

  // A model whose force constant is 20 % high: the loop hides part of it (a type-1 loop
  // tracks the setpoint whatever its gain), but the residual follows the reference.
  write_scaled_model(dir, 1.2, "wrong.json");
  const auto w = run_lpvid("compare --model " + (dir / "wrong.json") + loop);
  ASSERT_EQ(w.exit_code, 0) << w.err;
  const auto jw = nlohmann::json::parse(w.out);
  std::printf("axis, force constant +20 %%: fit %.4f %%, whiteness %s, cross %s (max |r|/bound %.2f)\n",
              jw["fit_percent"]["q"].get<double>(), jw["whiteness"][0]["pass"].dump().c_str(),
              jw["cross_correlation"][0]["pass"].dump().c_str(),
              jw["cross_correlation"][0]["worst_ratio"].get<double>());
  EXPECT_LT(jw["fit_percent"]["q"].get<double>(), ceiling - 1.0);
  EXPECT_EQ(jw["cross_correlation"][0]["pass"], false);
}

TEST(CompareModelLog, AnIntegratorSimulatedFromItsLoggedInputAndAContinuousModelSampledHere) {
  TempDir dir("cmp_open");
  write_files(dir.path(), 1.0, "axis.csv");
  const std::vector<double> q = column(dir / "axis.csv", "q");
  // Simulated from the logged force u the axis reproduces q_true exactly (u is what the
  // motor got): the residual is the sensor noise.
  const double ceiling = fit_against(q, column(dir / "axis.csv", "q_true"));
  const auto r = run_lpvid("compare --json --log " + (dir / "axis.csv") + " --model " + (dir / "truth.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["route"], "open loop: the model simulated from the logged input u");  // the model's names
  EXPECT_NEAR(j["fit_percent"]["q"].get<double>(), ceiling, 0.01);
  EXPECT_EQ(j["whiteness"][0]["pass"], true);
  EXPECT_EQ(j["cross_correlation"][0]["pass"], true);
  const auto text = run_lpvid("compare --log " + (dir / "axis.csv") + " --model " + (dir / "truth.json"));
  EXPECT_THAT(text.out, HasSubstr("marginally stable"));

  // The same axis in continuous time (K / (s (tau s + 1)) as written in positioning_axis.h):
  // compare samples it with a zero-order hold at the log's rate, which is truth.json (the
  // exact ZOH derived by hand), so the figures agree to rounding.
  std::ofstream(dir / "continuous.json")
      << nlohmann::json{{"type", "state_space"}, {"ts", 0.0},
                        {"A", {{0.0, 1.0}, {0.0, -1.0 / kTau}}}, {"B", {{0.0}, {kGain / kTau}}},
                        {"C", {{1.0, 0.0}}}, {"D", {{0.0}}}, {"inputs", {"u"}}, {"outputs", {"q"}}}
             .dump();
  const auto c = run_lpvid("compare --json --log " + (dir / "axis.csv") + " --model " + (dir / "continuous.json"));
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto jc = nlohmann::json::parse(c.out);
  EXPECT_NEAR(jc["fit_percent"]["q"].get<double>(), j["fit_percent"]["q"].get<double>(), 1e-6);
  EXPECT_THAT(jc["sampling"].get<std::string>(), HasSubstr("zero-order hold"));
}

TEST(CompareModelLog, WhatCannotBeComparedIsRefusedInOneLineAndWritesNothing) {
  TempDir dir("cmp_usage");
  write_files(dir.path(), 1.0, "axis.csv");
  const std::string log = " --log " + (dir / "axis.csv");
  const std::string png = " --out-png " + (dir / "o.png") + " --out " + (dir / "o.json");
  const auto refused = [&](const std::string& args, const std::string& what) {
    const auto r = run_lpvid("compare" + log + png + " " + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.out;
    EXPECT_THAT(r.err, HasSubstr(what)) << args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  };
  const std::string truth = " --model " + (dir / "truth.json");
  refused(truth + " --excitation r", "--excitation is the closed loop's (with --controller C.json)");
  refused(truth + " --controller " + (dir / "controller.json"), "give --excitation NAME");
  refused(truth + " --output q,r", "--output names 2 column(s) but the model");
  refused(truth + " --input nope", "no column 'nope'");
  // A model without channel names needs them on the command line.
  nlohmann::json m = nlohmann::json::parse(lpvid::testing::slurp(dir / "truth.json"));
  m.erase("inputs");
  m.erase("outputs");
  std::ofstream(dir / "nameless.json") << m.dump();
  refused(" --model " + (dir / "nameless.json"), "the model names no outputs; give --output");
  // Another sample rate.
  m["ts"] = 2 * kTs;
  std::ofstream(dir / "slow.json") << m.dump();
  refused(" --model " + (dir / "slow.json") + " --input u --output q", "the model samples at 0.002 s but the log");
  // A model that blows up on the log's input (|z| = 1.1 over 30 000 samples overflows).
  std::ofstream(dir / "exploding.json")
      << nlohmann::json{{"type", "state_space"}, {"ts", kTs}, {"A", {{1.1}}}, {"B", {{1.0}}}, {"C", {{1.0}}},
                        {"D", {{0.0}}}, {"inputs", {"u"}}, {"outputs", {"q"}}}
             .dump();
  refused(" --model " + (dir / "exploding.json"), "diverges on the log");
  // A plant that closes an unstable loop with the controller that ran (the axis with its
  // input's sign flipped: positive feedback) would print figures of 1e+60 %: refused.
  nlohmann::json flipped = nlohmann::json::parse(lpvid::testing::slurp(dir / "truth.json"));
  for (auto& row : flipped["B"])
    for (auto& b : row) b = -b.get<double>();
  std::ofstream(dir / "flipped.json") << flipped.dump();
  refused(" --model " + (dir / "flipped.json") + " --controller " + (dir / "controller.json") +
              " --excitation r --excitation-at reference",
          "the model's loop with");
  // The platform's route has fixed channels.
  refused(" --controller " + (dir / "controller.json") + " --input u", "are for a state-space model");
  EXPECT_FALSE(std::filesystem::exists(dir / "o.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "o.json"));
}

}  // namespace compare_model_log_test
}  // namespace lpvid
