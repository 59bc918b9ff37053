// Tests of the CSV reader's internals (formats/io/csv_detail.h): a regular file
// split into parts read on parallel threads gives exactly the serial result
// (data, line/column positions, the first error in file order), stdin reads the
// same, and the plain-decimal fast path gives the same doubles as strtod.
#include "formats/io/csv_detail.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

#include "tests/formats/io/test_util.h"

namespace lpvid::detail {
namespace csv_detail_test {

using test::input_error;

class CsvDetail : public test::TempDirTest {};

constexpr unsigned kSeed = 20261124;  // named seed of the random cells

const std::string kKeyHint = "add a time column 't' in seconds (see docs/formats.md)";

// Never split (a file smaller than this is read on one thread).
CsvReadTuning serial() {
  CsvReadTuning tuning;
  tuning.parallel_min_bytes = std::numeric_limits<uint64_t>::max();
  return tuning;
}

CsvReadTuning split_at(std::vector<uint64_t> offsets) {
  CsvReadTuning tuning = serial();
  tuning.split_offsets = std::move(offsets);
  return tuning;
}

// Everything a reader returns, with the key cell's position of every row.
std::string describe(const NumericCsv& csv) {
  std::string out = fmt::format("names {} header {} key {} end {}\n", fmt::join(csv.names, "|"), csv.header_line,
                                csv.key, csv.end_line);
  for (const auto& c : csv.leading_comments) out += fmt::format("# {}:{} {}\n", c.line, c.column, c.text);
  for (Index r = 0; r < csv.data.rows(); ++r) {
    const CellPosition at = csv.key_position(r);
    out += fmt::format("{}:{}", at.line, at.column);
    for (Index j = 0; j < csv.data.cols(); ++j) {
      const double v = csv.data(r, j);
      uint64_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      out += fmt::format(" {:x}", bits);
    }
    out += '\n';
  }
  return out;
}

// The result of a read, or its error message.
std::string outcome(const std::string& path, const CsvReadTuning& tuning) {
  std::string text;
  const std::string error = input_error([&] { text = describe(read_numeric_csv(path, "t", kKeyHint, tuning)); });
  return error == "<no error>" ? text : "error: " + error;
}

// Comments, blank and blank-with-CR lines, CRLF and LF, indented rows, '+'
// signs, a key column that moves, and a last line without '\n'.
const std::string kAwkward =
    "\xEF\xBB\xBF# leading\r\n"
    "\n"
    "a, t ,b\r\n"
    "1,0,2\r\n"
    "# mid comment, near a split\r\n"
    "  \t\r\n"
    "3, 0.5,4\n"
    "\n"
    "  # indented comment\n"
    " 5,1.0 ,+6\r\n"
    "7,1.5,-0\n"
    "#\n"
    "\r\n"
    "8,  2.0,  .25\n"
    "9,2.5,1.";

TEST_F(CsvDetail, SplitAtEveryOffset_MatchesSerialRead) {
  const std::string p = write("awkward.csv", kAwkward);
  const std::string expected = outcome(p, serial());
  ASSERT_EQ(expected.rfind("error", 0), std::string::npos) << expected;
  for (uint64_t at = 0; at <= kAwkward.size() + 1; ++at) {
    EXPECT_EQ(outcome(p, split_at({at})), expected) << "split at " << at;
    EXPECT_EQ(outcome(p, split_at({at, at + 5, at + 17})), expected) << "split at " << at << " +5 +17";
  }
}

TEST_F(CsvDetail, ErrorInSecondPart_HasTheSerialLineAndColumn) {
  const std::string text = "t,a\n# c\n0,1\n1,2\r\n\n2, 3\n3,x\n4,5\n";
  const std::string p = write("bad.csv", text);
  const std::string expected = outcome(p, serial());
  EXPECT_EQ(expected, "error: " + p +
                          ":7:3: cannot parse 'x' as a number in column 'a'; write a number there (every cell after the "
                          "header is a number)");
  for (uint64_t at = 0; at <= text.size(); ++at) EXPECT_EQ(outcome(p, split_at({at})), expected) << "split at " << at;
}

TEST_F(CsvDetail, ErrorsInBothParts_TheFirstInFileOrderWins) {
  const std::string text = "t,a\n0,1\n1,2,3\n2,3\n3,4\n4,nan\n5,6\n";
  const std::string p = write("two.csv", text);
  const std::string expected = outcome(p, serial());
  EXPECT_EQ(expected, "error: " + p +
                          ":3:5: row has 3 cells but the header names 2 columns; give every row one cell per column");
  for (uint64_t at = 0; at <= text.size(); ++at) EXPECT_EQ(outcome(p, split_at({at})), expected) << "split at " << at;
}

TEST_F(CsvDetail, LargeFileOnParallelThreads_ReportsAnErrorNearTheEndAtItsLine) {
  // ~10 MB: above parallel_min_bytes, so the default tuning splits it.
  constexpr int kRows = 500000;
  std::string text = "# big\nt,a,b\n";
  for (int k = 0; k < kRows; ++k) text += fmt::format("{},{}.125,-{}.5\n", k, k % 977, k % 13);
  const std::string p = write("big.csv", text);
  ASSERT_GE(text.size(), CsvReadTuning{}.parallel_min_bytes);
  const NumericCsv csv = read_numeric_csv(p, "t", kKeyHint);
  ASSERT_EQ(csv.data.rows(), kRows);
  for (int k = 0; k < kRows; k += 9973) {
    EXPECT_EQ(csv.data(k, 0), k);
    EXPECT_EQ(csv.data(k, 1), k % 977 + 0.125);
    EXPECT_EQ(csv.data(k, 2), -(k % 13 + 0.5));
    EXPECT_EQ(csv.key_position(k).line, k + 3);
  }
  EXPECT_EQ(csv.end_line, kRows + 3);
  const std::string q = write("big_bad.csv", text + "500000,1,2\n500001,1,2;\n");
  EXPECT_EQ(input_error([&] { read_numeric_csv(q, "t", kKeyHint); }),
            q + ":500004:10: cannot parse '2;' as a number in column 'b'; write a number there (every cell after the header is a number)");
}

TEST_F(CsvDetail, Stdin_ReadsTheSameAsTheFile) {
  const std::string p = write("awkward.csv", kAwkward);
  const int saved = ::dup(STDIN_FILENO);
  ASSERT_GE(saved, 0);
  const int fd = ::open(p.c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::dup2(fd, STDIN_FILENO), STDIN_FILENO);
  ::close(fd);
  const std::string from_stdin = outcome("-", serial());
  ASSERT_EQ(::dup2(saved, STDIN_FILENO), STDIN_FILENO);
  ::close(saved);
  EXPECT_EQ(from_stdin, outcome(p, serial()));
}

TEST_F(CsvDetail, PlainDecimals_GiveTheDoublesOfStrtod) {
  // Cells at the edges of the fast path (8 digits before and after the point,
  // 2^53, leading zeros, "-0", ".5", "5.") and random ones on both sides of it.
  std::vector<std::string> cells = {"0",
                                    "12345678.12345678",
                                    "99999999.99999999",
                                    "123456789.5",
                                    "0.123456789",
                                    "-00000000.00000001",
                                    "-0",
                                    ".5",
                                    "5.",
                                    "-.5",
                                    "007.0100",
                                    "9007199254740992",
                                    "9007199254740993",
                                    "-9007199254740993.5",
                                    "0.9007199254740993",
                                    "1234567890123456789",
                                    "12345678901234567890",
                                    "0.0000000000000000000001",
                                    "0.1234567890123456789",
                                    "0.30000000000000004",
                                    "1e5",
                                    "1.5E-3",
                                    "4.9e-324"};
  std::mt19937_64 rng(kSeed);
  std::uniform_int_distribution<int> digits(1, 21);
  std::uniform_int_distribution<int> digit(0, 9);
  for (int k = 0; k < 2000; ++k) {
    std::string cell = k % 2 ? "-" : "";
    const int before = digits(rng) % 12, after = digits(rng);
    for (int i = 0; i < before; ++i) cell += static_cast<char>('0' + digit(rng));
    cell += '.';
    for (int i = 0; i < after; ++i) cell += static_cast<char>('0' + digit(rng));
    cells.push_back(cell);
  }
  std::string text = "t,v\n";
  for (size_t k = 0; k < cells.size(); ++k) text += fmt::format("{},{}\n", k, cells[k]);
  const NumericCsv csv = read_numeric_csv(write("d.csv", text), "t", kKeyHint, serial());
  ASSERT_EQ(csv.data.rows(), static_cast<Index>(cells.size()));
  for (size_t k = 0; k < cells.size(); ++k) {
    const double expected = std::strtod(cells[k].c_str(), nullptr);
    const double got = csv.data(static_cast<Index>(k), 1);
    EXPECT_EQ(std::memcmp(&got, &expected, sizeof got), 0) << cells[k] << " read as " << got;
  }
}

}  // namespace csv_detail_test
}  // namespace lpvid::detail

