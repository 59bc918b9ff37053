#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "formats/io/model_json.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace simulate_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

TEST(SimulatePlatform, SetOverridesAPhysicalParameterAndChangesTheTruth) {
  TempDir dir("set");
  auto r = run_lpvid("simulate platform --out " + (dir / "a") + " --positions middle --duration-s 0.1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("simulate platform --out " + (dir / "b") +
                " --positions middle --duration-s 0.1 --set platform_mass_kg=9 --set coil_damping_Ns_per_m=40");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const StateSpace a = read_state_space(dir / "a/middle_1000hz/truth_plant_continuous.json");
  const StateSpace b = read_state_space(dir / "b/middle_1000hz/truth_plant_continuous.json");
  // z row of B is 1 / (m_p + m_b): 1/7 by default, 1/10 with m_p = 9 kg.
  EXPECT_NEAR(a.B(5, 2), 1.0 / 7.0, 1e-12);
  EXPECT_NEAR(b.B(5, 2), 1.0 / 10.0, 1e-12);
}

TEST(SimulatePlatform, UnknownParameterIsRejectedWithTheKnownNames) {
  TempDir dir("unknown");
  const auto r = run_lpvid("simulate platform --out " + (dir / "x") + " --set mass=3");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown parameter 'mass'"));
  EXPECT_THAT(r.err, HasSubstr("platform_mass_kg"));
  EXPECT_EQ(count_files(dir.path()), 0);
}

TEST(SimulatePlatform, NonNumericValueIsRejected) {
  TempDir dir("value");
  const auto r = run_lpvid("simulate platform --out " + (dir / "x") + " --set J_psi_kgm2=heavy");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("'heavy' is not a finite number"));
}

TEST(SimulatePlatform, BeamOutsideTheStrokeIsRejected) {
  TempDir dir("stroke");
  const auto r = run_lpvid("simulate platform --out " + (dir / "x") + " --positions 100");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

}  // namespace simulate_test
}  // namespace lpvid
