// A positioning axis through the program, as a user with a log of their own would run
// it: the description (samples/mechanical/ball_screw_axis.json) -> model init ->
// diagnose --log names Coulomb friction -> diagnose --log on its --out names the
// offset, explained -> fit --log reaches the floor.  The log comes from the
// independent simulator of tests/support/friction_axis.h (closed loop, PD on the
// quantised encoder, a reference trajectory); and the route's bad inputs.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "formats/io/physical_model_json.h"
#include "tests/support/friction_axis.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace friction_axis_cli_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

std::string sample() { return std::string(LPVID_SOURCE_DIR) + "/samples/mechanical/ball_screw_axis.json"; }

TEST(FrictionAxisCli, TheLoopNamesCoulombThenTheOffsetAndTheFitReachesTheFloor) {
  const TempDir dir("friction_cli");
  const friction_axis::Truth truth;
  friction_axis::write_csv(friction_axis::simulate(truth, friction_axis::Experiment{}), dir / "run.csv");
  const std::string m0 = dir / "axis.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), m0)).exit_code, 0);

  const auto r1 = run_lpvid(fmt::format("diagnose --model {} --log {} --out {} --report {} --json", m0,
                                        dir / "run.csv", dir / "next1.json", dir / "report1.json"));
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  const nlohmann::json d1 = nlohmann::json::parse(r1.out);
  EXPECT_EQ(d1["named"], nlohmann::json::array({"coulomb_friction"})) << d1["summary"];
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "report1.json"))["named"], d1["named"]);
  const PhysicalModel m1 = read_physical_model(dir / "next1.json");
  EXPECT_TRUE(m1.has_effect("coulomb_friction"));

  const auto r2 = run_lpvid(fmt::format("diagnose --model {} --log {} --out {}", dir / "next1.json",
                                        dir / "run.csv", dir / "next2.json"));
  ASSERT_EQ(r2.exit_code, 0) << r2.err;
  std::printf("%s\n", r2.out.c_str());
  EXPECT_THAT(r2.out, HasSubstr("missing: force_offset"));
  EXPECT_THAT(r2.out, HasSubstr("explained"));

  const auto r3 = run_lpvid(fmt::format("fit --model {} --log {} --out {} --json", dir / "next2.json",
                                        dir / "run.csv", dir / "fit3.json"));
  ASSERT_EQ(r3.exit_code, 0) << r3.err;
  const nlohmann::json f = nlohmann::json::parse(r3.out);
  EXPECT_LE(f["error_percent"].get<double>(), 1.5 * f["noise_floor_percent"].get<double>());
  const PhysicalModel m3 = read_physical_model(dir / "fit3.json");
  // 0.2 % (mass) and 0.5 % (forces): the tolerances of tests/idlib/fit/force_error_test.cc
  EXPECT_NEAR(m3.parameter("m_kg").value, truth.m_kg, 0.002 * truth.m_kg);
  EXPECT_NEAR(m3.parameter("coulomb_x_N").value, truth.coulomb_N, 0.005 * truth.coulomb_N);
  EXPECT_NEAR(m3.parameter("offset_x_N").value, truth.offset_N, 0.005 * truth.offset_N);
  // the lineage: diagnose's two --out and the fit, one history line each
  const std::string history = slurp(dir / "fit3.json.history.jsonl");
  EXPECT_EQ(std::count(history.begin(), history.end(), '\n'), 3) << history;
}

TEST(FrictionAxisCli, BadInputsGetOneLineAndLoseNothing) {
  const TempDir dir("friction_bad");
  friction_axis::Experiment e;
  e.seconds = 3.0;
  friction_axis::write_csv(friction_axis::simulate(friction_axis::Truth{}, e), dir / "run.csv");
  const std::string m0 = dir / "axis.json";
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), m0)).exit_code, 0);
  ASSERT_EQ(run_lpvid(fmt::format("model init --base mechanical --from {} --out {}", sample(), dir / "axis2.json"))
                .exit_code,
            0);
  ASSERT_EQ(run_lpvid(fmt::format("model add coulomb_friction --model {}", m0)).exit_code, 0);
  const std::string before = slurp(m0);
  auto one_line = [](const lpvid::testing::RunResult& r) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  };
  // the frequency route refuses a time-only effect, saying what to do
  std::ofstream(dir / "P.csv") << "# outputs: enc\n# inputs: i\nfreq_hz,P_enc_i_re,P_enc_i_im\n1,1e-3,0\n2,2e-4,0\n"
                                   "3,1e-4,0\n4,6e-5,0\n";
  const auto a = run_lpvid(fmt::format("fit --model {} --data {} --noise-level 0.01 --out {}", m0, dir / "P.csv",
                                       dir / "f.json"));
  one_line(a);
  EXPECT_THAT(a.err, HasSubstr("coulomb_friction, a nonlinear time-domain effect"));
  // nor takes one as a candidate
  const auto a2 = run_lpvid(fmt::format("diagnose --model {} --data {} --noise-level 0.01 --candidates force_offset",
                                        dir / "axis2.json", dir / "P.csv"));
  one_line(a2);
  EXPECT_THAT(a2.err, HasSubstr("'force_offset' is a nonlinear time-domain effect"));
  // a log without the base's output column
  std::ofstream(dir / "wrong.csv") << "t,i,x\n0,0,0\n0.001,0,0\n0.002,0,0\n";
  const auto b = run_lpvid(fmt::format("fit --model {} --log {} --out {}", m0, dir / "wrong.csv", dir / "f.json"));
  one_line(b);
  EXPECT_THAT(b.err, HasSubstr("enc"));
  // --method belongs to the stage
  const auto c = run_lpvid(fmt::format("fit --model {} --log {} --method equation --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(c);
  EXPECT_THAT(c.err, HasSubstr("force error"));
  // too short for the window
  const auto d = run_lpvid(fmt::format("fit --model {} --log {} --window-s 1 --out {}", m0, dir / "run.csv",
                                       dir / "f.json"));
  one_line(d);
  EXPECT_THAT(d.err, HasSubstr("--window-s"));
  // a candidate the route has no form for
  const auto g = run_lpvid(fmt::format("diagnose --model {} --log {} --candidates actuator_lag", m0, dir / "run.csv"));
  one_line(g);
  EXPECT_THAT(g.err, HasSubstr("force-error route tries coulomb_friction, force_offset"));
  EXPECT_FALSE(std::filesystem::exists(dir / "f.json"));
  EXPECT_FALSE(std::filesystem::exists(dir / "f.json.history.jsonl"));
  EXPECT_EQ(slurp(m0), before);
}

}  // namespace friction_axis_cli_test
}  // namespace lpvid
