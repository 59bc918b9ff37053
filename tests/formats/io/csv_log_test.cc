#include "formats/io/csv_log.h"

#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <random>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace csv_log_test {

using test::input_error;

class CsvLog : public test::TempDirTest {};

constexpr unsigned kSeed = 20261123;  // named seed for the random round trips

Eigen::MatrixXd random_log(Index n, Index channels, double ts, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> exponent(-300, 300);
  Eigen::MatrixXd data(n, channels + 1);
  for (Index k = 0; k < n; ++k) {
    data(k, 0) = static_cast<double>(k) * ts;
    for (Index j = 1; j <= channels; ++j)
      data(k, j) = normal(rng) * (j == channels ? std::pow(10.0, exponent(rng)) : 1.0);
  }
  return data;
}

TEST(CsvLogOptions, NegativeToleranceIsRejected) {
  LogReadOptions options;
  options.sampling_tolerance = -1;
  EXPECT_EQ(input_error([&] { options.validate(); }),
            "sampling tolerance -1 is not allowed; give a finite relative tolerance >= 0, e.g. 1e-3");
}

TEST_F(CsvLog, WriteThenRead_GivesIdenticalDoubles) {
  const Eigen::MatrixXd data = random_log(1000, 3, 1e-3, kSeed);
  const std::string p = path("run.csv");
  write_log(p, {"t", "v1", "q1", "tiny_or_huge"}, data, {"rig 2", "two\nlines"});
  const Log log = read_log(p);
  EXPECT_EQ(log.path, p);
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v1", "q1", "tiny_or_huge"}));
  ASSERT_EQ(log.data.rows(), 1000);
  ASSERT_EQ(log.data.cols(), 4);
  EXPECT_TRUE((log.data.array() == data.array()).all());
  EXPECT_DOUBLE_EQ(log.sample_period_s, 1e-3);
  EXPECT_EQ(read(p).substr(0, 35), "# rig 2\n# two\n# lines\nt,v1,q1,tiny_");
}

TEST_F(CsvLog, LargeFileAcrossReadChunks_RoundTrips) {
  // 200000 rows x 4 columns is ~10 MB: several 4 MiB read chunks, rows cut at chunk ends.
  const Eigen::MatrixXd data = random_log(200000, 3, 1e-4, kSeed + 1);
  const std::string p = path("big.csv");
  write_log(p, {"t", "a", "b", "c"}, data);
  ASSERT_GT(std::filesystem::file_size(p), size_t{8} << 20);
  const Log log = read_log(p);
  EXPECT_TRUE((log.data.array() == data.array()).all());
}

TEST_F(CsvLog, LineLongerThanReadBuffer_IsRead) {
  const std::string p = write("long.csv", "# " + std::string(9u << 20, 'x') + "\nt,a\n0,1\n1,2\n");
  const Log log = read_log(p);
  EXPECT_EQ(log.data.rows(), 2);
  EXPECT_EQ(log.data(1, 1), 2.0);
}

TEST_F(CsvLog, CommentsBlanksCrlfSpacesBomQuotesAndPlusSign_AreTolerated) {
  const std::string p = write("ok.csv",
                              "\xEF\xBB\xBF# header comment\r\n\r\n"
                              " t , \"v 1\",q1\r\n"
                              "# mid comment\r\n"
                              "0,  +1.5 ,-2\r\n"
                              "   \r\n"
                              "  # indented comment\r\n"
                              "0.5,.25,3e2\r\n"
                              "1.0,1.,-0");
  const Log log = read_log(p);
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v 1", "q1"}));
  Eigen::MatrixXd expected(3, 3);
  expected << 0, 1.5, -2, 0.5, 0.25, 300, 1.0, 1.0, -0.0;
  EXPECT_TRUE((log.data.array() == expected.array()).all());
  EXPECT_EQ(log.sample_period_s, 0.5);
}

