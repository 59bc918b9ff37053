// lpvid compare --model --data: the model-error form through the program.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

#include "formats/io/frd_csv.h"
#include "formats/io/model_json.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/plants/platform/platform.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace compare_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

constexpr double kDelay_s = 1e-3;
// Coherence of the fake measurements: σ_c = 4.1 % of |P| with 16 averages, so the
// 1 ms delay's error (ω τ) is significant above about 123 rad/s.
constexpr double kCoherence = 0.95;

class CompareCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const StateSpace plant = platform_model(PlatformParameters::defaults(), kBeamRight_m);
    write_state_space(dir / "model.json", plant);
    const Eigen::VectorXd omega = log_frequency_grid(1, 1000, 300);
    FrequencyResponse clean = frequency_response(plant, omega);
    for (Index f = 0; f < omega.size(); ++f)
      clean.coherence.push_back(Eigen::MatrixXd::Constant(3, 3, kCoherence));
    clean.averages = 16;  // stated in the files ('# averages: 16')
    FrequencyResponse delayed = clean;
    for (Index f = 0; f < omega.size(); ++f) delayed.response[f] *= std::polar(1.0, -omega(f) * kDelay_s);
    write_frd_csv(dir / "clean.csv", clean, "P");
    write_frd_csv(dir / "delayed.csv", delayed, "P");
    delayed.coherence.clear();
    delayed.averages = 0;
    write_frd_csv(dir / "no_coherence.csv", delayed, "P");
    clean.averages = 0;
    write_frd_csv(dir / "unstated.csv", clean, "P");
  }
  TempDir dir{"compare"};
};

TEST_F(CompareCli, DelayedDataFailsWithADelaySignatureAndAFigure) {
  const auto r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "delayed.csv") +
                           " --out-png " + (dir / "cmp.png") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;  // failures are results, not errors
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_GE(j["failing_bands"].get<int>(), 3);
  int diagonal = 0;
  for (const auto& f : j["failures"]) {
    EXPECT_EQ(f["signature"], "delay") << f.dump();
    if (f["output"] != (f["input"] == "T_psi" ? "psi" : f["input"] == "T_theta" ? "theta" : "z")) continue;
    ++diagonal;
    // Noise-free data: the band starts where ω τ crosses k σ (123 rad/s, 1.02 of
    // that on the chord |1 − e^{−jωτ}|), within one grid step (2.3 %).
    EXPECT_NEAR(f["band_rad_s"][0].get<double>(), 123.0, 5.0);
    EXPECT_EQ(f["band_rad_s"][1].get<double>(), 1000.0);
    EXPECT_THAT(f["hint"].get<std::string>(), HasSubstr("phase lag growing with frequency"));
  }
  EXPECT_EQ(diagonal, 3);
  EXPECT_EQ(j["data"][0]["noise"], "coherence (16 averages)");
  const std::string png = slurp(dir / "cmp.png");
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

TEST_F(CompareCli, DataEqualToTheModelHasNoFailingBand) {
  const auto r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "clean.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("no failing band"));
}

// No silent default: data without noise information need the user to say it.
TEST_F(CompareCli, WithoutNoiseInformationTheUserMustStateItAndThenItIsSaid) {
  auto r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "no_coherence.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("the noise of the data is not known (unknown); give --averages N"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "unstated.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("coherence without the number of averages"));
  r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "no_coherence.csv") +
                " --noise-level 0.02");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("noise from noise level 2 %"));
  r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "unstated.csv") + " --averages 16");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("noise from coherence (16 averages, given)"));
}

TEST_F(CompareCli, AFailureInOnlyOneDataSetIsMarked) {
  const auto r = run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "delayed.csv") +
                           " --data " + (dir / "clean.csv") + " --labels delayed,clean --out " + (dir / "c.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(dir / "c.json"));
  ASSERT_FALSE(j["failures"].empty());
  for (const auto& f : j["failures"]) {
    EXPECT_EQ(f["data"], 1);
    EXPECT_TRUE(f["differs_between_data"].get<bool>());
  }
  EXPECT_THAT(r.out, HasSubstr("differs between data sets (only in set 1 of 2)"));
}

TEST_F(CompareCli, BadInputIsOneLineExitCode2AndNoOutput) {
  const std::string png = dir / "out.png";
  const std::vector<std::string> cases = {
      "--model " + (dir / "model.json") + " --data " + (dir / "model.json") + " --out-png " + png,  // data is a model
      "--model " + (dir / "model.json") + " --data " + (dir / "missing.csv") + " --out-png " + png,
      "--model " + (dir / "model.json") + " --data " + (dir / "clean.csv") + " --confidence 2 --out-png " + png,
      "--model " + (dir / "model.json") + " --model " + (dir / "model.json") + " --data " + (dir / "clean.csv") +
          " --out-png " + png,  // two models for one data set
      "--model " + (dir / "model.json") + " --data " + (dir / "clean.csv") + " --out-png " + (dir / "clean.csv"),
      "--data " + (dir / "clean.csv") + " --out-png " + png,  // no model
  };
  for (const auto& args : cases) {
    const int before = count_files(dir.path());
    const auto r = run_lpvid("compare " + args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(count_files(dir.path()), before) << args;
  }
  EXPECT_THAT(run_lpvid("compare --model " + (dir / "model.json") + " --data " + (dir / "model.json")).err,
              HasSubstr("is a model; give measured frequency-response data (FRD .csv or .mat) to --data"));
}

}  // namespace compare_test
}  // namespace lpvid
