// Golden test of `lpvid identify` (cli/identify.cc): the whole chain on the
// golden logs, compared with the golden report and models.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "formats/io/markov_csv.h"
#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace identify_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

// Same chain as markov -> hankel -> realize -> unloop; the bars are theirs
// (markov_golden_test.cc, hankel_golden_test.cc, realize_golden_test.cc).
constexpr double kMarkovDigits = 10.0;
constexpr double kSingularValueDigits = 8.0;  // relative to the largest singular value
constexpr double kResponseDigits = 8.0;       // relative to each channel's peak
// The weighted error |W(P^ - P)W| / |WPW| is ~1.5 % here: the difference P^ - P
// cancels the leading two digits that P^ shares with the truth, so 8 digits of
// the response leave ~6 in the error figures.
constexpr double kWeightedErrorDigits = 6.0;

class IdentifyGolden : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("golden_identify");
    const auto r = run_lpvid("identify --method era --controller " + sim_dir() + "/controller.json " + kChannels + " --truth " +
                             sim_dir() + "/truth_plant.json --out " + (*dir_ / "out") + " --json " + golden_logs());
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string fresh(const std::string& name) { return *dir_ / ("out/" + name); }
  static TempDir* dir_;
};
TempDir* IdentifyGolden::dir_ = nullptr;

TEST_F(IdentifyGolden, ReportHasTheGoldenOrdersSingularValuesAndWeightedErrors) {
  const auto a = nlohmann::json::parse(slurp(fresh("report.json")));
  const auto b = nlohmann::json::parse(slurp(data("identify/report.json")));
  EXPECT_EQ(a["closed_loop"]["order"], b["closed_loop"]["order"]);
  EXPECT_EQ(a["closed_loop"]["block_rows"], b["closed_loop"]["block_rows"]);
  EXPECT_EQ(a["closed_loop"]["block_cols"], b["closed_loop"]["block_cols"]);
  EXPECT_EQ(a["plant"]["order"], b["plant"]["order"]);
  EXPECT_EQ(a["plant"]["removed_modes"], b["plant"]["removed_modes"]);
  EXPECT_EQ(a["plant"]["stable"], b["plant"]["stable"]);
  EXPECT_EQ(a["markov"]["lags"], b["markov"]["lags"]);

  const auto sa = a["closed_loop"]["singular_values"].get<std::vector<double>>();
  const auto sb = b["closed_loop"]["singular_values"].get<std::vector<double>>();
  ASSERT_EQ(sa.size(), sb.size());
  ASSERT_FALSE(sb.empty());
  Score sv;
  for (std::size_t i = 0; i < sb.size(); ++i)
    sv.add(digits(sa[i], sb[i], sb[0]), "singular value " + std::to_string(i + 1));
  sv.add(digits(a["closed_loop"]["noise_floor"].get<double>(), b["closed_loop"]["noise_floor"].get<double>(), sb[0]),
         "noise floor");
  record_digits("identify_singular_values", sv);
  EXPECT_GE(sv.min_digits, kSingularValueDigits) << sv.where;

  Score err;
  for (const char* key : {"weighted_error_mean", "weighted_error_max"}) {
    const double eb = b["truth"][key].get<double>();
    err.add(digits(a["truth"][key].get<double>(), eb, std::abs(eb)), key);
  }
  record_digits("identify_weighted_errors", err);
  EXPECT_GE(err.min_digits, kWeightedErrorDigits) << err.where;
}

TEST_F(IdentifyGolden, PlantAndClosedLoopMatchTheGoldenModelsByFrequencyResponse) {
  for (const char* name : {"plant.json", "closed_loop.json"}) {
    SCOPED_TRACE(name);
    const StateSpace a = read_state_space(fresh(name));
    const StateSpace b = read_state_space(data(std::string("identify/") + name));
    EXPECT_EQ(a.order(), b.order());
    EXPECT_EQ(a.input_names, b.input_names);
    EXPECT_EQ(a.output_names, b.output_names);
    const Score s = compare_frequency_response(a, b);
    record_digits(std::string("identify_") + name, s);
    EXPECT_GE(s.min_digits, kResponseDigits) << s.where;
  }
}

TEST_F(IdentifyGolden, MarkovParametersEqualTheMarkovSubcommandsGolden) {
  // identify's markov.csv is not stored (it would duplicate markov/g.csv).
  const MarkovFile a = read_markov_csv(fresh("markov.csv"));
  const MarkovFile b = read_markov_csv(data("markov/g.csv"));
  ASSERT_EQ(a.g.size(), b.g.size());
  Score g;
  for (Index i = 0; i < b.g.front().rows(); ++i) {
    for (Index j = 0; j < b.g.front().cols(); ++j) {
      double peak = 0;
      for (const auto& gk : b.g) peak = std::max(peak, std::abs(gk(i, j)));
      for (std::size_t k = 0; k < b.g.size(); ++k)
        g.add(digits(a.g[k](i, j), b.g[k](i, j), peak), "lag " + std::to_string(k));
    }
  }
  record_digits("identify_markov", g);
  EXPECT_GE(g.min_digits, kMarkovDigits) << g.where;
}

}  // namespace identify_golden_test
}  // namespace lpvid::golden
