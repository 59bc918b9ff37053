// Golden test of `lpvid hankel` (cli/hankel.cc) on the golden Markov parameters.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace hankel_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

// The 489 x 489 scaled block Hankel matrix is decomposed by Lanczos on its Gram
// matrix (Spectra, subspace tolerance 1e-10, a fixed start vector) followed by a
// Rayleigh-Ritz step.  A perturbation dH moves every singular value by at most
// |dH|_2 (Weyl), so digits are scored relative to the largest singular value.
// Across compilers the Lanczos iteration may stop at a different restart; the
// Ritz values then differ at the level of the 1e-10 subspace tolerance squared
// relative to sigma_1, a little worse for clustered values.  8 digits leave a
// margin of two orders on the subspace tolerance and catch any change in the
// scaling, the block sizes or the decomposition.
constexpr double kSingularValueDigits = 8.0;

TEST(HankelGolden, SingularValuesAgreeToEightDigitsAndChosenOrderIsUnchanged) {
  TempDir dir("golden_hankel");
  const auto r = run_lpvid("hankel " + data("markov/g.csv") + " --out " + (dir / "sv.csv") + " --count 12 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto fresh = nlohmann::json::parse(r.out);
  const auto golden = nlohmann::json::parse(slurp(data("hankel/summary.json")));
  EXPECT_EQ(fresh["order"], golden["order"]);
  EXPECT_EQ(fresh["block_rows"], golden["block_rows"]);
  EXPECT_EQ(fresh["block_cols"], golden["block_cols"]);
  EXPECT_EQ(fresh["stride"], golden["stride"]);

  std::vector<std::string> header_a, header_b;
  const Eigen::MatrixXd a = read_numeric_csv(dir / "sv.csv", &header_a);
  const Eigen::MatrixXd b = read_numeric_csv(data("hankel/sv.csv"), &header_b);
  ASSERT_EQ(header_a, header_b);
  ASSERT_EQ(a.rows(), b.rows());
  ASSERT_GT(b.rows(), 0);
  const double sigma1 = b(0, 1);
  Score score;
  for (Index i = 0; i < b.rows(); ++i) {
    EXPECT_EQ(a(i, 0), b(i, 0));
    // Which values stand above the noise floor decides the order: it must not move.
    EXPECT_EQ(a(i, 2), b(i, 2)) << "above_noise_floor of singular value " << i + 1;
    score.add(digits(a(i, 1), b(i, 1), sigma1), "singular value " + std::to_string(i + 1));
  }
  score.add(digits(fresh["noise_floor"].get<double>(), golden["noise_floor"].get<double>(), sigma1), "noise floor");
  record_digits("hankel_singular_values", score);
  EXPECT_GE(score.min_digits, kSingularValueDigits) << score.where;
}

}  // namespace hankel_golden_test
}  // namespace lpvid::golden
