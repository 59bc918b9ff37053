// diagnose with the model error in the weights (DiagnoseOptions::model_error_weighting;
// docs/math.md, "Weights when the model fails").  The data: the two-mass axis of
// tests/support/two_mass_axis.h from its independent oracle (the library's evaluation is
// not used), passed through a 1000 rad/s lag the model lacks, its noise stated as the
// data's variance and very uneven (the 30 lowest of 150 lines measured 100× more
// precisely: 0.01 % against 1 %), so that the noise-weighted fit and the error figure
// look at different lines.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "idlib/diagnose/diagnose.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace {

FitDataset lagged_axis() {
  const two_mass_axis::AxisValues truth{2.0, 6.5, 1.6e5, 55.0, 24.0, 12.0};
  FitDataset d;
  d.label = "two-mass oracle with a lag";
  d.response.omega_rad_s = log_frequency_grid(5.0, 3000.0, 150);
  d.response.input_names = {"i"};
  d.response.output_names = {"enc", "load"};
  for (Index k = 0; k < d.response.omega_rad_s.size(); ++k) {
    const double w = d.response.omega_rad_s(k);
    const Eigen::Vector2cd p = two_mass_axis::oracle(truth, w) / Complex(1.0, w / 1000.0);
    Eigen::MatrixXcd h(2, 1);
    h << p(0), p(1);
    const double rel = k < 30 ? 1e-4 : 1e-2;
    d.response.response.push_back(h);
    d.response.variance.push_back(h.cwiseAbs2() * rel * rel);
  }
  return d;
}

// The bookkeeping (the baseline's figure is the reweighted fit's, lower than the
// noise-weighted one it also reports; every candidate's figure no higher than its
// noise-weighted one; ΔBIC the same under both options), and the verdict: the lag is
// named under both weightings, and with the weights it is named within the noise.
TEST(DiagnoseWeighting, TheFiguresAreTheReweightedFitsAndTheLikelihoodIsUnchanged) {
  const PhysicalModel start = PhysicalModel::bare(make_mechanical_base(two_mass_axis::axis()));
  DiagnoseOptions noise;
  noise.candidates = {"actuator_lag", "input_delay", "gain_error"};
  noise.describe = false;
  DiagnoseOptions weighted = noise;
  weighted.model_error_weighting = true;
  const std::vector<FitDataset> data{lagged_axis()};
  const Diagnosis a = diagnose(start, data, noise);
  const Diagnosis b = diagnose(start, data, weighted);
  std::printf("baseline: noise-weighted %.3f %%, reweighted %.3f %% (model error %.3f %%); named %s / %s, %.4f %% / "
              "%.4f %% against a floor of %.4f %%\n",
              100 * a.baseline_error, 100 * b.baseline_error, 100 * b.model_error_weight, a.missing.c_str(),
              b.missing.c_str(), a.ranked.front().error * 100, b.ranked.front().error * 100, 100 * a.noise_floor);
  EXPECT_TRUE(std::isnan(a.noise_weighted_baseline_error));
  EXPECT_EQ(a.model_error_weight, 0.0);
  EXPECT_DOUBLE_EQ(b.noise_weighted_baseline_error, a.baseline_error);
  EXPECT_LT(b.baseline_error, a.baseline_error);
  EXPECT_GT(b.model_error_weight, 0.0);
  EXPECT_EQ(a.missing, "actuator_lag");
  EXPECT_EQ(b.missing, "actuator_lag");
  EXPECT_TRUE(b.explained);
  ASSERT_EQ(a.ranked.size(), b.ranked.size());
  for (const CandidateOutcome& cb : b.ranked) {
    const auto ca = std::find_if(a.ranked.begin(), a.ranked.end(),
                                 [&](const CandidateOutcome& c) { return c.effect == cb.effect; });
    ASSERT_NE(ca, a.ranked.end()) << cb.effect;
    if (!ca->fitted || !cb.fitted) continue;
    // the same noise-weighted refits: the same likelihood
    EXPECT_NEAR(cb.delta_bic, ca->delta_bic, 1e-6 * std::max(1.0, std::abs(ca->delta_bic))) << cb.effect;
    EXPECT_LE(cb.error, ca->error * (1 + 1e-9)) << cb.effect;
    if (std::isfinite(cb.noise_weighted_error)) {
      EXPECT_NEAR(cb.noise_weighted_error, ca->error, 1e-9) << cb.effect;
    }
  }
}

}  // namespace
}  // namespace lpvid
