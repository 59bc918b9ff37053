// band_support (identify.h): where the 95 % band is narrower than a fraction of the
// plant.  The cases are built by hand: a 1 × 1 response of magnitude 2 whose variance
// falls with frequency, so that r(ω) = 2 σ(ω) / 2 = σ(ω) is known at each point.
#include <gtest/gtest.h>

#include <vector>

#include "idlib/core/error.h"
#include "idlib/identify/identify.h"

namespace lpvid {
namespace band_support_test {

TEST(BandSupport, FindsTheFrequenciesWhereTheBandIsNarrowAndTheWorstOne) {
  const Eigen::VectorXd omega = (Eigen::VectorXd(5) << 1, 2, 5, 10, 20).finished();
  const std::vector<double> sigma = {1.5, 0.3, 0.08, 0.05, 0.02};  // r = σ (|P| = 2, radius 2σ)
  std::vector<Eigen::MatrixXcd> response(5, Eigen::MatrixXcd::Constant(1, 1, std::complex<double>(0.0, 2.0)));
  std::vector<Eigen::MatrixXd> variance;
  for (const double s : sigma) variance.push_back(Eigen::MatrixXd::Constant(1, 1, s * s));
  const BandSupport b = band_support(response, variance, omega, 0.1);
  EXPECT_EQ(b.points, 5);
  EXPECT_EQ(b.supported, 3);
  EXPECT_DOUBLE_EQ(b.lowest_supported_rad_s, 5.0);
  EXPECT_DOUBLE_EQ(b.highest_supported_rad_s, 20.0);
  EXPECT_NEAR(b.worst_relative, 1.5, 1e-12);
  EXPECT_DOUBLE_EQ(b.omega_at_worst_rad_s, 1.0);
}

TEST(BandSupport, AMatrixUsesTheFrobeniusNormsOfTheResponseAndOfTheSpread) {
  // |P|_F = 5 (entries 3 and 4); Σ var = 0.25 + 0.25 + 0 + 0 → r = 2 √0.5 / 5 = 0.283
  const Eigen::VectorXd omega = Eigen::VectorXd::Constant(1, 3.0);
  Eigen::MatrixXcd P = Eigen::MatrixXcd::Zero(2, 2);
  P(0, 0) = 3.0;
  P(1, 1) = std::complex<double>(0.0, 4.0);
  Eigen::MatrixXd var = Eigen::MatrixXd::Zero(2, 2);
  var(0, 1) = var(1, 0) = 0.25;
  const BandSupport b = band_support({P}, {var}, omega, 0.1);
  EXPECT_EQ(b.supported, 0);
  EXPECT_NEAR(b.worst_relative, 2.0 * std::sqrt(0.5) / 5.0, 1e-12);
}

TEST(BandSupport, CountsThatDoNotMatchAreRefused) {
  const Eigen::VectorXd omega = Eigen::VectorXd::Ones(2);
  EXPECT_THROW(band_support({Eigen::MatrixXcd::Ones(1, 1)}, {Eigen::MatrixXd::Ones(1, 1)}, omega, 0.1), InputError);
  EXPECT_THROW(band_support({}, {}, Eigen::VectorXd(), 0.0), InputError);
}

}  // namespace band_support_test
}  // namespace lpvid
