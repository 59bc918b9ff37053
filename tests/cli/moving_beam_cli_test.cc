// simulate platform --profile/--trajectory and compare --log, end to end.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "formats/io/csv_log.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace moving_beam_cli_test {

using ::testing::HasSubstr;
using ::testing::StartsWith;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

// One simulated 6 s sweep (two moves) shared by the tests of this file.
class MovingBeamCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("beamcli");
    // --excite all: without excitation z moves ~0.9 µm against 0.1 µm of sensor
    // noise, a fit ceiling of ~89 % (see the noise-ceiling test below).
    const auto r = run_lpvid("simulate platform --out " + (*dir_ / "data") +
                             " --profile sweep --duration-s 6 --seed 7 --excite all");
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string run_dir() { return *dir_ / "data/sweep_1000hz"; }
  static TempDir* dir_;
};
TempDir* MovingBeamCli::dir_ = nullptr;

TEST_F(MovingBeamCli, ProfileRunHasTheBeamColumnAndTheTruth) {
  const Log log = read_log(run_dir() + "/run.csv");
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v1", "v2", "v3", "u1", "u2", "u3", "q1", "q2", "q3", "x_b"}));
  EXPECT_EQ(log.num_samples(), 6001);
  EXPECT_EQ(log.data(0, 10), -0.1);  // starts at left
  EXPECT_NEAR(log.data.col(10).maxCoeff(), 0.1, 1e-12);
  EXPECT_TRUE(std::filesystem::exists(run_dir() + "/controller.json"));
  EXPECT_TRUE(std::filesystem::exists(run_dir() + "/truth_parameters.json"));
}

TEST_F(MovingBeamCli, CompareWithTheTruthFitsThetaAndZAbove95Percent) {
  TempDir out("cmp");
  const auto r = run_lpvid("compare --log " + run_dir() + "/run.csv --params " + run_dir() +
                           "/truth_parameters.json --controller " + run_dir() + "/controller.json --json --out-png " +
                           (out / "overlay.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  // Issue 4: >= 95 % on theta and z when the model lacks nothing.
  EXPECT_GE(j["fit_percent"]["theta"].get<double>(), 95.0);
  EXPECT_GE(j["fit_percent"]["z"].get<double>(), 95.0);
  // The true model reaches the ceiling the noise allows (within 1 %: the closed
  // loop colours the noise a little, so σ̂ from differences is not exact).
  for (const char* ch : {"psi", "theta", "z"})
    EXPECT_NEAR(j["fit_percent"][ch].get<double>(), j["fit_ceiling_percent"][ch].get<double>(), 1.0) << ch;
  EXPECT_TRUE(j["failures"].empty()) << j["failures"].dump();
  for (const auto& w : j["whiteness"])
    EXPECT_TRUE(w["pass"].get<bool>()) << w.dump();
  const std::string png = slurp(out / "overlay.png");
  ASSERT_GT(png.size(), 8u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
}

TEST_F(MovingBeamCli, CompareWithAHeavierBeamListsTheFailingWindows) {
  TempDir out("cmp2");
  const auto r = run_lpvid("compare --log " + run_dir() + "/run.csv --controller " + run_dir() +
                           "/controller.json --set beam_mass_kg=1.2 --json --out " + (out / "cmp.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(slurp(out / "cmp.json"));
  EXPECT_LT(j["fit_percent"]["theta"].get<double>(), j["fit_ceiling_percent"]["theta"].get<double>() - 10.0);
  bool theta = false;
  for (const auto& f : j["failures"]) {
    EXPECT_LT(f["t_start_s"].get<double>(), f["t_end_s"].get<double>());
    if (f["channel"] == "theta") theta = true;
  }
  EXPECT_TRUE(theta) << j["failures"].dump();
  bool white_theta_fails = false;
  for (const auto& w : j["whiteness"])
    if (w["channel"] == "theta" && !w["pass"].get<bool>()) white_theta_fails = true;
  EXPECT_TRUE(white_theta_fails);
}

TEST(MovingBeamCliNoise, BeamOnlyRunTheTruthReachesTheNoiseCeiling) {
  TempDir dir("beamonly");
  auto r = run_lpvid("simulate platform --out " + (dir / "d") + " --profile sweep --duration-s 6 --seed 3");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string run = dir / "d/sweep_1000hz";
  r = run_lpvid("compare --log " + run + "/run.csv --controller " + run + "/controller.json --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GE(j["fit_percent"]["theta"].get<double>(), 95.0);
  // Without excitation z is ~0.9 µm rms against 0.1 µm of noise: the ceiling is
  // below 95 % and the true model sits on it (1 % as above).
  EXPECT_NEAR(j["fit_percent"]["z"].get<double>(), j["fit_ceiling_percent"]["z"].get<double>(), 1.0);
  EXPECT_TRUE(j["failures"].empty()) << j["failures"].dump();
}

TEST_F(MovingBeamCli, CompareNeedsTheController) {
  const auto r = run_lpvid("compare --log " + run_dir() + "/run.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--controller"));
  EXPECT_EQ(lines(r.err), 1) << r.err;
}

void write(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

TEST(MovingBeamCliInput, BadTrajectoriesAreOneLineErrorsWithPositionAndNoOutput) {
  TempDir dir("traj");
  struct Case {
    std::string text, expect;
  };
  const std::vector<Case> cases = {
      {"t,x_b\n0,0\n0.001,0.01\n0.001,0.02\n", "traj.csv:4:1:"},         // t not increasing
      {"t,x_b\n0,0\n0.001,0.3\n0.002,0.02\n", "traj.csv:3:7: x_b = 0.3 m is outside the stroke"},
      {"t,x_b\n0,0\n0.001,nan\n0.002,0.02\n", "traj.csv:3:7:"},          // NaN
  };
  for (const auto& c : cases) {
    write(dir / "traj.csv", c.text);
    const auto r = run_lpvid("simulate platform --out " + (dir / "out") + " --trajectory " + (dir / "traj.csv"));
    EXPECT_EQ(r.exit_code, 2) << c.text;
    EXPECT_EQ(lines(r.err), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.expect)) << r.err;
    EXPECT_EQ(count_files(dir / "out"), 0);
  }
}

TEST(MovingBeamCliInput, TrajectoryFileRunFollowsTheFile) {
  TempDir dir("trajok");
  std::string text = "t,x_b\n";
  for (int k = 0; k <= 500; ++k) text += std::to_string(k * 0.002) + "," + std::to_string(0.05 * k / 500.0) + "\n";
  write(dir / "ramp.csv", text);
  const auto r = run_lpvid("simulate platform --out " + (dir / "out") + " --trajectory " + (dir / "ramp.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Log log = read_log(dir / "out/ramp_1000hz/run.csv");
  EXPECT_EQ(log.num_samples(), 1001);  // 1 s at 1 kHz
  // The spline through a straight line is that line.
  EXPECT_NEAR(log.data(500, 10), 0.025, 1e-12);
}

TEST(MovingBeamCliInput, UnknownProfileIsRejected) {
  TempDir dir("prof");
  const auto r = run_lpvid("simulate platform --out " + (dir / "out") + " --profile zigzag");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("use sweep"));
  EXPECT_EQ(count_files(dir / "out"), 0);
}

}  // namespace moving_beam_cli_test
}  // namespace lpvid
