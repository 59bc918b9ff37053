// identify with every default on the LEVITATED platform (issue 24): the plant seed 000
// builds towards, from the INDEPENDENT simulator (tests/support/independent_draw.h,
// indep::levitate: no spring stiffness, the raised beam's gravity making the tilts
// open-loop unstable, the heave a free mass with air damping; indep_sim --levitated),
// under the draw's PID with integral action designed on it.  Before issue 24 identify
// failed on every such draw ("no candidate plant ... closes a stable loop"): the plant's
// impulse response behind its starting models was computed on the unit circle, which
// holds only for a response that decays (idlib/closedloop/plant_markov.h).
#include <gtest/gtest.h>

#include <cstdio>

#include "idlib/core/error.h"
#include "idlib/identify/identify.h"
#include "idlib/identify/output_error.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "tests/idlib/identify/independent_case.h"
#include "tests/support/statistics.h"

namespace lpvid {
namespace levitated_identify_test {

testing::IndependentOutcome run_levitated(std::uint64_t seed, int position, double noise_scale) {
  testing::IndependentCase c;
  c.seed = seed;
  c.position = position;
  c.noise_scale = noise_scale;
  c.levitated = true;
  const testing::IndependentOutcome o = testing::run_independent(c);
  std::printf("levitated seed %llu position %d noise x%.3g: order %ld, mean %.4f %%, max %.4f %%\n",
              static_cast<unsigned long long>(seed), position, o.noise_scale,
              static_cast<long>(o.result.plant.order()), 100 * o.error.mean, 100 * o.error.max);
  EXPECT_FALSE(is_stable(o.truth));  // the case is what it claims: an open-loop unstable plant
  EXPECT_EQ(o.result.plant.order(), 6) << o.result.choices.order_reason;  // three free rigid-body axes
  EXPECT_FALSE(is_stable(o.result.plant));                                 // as the logs say
  EXPECT_TRUE(is_stable(closed_loop_output(o.result.plant, o.controller)));
  return o;
}

// Noise-free logs: the plant exactly, at every beam position.  Measured (this commit):
// seed 104 0.0000 / 0.0000 / 0.0000 %, seed 106 0.0001 / 0.0000 / 0.0000 % mean error
// over 1–400 rad/s; the bound is the robustness suite's noise-free bound (0.01 %), which
// is round-off and the tail rounds' last change, far below any modelling error.
TEST(IndependentLevitated, NoiseFreeLogsGiveTheExactUnstablePlantAtEveryBeamPosition) {
  for (const std::uint64_t seed : testing::statistical_cases<std::uint64_t>({104, 106}, {106}))
    for (int position = 0; position < 3; ++position)
      EXPECT_LE(run_levitated(seed, position, 0.0).error.mean, 0.01 / 100) << "seed " << seed << " position " << position;
}

// Noisy logs (the drawn sensor noise, 60 s per experiment): the error is the noise's,
// not a bias, so the test is the 95 % bands' coverage of the truth (the bound of
// IndependentBands: at least 0.85 of the (frequency, entry) pairs, pooled), not an
// error bound.  With the loop gain high at low frequencies (a levitated plant's
// response grows as 1/ω² there, the PID holds it) the noise reaches the plant
// estimate strongly: measured mean errors 0.14 % (seed 104, noise ×0.20), 0.063 %
// (seed 107, ×0.17) and 2.3 % (seed 106, ×5.2) over 1–400 rad/s; the bands contain the
// truth at 0.940 of the pairs pooled (30 s logs through the CLI: 80–100 % per run).
TEST(IndependentLevitated, NoisyLogsGiveBandsThatCoverTheTruth) {
  const Eigen::VectorXd omega =
      log_frequency_grid(testing::kIndependentBandLow, testing::kIndependentBandHigh, testing::kIndependentBandPoints);
  Index inside = 0, total = 0;
  for (const std::uint64_t seed : testing::statistical_cases<std::uint64_t>({104, 106, 107}, {107})) {
    const testing::IndependentOutcome o = run_levitated(seed, 1, -1.0);
    ASSERT_GT(o.result.fit.replicates, 0) << o.result.choices.bands_reason;
    const auto est = evaluate_response(o.result.plant, omega), truth = evaluate_response(o.truth, omega);
    const auto var = plant_response_variance(o.result.fit, omega);
    for (Index k = 0; k < omega.size(); ++k)
      for (Index i = 0; i < 3; ++i)
        for (Index j = 0; j < 3; ++j) {
          const auto f = static_cast<std::size_t>(k);
          inside += std::norm(est[f](i, j) - truth[f](i, j)) <= kBandRadiusPerSigma * kBandRadiusPerSigma * var[f](i, j);
          ++total;
        }
  }
  const double coverage = static_cast<double>(inside) / static_cast<double>(total);
  std::printf("levitated, noisy: the 95 %% bands contain the truth at %.3f of %ld (frequency, entry) pairs\n", coverage,
              static_cast<long>(total));
  EXPECT_GE(coverage, 0.85);
}

// The paper's recipe (--method era: Markov, ERA, unloop) on the levitated platform: unloop
// must tell the PID's integrators (z = 1) from the plant's rigid-body poles at and near
// z = 1, and on these logs it cannot (issue 24 measured 102-4904 % error).  The plant is
// now judged by the loop it makes with the controller that ran: one that closes an
// unstable loop is refused with the way out named, one whose loop misses the logs far
// more than the ERA closed loop it came from is warned of — never a wrong plant in
// silence.  Truth: the independent simulator's plant, which closed with the same
// controller simulates these noise-free logs (the returned one's loop, if any, does not:
// what the warning claims).
TEST(IndependentLevitated, TheEraRecipeThatCannotUnloopThePlantSaysSo) {
  testing::IndependentCase c;
  c.seed = 104;
  c.noise_scale = 0.0;
  c.duration_s = 20;
  c.identify = false;
  const testing::IndependentOutcome o = testing::run_independent(c);
  std::vector<ExperimentView> views;
  for (std::size_t j = 0; j < 3; ++j) views.push_back({o.v[j], o.q[j]});
  IdentifyOptions era;
  era.method = IdentifyMethod::kEra;
  try {
    const IdentifyResult r = identify_closed_loop(views, c.sample_period_s, o.controller, era);
    bool warned = false;
    for (const auto& w : r.warnings) warned = warned || w.find("misses the logs") != std::string::npos;
    // The warning is right when the true plant, closed with the same controller, simulates
    // these noise-free logs (to 99 % at every output) and the returned one does not.
    const Eigen::VectorXd truth_fit =
        simulation_fit_percent(closed_loop_output(o.truth, o.controller), views, false);
    std::printf("era on the levitated plant: returned, %s; the true plant in its loop: %.2f / %.2f / %.2f %%\n",
                r.reclosed_reason.c_str(), truth_fit(0), truth_fit(1), truth_fit(2));
    EXPECT_TRUE(warned);
    ASSERT_EQ(r.reclosed_fit_percent.size(), 3);
    EXPECT_GE(truth_fit.minCoeff(), 99.0);
    EXPECT_LT(r.reclosed_fit_percent.minCoeff(), 90.0);
  } catch (const NumericalError& e) {
    std::printf("era on the levitated plant: refused: %s\n", e.what());
    EXPECT_NE(std::string(e.what()).find("UNSTABLE loop"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("--method structured"), std::string::npos);
  }
}

}  // namespace levitated_identify_test
}  // namespace lpvid
