// plant_markov_from_closed_loop: p̂ = ĝ (I − C ĝ)⁻¹ as an impulse response.  The truth
// is the Markov parameters of a plant written out here (C A^(k−1) B); the closed loop's
// parameters come from the state-space interconnection, not from the code under test.
#include "idlib/closedloop/plant_markov.h"

#include <gtest/gtest.h>

#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/small_loop.h"

namespace lpvid {
namespace plant_markov_test {

constexpr double kTs = 1e-3;

// Largest |p̂[k] − p[k]| over lags 1..L relative to the largest |p[k]|.
double relative_error(const MarkovSequence& estimate, const MarkovSequence& truth) {
  double err = 0, scale = 0;
  for (std::size_t k = 1; k < truth.size(); ++k) {
    err = std::max(err, (estimate[k] - truth[k]).cwiseAbs().maxCoeff());
    scale = std::max(scale, truth[k].cwiseAbs().maxCoeff());
  }
  return err / scale;
}

// A levitated axis: unit mass, a negative stiffness of 10 N/m (the beam's gravity on the
// platform's tilts: an open-loop pole at +3.16 rad/s), light damping, force → position,
// sampled by forward differences (any discrete plant will do: the truth is its own
// C A^(k−1) B).  Open-loop poles 1.00316 and 0.99684 (times the damping).
StateSpace levitated_axis() {
  StateSpace s;
  s.A.resize(2, 2);
  s.A << 1.0, kTs, 10.0 * kTs, 1.0 - 0.5 * kTs;
  s.B.resize(2, 1);
  s.B << 0.0, kTs;
  s.C.resize(1, 2);
  s.C << 1.0, 0.0;
  s.D = Eigen::MatrixXd::Zero(1, 1);
  s.sample_period_s = kTs;
  return s;
}

// PID with a filtered derivative on e = −q: integrator x_i += Ts e, derivative filter
// x_f tracks e with pole a = e^(−ω_f Ts); u = k_p e + k_d ω_f (e − x_f) + k_i x_i.
// Gains for ≈ 20 rad/s on the unit mass.
StateSpace pid_controller() {
  const double kp = 410, kd = 28, ki = 1600, wf = 200, a = std::exp(-wf * kTs);
  StateSpace c;
  c.A.resize(2, 2);
  c.A << a, 0.0, 0.0, 1.0;
  c.B.resize(2, 1);
  c.B << 1.0 - a, kTs;
  c.C.resize(1, 2);
  c.C << -kd * wf, ki;
  c.D = Eigen::MatrixXd::Constant(1, 1, kp + kd * wf);
  c.sample_period_s = kTs;
  return c;
}

TEST(PlantMarkov, AStablePlantUnderAPiControllerIsRecoveredToRounding) {
  const StateSpace plant = testing::coupled_plant(), controller = testing::pi_controller_2x2();
  ASSERT_TRUE(is_stable(closed_loop_output(plant, controller)));
  const Index L = 400;
  const MarkovSequence g = markov_parameters(closed_loop_output(plant, controller), L);
  // The recursion is exact for lags 1..L of the FIR ĝ: rounding only (1e-12 of the peak).
  EXPECT_LE(relative_error(plant_markov_from_closed_loop(g, controller, L), markov_parameters(plant, L)), 1e-10);
}

// Issue 24: an unstable plant with an integrating controller.  The response grows along
// the lags (e^(3.16 t): ×6.6 over 600 lags) and never decays, so a transform on the unit
// circle returns the stable two-sided sequence with the same spectrum; the causal
// recursion returns the plant's own response.
TEST(PlantMarkov, AnUnstableLevitatedAxisUnderAPidIsRecoveredAlongEveryLag) {
  const StateSpace plant = levitated_axis(), controller = pid_controller();
  ASSERT_FALSE(is_stable(plant));
  ASSERT_TRUE(is_stable(closed_loop_output(plant, controller)));
  const Index L = 600;
  const MarkovSequence g = markov_parameters(closed_loop_output(plant, controller), L);
  const MarkovSequence truth = markov_parameters(plant, L);
  ASSERT_GT(std::abs(truth[L](0, 0)), 5 * std::abs(truth[100](0, 0)));  // it grows
  EXPECT_LE(relative_error(plant_markov_from_closed_loop(g, controller, L), truth), 1e-9);
}

// An estimated ĝ[0] is never exactly 0: the lag-0 term closes an algebraic loop with
// the controller's feedthrough.  The truth here is P = G (I − C G)⁻¹ built as a state
// space (positive_feedback_with) from a G with a feedthrough.
TEST(PlantMarkov, ALagZeroTermIsSolvedWithTheControllersFeedthrough) {
  StateSpace G = closed_loop_output(testing::coupled_plant(), testing::pi_controller_2x2());
  G.D << 0.02, -0.01, 0.005, 0.03;
  const StateSpace controller = testing::pi_controller_2x2();
  const Index L = 300;
  const MarkovSequence truth = markov_parameters(positive_feedback_with(G, controller), L);
  const MarkovSequence p = plant_markov_from_closed_loop(markov_parameters(G, L), controller, L);
  EXPECT_LE(relative_error(p, truth), 1e-10);
  EXPECT_LE((p[0] - truth[0]).norm(), 1e-12);
}

TEST(PlantMarkov, ShapesThatDoNotFitAreRefused) {
  const StateSpace controller = testing::pi_controller_2x2();
  EXPECT_THROW(plant_markov_from_closed_loop({}, controller, 10), InputError);
  const MarkovSequence g(5, Eigen::MatrixXd::Zero(3, 2));
  EXPECT_THROW(plant_markov_from_closed_loop(g, controller, 10), InputError);
  const MarkovSequence g2(5, Eigen::MatrixXd::Zero(2, 2));
  EXPECT_THROW(plant_markov_from_closed_loop(g2, controller, 0), InputError);
}

}  // namespace plant_markov_test
}  // namespace lpvid
