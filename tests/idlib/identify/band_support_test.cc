// band_support (identify.h): where the 95 % band is narrower than a fraction of the
// plant.  The cases are built by hand: a 1 × 1 response of magnitude 2 whose variance
// falls with frequency, so that r(ω) = 2 σ(ω) / 2 = σ(ω) is known at each point.
#include <gtest/gtest.h>

#include <cmath>
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

// instability_evidence: a pole outside the unit circle growing at a = ln|z|/Ts moves the
// response at ω by about a/ω against an integrator, so logs that support the plant only
// down to ω_L (band within ±10 %) prove the instability when a > 0.1 ω_L.  Plants built
// by hand at Ts = 1 ms: x+ = z x + u, y = x.
StateSpace first_order(double z) {
  StateSpace s;
  s.A = Eigen::MatrixXd::Constant(1, 1, z);
  s.B = Eigen::MatrixXd::Ones(1, 1);
  s.C = Eigen::MatrixXd::Ones(1, 1);
  s.D = Eigen::MatrixXd::Zero(1, 1);
  s.sample_period_s = 1e-3;
  return s;
}

TEST(InstabilityEvidence, APoleTheSupportedBandCannotTellFromAnIntegratorIsNotProof) {
  BandSupport support;
  support.threshold = 0.1;
  support.lowest_supported_rad_s = 12.0;  // a = 0.1 x 12 = 1.2 rad/s is the line
  // |z| = 1.00012: a = 0.12 rad/s, a tenth of the line (an integrator estimated on noisy logs)
  InstabilityEvidence e = instability_evidence(first_order(1.00012), &support);
  EXPECT_EQ(e.unstable_poles, 1);
  EXPECT_NEAR(e.growth_rate_rad_s, std::log(1.00012) / 1e-3, 1e-9);
  EXPECT_FALSE(e.proven);
  // |z| = 1.0024 (a levitated tilt, +2.4 rad/s): twice the line, proven
  e = instability_evidence(first_order(1.0024), &support);
  EXPECT_TRUE(e.proven);
  EXPECT_NEAR(e.largest_magnitude, 1.0024, 1e-15);
  // no support known (the ERA route): as the poles say
  EXPECT_TRUE(instability_evidence(first_order(1.00012), nullptr).proven);
  // a stable plant: nothing to prove
  e = instability_evidence(first_order(0.99), &support);
  EXPECT_EQ(e.unstable_poles, 0);
  EXPECT_FALSE(e.proven);
}

}  // namespace band_support_test
}  // namespace lpvid
