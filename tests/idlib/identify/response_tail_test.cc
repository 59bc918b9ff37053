// closed_loop_response_beyond (idlib/identify/response_tail.h) against truth computed
// without it: the closed form of a first-order loop's impulse response, and the
// defining equation q(t) = Σ_{k=1}^{L} g[k] v(t − k) + y_L(t) with q simulated state by
// state and g from markov_parameters, on the modal route and on the dense route.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "idlib/core/error.h"
#include "idlib/identify/response_tail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/small_loop.h"

namespace lpvid {
namespace response_tail_test {

using testing::coupled_plant;
using testing::FirstOrderLoop;
using testing::pi_controller_2x2;

constexpr std::uint64_t kExcitationSeed = 1123;
// Double round-off of a sum of ~10³ terms of size ≤ 1 (the modal recursion and the
// direct sums of the truth accumulate independently).
constexpr double kRoundOff = 1e-11;

// q(t) of the closed loop from rest, simulated with the full state.
Eigen::MatrixXd simulate(const StateSpace& loop, const Eigen::MatrixXd& v) {
  Eigen::MatrixXd q(v.rows(), loop.num_outputs());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(loop.order());
  for (Index t = 0; t < v.rows(); ++t) {
    q.row(t) = (loop.C * x + loop.D * v.row(t).transpose()).transpose();
    x = loop.A * x + loop.B * v.row(t).transpose();
  }
  return q;
}

// Σ_{k=1}^{L} g[k] v(t − k) (v = 0 before the record).
Eigen::MatrixXd fir_part(const MarkovSequence& g, const Eigen::MatrixXd& v, Index L) {
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(v.rows(), g.front().rows());
  for (Index t = 0; t < v.rows(); ++t)
    for (Index k = 1; k <= L && k <= t; ++k) y.row(t) += (g[static_cast<std::size_t>(k)] * v.row(t - k).transpose()).transpose();
  return y;
}

Eigen::MatrixXd white(Index rows, Index cols, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::MatrixXd v(rows, cols);
  for (Index j = 0; j < cols; ++j)
    for (Index t = 0; t < rows; ++t) v(t, j) = n(rng);
  return v;
}

TEST(ResponseBeyond, ImpulseOfAFirstOrderLoopIsItsClosedFormTailBeyondTheLag) {
  const FirstOrderLoop s;
  constexpr Index kRecord = 400, kImpulseAt = 30, kLag = 50;
  Eigen::MatrixXd v = Eigen::MatrixXd::Zero(kRecord, 1);
  v(kImpulseAt, 0) = 1.0;
  const Eigen::MatrixXd y = closed_loop_response_beyond(s.plant(), s.controller(), v, kLag);
  ASSERT_EQ(y.rows(), kRecord);
  ASSERT_EQ(y.cols(), 1);
  for (Index t = 0; t < kRecord; ++t) {
    const Index j = t - kImpulseAt;  // lag since the impulse
    const double truth = j > kLag ? s.b * std::pow(s.lambda(), static_cast<double>(j - 1)) : 0.0;
    EXPECT_NEAR(y(t, 0), truth, kRoundOff * s.b) << "t = " << t;
  }
}

TEST(ResponseBeyond, CoupledLoopSatisfiesTheDefiningEquationOnTheModalRoute) {
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const StateSpace loop = closed_loop_output(plant, controller);
  ASSERT_TRUE(is_stable(loop));
  constexpr Index kRecord = 1500, kLag = 200;  // |λ|^200 ≈ 0.37: much of the response lies beyond
  const Eigen::MatrixXd v = white(kRecord, 2, kExcitationSeed);
  const Eigen::MatrixXd q = simulate(loop, v);
  const Eigen::MatrixXd expected = q - fir_part(markov_parameters(loop, kLag), v, kLag);
  const Eigen::MatrixXd y = closed_loop_response_beyond(plant, controller, v, kLag);
  EXPECT_GT(expected.norm(), 0.1 * q.norm());  // the tail is not negligible here
  EXPECT_LE((y - expected).cwiseAbs().maxCoeff(), kRoundOff * q.cwiseAbs().maxCoeff());
}

TEST(ResponseBeyond, JordanBlockTakesTheDenseRouteAndSatisfiesTheDefiningEquation) {
  // A double pole with one eigenvector: the modal route cannot diagonalise it.
  StateSpace plant;
  plant.A.resize(2, 2);
  plant.A << 0.97, 1.0, 0.0, 0.97;
  plant.B.resize(2, 1);
  plant.B << 0.0, 0.01;
  plant.C.resize(1, 2);
  plant.C << 0.05, 0.0;
  plant.D = Eigen::MatrixXd::Zero(1, 1);
  plant.sample_period_s = testing::kSmallLoopTs_s;
  StateSpace controller = FirstOrderLoop{}.controller();
  controller.D(0, 0) = 0.0;  // open loop: the Jordan block stays in A_cl
  const StateSpace loop = closed_loop_output(plant, controller);
  ASSERT_TRUE(is_stable(loop));
  constexpr Index kRecord = 800, kLag = 60;
  const Eigen::MatrixXd v = white(kRecord, 1, kExcitationSeed + 1);
  const Eigen::MatrixXd q = simulate(loop, v);
  const Eigen::MatrixXd expected = q - fir_part(markov_parameters(loop, kLag), v, kLag);
  const Eigen::MatrixXd y = closed_loop_response_beyond(plant, controller, v, kLag);
  EXPECT_GT(expected.norm(), 0.01 * q.norm());
  EXPECT_LE((y - expected).cwiseAbs().maxCoeff(), kRoundOff * q.cwiseAbs().maxCoeff());
}

TEST(ResponseBeyond, RecordNoLongerThanTheLagGivesZeros) {
  const FirstOrderLoop s;
  const Eigen::MatrixXd v = Eigen::MatrixXd::Ones(20, 1);
  EXPECT_EQ(closed_loop_response_beyond(s.plant(), s.controller(), v, 20).norm(), 0.0);
}

TEST(ResponseBeyond, RejectsALagBelowOneAndAWrongExcitationWidth) {
  const FirstOrderLoop s;
  try {
    closed_loop_response_beyond(s.plant(), s.controller(), Eigen::MatrixXd::Ones(10, 1), 0);
    FAIL() << "lag 0 accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "response beyond the horizon: lag 0 < 1");
  }
  try {
    closed_loop_response_beyond(s.plant(), s.controller(), Eigen::MatrixXd::Ones(10, 2), 3);
    FAIL() << "two excitation columns accepted for one input";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "response beyond the horizon: 2 excitation columns for 1 plant inputs");
  }
}

// refit_response_beyond against the true tail: logs of the coupled loop (a third of the
// response beyond the horizon), the tail removed with a WRONG model (the plant's input
// matrix 10 % off: amplitudes and, slightly, poles wrong), ĝ estimated on what is left;
// the refit must take the tail most of the way to the truth (it keeps the model's poles,
// so not all the way: measured 28x closer) and must leave an exact model alone.
TEST(RefitResponseBeyond, TakesAWrongModelsTailMostOfTheWayToTheTruth) {
  const StateSpace plant = coupled_plant(), controller = pi_controller_2x2();
  const StateSpace loop = closed_loop_output(plant, controller);
  constexpr Index kRecord = 40000, kLag = 200;
  const Eigen::MatrixXd v = white(kRecord, 2, kExcitationSeed);
  const Eigen::MatrixXd q = simulate(loop, v);
  const Eigen::MatrixXd truth_tail = closed_loop_response_beyond(plant, controller, v, kLag);
  StateSpace wrong = plant;
  wrong.B *= 1.1;
  ASSERT_TRUE(is_stable(closed_loop_output(wrong, controller)));
  auto refit_error = [&](const StateSpace& model) {
    const Eigen::MatrixXd model_tail = closed_loop_response_beyond(model, controller, v, kLag);
    const Eigen::MatrixXd corrected = q - model_tail;
    const std::vector<ExperimentView> views = {{v, corrected}};
    MarkovOptions mo;
    mo.num_lags = kLag;
    const MarkovResult mr = estimate_markov(views, mo);
    const std::vector<Eigen::MatrixXd> d = refit_response_beyond(model, controller, views, mr.g, kLag);
    EXPECT_EQ(d.size(), 1u);
    // The refit removes the tail up to a constant (the offset is estimated with ĝ).
    Eigen::MatrixXd before = model_tail - truth_tail, after = model_tail + d[0] - truth_tail;
    before.rowwise() -= before.colwise().mean();
    after.rowwise() -= after.colwise().mean();
    return std::make_pair(before.norm(), after.norm());
  };
  const auto [before, after] = refit_error(wrong);
  std::printf("tail error of the wrong model %.3g, after the refit %.3g (%.1fx closer); tail norm %.3g\n", before,
              after, before / after, truth_tail.norm());
  EXPECT_LT(after, 0.2 * before);
  const auto [exact_before, exact_after] = refit_error(plant);
  EXPECT_LE(exact_before, 1e-9 * truth_tail.norm());
  EXPECT_LE(exact_after, 1e-8 * truth_tail.norm());
}

}  // namespace response_tail_test
}  // namespace lpvid
