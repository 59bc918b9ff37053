// The program as a user runs it: simulate platform experiments, identify them,
// check the outputs against the truth written beside the logs; and every bad
// input path of the chain gives one line on stderr, exit code 2 (or 1), and no
// partial output.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "formats/io/csv_log.h"
#include "formats/io/model_json.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace identify_cli_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

// One simulated dataset shared by the tests of this file (simulation is the slow part).
class CliPipeline : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("e2e");
    const auto r = run_lpvid("simulate platform --out " + (*dir_ / "data") +
                             " --positions middle --rate-hz 1000 --duration-s 30 --seed 5");
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string data(const std::string& name) { return *dir_ / ("data/middle_1000hz/" + name); }
  static std::string logs() { return data("exp_T_psi.csv") + " " + data("exp_T_theta.csv") + " " + data("exp_F_z.csv"); }
  static TempDir* dir_;
};
TempDir* CliPipeline::dir_ = nullptr;

TEST_F(CliPipeline, IdentifyWritesEveryOutputAndFindsOrders9And6) {
  TempDir out("identify");
  const auto r = run_lpvid("identify --method era --controller " + data("controller.json") +
                           " --excitation v1,v2,v3 --output q1,q2,q3 --truth " + data("truth_plant.json") +
                           " --out " + out.path().string() + " --json " + logs());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* f : {"closed_loop.json", "plant.json", "markov.csv", "hankel_sv.csv", "hankel_sv.png", "bode.png",
                        "report.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  const auto report = nlohmann::json::parse(slurp(out / "report.json"));
  EXPECT_EQ(report["closed_loop"]["order"], 9);
  // unloop is exact enough here for the plant closed with the controller to simulate the
  // logs as the ERA closed loop does (to 1 point of MATLAB compare's fit per output).
  ASSERT_TRUE(report["plant"]["reclosed_simulation_fit_percent"].is_array());
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(report["plant"]["reclosed_simulation_fit_percent"][i].get<double>(),
                report["closed_loop"]["simulation_fit_percent"][i].get<double>(), 1.0);
  EXPECT_EQ(report["plant"]["order"], 6);
  EXPECT_TRUE(report["plant"]["stable"].get<bool>());
  // 30 s per experiment (half the issue's 60 s): noise std of the estimate grows by
  // sqrt(2), so allow twice the 60 s thresholds (0.3 % mean, 1 % max) here.
  constexpr double kMeanErrorAt30s = 0.006;
  constexpr double kMaxErrorAt30s = 0.02;
  EXPECT_LE(report["truth"]["weighted_error_mean"].get<double>(), kMeanErrorAt30s);
  EXPECT_LE(report["truth"]["weighted_error_max"].get<double>(), kMaxErrorAt30s);
  // --json prints the same report on stdout.
  EXPECT_EQ(nlohmann::json::parse(r.out), report);
  const StateSpace plant = read_state_space(out / "plant.json");
  EXPECT_EQ(plant.input_names.size(), 3u);
  EXPECT_EQ(plant.output_names, (std::vector<std::string>{"q1", "q2", "q3"}));
}

TEST_F(CliPipeline, StepByStepChainGivesTheSamePlantAsIdentify) {
  TempDir out("steps");
  const std::string g = out / "g.csv", cl = out / "cl.json", p = out / "p.json";
  auto r = run_lpvid("markov --excitation v1,v2,v3 --output q1,q2,q3 --out " + g + " " + logs());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("hankel " + g + " --out " + (out / "sv.csv") + " --png " + (out / "sv.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("realize " + g + " --out " + cl);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("unloop --closed-loop " + cl + " --controller " + data("controller.json") + " --out " + p);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("bode --out " + (out / "b.png") + " --labels step,truth " + p + " " + data("truth_plant.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_state_space(p).order(), 6);
  EXPECT_EQ(read_state_space(cl).order(), 9);
}

TEST_F(CliPipeline, FrequencyDomainRouteFromSensitivityAgreesWithTheTruth) {
  TempDir out("frd");
  const std::string S = out / "S.csv", P = out / "P.csv", cmp = out / "cmp.json";
  auto r = run_lpvid("frf --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out " + S + " " + logs());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("unloop --sensitivity " + S + " --controller " + data("controller.json") + " --out " + P + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["route"], "P = C^-1 (S^-1 - I)");
  r = run_lpvid("compare " + P + " " + data("truth_plant.json") +
                " --band-min 1 --band-max 400 --weights 0.1,0.1,1 --out " + cmp);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(slurp(cmp));
  // Welch H1 from 3 x 30 s with Hann segments of 2048 samples (about 28 averages
  // per experiment): the random error of each bin is a few percent, and inverting
  // the loop amplifies it where the loop gain is small (above ~100 rad/s).
  // Measured 3.5 % mean (60 s records: 2.5 %); 5 % leaves room for other seeds.
  constexpr double kMeanErrorFromS = 0.05;
  EXPECT_LE(summary["weighted_error_mean"].get<double>(), kMeanErrorFromS);
  EXPECT_FALSE(summary["channels"].empty());
  std::printf("P from S vs truth, 1-400 rad/s: mean %.3f %%, max %.3f %%\n",
              100 * summary["weighted_error_mean"].get<double>(), 100 * summary["weighted_error_max"].get<double>());
  r = run_lpvid("bode --out " + (out / "b.png") + " --labels \"P from S,truth\" " + P + " " + data("truth_plant.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
}

TEST_F(CliPipeline, SensitivityFileWithAMissingPairIsRejected) {
  TempDir out("frdbad");
  std::ofstream(out / "S.csv") << "freq_hz,S_1_1_re,S_1_1_im,S_1_2_re\n1,1,0,0\n2,1,0,0\n";
  const auto r = run_lpvid("unloop --sensitivity " + (out / "S.csv") + " --controller " + data("controller.json") +
                           " --out " + (out / "P.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("S.csv"));
  EXPECT_FALSE(std::filesystem::exists(out / "P.csv"));
}

// ---- bad input: one line, exit code 2 (1 for failed computations), nothing written ----

struct Failure {
  int exit_code;
  std::string err;
  int files_written;
};

class CliBadInput : public CliPipeline {
 protected:
  Failure identify_with(const std::string& log_args, const std::string& controller = "") {
    TempDir out("bad");
    const auto r = run_lpvid("identify --method era --controller " + (controller.empty() ? data("controller.json") : controller) +
                             " --excitation v1,v2,v3 --output q1,q2,q3 --out " + (out / "result") + " " + log_args);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not one line: " << r.err;
    return {r.exit_code, r.err, count_files(out.path())};
  }
  // Writes a copy of the T_psi log with line `line` (1-based, counting the
  // comment and header lines) replaced by `text`, or truncated to `keep_rows` data rows.
  std::string edited_log(const TempDir& dir, int line, const std::string& text, int keep_rows = -1) {
    std::ifstream in(data("exp_T_psi.csv"));
    std::ofstream out(dir / "edited.csv");
    std::string row;
    int n = 0, data_rows = 0;
    while (std::getline(in, row)) {
      ++n;
      const bool is_data = !row.empty() && row[0] != '#' && row[0] != 't';
      if (is_data && keep_rows >= 0 && data_rows >= keep_rows) break;
      data_rows += is_data ? 1 : 0;
      out << (n == line ? text : row) << "\n";
    }
    return dir / "edited.csv";
  }
};

TEST_F(CliBadInput, MissingFile) {
  const auto f = identify_with("/nonexistent/run.csv");
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr("/nonexistent/run.csv"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, MissingColumnNamesTheColumn) {
  TempDir out("bad");
  const auto r = run_lpvid("identify --method era --controller " + data("controller.json") +
                           " --excitation v1,v2,v9 --output q1,q2,q3 --out " + (out / "r") + " " + logs());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("v9"));
  EXPECT_EQ(count_files(out.path()), 0);
}

TEST_F(CliBadInput, NonNumericCellIsReportedWithFileLineColumn) {
  TempDir dir("cell");
  const std::string path = edited_log(dir, 10, "0.007,1,2,abc,4,5,6,7,8,9");
  const auto f = identify_with(path);
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr(path + ":10:"));
  EXPECT_THAT(f.err, HasSubstr("abc"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, NaNCellIsRejected) {
  TempDir dir("nan");
  const auto f = identify_with(edited_log(dir, 12, "0.009,1,2,nan,4,5,6,7,8,9"));
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr(":12:"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, NonIncreasingTimeIsRejected) {
  TempDir dir("time");
  const auto f = identify_with(edited_log(dir, 12, "0.001,1,2,3,4,5,6,7,8,9"));
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr(":12:"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, NonUniformTimeIsRejected) {
  TempDir dir("uniform");
  const auto f = identify_with(edited_log(dir, 12, "0.00955,1,2,3,4,5,6,7,8,9"));
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr(":12:"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, RecordTooShortForTheLags) {
  TempDir dir("short");
  const auto f = identify_with(edited_log(dir, -1, "", 30) + " --lags 100");
  EXPECT_EQ(f.exit_code, 2);
  // The message says what was asked, what the record has, and the most it allows.
  EXPECT_THAT(f.err, HasSubstr("--lags 100 needs records longer than 100 samples, but the shortest has 30; give at "
                               "most 7 lags"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, MismatchedSampleRatesBetweenLogsAndController) {
  TempDir other("ctl");
  const auto r = run_lpvid("simulate platform --out " + (other / "d") +
                           " --positions middle --rate-hz 10000 --duration-s 0.2 --seed 1");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto f = identify_with(logs(), other / "d/middle_10000hz/controller.json");
  EXPECT_EQ(f.exit_code, 2);
  EXPECT_THAT(f.err, HasSubstr("mismatched sample rates"));
  EXPECT_EQ(f.files_written, 0);
}

TEST_F(CliBadInput, ExcitationWithoutSignalGivesNoModel) {
  // Logs whose outputs are pure noise unrelated to v: no order stands above the
  // noise floor (order 0) -> a failed computation, exit code 1.
  TempDir dir("noise");
  std::string paths;
  for (const char* name : {"exp_T_psi.csv", "exp_T_theta.csv", "exp_F_z.csv"}) {
    const Log log = read_log(data(name));
    Eigen::MatrixXd d = log.data;
    d.middleCols(7, 3) = Eigen::MatrixXd::Random(d.rows(), 3) * 1e-6;  // Eigen's fixed default seed
    write_log(dir / name, log.names, d);
    paths += " " + (dir / name);
  }
  const auto f = identify_with(paths);
  EXPECT_EQ(f.exit_code, 1) << f.err;
  EXPECT_EQ(f.files_written, 0);
  // hankel still shows the singular values, with order 0 and a warning.
  TempDir out("hankel0");
  auto r = run_lpvid("markov --excitation v1,v2,v3 --output q1,q2,q3 --out " + (out / "g.csv") + paths);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("hankel " + (out / "g.csv") + " --out " + (out / "sv.csv") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["order"], 0);
  EXPECT_TRUE(std::filesystem::exists(out / "sv.csv"));
}

TEST_F(CliBadInput, SingularIMinusCGIsRejected) {
  // A closed loop and a controller whose direct feedthroughs make I - D_C D_G singular.
  TempDir dir("singular");
  std::ofstream(dir / "g.json") << R"({"type":"state_space","ts":0.001,"A":[[0.5,0],[0,0.2]],"B":[[1],[1]],"C":[[1,1]],"D":[[1]],"inputs":["v"],"outputs":["q"]})";
  std::ofstream(dir / "c.json") << R"({"type":"state_space","ts":0.001,"A":[[0.5]],"B":[[1]],"C":[[1]],"D":[[1]],"inputs":["e"],"outputs":["u"]})";
  const auto r = run_lpvid("unloop --closed-loop " + (dir / "g.json") + " --controller " + (dir / "c.json") +
                           " --out " + (dir / "p.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("singular"));
  EXPECT_FALSE(std::filesystem::exists(dir / "p.json"));
}

TEST_F(CliBadInput, OutputOverInputIsRefused) {
  const std::string before = slurp(data("controller.json"));
  const auto r = run_lpvid("unloop --closed-loop " + data("truth_closed_loop.json") + " --controller " +
                           data("controller.json") + " --out " + data("controller.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("overwrite"));
  EXPECT_EQ(slurp(data("controller.json")), before);
}

}  // namespace identify_cli_test
}  // namespace lpvid
