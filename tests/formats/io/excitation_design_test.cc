#include "formats/io/excitation_design.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/excitation_file.h"
#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace excitation_design_test {

using ::testing::HasSubstr;

// A periodic design of 2 channels, Hadamard-coded (E = 2), R = 1, T = 1, P = 2, L = 8.
ExcitationDesign sample_design() {
  ExcitationDesign d;
  d.kind = "multisine";
  d.sample_rate_hz = 1000;
  d.channels = 2;
  d.period_samples = 8;
  d.periods = 2;
  d.transient_periods = 1;
  d.realisations = 1;
  d.experiments = 2;
  d.mimo = "hadamard";
  d.excited_bins = {{1, 2, 3}, {1, 3}};
  d.coding = Eigen::MatrixXd(2, 2);
  d.coding << 1, 1, 1, -1;
  d.phase = "random";
  d.seed = 18446744073709551615ULL;  // the largest seed survives (no double on the way)
  d.crest_factor = {1.5, 1.25};
  d.rms = {0.1, 0.30000000000000004};
  d.peak = {0.15, 0.375};
  return d;
}

void expect_same(const ExcitationDesign& a, const ExcitationDesign& b) {
  EXPECT_EQ(a.format, b.format);
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz);
  EXPECT_EQ(a.channels, b.channels);
  EXPECT_EQ(a.period_samples, b.period_samples);
  EXPECT_EQ(a.periods, b.periods);
  EXPECT_EQ(a.transient_periods, b.transient_periods);
  EXPECT_EQ(a.realisations, b.realisations);
  EXPECT_EQ(a.experiments, b.experiments);
  EXPECT_EQ(a.mimo, b.mimo);
  EXPECT_EQ(a.excited_bins, b.excited_bins);
  EXPECT_TRUE(a.coding == b.coding);
  EXPECT_EQ(a.phase, b.phase);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.crest_factor, b.crest_factor);
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.peak, b.peak);
}

class ExcitationDesignTest : public test::TempDirTest {};

TEST_F(ExcitationDesignTest, JsonRoundTripKeepsEveryFieldExactly) {
  const ExcitationDesign d = sample_design();
  const std::string json = excitation_design_json(d);
  EXPECT_EQ(json.find('\n'), std::string::npos);  // one line
  EXPECT_EQ(json.rfind("{\"format\":1,\"kind\":\"multisine\",", 0), 0u) << json;
  expect_same(parse_excitation_design(json, "x.csv"), d);
  EXPECT_EQ(d.total_samples(), 2 * 3 * 8);
}

// excite --amplitude records every line's amplitude; a design without the key (every
// design before it) still reads, with none.
TEST_F(ExcitationDesignTest, AmplitudesRoundTripAndAreOptional) {
  EXPECT_TRUE(parse_excitation_design(excitation_design_json(sample_design()), "x.csv").amplitudes.empty());
  ExcitationDesign d = sample_design();
  d.amplitudes = {{0.25, 0.125, 0.1}, {1e-3, 2.5}};
  const std::string json = excitation_design_json(d);
  EXPECT_NE(json.find(",\"amplitudes\":[[0.25,0.125,0.1],[0.001,2.5]]}"), std::string::npos) << json;
  EXPECT_EQ(parse_excitation_design(json, "x.csv").amplitudes, d.amplitudes);
  auto refused = [&](const std::string& text, const std::string& what) {
    try {
      parse_excitation_design(text, "x.csv");
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(what));
      EXPECT_THAT(e.what(), HasSubstr("x.csv:1:"));
    }
  };
  std::string short_list = json;
  short_list.replace(short_list.find("[0.001,2.5]"), 11, "[0.001]");
  refused(short_list, "amplitudes of v2: 1 values for 2 excited bins");
  std::string negative = json;
  negative.replace(negative.find("0.125"), 5, "-0.12");
  refused(negative, "amplitudes of v1: -0.12 is not a positive number");
  std::string text = json;
  text.replace(text.find("2.5]"), 3, "\"x\"");
  refused(text, "x.csv:1:" + std::to_string(text.find("\"amplitudes\"") + 1) + ": excitation design \"amplitudes\"");
}

TEST_F(ExcitationDesignTest, TheLineIsFoundInALogWrittenWithIt) {
  const ExcitationDesign d = sample_design();
  const Index N = d.total_samples();
  Eigen::MatrixXd data(N, 3);
  for (Index k = 0; k < N; ++k) data.row(k) << k / 1000.0, 0.1 * (k % 8 == 1), -0.2;
  const std::string p = path("ms.csv");
  write_log(p, {"t", "v1", "v2"}, data, {"made by a test", excitation_design_comment(d)});
  const std::string text = read(p);
  EXPECT_THAT(text, HasSubstr("\n# lpvid-excitation: {\"format\":1,"));
  const auto found = read_excitation_design(p);
  ASSERT_TRUE(found.has_value());
  expect_same(*found, d);
  const ExcitationFile file = read_excitation_file(p);
  EXPECT_TRUE(file.log.data == data);
  // A log without the line: no design.
  write_log(path("plain.csv"), {"t", "v1", "v2"}, data);
  EXPECT_FALSE(read_excitation_design(path("plain.csv")).has_value());
  EXPECT_THROW(read_excitation_file(path("plain.csv")), InputError);
}

