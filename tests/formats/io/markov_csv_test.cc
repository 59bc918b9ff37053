#include "formats/io/markov_csv.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace markov_csv_test {

using test::input_error;

class MarkovCsv : public test::TempDirTest {};

constexpr unsigned kSeed = 11;  // named seed for the random Markov parameters

MarkovFile random_file(Index p, Index m, Index lags) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> normal(0.0, 1e-3);
  MarkovFile file;
  file.sample_period_s = 1e-3 / 3;
  for (Index i = 0; i < m; ++i) file.inputs.push_back("v" + std::to_string(i + 1));
  for (Index i = 0; i < p; ++i) file.outputs.push_back("q" + std::to_string(i + 1));
  for (Index k = 0; k < lags; ++k) {
    Eigen::MatrixXd g(p, m);
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) g(i, j) = normal(rng);
    file.g.push_back(g);
  }
  file.noise_std = Eigen::MatrixXd::Constant(p, m, 1e-6 / 7);
  file.input_rms = Eigen::VectorXd::LinSpaced(m, 0.1, 0.3);
  file.output_rms = Eigen::VectorXd::Constant(p, 2.0 / 3);
  return file;
}

void expect_identical(const MarkovFile& a, const MarkovFile& b) {
  ASSERT_EQ(a.g.size(), b.g.size());
  for (size_t k = 0; k < a.g.size(); ++k) EXPECT_TRUE(a.g[k] == b.g[k]) << "lag " << k;
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);
  EXPECT_EQ(a.inputs, b.inputs);
  EXPECT_EQ(a.outputs, b.outputs);
  EXPECT_TRUE(a.noise_std.rows() == b.noise_std.rows() && a.noise_std.cols() == b.noise_std.cols() &&
              a.noise_std == b.noise_std);
  EXPECT_TRUE(a.input_rms.size() == b.input_rms.size() && a.input_rms == b.input_rms);
  EXPECT_TRUE(a.output_rms.size() == b.output_rms.size() && a.output_rms == b.output_rms);
}

TEST_F(MarkovCsv, WriteThenRead_IsIdentical) {
  const MarkovFile file = random_file(2, 3, 50);
  const std::string p = path("g.csv");
  write_markov_csv(p, file);
  expect_identical(read_markov_csv(p), file);
  EXPECT_EQ(entries(), std::vector<std::string>{"g.csv"});
}

TEST_F(MarkovCsv, WithoutOptionalMetadata_RoundTripsWithEmptyFields) {
  MarkovFile file = random_file(1, 1, 3);
  file.noise_std.resize(0, 0);
  file.input_rms.resize(0);
  file.output_rms.resize(0);
  const std::string p = path("g.csv");
  write_markov_csv(p, file);
  expect_identical(read_markov_csv(p), file);
}

TEST_F(MarkovCsv, Text_FollowsTheLayout) {
  MarkovFile file;
  file.sample_period_s = 0.001;
  file.inputs = {"v1", "v2"};
  file.outputs = {"q1"};
  Eigen::MatrixXd g0(1, 2), g1(1, 2);
  g0 << 0, 0;
  g1 << 1.5e-06, -2e-07;
  file.g = {g0, g1};
  file.noise_std = Eigen::MatrixXd(1, 2);
  file.noise_std << 1e-06, 2e-06;
  file.input_rms = Eigen::Vector2d(0.5, 0.5);
  file.output_rms = Eigen::VectorXd::Constant(1, 1e-4);
  EXPECT_EQ(markov_csv_text(file),
            "# lpvid markov 1\n"
            "# sample_period_s: 0.001\n"
            "# inputs: v1,v2\n"
            "# outputs: q1\n"
            "# noise_std: 1e-06,2e-06\n"
            "# input_rms: 0.5,0.5\n"
            "# output_rms: 0.0001\n"
            "lag,g_q1_v1,g_q1_v2\n"
            "0,0,0\n"
            "1,1.5e-06,-2e-07\n");
}

