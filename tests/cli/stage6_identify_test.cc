// lpvid stage6 fit / diagnose / history on a simulated closed-loop log of the
// 6-DOF stage with a hidden gap-dependent force constant alpha(z) (issue 6).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>

#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace {

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
  EXPECT_EQ(j["missing"], "gap");
  // The issue: adding it makes the error fall >= 10x.
  EXPECT_LT(j["candidates"][0]["rms_residual"].get<double>(), j["base"]["rms_residual"].get<double>() / 10.0);
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

}  // namespace
}  // namespace lpvid