TEST_F(ExcitationDesignTest, MatFileRoundTripsTheSamplesNamesAndDesign) {
  const ExcitationDesign d = sample_design();
  const Index N = d.total_samples();
  Eigen::MatrixXd data(N, 3);
  for (Index k = 0; k < N; ++k) data.row(k) << k / 1000.0, std::sin(0.3 * k), std::cos(0.1 * k) / 3;
  const std::string p = path("ms.mat");
  {
    AtomicFileWriter out(p);
    write_excitation_mat(out, {"t", "v1", "v2"}, data, d);
    out.commit();
  }
  const ExcitationFile file = read_excitation_file(p);
  EXPECT_TRUE(file.log.data == data);
  EXPECT_EQ(file.log.names, (std::vector<std::string>{"t", "v1", "v2"}));
  EXPECT_NEAR(file.log.sample_period_s, 1e-3, 1e-15);
  expect_same(file.design, d);
}

TEST_F(ExcitationDesignTest, MalformedLinesAreRefusedAtFileLineColumn) {
  // Line 2, the JSON starts after "# lpvid-excitation: " (20 bytes): column 21.
  auto expect_error = [&](const std::string& json, const std::string& text) {
    const std::string p = write("bad.csv", "# a comment\n# lpvid-excitation: " + json + "\nt,v1\n0,1\n0.001,2\n");
    try {
      read_excitation_design(p);
      ADD_FAILURE() << "no error for " << json;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(text)) << json;
      EXPECT_THAT(e.what(), HasSubstr("bad.csv:2:")) << e.what();
    }
  };
  std::string good = excitation_design_json(sample_design());
  expect_error(good.substr(0, good.size() - 1), "bad.csv:2:");                         // truncated JSON
  expect_error("[1,2]", "bad.csv:2:21: the excitation design must be a JSON object");  // not an object
  std::string no_kind = good;
  no_kind.replace(no_kind.find("\"kind\""), 6, "\"kine\"");
  expect_error(no_kind, "no key \"kind\"");
  std::string bad_l = good;
  bad_l.replace(bad_l.find("\"period_samples\":8"), 18, "\"period_samples\":\"8\"");
  expect_error(bad_l, "\"period_samples\": \"8\" is not a whole number");
  std::string bad_bin = good;
  bad_bin.replace(bad_bin.find("[[1,2,3]"), 8, "[[1,2,4]");  // 4 = L/2 is not below Nyquist
  expect_error(bad_bin, "bin 4 is not in 1..3");
  std::string bad_mimo = good;
  bad_mimo.replace(bad_mimo.find("hadamard"), 8, "hadamart");
  expect_error(bad_mimo, "mimo 'hadamart'");
  // The position points at the key: "period_samples" in the line.
  const std::string p = write("col.csv", "# lpvid-excitation: " + bad_l + "\nt,v1\n0,1\n0.001,2\n");
  const size_t column = 20 + bad_l.find("\"period_samples\"") + 1;
  try {
    read_excitation_design(p);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("col.csv:1:" + std::to_string(column) + ":"));
  }
}

TEST_F(ExcitationDesignTest, TwoDesignLinesAreRefused) {
  const std::string line = "# lpvid-excitation: " + excitation_design_json(sample_design()) + "\n";
  const std::string p = write("two.csv", line + line + "t,v1,v2\n0,1,1\n0.001,2,2\n");
  try {
    read_excitation_design(p);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("two.csv:2:1: a second excitation design line (the first is on line 1)"));
  }
}

TEST_F(ExcitationDesignTest, ALogThatDoesNotMatchItsDesignIsRefused) {
  const ExcitationDesign d = sample_design();
  EXPECT_NO_THROW(check_design_matches(d, 48, 1e-3, 2, "x.csv"));
  EXPECT_THROW(check_design_matches(d, 47, 1e-3, 2, "x.csv"), InputError);   // cut
  EXPECT_THROW(check_design_matches(d, 48, 5e-4, 2, "x.csv"), InputError);   // other rate
  EXPECT_THROW(check_design_matches(d, 48, 1e-3, 3, "x.csv"), InputError);   // other channels
  try {
    check_design_matches(d, 47, 1e-3, 2, "x.csv");
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("x.csv: 47 samples but the excitation design describes 48"));
  }
}

}  // namespace excitation_design_test
}  // namespace lpvid