const char* const kGood =
    "# lpvid markov 1\n"
    "# made by hand\n"
    "# sample_period_s: 0.001\n"
    "# inputs: v1, v2\n"
    "# outputs: q1\n"
    "lag,g_q1_v1,g_q1_v2\n"
    "0,0,0\n"
    "1,1,2\n"
    "2,3,4\n";

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST_F(MarkovCsv, HandWrittenFile_Reads) {
  const MarkovFile file = read_markov_csv(write("g.csv", kGood));
  ASSERT_EQ(file.g.size(), 3u);
  EXPECT_EQ(file.g[2](0, 1), 4.0);
  EXPECT_EQ(file.inputs, (std::vector<std::string>{"v1", "v2"}));
  EXPECT_EQ(file.noise_std.size(), 0);
}

TEST_F(MarkovCsv, MissingMagicLine_SaysNotAMarkovFile) {
  const std::string p = write("g.csv", replace(kGood, "# lpvid markov 1\n", ""));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":1:1: not an lpvid Markov-parameter file: the first line must be '# lpvid markov 1'; write the file "
                "with `lpvid markov`");
}

TEST_F(MarkovCsv, OtherVersion_IsUnsupported) {
  const std::string p = write("g.csv", replace(kGood, "markov 1", "markov 2"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":1:3: unsupported format 'lpvid markov 2'; write the file with this lpvid's `lpvid markov` ('lpvid markov 1')");
}

TEST_F(MarkovCsv, MissingSamplePeriod_IsNamed) {
  const std::string p = write("g.csv", replace(kGood, "# sample_period_s: 0.001\n", ""));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":5:1: missing metadata line '# sample_period_s: <seconds>' before the header; write the file with "
                "`lpvid markov`");
}

TEST_F(MarkovCsv, BadSamplePeriod_PointsAtTheValue) {
  const std::string p = write("g.csv", replace(kGood, "0.001", "1ms"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":3:20: cannot parse '1ms' as a finite number for 'sample_period_s'; write a decimal number such as 0.001");
  const std::string q = write("h.csv", replace(kGood, "0.001", "0"));
  EXPECT_EQ(input_error([&] { read_markov_csv(q); }),
            q + ":3:20: sample_period_s is 0; write the positive sample period in seconds");
}

TEST_F(MarkovCsv, DuplicateInputName_PointsAtIt) {
  const std::string p = write("g.csv", replace(kGood, "v1, v2", "v1, v1"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":4:15: name 'v1' appears twice in 'inputs'; give every signal its own name");
}

TEST_F(MarkovCsv, HeaderNotMatchingNames_PointsAtTheColumn) {
  const std::string p = write("g.csv", replace(kGood, "g_q1_v2", "g_q1_v3"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":6:13: column 3 is 'g_q1_v3' where 'g_q1_v2' is expected; the header is 'lag' then g_<output>_<input> "
                "over outputs (outer) and inputs (inner) as listed in the metadata: write the file with `lpvid markov`");
}

TEST_F(MarkovCsv, LagGap_PointsAtTheRow) {
  const std::string p = write("g.csv", replace(kGood, "2,3,4", "3,3,4"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":9:1: lag 3 where lag 2 is expected; rows must list lags 0, 1, 2, ... in order without gaps");
}

TEST_F(MarkovCsv, NoiseStdWithWrongCount_IsRejected) {
  const std::string p = write("g.csv", replace(kGood, "# outputs: q1\n", "# outputs: q1\n# noise_std: 1e-6\n"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":6:14: 'noise_std' has 1 values; it needs 2 (comma separated, row-major over outputs then inputs): give that many");
}

TEST_F(MarkovCsv, NonNumericCell_FollowsTheLogRules) {
  const std::string p = write("g.csv", replace(kGood, "1,1,2", "1,one,2"));
  EXPECT_EQ(input_error([&] { read_markov_csv(p); }),
            p + ":8:3: cannot parse 'one' as a number in column 'g_q1_v1'; write a number there (every cell after the header "
            "is a number)");
}

TEST_F(MarkovCsv, WriteWithWrongShape_FailsAndLeavesNoFile) {
  MarkovFile file = random_file(2, 2, 3);
  file.g[1] = Eigen::MatrixXd::Zero(2, 3);
  const std::string p = path("g.csv");
  EXPECT_EQ(input_error([&] { write_markov_csv(p, file); }),
            "cannot write '" + p + "': g[1] is 2×3, expected 2×2 (outputs × inputs)");
  EXPECT_TRUE(entries().empty());
}

}  // namespace markov_csv_test
}  // namespace lpvid
