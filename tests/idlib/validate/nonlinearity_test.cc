// nonlinearity_tests (idlib/validate/nonlinearity.h).  Signals written here: x, a coloured
// Gaussian signal (white noise through a second-order low-pass), stands for the linear
// model's simulation ŷ (poles at 0.9: correlated over tens of samples); the residual is white noise (a linear plant) or noise plus a
// nonlinear function of x passed through a short filter (what a linear approximation
// leaves of a nonlinear plant).
#include "idlib/validate/nonlinearity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "idlib/core/error.h"

namespace lpvid {
namespace nonlinearity_test {

Eigen::VectorXd coloured(Index N, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd x(N);
  double a = 0, b = 0;
  for (Index t = 0; t < N; ++t) {
    a = 0.9 * a + g(rng);
    b = 0.9 * b + a;
    x(t) = b;
  }
  return x / std::sqrt(x.squaredNorm() / static_cast<double>(N));
}

Eigen::VectorXd noise(Index N, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::VectorXd e(N);
  for (Index t = 0; t < N; ++t) e(t) = g(rng);
  return e;
}

// y(t) = 0.5 y(t−1) + 0.5 u(t): a short filter, as the loop passes a force to the output.
Eigen::VectorXd filtered(const Eigen::VectorXd& u) {
  Eigen::VectorXd y(u.size());
  double s = 0;
  for (Index t = 0; t < u.size(); ++t) y(t) = s = 0.5 * s + 0.5 * u(t);
  return y;
}

// A linear plant: the residual is noise, independent of ŷ.  Over 20 draws at the 99 %
// family-wise level, at most one false alarm is expected (0.2 on average); two would be
// a 2 % event.
TEST(Nonlinearity, NoiseIndependentOfTheSimulationIsNotCalledNonlinear) {
  int alarms = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const Index N = 20000;
    const NonlinearityResult r = nonlinearity_tests(noise(N, 100 + seed), coloured(N, seed));
    ASSERT_TRUE(r.ran) << r.reason;
    alarms += r.significant.empty() ? 0 : 1;
  }
  EXPECT_LE(alarms, 1);
}

// A wrong LINEAR model leaves a linear function of the excitation in the residual: not a
// nonlinearity (the features are made orthogonal to what a short linear filter of ŷ holds).
TEST(Nonlinearity, ALinearModelErrorIsNotCalledNonlinear) {
  int alarms = 0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    const Index N = 20000;
    const Eigen::VectorXd x = coloured(N, seed);
    const NonlinearityResult r = nonlinearity_tests(0.3 * filtered(x) + noise(N, 200 + seed), x);
    alarms += r.significant.empty() ? 0 : 1;
  }
  EXPECT_LE(alarms, 1);
}

// Friction-like (a force that flips with the rate), even (a square) and odd (a cube)
// nonlinearities, each at a tenth of the noise's rms before the filter: each found, and
// its own feature the strongest.
TEST(Nonlinearity, EachKindIsFoundByItsOwnFeature) {
  const Index N = 20000;
  const Eigen::VectorXd x = coloured(N, 7), n = noise(N, 8);
  Eigen::VectorXd sign(N), square(N), cube(N);
  for (Index t = 0; t < N; ++t) {
    const double rate = t + 1 < N ? x(t + 1) - x(t) : x(t) - x(t - 1);
    sign(t) = rate > 0 ? 1.0 : -1.0;
    square(t) = x(t) * x(t);
    cube(t) = x(t) * x(t) * x(t);
  }
  const struct {
    const char* feature;
    Eigen::VectorXd f;
  } cases[] = {{"sign of the rate", sign}, {"square", square}, {"cube", cube}};
  for (const auto& c : cases) {
    const Eigen::VectorXd e = n + 0.3 * filtered(c.f);
    const NonlinearityResult r = nonlinearity_tests(e, x);
    ASSERT_FALSE(r.significant.empty()) << c.feature;
    EXPECT_EQ(r.tests[static_cast<std::size_t>(r.significant.front())].feature, c.feature);
    std::printf("%s: %s\n", c.feature, nonlinearity_sentence(r, {"y"}).c_str());
  }
}

TEST(Nonlinearity, AShortRecordIsNotTestedAndShapesMustMatch) {
  const NonlinearityResult r = nonlinearity_tests(noise(500, 1), coloured(500, 2));
  EXPECT_FALSE(r.ran);
  EXPECT_NE(r.reason.find("not tested"), std::string::npos);
  EXPECT_THROW(nonlinearity_tests(noise(500, 1), Eigen::MatrixXd::Zero(400, 1)), InputError);
}

}  // namespace nonlinearity_test
}  // namespace lpvid