TEST_F(CsvLog, ColumnLookup_ReturnsIndexAndCopies_OrNamesTheColumns) {
  const Log log = read_log(write("a.csv", "t,v1,q1\n0,1,2\n1,3,4\n"));
  EXPECT_EQ(log.column("q1"), 2);
  Eigen::MatrixXd expected(2, 2);
  expected << 2, 1, 4, 3;
  EXPECT_EQ(log.columns({"q1", "v1"}), expected);
  EXPECT_EQ(input_error([&] { log.column("q9"); }),
            path("a.csv") + ": no column 'q9'; columns are: t, v1, q1; check --excitation/--output names");
}

TEST_F(CsvLog, MissingFile_SaysCannotOpen) {
  EXPECT_EQ(input_error([&] { read_log(path("x.csv")); }),
            "cannot open '" + path("x.csv") + "': No such file or directory; check the path");
}

TEST_F(CsvLog, Directory_SaysGiveAFile) {
  EXPECT_EQ(input_error([&] { read_log(dir_.string()); }),
            "cannot open '" + dir_.string() + "': Is a directory; give a file, not a directory");
}

TEST_F(CsvLog, EmptyFile_IsReportedAtLine1) {
  const std::string p = write("e.csv", "");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":1:1: the file is empty; give a file that starts with a header row naming the columns, e.g. 't,v1,q1'");
}

TEST_F(CsvLog, OnlyComments_NoHeader) {
  const std::string p = write("c.csv", "# a\n\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:1: no header row, only comments and blank lines; add a header row naming the columns, "
                "e.g. 't,v1,q1'");
}

