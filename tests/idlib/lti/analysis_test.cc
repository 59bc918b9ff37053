#include "idlib/lti/analysis.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "tests/idlib/lti/test_systems.h"

namespace lpvid {
namespace analysis_test {
using test_systems::random_system;

constexpr std::uint32_t kSeedMarkov = 303;

TEST(Poles, DiagonalSystemHasItsDiagonal) {
  StateSpace s{Eigen::Vector3d(-1.0, -2.0, -3.0).asDiagonal(), Eigen::MatrixXd::Ones(3, 1), Eigen::MatrixXd::Ones(1, 3),
               Eigen::MatrixXd::Zero(1, 1), 0.0, {}, {}};
  Eigen::VectorXd re = poles(s).real();
  std::sort(re.data(), re.data() + re.size());
  EXPECT_NEAR(re[0], -3.0, 1e-14);
  EXPECT_NEAR(re[2], -1.0, 1e-14);
}

TEST(IsStable, DiscreteBoundaryAndMargin) {
  StateSpace s{Eigen::MatrixXd::Constant(1, 1, 0.999), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1),
               Eigen::MatrixXd::Zero(1, 1), 1e-3, {}, {}};
  EXPECT_TRUE(is_stable(s));
  EXPECT_FALSE(is_stable(s, 2e-3));  // 0.999 is not below 1 − 2e-3
  s.A(0, 0) = 1.0;
  EXPECT_FALSE(is_stable(s));  // an integrator is not asymptotically stable
  s.A(0, 0) = -1.0 - 1e-9;
  EXPECT_FALSE(is_stable(s));
}

TEST(IsStable, ContinuousUsesRealPart) {
  StateSpace s{(Eigen::MatrixXd(2, 2) << -0.01, 100.0, -100.0, -0.01).finished(), Eigen::MatrixXd::Ones(2, 1),
               Eigen::MatrixXd::Ones(1, 2), Eigen::MatrixXd::Zero(1, 1), 0.0, {}, {}};
  EXPECT_TRUE(is_stable(s));
  s.A(0, 0) = s.A(1, 1) = 0.0;
  EXPECT_FALSE(is_stable(s));
}

TEST(MarkovParameters, MatchPowersOfA) {
  const StateSpace s = random_system(4, 2, 3, 1e-3, kSeedMarkov);
  const MarkovSequence g = markov_parameters(s, 5);
  ASSERT_EQ(g.size(), 6u);
  EXPECT_EQ(g[0], s.D);
  Eigen::MatrixXd Ak = Eigen::MatrixXd::Identity(4, 4);
  for (size_t k = 1; k <= 5; ++k) {
    EXPECT_LT((g[k] - s.C * Ak * s.B).norm(), 1e-13 * (1.0 + g[k].norm()));
    Ak = Ak * s.A;
  }
}

TEST(MarkovParameters, ContinuousModelIsRejected) {
  const StateSpace s = random_system(2, 1, 1, 0.0, kSeedMarkov);
  try {
    markov_parameters(s, 3);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "Markov parameters: the model is continuous (ts = 0); discretise it first (discretize_zoh)");
  }
}

}  // namespace analysis_test
}  // namespace lpvid
