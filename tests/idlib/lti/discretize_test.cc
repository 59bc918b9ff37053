#include "idlib/lti/discretize.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"

namespace lpvid {
namespace discretize_test {

// The Padé exponential of a nilpotent matrix is exact up to rounding.
constexpr double kClosedFormAgreement = 1e-14;

TEST(DiscretizeZoh, DoubleIntegratorMatchesClosedForm) {
  // x = [position; velocity], force input: A = [[0 1][0 0]], B = [0; 1/m].
  const double mass_kg = 7.0, Ts = 1e-3;
  StateSpace c{(Eigen::MatrixXd(2, 2) << 0, 1, 0, 0).finished(), (Eigen::MatrixXd(2, 1) << 0, 1.0 / mass_kg).finished(),
               (Eigen::MatrixXd(1, 2) << 1, 0).finished(), Eigen::MatrixXd::Zero(1, 1), 0.0, {"F_z"}, {"z"}};
  const StateSpace d = discretize_zoh(c, Ts);
  Eigen::MatrixXd Ad(2, 2), Bd(2, 1);
  Ad << 1, Ts, 0, 1;
  Bd << Ts * Ts / (2 * mass_kg), Ts / mass_kg;
  EXPECT_LT((d.A - Ad).norm(), kClosedFormAgreement);
  EXPECT_LT((d.B - Bd).norm(), kClosedFormAgreement * Bd.norm());
  EXPECT_EQ(d.C, c.C);
  EXPECT_EQ(d.D, c.D);
  EXPECT_EQ(d.sample_period_s, Ts);
  EXPECT_EQ(d.input_names, c.input_names);
}

TEST(DiscretizeZoh, FirstOrderPoleMapsToExpOfSTs) {
  // a/(s + a): discrete pole e^{−a Ts}, DC gain preserved (ZOH is exact at DC).
  const double a = 3.0, Ts = 0.01;
  StateSpace c{Eigen::MatrixXd::Constant(1, 1, -a), Eigen::MatrixXd::Constant(1, 1, a), Eigen::MatrixXd::Ones(1, 1),
               Eigen::MatrixXd::Zero(1, 1), 0.0, {}, {}};
  const StateSpace d = discretize_zoh(c, Ts);
  EXPECT_NEAR(poles(d)[0].real(), std::exp(-a * Ts), 1e-15);
  const double dc = (d.C * (Eigen::MatrixXd::Identity(1, 1) - d.A).inverse() * d.B)(0, 0);
  EXPECT_NEAR(dc, 1.0, 1e-13);
}

TEST(DiscretizeZoh, DiscreteModelIsRejected) {
  StateSpace c{Eigen::MatrixXd::Zero(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Zero(1, 1),
               1e-3, {}, {}};
  try {
    discretize_zoh(c, 1e-3);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "discretize: the model is already discrete (ts = 0.001 s); pass a continuous model (ts = 0)");
  }
  c.sample_period_s = 0.0;
  EXPECT_THROW(discretize_zoh(c, -1.0), InputError);
}

}  // namespace discretize_test
}  // namespace lpvid
