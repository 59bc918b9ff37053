// Golden test of `lpvid simulate platform` (cli/simulate.cc): the same seed gives
// the same logs and the same controller and truth models as the golden run
// (tests/golden/regenerate.sh: --positions middle --rate-hz 1000 --duration-s 2 --seed 11).
#include <gtest/gtest.h>

#include "formats/io/csv_log.h"
#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace simulate_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

// Same seed, same arithmetic: the logs are a deterministic function of the seed
// and are written in the shortest form that reads back to the identical double,
// so on the machine that made them they agree bit for bit.  Another compiler or
// libm may round the last bit of an exp/sin or contract a*b+c into an FMA; the
// simulation is a stable discrete recursion over 2000 steps, so such differences
// stay near the unit roundoff (2.2e-16) times a modest growth.  1e-12 of the
// column's peak leaves four orders of magnitude for that and still catches any
// change in the model, the noise stream or the controller.
constexpr double kLogColumnRelTol = 1e-12;
// The controller and truth models are the same deterministic computation
// (parameters -> continuous model -> ZOH / PI design); compared by frequency
// response, 12 digits is the same 1e-12 budget.
constexpr double kModelDigits = 12.0;

class SimulateGolden : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir("golden_sim");
    const auto r = run_lpvid("simulate platform --out " + (*dir_ / "sim") + " " + kSimulateArgs);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string fresh(const std::string& name) { return *dir_ / ("sim/middle_1000hz/" + name); }
  static std::string golden(const std::string& name) { return sim_dir() + "/" + name; }
  static TempDir* dir_;
};
TempDir* SimulateGolden::dir_ = nullptr;

TEST_F(SimulateGolden, SameSeedReproducesEveryLogColumnWithin1e12OfItsPeak) {
  for (const char* name : {"exp_T_psi.csv", "exp_T_theta.csv", "exp_F_z.csv"}) {
    SCOPED_TRACE(name);
    const Log a = read_log(fresh(name));
    const Log b = read_log(golden(name));
    ASSERT_EQ(a.names, b.names);
    ASSERT_EQ(a.data.rows(), b.data.rows());
    double worst = 0;
    for (Index c = 0; c < b.data.cols(); ++c) {
      // Relative to the column's peak: an entrywise relative error is meaningless
      // where a signal crosses zero (v is exactly 0 in the unexcited channels).
      const double peak = b.data.col(c).cwiseAbs().maxCoeff();
      const double diff = (a.data.col(c) - b.data.col(c)).cwiseAbs().maxCoeff();
      const double rel = peak > 0 ? diff / peak : diff;
      worst = std::max(worst, rel);
      EXPECT_LE(rel, kLogColumnRelTol) << "column " << b.names[static_cast<std::size_t>(c)];
    }
    std::cout << "[ rel diff ] " << name << " max over columns = " << worst << "\n";
  }
}

TEST_F(SimulateGolden, SameSeedReproducesControllerAndTruthModelsByFrequencyResponse) {
  for (const char* name :
       {"controller.json", "truth_plant.json", "truth_plant_continuous.json", "truth_closed_loop.json"}) {
    SCOPED_TRACE(name);
    const StateSpace a = read_state_space(fresh(name));
    const StateSpace b = read_state_space(golden(name));
    EXPECT_EQ(a.order(), b.order());
    EXPECT_EQ(a.sample_period_s, b.sample_period_s);
    EXPECT_EQ(a.input_names, b.input_names);
    EXPECT_EQ(a.output_names, b.output_names);
    const Score s = compare_frequency_response(a, b);
    record_digits(std::string("simulate_") + name, s);
    EXPECT_GE(s.min_digits, kModelDigits) << s.where;
  }
}

}  // namespace simulate_golden_test
}  // namespace lpvid::golden
