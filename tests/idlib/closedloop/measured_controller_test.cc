// A controller known by its measured response (KnownController from an FRD): the
// per-frequency routes give the plant of the model controller it was computed
// from, and refuse a response on other frequencies.
#include <gtest/gtest.h>

#include <cstdio>
#include <numbers>

#include "idlib/closedloop/sensitivity.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {
namespace measured_controller_test {

constexpr double kTs = 1e-3;

// A 2 x 2 discrete plant (two lightly damped modes) and a PI-like diagonal controller.
StateSpace plant() {
  StateSpace p;
  p.sample_period_s = kTs;
  p.A = (Eigen::Matrix4d() << 1.9, -0.95, 0, 0, 1, 0, 0, 0, 0, 0, 1.8, -0.9, 0, 0, 1, 0).finished();
  p.B = (Eigen::Matrix<double, 4, 2>() << 1, 0.2, 0, 0, 0.1, 1, 0, 0).finished();
  p.C = (Eigen::Matrix<double, 2, 4>() << 0.01, 0.005, 0, 0, 0, 0, 0.01, 0.004).finished();
  p.D = Eigen::Matrix2d::Zero();
  return p;
}
StateSpace controller() {
  StateSpace c;
  c.sample_period_s = kTs;
  c.A = Eigen::Matrix2d::Identity() * 0.99;
  c.B = Eigen::Matrix2d::Identity() * 0.1;
  c.C = Eigen::Matrix2d::Identity();
  c.D = Eigen::Matrix2d::Identity() * 2.0;
  return c;
}

double max_rel_diff(const std::vector<Eigen::MatrixXcd>& a, const std::vector<Eigen::MatrixXcd>& b) {
  double worst = 0;
  for (size_t k = 0; k < a.size(); ++k) worst = std::max(worst, (a[k] - b[k]).norm() / b[k].norm());
  return worst;
}

TEST(MeasuredController, FrdOfTheModel_GivesThePlantOfTheModelOnBothRoutes) {
  const StateSpace p = plant(), c = controller();
  const Eigen::VectorXd w = log_frequency_grid(0.5, 0.9 * std::numbers::pi / kTs, 120);
  const FrequencyResponse c_frd = frequency_response(c, w);
  const FrequencyResponse g = frequency_response(closed_loop_output(p, c), w);
  const FrequencyResponse s = frequency_response(closed_loop_input_sensitivity(p, c), w);
  // The same C(ω) doubles (evaluate_response on the same grid) through the same
  // formula: identical.
  EXPECT_EQ(max_rel_diff(plant_from_closed_loop_frd(g, c_frd).response, plant_from_closed_loop_frd(g, c).response), 0.0);
  EXPECT_EQ(max_rel_diff(plant_from_sensitivity(s, c_frd, {}).plant.response, plant_from_sensitivity(s, c, {}).plant.response),
            0.0);
  // And that plant is P (independent truth: P's own response), to the round-off of
  // inverting the loop (measured 4.4e-13 here).
  constexpr double kLoopRoundOff = 1e-10;
  const double vs_truth = max_rel_diff(plant_from_closed_loop_frd(g, c_frd).response, frequency_response(p, w).response);
  EXPECT_LE(vs_truth, kLoopRoundOff);
  std::fprintf(stderr, "[measured] vs truth %.3g\n", vs_truth);
}

TEST(MeasuredController, OtherFrequenciesOrCount_AreAnInputErrorNamingTheLine) {
  const StateSpace p = plant(), c = controller();
  const Eigen::VectorXd w = log_frequency_grid(0.5, 100, 20);
  const FrequencyResponse g = frequency_response(closed_loop_output(p, c), w);
  Eigen::VectorXd shifted = w;
  shifted[4] *= 1 + 1e-6;
  try {
    plant_from_closed_loop_frd(g, frequency_response(c, shifted));
    FAIL() << "accepted a controller on other frequencies";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("plant_from_closed_loop_frd: frequency 5 of the measured controller is", 0), 0u)
        << e.what();
  }
  shifted[4] = w[4] * (1 + 1e-12);  // within 1e-9: the same line
  EXPECT_NO_THROW(plant_from_closed_loop_frd(g, frequency_response(c, shifted)));
  EXPECT_THROW(plant_from_closed_loop_frd(g, frequency_response(c, w.head(19))), InputError);
}

}  // namespace measured_controller_test
}  // namespace lpvid
