// refine_output_error and simulation_fit_percent (output_error.h).  The truth is a plant
// written here (a lightly damped mode and a real pole), its logs simulated here by its own
// recursion; the start handed to the refinement is the truth with its poles moved.
#include "idlib/identify/output_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"

namespace lpvid {
namespace output_error_test {

constexpr double kTs = 1e-3;

// Mode at 60 rad/s (damping 0.05) and a real pole at 20 rad/s; y the mode's second state
// plus the pole.
StateSpace truth(double radius_scale = 1.0) {
  StateSpace s;
  const double w = 60.0, z = 0.05, r = std::exp(-z * w * kTs) * radius_scale, th = w * std::sqrt(1 - z * z) * kTs;
  s.A = Eigen::MatrixXd::Zero(3, 3);
  s.A << r * std::cos(th), -r * std::sin(th), 0, r * std::sin(th), r * std::cos(th), 0, 0, 0,
      std::exp(-20.0 * kTs) * radius_scale;
  s.B = (Eigen::MatrixXd(3, 1) << 0.02, 0.0, 0.01).finished();
  s.C = (Eigen::MatrixXd(1, 3) << 0.0, 1.0, 1.0).finished();
  s.D = Eigen::MatrixXd::Zero(1, 1);
  s.sample_period_s = kTs;
  return s;
}

// N samples of white u, y from the initial state x0, plus white noise of `noise` × y's RMS.
void simulate(const StateSpace& s, const Eigen::Vector3d& x0, double noise, Eigen::MatrixXd& u, Eigen::MatrixXd& y) {
  const Index N = 4000;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  u.resize(N, 1);
  y.resize(N, 1);
  Eigen::Vector3d x = x0;
  for (Index t = 0; t < N; ++t) {
    u(t, 0) = normal(rng);
    y(t, 0) = (s.C * x)(0);
    x = s.A * x + s.B * u(t, 0);
  }
  const double rms = std::sqrt((y.array() - y.mean()).square().mean());
  for (Index t = 0; t < N; ++t) y(t, 0) += noise * rms * normal(rng);
}

double markov_error(const StateSpace& a, const StateSpace& b) {
  const MarkovSequence ga = markov_parameters(a, 400), gb = markov_parameters(b, 400);
  double e = 0, n = 0;
  for (std::size_t k = 1; k < ga.size(); ++k) e += (ga[k] - gb[k]).squaredNorm(), n += gb[k].squaredNorm();
  return std::sqrt(e / n);
}

TEST(OutputError, RefinesAStartWithMovedPolesToTheTruthAndItsInitialState) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d(0.5, -0.3, 0.2), 0.0, u, y);
  const StateSpace start = truth(0.995);  // every pole 0.5 % further in: 30-180 % slower decay
  ASSERT_GT(markov_error(start, truth()), 0.3);
  OutputErrorOptions o;
  const OutputErrorResult r = refine_output_error({{u, y}}, start, o);
  ASSERT_TRUE(r.accepted) << r.reason;
  std::printf("%s; Markov error %.3g\n", r.reason.c_str(), markov_error(r.model, truth()));
  // Noise-free: the optimum is the truth (u as logged, the output's offset and initial
  // state fitted): to the solver's tolerance.
  EXPECT_LE(markov_error(r.model, truth()), 1e-6);
  EXPECT_NEAR(simulation_fit_percent(r.model, {{u, y}}, true)(0), 100.0, 1e-4);
  // From zero state the record's own transient is missing: below 100 %.
  EXPECT_LT(simulation_fit_percent(r.model, {{u, y}}, false)(0), 99.9);
}

TEST(OutputError, WithNoiseTheBandsHoldTheTruthsResponse) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.05, u, y);
  OutputErrorOptions o;
  o.estimate_initial_states = false;
  const OutputErrorResult r = refine_output_error({{u, y}}, truth(0.995), o);
  ASSERT_TRUE(r.accepted) << r.reason;
  ASSERT_EQ(r.covariance.rows(), 9 + 3 + 3);
  EXPECT_GE(r.replicates, 8);
  // 5 % output noise on 4000 samples: measured 0.16 % error in the Markov parameters
  // (400 lags); the bound is 3x that.
  const double err = markov_error(r.model, truth());
  std::printf("noisy: Markov error %.4f, %ld replicates\n", err, static_cast<long>(r.replicates));
  EXPECT_LE(err, 0.005);
  EXPECT_GT(simulation_fit_percent(r.model, {{u, y}}, false)(0), 90.0);
}

TEST(OutputError, AnUnstableOptimumOrABadShapeIsNotUsed) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.0, u, y);
  StateSpace wrong = truth();
  wrong.B.resize(3, 2);
  wrong.B.setZero();
  wrong.D = Eigen::MatrixXd::Zero(1, 2);
  EXPECT_THROW(refine_output_error({{u, y}}, wrong, {}), InputError);
  // A start that diverges on the logs is kept, with the reason.
  StateSpace diverging = truth();
  diverging.A *= 1.2;
  const OutputErrorResult r = refine_output_error({{u, y}}, diverging, {});
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.reason.find("not refined"), std::string::npos) << r.reason;
}

TEST(SimulationFit, IsOneHundredForTheModelThatMadeTheData) {
  Eigen::MatrixXd u, y;
  simulate(truth(), Eigen::Vector3d::Zero(), 0.0, u, y);
  EXPECT_NEAR(simulation_fit_percent(truth(), {{u, y}}, false)(0), 100.0, 1e-6);
  StateSpace unstable = truth();
  unstable.A *= 1.5;
  EXPECT_EQ(simulation_fit_percent(unstable, {{u, y}}, false).size(), 0);
}

}  // namespace output_error_test
}  // namespace lpvid
