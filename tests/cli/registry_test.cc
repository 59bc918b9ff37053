#include "cli/registry.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/run_lpvid.h"

namespace lpvid::cli {
namespace registry_test {

using ::testing::HasSubstr;

// The registry is the one list of subcommands; adding or removing one is a
// deliberate change to the user interface and must update this test and docs/.
TEST(Registry, ListsTheSubcommandsInOrder) {
  std::vector<std::string> names;
  for (const auto& c : commands()) names.push_back(c.name);
  EXPECT_EQ(names, (std::vector<std::string>{"simulate", "markov", "hankel", "realize", "unloop", "bode", "identify",
                                             "frf", "compare", "model", "fit", "diagnose", "history", "stage6", "excite"}));
}

TEST(Registry, EverySubcommandHasHelpWithAWorkedExample) {
  for (const auto& c : commands()) {
    const std::string args = c.name == "simulate" ? "simulate platform --help" : c.name + " --help";
    const auto r = lpvid::testing::run_lpvid(args);
    EXPECT_EQ(r.exit_code, 0) << c.name << ": " << r.err;
    EXPECT_THAT(r.out, HasSubstr("Example:")) << c.name;
    EXPECT_THAT(r.out, HasSubstr("lpvid " + c.name)) << c.name;
  }
}

TEST(Registry, UnknownSubcommandIsBadUsageWithExitCode2) {
  const auto r = lpvid::testing::run_lpvid("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("error"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(Registry, UnknownFlagIsRejectedWithExitCode2) {
  const auto r = lpvid::testing::run_lpvid("markov --excitation v1 --output q1 --out x.csv --bogus 3 a.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--bogus"));
}

TEST(Registry, MissingRequiredOptionIsBadUsage) {
  const auto r = lpvid::testing::run_lpvid("identify a.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("required"));
}

}  // namespace registry_test
}  // namespace lpvid::cli
