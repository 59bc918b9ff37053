#include "idlib/lti/frequency_response.h"

#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "tests/idlib/lti/test_systems.h"

namespace lpvid {
namespace frequency_response_test {

using test_systems::direct_response;
using test_systems::random_system;

constexpr std::uint32_t kSeedContinuous = 101;
constexpr std::uint32_t kSeedDiscrete = 202;
// Both evaluations are backward stable; the poles are at least 0.1 (continuous)
// or 0.1 in |z| from the boundary, so (λI − A) has condition ≲ 1e3 and the two
// agree to ~1e3·ε·n.
constexpr double kResponseAgreement = 1e-10;

TEST(EvaluateResponse, MatchesDenseSolveForRandomContinuousSystem) {
  const StateSpace s = random_system(12, 3, 2, 0.0, kSeedContinuous);
  const Eigen::VectorXd w = log_frequency_grid(1e-2, 1e3, 50);
  const auto h = evaluate_response(s, w);
  ASSERT_EQ(h.size(), 50u);
  for (Index k = 0; k < w.size(); ++k) {
    const Eigen::MatrixXcd ref = direct_response(s, w[k]);
    EXPECT_LT((h[static_cast<size_t>(k)] - ref).norm(), kResponseAgreement * ref.norm()) << "ω = " << w[k];
  }
}

TEST(EvaluateResponse, MatchesDenseSolveForRandomDiscreteSystemIncludingNegativeOmega) {
  const StateSpace s = random_system(9, 2, 3, 1e-3, kSeedDiscrete);
  Eigen::VectorXd w(5);
  w << -100.0, 0.0, 1.0, 1000.0, 3141.0;
  const auto h = evaluate_response(s, w);
  for (Index k = 0; k < w.size(); ++k) {
    const Eigen::MatrixXcd ref = direct_response(s, w[k]);
    EXPECT_LT((h[static_cast<size_t>(k)] - ref).norm(), kResponseAgreement * ref.norm()) << "ω = " << w[k];
  }
}

TEST(EvaluateResponse, StaticGainHasConstantResponse) {
  StateSpace s{Eigen::MatrixXd(0, 0), Eigen::MatrixXd(0, 2), Eigen::MatrixXd(1, 0), Eigen::MatrixXd::Constant(1, 2, 3.0), 0.0, {}, {}};
  const auto h = evaluate_response(s, log_frequency_grid(1.0, 10.0, 3));
  for (const auto& m : h) EXPECT_EQ(m, Eigen::MatrixXcd::Constant(1, 2, Complex(3.0, 0.0)));
}

TEST(FrequencyResponse, CarriesNamesAndGrid) {
  StateSpace s = random_system(2, 1, 1, 0.0, kSeedContinuous);
  s.input_names = {"v_z"};
  s.output_names = {"z"};
  const Eigen::VectorXd w = log_frequency_grid(1.0, 100.0, 7);
  const FrequencyResponse frd = frequency_response(s, w);
  EXPECT_EQ(frd.omega_rad_s, w);
  EXPECT_EQ(frd.num_frequencies(), 7);
  EXPECT_EQ(frd.input_names, s.input_names);
  EXPECT_EQ(frd.output_names, s.output_names);
  EXPECT_EQ(frd.num_outputs(), 1);
}

TEST(EvaluateResponse, IntegratorAtZeroFrequencyIsRejected) {
  StateSpace s{Eigen::MatrixXd::Zero(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1),
               0.0, {}, {}};
  Eigen::VectorXd w(1);
  w << 0.0;
  try {
    evaluate_response(s, w);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "frequency response: ω = 0 rad/s hits a pole of the model exactly (λ = 0+0j); leave this frequency out of the grid");
  }
}

TEST(LogFrequencyGrid, EndpointsAndLogSpacing) {
  const Eigen::VectorXd w = log_frequency_grid(1.0, 1000.0, 4);
  ASSERT_EQ(w.size(), 4);
  EXPECT_DOUBLE_EQ(w[0], 1.0);
  EXPECT_NEAR(w[1], 10.0, 1e-12);
  EXPECT_NEAR(w[2], 100.0, 1e-10);
  EXPECT_DOUBLE_EQ(w[3], 1000.0);
}

TEST(LogFrequencyGrid, NonPositiveLowerBoundIsRejected) {
  try {
    log_frequency_grid(0.0, 10.0, 5);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "frequency grid: [0, 10] rad/s; need 0 < lo <= hi, both finite");
  }
  EXPECT_THROW(log_frequency_grid(1.0, 10.0, 0), InputError);
}

}  // namespace frequency_response_test
}  // namespace lpvid
