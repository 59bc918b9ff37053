// The habits of real logs through the commands (issue 24): a clipped sensor and a drifting
// channel are said, with the file, the column and the rows, by every command that reads
// logs through the shared reader, and identify's report carries them; the log is used as
// it is (nothing silently corrected).  The log is built here: a first-order plant's
// response to white noise, its output clipped at a known rail.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace log_checks_cli_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

TEST(LogChecksCli, AClippedOutputIsNamedWithItsRowsAndLandsInTheReport) {
  TempDir dir("log_checks");
  std::mt19937_64 rng(99);
  std::normal_distribution<double> d(0.0, 1.0);
  constexpr int kN = 4000;
  constexpr double kRail = 1.5;  // the sensor's range
  std::ofstream f(dir / "run.csv");
  f << "t,u,y\n";
  f.precision(17);
  double x = 0.0;
  int clipped = 0, first = -1;
  for (int k = 0; k < kN; ++k) {
    const double u = d(rng);
    const double y = x + 0.01 * d(rng);
    if (y >= kRail && first < 0) first = k;
    clipped += y >= kRail;
    f << k * 1e-3 << ',' << u << ',' << std::min(y, kRail) << '\n';
    x = 0.95 * x + 0.3 * u;  // rms about 0.96: the rail clips its peaks
  }
  f.close();
  ASSERT_GE(clipped, 3);
  const auto m = run_lpvid("markov --excitation u --output y --lags 50 --out " + (dir / "g.csv") + " " + (dir / "run.csv"));
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_THAT(m.err, HasSubstr("lpvid: warning: " + (dir / "run.csv") +
                               ": channel y sits at its maximum 1.5 in " + std::to_string(clipped) + " samples (rows " +
                               std::to_string(first + 1) + ".."));
  EXPECT_THAT(m.err, HasSubstr("clipped (a saturated sensor, amplifier or actuator), or a designed dwell"));
  const auto id = run_lpvid("identify --open-loop --excitation u --output y --json --out " + (dir / "out") + " " +
                            (dir / "run.csv"));
  ASSERT_EQ(id.exit_code, 0) << id.err;
  const auto report = nlohmann::json::parse(id.out);
  ASSERT_EQ(report["log_findings"].size(), 1u) << report["log_findings"].dump();
  EXPECT_THAT(report["log_findings"][0].get<std::string>(), HasSubstr("channel y sits at its maximum 1.5"));
}

}  // namespace log_checks_cli_test
}  // namespace lpvid
