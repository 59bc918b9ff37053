// lpvid simulate stage6 through the program: outputs, their layout, bad input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "formats/io/csv_log.h"
#include "formats/io/model_json.h"
#include "tests/support/run_lpvid.h"

namespace lpvid::cli {
namespace {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;
namespace fs = std::filesystem;

TEST(SimulateStage6, HelpHasAWorkedExample) {
  const auto r = run_lpvid("simulate stage6 --help");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("Example:"));
  EXPECT_THAT(r.out, HasSubstr("lpvid simulate stage6"));
}

TEST(SimulateStage6, RegulationRunWritesTheCsvAndFourPlots) {
  TempDir dir("stage6_reg");
  const auto r = run_lpvid("simulate stage6 --out " + (dir / "fig6") + " --duration-s 1 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* f : {"stage6_run.csv", "fig6a_xyz.png", "fig6b_angles.png", "fig6c_forces.png", "fig6d_torques.png"})
    EXPECT_TRUE(fs::exists(fs::path(dir / "fig6") / f)) << f;
  const Log log = read_log(dir / "fig6/stage6_run.csv");
  EXPECT_EQ(log.data.rows(), 1001);  // 1 s at 1 kHz, both ends
  EXPECT_EQ(log.data.cols(), 33);
  EXPECT_DOUBLE_EQ(log.data(0, 3), 250e-6);  // z(0) of seed 001 section 3.5
  EXPECT_THAT(r.out, HasSubstr("final_angle_error_rad"));
}

TEST(SimulateStage6, ExperimentWritesTheUsualLogAndTheLinearisedTruth) {
  TempDir dir("stage6_exp");
  const auto r = run_lpvid("simulate stage6 --experiment --out " + (dir / "exp") + " --duration-s 0.2 --effects lag");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Log log = read_log(dir / "exp/exp_stage6.csv");
  ASSERT_EQ(log.names.size(), 19u);
  EXPECT_EQ(log.names[1], "v1");
  EXPECT_EQ(log.names[7], "u1");
  EXPECT_EQ(log.names[13], "q1");
  const StateSpace plant = read_state_space(dir / "exp/truth_plant.json");
  EXPECT_EQ(plant.order(), 12);
  EXPECT_EQ(plant.num_inputs(), 6);
  EXPECT_DOUBLE_EQ(plant.sample_period_s, 1e-3);
}

TEST(SimulateStage6, UnknownEffectIsBadInputWithNoOutput) {
  TempDir dir("stage6_bad");
  const auto r = run_lpvid("simulate stage6 --experiment --out " + (dir / "x") + " --effects friction");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("friction"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x/exp_stage6.csv"));
}

TEST(SimulateStage6, NonPositiveBoundaryLayerIsBadInputWithNoOutput) {
  TempDir dir("stage6_bad2");
  const auto r = run_lpvid("simulate stage6 --out " + (dir / "x") + " --delta 0");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--delta: '0' is out of range; give the boundary layer delta > 0"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x/stage6_run.csv"));
}

}  // namespace
}  // namespace lpvid::cli
