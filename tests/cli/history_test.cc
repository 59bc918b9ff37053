// lpvid history: the fits of a model through the program.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

#include "formats/io/history.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace history_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

HistoryRecord fit(std::vector<std::string> effects, Index params, double error) {
  HistoryRecord r;
  r.timestamp = "2026-11-23T12:00:00Z";
  r.model = "plant.json";
  r.effects = std::move(effects);
  r.free_parameters = params;
  r.cost = error * error;
  r.error_mean = error;
  r.error_max = 3 * error;
  return r;
}

class HistoryCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string h = history_path_for(dir / "plant.json");
    append_history(h, fit({"rigid body"}, 6, 0.4));
    append_history(h, fit({"rigid body", "suspension"}, 9, 0.05));
    append_history(h, fit({"rigid body", "suspension", "delay"}, 10, 0.01));
  }
  TempDir dir{"history"};
};

TEST_F(HistoryCli, ListsTheFitsWithTheErrorFallingAndDrawsIt) {
  const auto r = run_lpvid("history --model " + (dir / "plant.json") + " --png " + (dir / "h.png") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["fits"].size(), 3u);
  EXPECT_TRUE(j["fits"][0]["change_percent"].is_null());
  // (0.05 − 0.4) / 0.4 = −87.5 %; 1e-9 is rounding.
  EXPECT_NEAR(j["fits"][1]["change_percent"].get<double>(), -87.5, 1e-9);
  EXPECT_EQ(j["fits"][2]["effects"].size(), 3u);
  EXPECT_EQ(slurp(dir / "h.png").substr(1, 3), "PNG");
  const auto t = run_lpvid("history --model " + (dir / "plant.json"));
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_THAT(t.out, HasSubstr("rigid body, suspension, delay"));
}

TEST(HistoryFigure, RecordsWithTheErrorFigureShowItBesideTheNoiseFloor) {
  TempDir dir{"history_figure"};
  const std::string h = history_path_for(dir / "m.json");
  HistoryRecord a = fit({"beam_gravity"}, 14, 0.03);  // channel mean 3 %, figure 5.23 %
  a.error = 0.0523;
  a.noise_floor = 0.0007;
  HistoryRecord b = fit({"beam_gravity", "input_delay"}, 15, 0.001);
  b.error = 0.000714;
  b.noise_floor = 0.0007;
  append_history(h, a);
  append_history(h, b);
  const auto r = run_lpvid("history --model " + (dir / "m.json") + " --png " + (dir / "h.png") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_DOUBLE_EQ(j["fits"][0]["error"].get<double>(), 0.0523);
  EXPECT_DOUBLE_EQ(j["fits"][1]["noise_floor"].get<double>(), 0.0007);
  // the change is of the error figure, not of the channel mean: (0.000714 − 0.0523) / 0.0523
  EXPECT_NEAR(j["fits"][1]["change_percent"].get<double>(), 100 * (0.000714 - 0.0523) / 0.0523, 1e-9);
  EXPECT_EQ(slurp(dir / "h.png").substr(1, 3), "PNG");
  const auto t = run_lpvid("history --model " + (dir / "m.json"));
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_THAT(t.out, HasSubstr("  5.230 %    0.070 %"));  // error, then floor
  EXPECT_THAT(t.out, HasSubstr("  0.071 %    0.070 %"));
}

TEST_F(HistoryCli, BadLineIsFileLineErrorExitCode2AndNoPng) {
  std::ofstream(history_path_for(dir / "plant.json"), std::ios::app) << "{\"timestamp\": 3}\n";
  const auto r = run_lpvid("history --model " + (dir / "plant.json") + " --png " + (dir / "h.png"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("plant.json.history.jsonl:4:1: key 'timestamp' must be a string"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(count_files(dir.path()), 1);
}

TEST_F(HistoryCli, ModelWithoutHistoryIsExitCode2) {
  const auto r = run_lpvid("history --model " + (dir / "other.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("fit a model first"));
}

}  // namespace history_test
}  // namespace lpvid