namespace lpvid::detail {
namespace csv_detail_test {

class CsvLimits : public test::TempDirTest {};

TEST_F(CsvLimits, EndlessLine_FromADevice_FailsAtTheLimit) {
  // markov ... /dev/zero read until memory ran out.
  EXPECT_EQ(test::input_error([&] { read_numeric_csv("/dev/zero", "t", "hint"); }),
            "/dev/zero:1:1: line longer than 16 MiB; a CSV line holds one row of numbers: check that this is the "
            "right file (not a binary or a device)");
}

TEST_F(CsvLimits, LongLineInARegularFile_NamesItsLine) {
  const std::string p = write("long.csv", "t,a\n0,1\n1," + std::string(kMaxCsvLineBytes + 10, '1') + "\n");
  EXPECT_EQ(test::input_error([&] { read_numeric_csv(p, "t", "hint"); }),
            p + ":3:1: line longer than 16 MiB; a CSV line holds one row of numbers: check that this is the right file "
                "(not a binary or a device)");
}

TEST_F(CsvLimits, WideHeader_IsLinearAndBounded) {
  // 300,000 columns took more than 60 s (quadratic duplicate check).
  std::string header = "t";
  for (size_t j = 1; j <= kMaxCsvColumns; ++j) header += ",c" + std::to_string(j);
  const std::string p = write("wide.csv", header + "\n");
  EXPECT_EQ(test::input_error([&] { read_numeric_csv(p, "t", "hint"); }),
            p + ":1:" + std::to_string(header.rfind(',') + 2) + ": the header has more than 65536 columns; lpvid reads at "
                "most 65536: check that this is the right file, or split it");
  std::string dup = "t";
  for (size_t j = 1; j < 60000; ++j) dup += ",c" + std::to_string(j);
  dup += ",c17\n0";
  for (size_t j = 1; j <= 60000; ++j) dup += ",0";
  const std::string q = write("dup.csv", dup + "\n");
  EXPECT_NE(test::input_error([&] { read_numeric_csv(q, "t", "hint"); }).find("duplicate column name 'c17' (also column 18)"),
            std::string::npos);
}

}  // namespace csv_detail_test
}  // namespace lpvid::detail
