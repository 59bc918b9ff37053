// estimate_lpm_frf: the Local Polynomial Method on random-noise data.  Truth: a
// lightly damped discrete second-order system written out in local_fixtures.h (its transfer
// function evaluated from its two poles, not by lpvid), and the 3-DOF stage loop of
// periodic_frf_test.cc for the closed-loop route (fixture state space via idlib/lti).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "idlib/lti/frequency_response.h"
#include "idlib/signal/frf.h"
#include "idlib/signal/lpm.h"
#include "tests/idlib/closedloop/stage_fixture.h"
#include "tests/idlib/signal/multisine.h"
#include "tests/idlib/signal/local_fixtures.h"

namespace lpvid {
namespace lpm_test {

constexpr double kTs = testing::kResonatorTs;
using testing::median;
using testing::record;
using testing::Resonator;

// Relative errors |Ĝ − G|/|G| of the LPM (default order and width) and of Welch
// (segments of N/4: 7 Hann segments at 50 % overlap) on Welch's lines in 10–200 rad/s
// (a subset of the LPM's bins: Welch line k = LPM bin 4k): their rms and their median.
struct Errors {
  double lpm_rms = 0, welch_rms = 0, lpm_median = 0, welch_median = 0;
  Index half_width = 0, dof = 0;
};
Errors lpm_and_welch(const Resonator& g, Index N, std::uint64_t seed) {
  Eigen::MatrixXd u, y;
  record(g, N, 1e-3, seed, u, y);
  LpmOptions lo;
  lo.sample_period_s = kTs;
  const LpmResult lpm = estimate_lpm_frf({{u, y}}, 0, lo);
  FrfOptions wo;
  wo.sample_period_s = kTs;
  wo.segment_length = N / 4;
  const FrequencyResponse welch = estimate_frf({{u, y}}, wo);
  Errors out;
  out.half_width = lpm.half_width;
  out.dof = lpm.dof;
  std::vector<double> el, ew;
  for (Index k = 0; k < welch.num_frequencies(); ++k) {
    const double w = welch.omega_rad_s(k);
    if (w < 10 || w > 200) continue;
    const size_t f = static_cast<size_t>(4 * (k + 1) - lpm.bins.front());
    EXPECT_NEAR(lpm.frd.omega_rad_s(static_cast<Index>(f)), w, 1e-9);
    const Complex truth = g.response(w);
    el.push_back(std::abs((lpm.frd.response[f](0, 0) - truth) / truth));
    ew.push_back(std::abs((welch.response[static_cast<size_t>(k)](0, 0) - truth) / truth));
    out.lpm_rms += el.back() * el.back();
    out.welch_rms += ew.back() * ew.back();
  }
  out.lpm_rms = std::sqrt(out.lpm_rms / static_cast<double>(el.size()));
  out.welch_rms = std::sqrt(out.welch_rms / static_cast<double>(ew.size()));
  out.lpm_median = median(el);
  out.welch_median = median(ew);
  return out;
}

TEST(Lpm, BeatsWelchOnALightlyDampedModeInAShortRecord) {
  // 8.2 s of white noise through a mode at 60 rad/s; Welch's 2 s segments leak.
  // Measured (seed 7): ζ = 0.05: rms ratio 2.9, median ratio 7.6; ζ = 0.02: rms ratio
  // 0.96 (both fail at the peak, which is narrower than the LPM's 13-bin window: the
  // polynomial cannot follow it), median ratio 7.6.  The LPM wins wherever leakage
  // dominates, i.e. off the peak; at a peak narrower than its window it is no better.
  for (const double zeta : {0.05, 0.02}) {
    Resonator g;
    g.zeta = zeta;
    const Errors e = lpm_and_welch(g, 8192, 7);
    std::printf("mode zeta %.2f at 60 rad/s, N = 8192 (n = %d, q = %d): relative error rms LPM %.3g Welch %.3g "
                "(ratio %.2f), median LPM %.3g Welch %.3g (ratio %.1f)\n",
                zeta, static_cast<int>(e.half_width), static_cast<int>(e.dof), e.lpm_rms, e.welch_rms,
                e.welch_rms / e.lpm_rms, e.lpm_median, e.welch_median, e.welch_median / e.lpm_median);
    EXPECT_GE(e.welch_median / e.lpm_median, 5.0) << zeta;
    if (zeta >= 0.05) {
      EXPECT_GE(e.welch_rms / e.lpm_rms, 2.0);
    }
  }
}

TEST(Lpm, VarianceMatchesTheScatterAwayFromTheResonance) {
  // A smooth system (ζ = 0.3) with noise: the polynomial error is far below the noise,
  // so |Ĝ − G|²/σ̂² must follow F(2, 2q): coverage of its 99 % band >= 95 %.
  Resonator g;
  g.zeta = 0.3;
  Eigen::MatrixXd u, y;
  record(g, 1 << 14, 0.05, 9, u, y);
  LpmOptions lo;
  lo.sample_period_s = kTs;
  const LpmResult lpm = estimate_lpm_frf({{u, y}}, 0, lo);
  const double band = testing::f2_quantile(0.99, 2.0 * static_cast<double>(lpm.dof));
  double inside = 0, ratio = 0;
  Index count = 0;
  for (Index f = 0; f < lpm.frd.num_frequencies(); ++f) {
    const double w = lpm.frd.omega_rad_s(f);
    if (w < 5 || w > 1000) continue;
    const double e2 = std::norm(lpm.frd.response[static_cast<size_t>(f)](0, 0) - g.response(w));
    const double var = lpm.frd.variance[static_cast<size_t>(f)](0, 0);
    inside += e2 <= band * var ? 1 : 0;
    ratio += e2 / var;
    ++count;
  }
  std::printf("LPM calibration: coverage %.4f, mean |e|^2/var %.3f over %d bins (q = %d)\n",
              inside / static_cast<double>(count), ratio / static_cast<double>(count), static_cast<int>(count),
              static_cast<int>(lpm.dof));
  EXPECT_GE(inside / static_cast<double>(count), 0.95);
  // E[F(2, 2q)] = q/(q − 1) (1.17 for q = 7); a variance off by 2× leaves [0.7, 1.8].
  EXPECT_GT(ratio / static_cast<double>(count), 0.7);
  EXPECT_LT(ratio / static_cast<double>(count), 1.8);
}

TEST(Lpm, ClosedLoopPlantFromTheReference) {
  // The stage loop with three simultaneous white excitations, 32 s, sensor noise:
  // P̂ = P̂S Ŝ⁻¹ from one LPM fit of v -> [q u].
  Eigen::MatrixXd v, z;
  testing::stage_loop_record(1 << 15, kTs, 13, v, z);
  LpmOptions o;
  o.sample_period_s = kTs;
  o.stride = 8;
  const LpmResult r = estimate_lpm_frf({{v, z}}, 3, o);
  const double coverage = testing::stage_plant_coverage(r.frd, r.dof, kTs);
  std::printf("LPM closed-loop plant: 99%% band coverage %.4f (n = %d, q = %d)\n", coverage,
              static_cast<int>(r.half_width), static_cast<int>(r.dof));
  EXPECT_GE(coverage, 0.95);
}

// Keeps the reports of a local method (idlib/core/progress.h).
class LineRecorder final : public Progress {
 public:
  void report(const ProgressStep& s) noexcept override {
    task = s.task;
    step = s.step;
    indices.push_back(s.index);
    count = s.count;
  }
  std::string task, step;
  std::vector<Index> indices;
  Index count = 0;
};

TEST(Lpm, ReportsItsFrequencyLinesAFewHundredTimesAndGivesTheSameResult) {
  Resonator g;
  Eigen::MatrixXd u, y;
  record(g, 8192, 1e-3, 7, u, y);
  LpmOptions lo;
  lo.sample_period_s = kTs;
  const LpmResult plain = estimate_lpm_frf({{u, y}}, 0, lo);
  LineRecorder rec;
  lo.progress = &rec;
  const LpmResult watched = estimate_lpm_frf({{u, y}}, 0, lo);
  const Index F = plain.frd.num_frequencies();
  EXPECT_EQ(rec.task, "frf lpm");
  EXPECT_EQ(rec.step, "frequency line");
  EXPECT_EQ(rec.count, F);
  ASSERT_FALSE(rec.indices.empty());
  EXPECT_EQ(rec.indices.front(), 1);
  EXPECT_TRUE(std::is_sorted(rec.indices.begin(), rec.indices.end()));
  EXPECT_LE(rec.indices.back(), F);
  // ~200 reports (one per F/200 lines, F = 4095 here): few enough to cost nothing.
  EXPECT_GE(rec.indices.size(), 100u);
  EXPECT_LE(rec.indices.size(), 410u);
  for (Index k = 0; k < F; ++k)
    EXPECT_EQ(watched.frd.response[static_cast<size_t>(k)], plain.frd.response[static_cast<size_t>(k)]) << k;
}

TEST(Lpm, RefusesARecordShorterThanItsWindow) {
  const Eigen::MatrixXd u = Eigen::MatrixXd::Random(20, 1), y = Eigen::MatrixXd::Random(20, 1);
  LpmOptions lo;
  lo.sample_period_s = kTs;
  try {
    estimate_lpm_frf({{u, y}}, 0, lo);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fewer than the LPM window"), std::string::npos) << e.what();
  }
}

}  // namespace lpm_test
}  // namespace lpvid