TEST_F(CsvLog, DuplicateColumnName_PointsAtSecondOccurrence) {
  const std::string p = write("d.csv", "t,v1, v1\n0,1,2\n1,2,3\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":1:7: duplicate column name 'v1' (also column 2); give every column its own name");
}

TEST_F(CsvLog, EmptyColumnName_IsRejected) {
  const std::string p = write("d.csv", "t,,q\n");
  EXPECT_EQ(input_error([&] { read_log(p); }), p + ":1:3: column 2 of the header has no name; name every column");
}

TEST_F(CsvLog, MissingTimeColumn_IsRejected) {
  const std::string p = write("m.csv", "# c\ntime,v1\n0,1\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":2:1: no column 't' in the header; add a time column 't' in seconds (see docs/formats.md)");
}

TEST_F(CsvLog, SemicolonSeparated_SaysUseCommas) {
  const std::string p = write("s.csv", "t;v1\n0;1\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":1:1: the header 't;v1' has a single column; separate columns with commas");
}

TEST_F(CsvLog, TooFewCells_PointsAtEndOfRow) {
  const std::string p = write("f.csv", "t,a,b\n0,1,2\n0.001,1\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:8: row has 2 cells but the header names 3 columns; give every row one cell per column");
}

TEST_F(CsvLog, TooManyCells_PointsAtFirstExtraCell) {
  const std::string p = write("f.csv", "t,a,b\n0,1,2\n0.001,1,2, 3\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:12: row has 4 cells but the header names 3 columns; give every row one cell per column");
}

TEST_F(CsvLog, NonNumericCell_NamesTextColumnAndRule) {
  const std::string p = write("n.csv", "t,q1,q2\n0,1,2\n0.001, 1,abc\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:10: cannot parse 'abc' as a number in column 'q2'; write a number there (every cell after the header is a number)");
}

TEST_F(CsvLog, NumberWithTrailingText_IsRejected) {
  const std::string p = write("n.csv", "t,q1\n0,1.5x\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":2:3: cannot parse '1.5x' as a number in column 'q1'; write a number there (every cell after the header is a number)");
}

TEST_F(CsvLog, EmptyCell_IsRejected) {
  const std::string p = write("n.csv", "t,q1,q2\n0,,1\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":2:3: empty cell in column 'q1'; write a number there (every cell after the header is a number)");
}

TEST_F(CsvLog, NaNAndInf_AreRejected) {
  const std::string p = write("nan.csv", "t,q1\n0,1\n1,nan\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:3: 'nan' in column 'q1' is not a finite number; write a finite number there (NaN/Inf not allowed)");
  const std::string q = write("inf.csv", "t,q1\n0,-inf\n");
  EXPECT_EQ(input_error([&] { read_log(q); }),
            q + ":2:3: '-inf' in column 'q1' is not a finite number; write a finite number there (NaN/Inf not allowed)");
}

TEST_F(CsvLog, SingleSample_IsTooFew) {
  const std::string p = write("one.csv", "t,a\n0,1\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":3:1: the log has 1 sample; a log needs at least 2 rows of samples after the header: record a longer log");
}

TEST_F(CsvLog, RepeatedTime_PointsAtTheRowAfterComments) {
  const std::string p = write("r.csv", "t,a\n0,1\n# c\n\n0.001,1\n0.001,2\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":6:1: time t = 0.001 s is not after the previous row's t = 0.001 s; t must increase strictly from row "
                "to row (one file = one experiment)");
}

TEST_F(CsvLog, NonUniformSampling_ReportsStepNominalAndTolerance) {
  // Mean period (4 - 0) / 4 = 1 s; the step 2 -> 3.5 deviates by 0.5.
  const std::string p = write("u.csv", "a, t\n1,0\n1, 1\n1, 2\n-1, 3.5\n1, 4\n");
  EXPECT_EQ(input_error([&] { read_log(p); }),
            p + ":5:5: time step 1.5 s (from t = 2 s) differs from the mean sample period 1 s by a relative 0.5, above "
                "the sampling tolerance 0.001; resample the log to a uniform grid (or split it at the gap), or raise "
                "the sampling tolerance");
  LogReadOptions loose;
  loose.sampling_tolerance = 0.5;
  EXPECT_EQ(read_log(p, loose).sample_period_s, 1.0);
}

TEST_F(CsvLog, JitterWithinTolerance_IsAccepted) {
  // t printed with 7 decimals at 1 kHz: rounding moves a step by up to 1e-7 s = 1e-4 relative.
  std::string text = "t,a\n";
  for (int k = 0; k < 100; ++k) text += fmt::format("{:.7f},0\n", k * 1e-3 + (k % 2 ? 4e-8 : -4e-8));
  const Log log = read_log(write("j.csv", text));
  EXPECT_NEAR(log.sample_period_s, 1e-3, 1e-9);
}

TEST_F(CsvLog, WriteRejectsNaNBadNamesAndMissingTime_LeavingNoFile) {
  Eigen::MatrixXd data(2, 2);
  data << 0, 1, 1, std::nan("");
  const std::string p = path("w.csv");
  EXPECT_EQ(input_error([&] { write_log(p, {"t", "a"}, data); }),
            "cannot write '" + p + "': row 2 (line 3), column 'a' holds nan; only finite numbers can be written, check "
            "the computation that produced it");
  EXPECT_EQ(input_error([&] { write_log(p, {"t", "a,b"}, Eigen::MatrixXd::Zero(2, 2)); }),
            "cannot write '" + p + "': column name 'a,b' is not allowed; a name is non-empty, has no comma, quote or "
            "line break, no surrounding blanks and does not start with '#'");
  EXPECT_EQ(input_error([&] { write_log(p, {"time", "a"}, Eigen::MatrixXd::Zero(2, 2)); }),
            "cannot write '" + p + "': no column 't'; a log needs a time column 't' in seconds");
  EXPECT_EQ(input_error([&] { write_log(p, {"t"}, Eigen::MatrixXd::Zero(2, 2)); }),
            "cannot write '" + p + "': 1 column names for 2 columns of data; give one name per column");
  EXPECT_TRUE(entries().empty());
}

}  // namespace csv_log_test
}  // namespace lpvid
