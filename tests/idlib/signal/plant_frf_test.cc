// estimate_plant_frf: the plant P = S_yv S_uv⁻¹ from closed-loop logs, against the
// plant's own frequency response (the fixture's state space, evaluated by
// idlib/lti — not by the estimator), with a NONLINEAR controller (saturating
// proportional path) and sensor noise: the estimate must be unbiased and its
// reported variance must match the scatter.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "idlib/lti/frequency_response.h"
#include "idlib/signal/frf.h"
#include "tests/idlib/closedloop/stage_fixture.h"

namespace lpvid {
namespace plant_frf_test {

constexpr double kTs = 1e-3;
constexpr Index kRecord = 1 << 17;  // 131 s per experiment
constexpr Index kSegment = 4096;    // Δω = 1.53 rad/s

struct Logs {
  Eigen::MatrixXd v, z;  // z = [q measured, u]
};

// e = −(q + n), u = C e (its proportional path through a saturation 3 tanh(x/3) of
// each channel's scale: a controller no linear model describes) + v.
Logs simulate(const Eigen::MatrixXd& v, const Eigen::MatrixXd& n, bool saturate) {
  const StateSpace P = stage_fixture::discrete_plant(kTs), C = stage_fixture::pi_controller(kTs);
  Eigen::VectorXd xp = Eigen::VectorXd::Zero(P.A.rows()), xc = Eigen::VectorXd::Zero(C.A.rows());
  Logs out{v, Eigen::MatrixXd(v.rows(), 6)};
  const Eigen::Vector3d scale(0.5, 0.5, 20.0);  // N·m, N·m, N: around the proportional path's rms
  for (Index t = 0; t < v.rows(); ++t) {
    const Eigen::Vector3d qm = P.C * xp + n.row(t).transpose();
    const Eigen::Vector3d e = -qm;
    Eigen::Vector3d prop = C.D * e;
    if (saturate)
      for (int c = 0; c < 3; ++c) prop(c) = 3.0 * scale(c) * std::tanh(prop(c) / (3.0 * scale(c)));
    const Eigen::Vector3d u = C.C * xc + prop + v.row(t).transpose();
    out.z.row(t) << qm.transpose(), u.transpose();
    xp = P.A * xp + P.B * u;
    xc = C.A * xc + C.B * e;
  }
  return out;
}

std::vector<Logs> experiments(double noise_rms, bool saturate, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> d(0.0, 1.0);
  const Eigen::Vector3d v_rms(1.0, 1.0, 100.0), n_rms = Eigen::Vector3d(1e-3, 1e-3, 1e-4) * noise_rms;
  std::vector<Logs> logs;
  for (int j = 0; j < 3; ++j) {  // experiment j excites input j (the paper's design)
    Eigen::MatrixXd v = Eigen::MatrixXd::Zero(kRecord, 3), n(kRecord, 3);
    for (Index t = 0; t < kRecord; ++t) {
      v(t, j) = v_rms(j) * d(rng);
      for (int c = 0; c < 3; ++c) n(t, c) = n_rms(c) * d(rng);
    }
    logs.push_back(simulate(v, n, saturate));
  }
  return logs;
}

FrequencyResponse estimate(const std::vector<Logs>& logs) {
  std::vector<ExperimentView> views;
  for (const Logs& l : logs) views.push_back({l.v, l.z});
  FrfOptions o;
  o.sample_period_s = kTs;
  o.segment_length = kSegment;
  return estimate_plant_frf(views, o);
}

// Over 5–300 rad/s: the mean of |P̂ − P|²/var and the share of entries whose error
// lies within 2σ (a disc of radius 2 sqrt(var)).
struct Calibration {
  double ratio = 0, coverage = 0, worst_relative = 0;
};
Calibration calibration(const FrequencyResponse& est) {
  const auto truth = evaluate_response(stage_fixture::discrete_plant(kTs), est.omega_rad_s);
  Calibration c;
  Index n = 0;
  for (Index k = 0; k < est.num_frequencies(); ++k) {
    const double w = est.omega_rad_s(k);
    if (w < 5.0 || w > 300.0 || est.flagged[static_cast<size_t>(k)]) continue;
    const auto& T = truth[static_cast<size_t>(k)];
    for (Index i = 0; i < 3; ++i)
      for (Index j = 0; j < 3; ++j) {
        const double e2 = std::norm(est.response[static_cast<size_t>(k)](i, j) - T(i, j));
        const double var = est.variance[static_cast<size_t>(k)](i, j);
        c.ratio += e2 / var;
        c.coverage += e2 <= 4.0 * var ? 1.0 : 0.0;
        c.worst_relative = std::max(c.worst_relative, std::sqrt(e2) / std::sqrt(std::abs(T(i, i)) * std::abs(T(j, j))));
        ++n;
      }
  }
  c.ratio /= static_cast<double>(n);
  c.coverage /= static_cast<double>(n);
  return c;
}

TEST(EstimatePlantFrf, NoiseFreeLinearLoopGivesThePlant) {
  const Calibration c = calibration(estimate(experiments(0.0, false, 11)));
  // Hann leakage of the loop's transients only, largest at the low end next to the
  // plant's 4.8 rad/s mode (bin width 1.5 rad/s): measured worst 0.069 of the channel
  // scale; the reported variance (its leakage-bias term) holds it: mean |δ|²/var
  // 0.62, 97 % of the entries within 2σ.
  EXPECT_LT(c.worst_relative, 0.1);
  EXPECT_LT(c.ratio, 1.0);
  EXPECT_GT(c.coverage, 0.9);
}

TEST(EstimatePlantFrf, NonlinearControllerAndSensorNoiseLeaveItUnbiasedWithCalibratedVariance) {
  // Pooled over three noise realisations: a linear-loop H1 from u to q would be
  // biased by the feedback of the noise; S_yv S_uv⁻¹ is not, and the saturation in
  // the controller does not matter.  Measured ratio 0.991–1.013 and 2σ coverage
  // 0.979 per seed; for a circular complex Gaussian error the 2σ disc holds
  // 1 − e⁻⁴ = 98.2 %.
  for (std::uint64_t seed : {21, 22, 23}) {
    const FrequencyResponse est = estimate(experiments(1.0, true, seed));
    const Calibration c = calibration(est);
    EXPECT_GT(c.ratio, 0.7) << seed;
    EXPECT_LT(c.ratio, 1.4) << seed;
    EXPECT_GT(c.coverage, 0.93) << seed;
  }
}

TEST(EstimatePlantFrf, NeedsTheOutputsBeforeTheInputs) {
  const Eigen::MatrixXd v = Eigen::MatrixXd::Random(4096, 3), z = Eigen::MatrixXd::Random(4096, 3);
  FrfOptions o;
  o.sample_period_s = kTs;
  EXPECT_THROW(estimate_plant_frf({{v, z}}, o), InputError);
}

}  // namespace plant_frf_test
}  // namespace lpvid
