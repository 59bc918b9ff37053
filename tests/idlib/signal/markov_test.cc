#include "idlib/signal/markov.h"
#include "idlib/core/eigen_decompositions.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

namespace lpvid {
namespace markov_test {

using ::testing::HasSubstr;
using Method = MarkovOptions::Method;

constexpr std::uint64_t kSystemSeed = 7001;
constexpr std::uint64_t kExcitationSeed = 7002;
constexpr std::uint64_t kNoiseSeed = 7003;

// Test system: order 6, 3 inputs, 3 outputs, poles inside radius 0.7, so that
// |g[k]| ~ 0.7^k is below 1e-15 of |g[0..5]| after kLags = 100 lags: truncation
// error is negligible against kExactRelTol.
constexpr Index kOrder = 6;
constexpr Index kInputs = 3;
constexpr Index kOutputs = 3;
constexpr double kSpectralRadius = 0.7;
constexpr Index kLags = 100;

// Noise-free data: the covariance method is exact up to the PCG tolerance (1e-12 in
// these tests) times the condition number of the normal matrix (<= ~100 for the
// coloured case) plus FFT round-off; measured 1.5e-13 (white) to 6.5e-12 (coloured).
constexpr double kExactRelTol = 1e-8;
constexpr double kTightPcgTolerance = 1e-12;
// The correlation method on 6000-20000 samples is off by the sample autocorrelation
// of white noise (~1/sqrt(N) per lag, accumulated over the significant lags and the
// 3 inputs): measured 12-13 % (white), 194 % (coloured); it must be at least this
// bad, which pins that the two methods differ.
constexpr double kCorrelationMethodMinRelError = 0.01;

StateSpace random_stable_system(std::mt19937_64& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  auto randn = [&](Index r, Index c) {
    Eigen::MatrixXd x(r, c);
    for (Index i = 0; i < r; ++i)
      for (Index j = 0; j < c; ++j) x(i, j) = d(rng);
    return x;
  };
  StateSpace ss;
  ss.A = randn(kOrder, kOrder);
  const double radius = Eigen::EigenSolver<Eigen::MatrixXd>(ss.A).eigenvalues().cwiseAbs().maxCoeff();
  ss.A *= kSpectralRadius / radius;
  ss.B = randn(kOrder, kInputs);
  ss.C = randn(kOutputs, kOrder);
  ss.D = randn(kOutputs, kInputs);
  ss.sample_period_s = 1e-3;
  return ss;
}

MarkovSequence true_markov(const StateSpace& ss, Index L) {
  MarkovSequence g{ss.D};
  Eigen::MatrixXd ab = ss.B;
  for (Index k = 1; k <= L; ++k) {
    g.push_back(ss.C * ab);
    ab = ss.A * ab;
  }
  return g;
}

// x[t+1] = A x[t] + B v[t], q[t] = C x[t] + D v[t], x[0] = 0 (excitation starts with the record).
Eigen::MatrixXd simulate(const StateSpace& ss, const Eigen::MatrixXd& v) {
  Eigen::MatrixXd q(v.rows(), ss.C.rows());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(ss.A.rows());
  for (Index t = 0; t < v.rows(); ++t) {
    const Eigen::VectorXd u = v.row(t).transpose();
    q.row(t) = (ss.C * x + ss.D * u).transpose();
    x = ss.A * x + ss.B * u;
  }
  return q;
}

Eigen::MatrixXd white(Index n, Index channels, std::mt19937_64& rng, double std_dev = 1.0) {
  std::normal_distribution<double> d(0.0, std_dev);
  Eigen::MatrixXd v(n, channels);
  for (Index c = 0; c < channels; ++c)
    for (Index t = 0; t < n; ++t) v(t, c) = d(rng);
  return v;
}

// Excitation that only drives input j (the other columns identically zero).
Eigen::MatrixXd single_input(Index n, Index j, std::mt19937_64& rng) {
  Eigen::MatrixXd v = Eigen::MatrixXd::Zero(n, kInputs);
  v.col(j) = white(n, 1, rng);
  return v;
}

double relative_error(const MarkovSequence& est, const MarkovSequence& truth) {
  double num = 0.0, den = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    num += (est[k] - truth[k]).squaredNorm();
    den += truth[k].squaredNorm();
  }
  return std::sqrt(num / den);
}

// Exactness tests keep the sample mean: the data were simulated from the raw
// excitation (zero before the record), and removing its small sample mean
// (~1/sqrt(N)) changes the regression at the record start.
MarkovOptions options(Method method, Index lags = kLags, bool remove_mean = false) {
  MarkovOptions o;
  o.num_lags = lags;
  o.method = method;
  o.tolerance = kTightPcgTolerance;
  o.remove_mean = remove_mean;
  return o;
}

struct Fixture {
  StateSpace ss;
  MarkovSequence truth;
  std::vector<Eigen::MatrixXd> v, q;
  std::vector<ExperimentView> views() const {
    std::vector<ExperimentView> x;
    for (size_t e = 0; e < v.size(); ++e) x.push_back({v[e], q[e]});
    return x;
  }
};

Fixture one_input_per_experiment(Index n) {
  std::mt19937_64 sys_rng(kSystemSeed), rng(kExcitationSeed);
  Fixture f;
  f.ss = random_stable_system(sys_rng);
  f.truth = true_markov(f.ss, kLags);
  for (Index j = 0; j < kInputs; ++j) {
    f.v.push_back(single_input(n, j, rng));
    f.q.push_back(simulate(f.ss, f.v.back()));
  }
  return f;
}

Fixture simultaneous(Index n) {
  std::mt19937_64 sys_rng(kSystemSeed), rng(kExcitationSeed);
  Fixture f;
  f.ss = random_stable_system(sys_rng);
  f.truth = true_markov(f.ss, kLags);
  f.v.push_back(white(n, kInputs, rng));
  f.q.push_back(simulate(f.ss, f.v.back()));
  return f;
}

TEST(EstimateMarkov, LeastSquaresIsExactOnNoiseFreeDataWithOneInputPerExperiment) {
  const Fixture f = one_input_per_experiment(6000);
  const MarkovResult r = estimate_markov(f.views(), options(Method::kLeastSquares));
  ASSERT_EQ(r.g.size(), static_cast<size_t>(kLags + 1));
  ASSERT_EQ(r.g[0].rows(), kOutputs);
  ASSERT_EQ(r.g[0].cols(), kInputs);
  EXPECT_TRUE(r.report.usable) << r.report.termination;
  EXPECT_LE(relative_error(r.g, f.truth), kExactRelTol);
  EXPECT_GT(r.iterations, 0);
  EXPECT_EQ(r.total_samples, 3 * 6000);
}

TEST(EstimateMarkov, CorrelationMethodIsMeasurablyBiasedWithOneInputPerExperiment) {
  const Fixture f = one_input_per_experiment(6000);
  const MarkovResult r = estimate_markov(f.views(), options(Method::kCorrelation));
  EXPECT_GT(relative_error(r.g, f.truth), kCorrelationMethodMinRelError);
  // Still the right quantity, not junk: measured 13 %.
  constexpr double kCorrelationMethodMaxRelError = 0.3;
  EXPECT_LT(relative_error(r.g, f.truth), kCorrelationMethodMaxRelError);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_THAT(r.report.termination, HasSubstr("biased"));
}

TEST(EstimateMarkov, LeastSquaresIsExactWithSimultaneousExcitationOfAllInputs) {
  const Fixture f = simultaneous(20000);
  const MarkovResult r = estimate_markov(f.views(), options(Method::kLeastSquares));
  EXPECT_LE(relative_error(r.g, f.truth), kExactRelTol);
  const MarkovResult c = estimate_markov(f.views(), options(Method::kCorrelation));
  EXPECT_GT(relative_error(c.g, f.truth), kCorrelationMethodMinRelError);
  ASSERT_FALSE(c.report.warnings.empty());
  EXPECT_THAT(c.report.warnings[0], HasSubstr("excites inputs [0, 1, 2] at once"));
}

TEST(EstimateMarkov, LeastSquaresIsExactWithColouredCorrelatedExcitation) {
  std::mt19937_64 sys_rng(kSystemSeed), rng(kExcitationSeed);
  Fixture f;
  f.ss = random_stable_system(sys_rng);
  f.truth = true_markov(f.ss, kLags);
  // AR(1) with pole 0.8 per channel, then mixed: spectrum ratio ~(1.8/0.2)^2 = 81
  // and correlated inputs.
  Eigen::MatrixXd e = white(20000, kInputs, rng);
  Eigen::MatrixXd mix(kInputs, kInputs);
  mix << 1.0, 0.5, 0.0, 0.0, 1.0, -0.4, 0.3, 0.0, 1.0;
  Eigen::MatrixXd v(e.rows(), kInputs);
  Eigen::RowVectorXd state = Eigen::RowVectorXd::Zero(kInputs);
  for (Index t = 0; t < e.rows(); ++t) {
    state = 0.8 * state + e.row(t);
    v.row(t) = state * mix;
  }
  f.v.push_back(v);
  f.q.push_back(simulate(f.ss, v));
  const MarkovResult r = estimate_markov(f.views(), options(Method::kLeastSquares));
  EXPECT_TRUE(r.report.usable) << r.report.termination;
  EXPECT_LE(relative_error(r.g, f.truth), kExactRelTol);
  const MarkovResult c = estimate_markov(f.views(), options(Method::kCorrelation));
  EXPECT_GT(relative_error(c.g, f.truth), 10 * kCorrelationMethodMinRelError);
}

TEST(EstimateMarkov, LeastSquaresIsExactForAnFirSystemOnAShortRecordWithLargeLateLags) {
  // g[k] is O(1) up to k = L, so the end-of-record correction carries full weight:
  // the plain Toeplitz (autocorrelation-method) approximation would miss by O(L/N) = 10 %.
  constexpr Index kFirLags = 40;
  constexpr Index kShortRecord = 400;
  std::mt19937_64 rng(kExcitationSeed);
  MarkovSequence truth;
  for (Index k = 0; k <= kFirLags; ++k) truth.push_back(white(kOutputs, kInputs, rng));
  std::vector<Eigen::MatrixXd> v, q;
  std::vector<ExperimentView> views;
  for (int e = 0; e < 2; ++e) {
    v.push_back(white(kShortRecord, kInputs, rng));
    Eigen::MatrixXd out = Eigen::MatrixXd::Zero(kShortRecord, kOutputs);
    for (Index t = 0; t < kShortRecord; ++t)
      for (Index k = 0; k <= std::min(t, kFirLags); ++k)
        out.row(t) += (truth[k] * v.back().row(t - k).transpose()).transpose();
    q.push_back(out);
  }
  for (int e = 0; e < 2; ++e) views.push_back({v[e], q[e]});
  const MarkovResult r = estimate_markov(views, options(Method::kLeastSquares, kFirLags));
  EXPECT_LE(relative_error(r.g, truth), kExactRelTol);
  // Noise-free: the residual, hence noise_std, is round-off only.
  EXPECT_LE(r.noise_std.maxCoeff(), kExactRelTol);
}

TEST(EstimateMarkov, LeastSquaresErrorIsConsistentWithNoiseStd) {
  Fixture f = simultaneous(20000);
  std::mt19937_64 noise_rng(kNoiseSeed);
  constexpr double kNoiseStd = 0.5;
  for (auto& q : f.q) q += white(q.rows(), kOutputs, noise_rng, kNoiseStd);
  const MarkovResult r = estimate_markov(f.views(), options(Method::kLeastSquares));
  // 909 estimates with (nearly) Gaussian errors of standard deviation noise_std:
  // P(|z| > 4) = 6e-5, so more than 1 % beyond 4 sigma means noise_std is too small;
  // the RMS of z is 1 +- 0.05 (chi-square with 909 dof), so [0.8, 1.2] rejects a
  // noise_std that is wrong by 20 %.
  constexpr double kSigmaBound = 4.0;
  constexpr double kMaxFractionBeyond = 0.01;
  constexpr double kZRmsLow = 0.8, kZRmsHigh = 1.2;
  Index beyond = 0, count = 0;
  double z2 = 0.0;
  for (Index k = 0; k <= kLags; ++k) {
    const Eigen::MatrixXd z = (r.g[k] - f.truth[k]).cwiseQuotient(r.noise_std);
    beyond += (z.array().abs() > kSigmaBound).count();
    z2 += z.squaredNorm();
    count += z.size();
  }
  EXPECT_LE(static_cast<double>(beyond) / static_cast<double>(count), kMaxFractionBeyond);
  const double z_rms = std::sqrt(z2 / static_cast<double>(count));
  EXPECT_GT(z_rms, kZRmsLow);
  EXPECT_LT(z_rms, kZRmsHigh);
  // noise_std is sigma_e / sqrt(sum v_j^2) = 0.5 / sqrt(20000) for unit excitation.
  constexpr double kStdRelTol = 0.05;  // sample RMS of 20000 unit normals: +-1 %
  EXPECT_NEAR(r.noise_std(0, 0), kNoiseStd / std::sqrt(20000.0), kStdRelTol * kNoiseStd / std::sqrt(20000.0));
}

// A warm start (MarkovOptions::initial_guess) changes the path, not the answer: PCG
// stops at the same relative residual, so the estimate equals the cold one to within
// the tolerance's effect (measured ~1e-12 relative here), with fewer iterations from a
// close guess (the cold estimate of the same data with the outputs changed by 1 %, as
// identify's tail rounds change them) and from the estimate at half the horizon.
TEST(EstimateMarkov, AWarmStartGivesTheSameEstimateInFewerIterations) {
  Fixture f = simultaneous(20000);
  std::mt19937_64 noise_rng(kNoiseSeed + 3);
  for (auto& q : f.q) q += white(q.rows(), kOutputs, noise_rng, 0.5);
  const MarkovResult cold = estimate_markov(f.views(), options(Method::kLeastSquares));
  Fixture g = f;
  for (auto& q : g.q) q *= 1.01;
  const MarkovResult cold_changed = estimate_markov(g.views(), options(Method::kLeastSquares));
  MarkovOptions warm_options = options(Method::kLeastSquares);
  warm_options.initial_guess = cold.g;
  const MarkovResult warm = estimate_markov(g.views(), warm_options);
  EXPECT_TRUE(warm.report.usable) << warm.report.termination;
  EXPECT_LE(relative_error(warm.g, cold_changed.g), 1e-8);
  EXPECT_LT(warm.iterations, cold_changed.iterations);
  // From the estimate at half the horizon (padded with zeros).
  MarkovOptions half = options(Method::kLeastSquares);
  half.num_lags = kLags / 2;
  MarkovOptions from_half = options(Method::kLeastSquares);
  from_half.initial_guess = estimate_markov(f.views(), half).g;
  const MarkovResult doubled = estimate_markov(f.views(), from_half);
  EXPECT_LE(relative_error(doubled.g, cold.g), 1e-8);
  EXPECT_LE(doubled.iterations, cold.iterations);
  std::printf("PCG iterations: outputs changed by 1 %%: cold %ld, warm %ld; from half the horizon %ld (cold %ld)\n",
              static_cast<long>(cold_changed.iterations), static_cast<long>(warm.iterations),
              static_cast<long>(doubled.iterations), static_cast<long>(cold.iterations));
  // A guess of the wrong shape is refused.
  MarkovOptions wrong = options(Method::kLeastSquares);
  wrong.initial_guess.assign(3, Eigen::MatrixXd::Zero(kOutputs + 1, kInputs));
  EXPECT_THROW(estimate_markov(f.views(), wrong), InputError);
}

// Reused correlations (computed at 4x the horizon, then the same outputs at 2x, then new
// outputs over the same excitation) give the estimates of calls without them, to the
// round-off of the FFT block length (~1e-15 relative to Σ|q||v|; PCG's 1e-12 tolerance
// dominates the comparison).
TEST(EstimateMarkov, ReusedCorrelationsGiveTheSameEstimates) {
  constexpr double kReuseRelTol = 1e-9;
  Fixture f = one_input_per_experiment(20000);
  std::mt19937_64 noise_rng(kNoiseSeed + 5);
  for (auto& q : f.q) q += white(q.rows(), kOutputs, noise_rng, 0.5);
  MarkovCorrelations corr;
  corr.max_lag = 4 * (kLags / 2);
  const MarkovOptions half = options(Method::kLeastSquares, kLags / 2, true);
  const MarkovResult a = estimate_markov(f.views(), half, &corr);
  EXPECT_EQ(corr.max_lag, 4 * (kLags / 2));
  ASSERT_EQ(corr.vv.size(), static_cast<std::size_t>(corr.max_lag + 1));
  ASSERT_EQ(corr.qv.size(), corr.vv.size());
  EXPECT_LE(relative_error(a.g, estimate_markov(f.views(), half).g), kReuseRelTol);
  const MarkovOptions full = options(Method::kLeastSquares, kLags, true);
  const MarkovResult b = estimate_markov(f.views(), full, &corr);
  EXPECT_LE(relative_error(b.g, estimate_markov(f.views(), full).g), kReuseRelTol);
  EXPECT_NEAR(b.noise_std(0, 0), estimate_markov(f.views(), full).noise_std(0, 0), 1e-9 * b.noise_std(0, 0));
  Fixture g = f;
  for (auto& q : g.q) q *= 0.9;
  corr.qv.clear();
  const MarkovResult c = estimate_markov(g.views(), full, &corr);
  EXPECT_LE(relative_error(c.g, estimate_markov(g.views(), full).g), kReuseRelTol);
  EXPECT_TRUE(corr.qv.empty());
  // Correlations of other channels are refused.
  MarkovCorrelations wrong = corr;
  for (auto& x : wrong.vv) x = Eigen::MatrixXd::Zero(kInputs + 1, kInputs);
  EXPECT_THROW(estimate_markov(g.views(), full, &wrong), InputError);
}

TEST(EstimateMarkov, DefaultOffsetEstimateKeepsZeroColumnsZeroWithOneInputPerExperiment) {
  const Fixture f = one_input_per_experiment(6000);
  MarkovOptions o;  // defaults: least squares, remove_mean = true (output offsets estimated)
  o.num_lags = kLags;
  o.tolerance = kTightPcgTolerance;
  const MarkovResult r = estimate_markov(f.views(), o);
  // The offsets are estimated jointly (an intercept per experiment), so noise-free data
  // from rest are reproduced exactly; subtracting the excitation's sample mean instead
  // (the former method) was off by 4e-6 here.  A zero column turned into junk would
  // give errors of order 1.
  EXPECT_LE(relative_error(r.g, f.truth), kExactRelTol);
  EXPECT_TRUE(r.report.usable) << r.report.termination;
}

TEST(EstimateMarkov, OutputOffsetsPerExperimentAreEstimatedExactly) {
  // Noise-free data from rest plus a different constant offset on every output of
  // every experiment (sensor biases): the intercept absorbs them and g stays exact.
  Fixture f = one_input_per_experiment(6000);
  const double offsets[3] = {0.3, -2.0, 5.0};
  for (std::size_t e = 0; e < f.q.size(); ++e)
    for (Index i = 0; i < kOutputs; ++i) f.q[e].col(i).array() += offsets[i] * static_cast<double>(e + 1);
  MarkovOptions o;
  o.num_lags = kLags;
  o.tolerance = kTightPcgTolerance;
  const MarkovResult r = estimate_markov(f.views(), o);
  EXPECT_LE(relative_error(r.g, f.truth), kExactRelTol);
  // Nothing left but round-off: the residual standard error is far below the signal.
  constexpr double kNoiseFreeStd = 1e-8;
  EXPECT_LE(r.noise_std.maxCoeff(), kNoiseFreeStd);
}

TEST(EstimateMarkov, ReportsRmsOfMeanRemovedSignalsAndIgnoresOffsets) {
  Fixture f = simultaneous(20000);
  constexpr bool kRemoveMean = true;
  const MarkovResult plain = estimate_markov(f.views(), options(Method::kLeastSquares, kLags, kRemoveMean));
  // An offset on the output (sensor bias) is removed with the mean; the estimate
  // changes only by the mean of the original output (small), never by the offset.
  Fixture shifted = f;
  shifted.q[0].array() += 123.0;
  const MarkovResult r = estimate_markov(shifted.views(), options(Method::kLeastSquares, kLags, kRemoveMean));
  EXPECT_LE(relative_error(r.g, plain.g), kExactRelTol);
  // RMS from sums about the first sample vs. a two-pass reference: round-off only.
  constexpr double kRmsRelTol = 1e-12;
  for (Index j = 0; j < kInputs; ++j) {
    const Eigen::ArrayXd c = f.v[0].col(j).array() - f.v[0].col(j).mean();
    const double ref = std::sqrt(c.square().mean());
    EXPECT_NEAR(r.excitation_rms(j), ref, kRmsRelTol * ref);
  }
  // The +123 offset costs the shifted data ~log10(123 / 3.8) = 1.5 digits of round-off.
  constexpr double kOffsetRmsRelTol = 1e-10;
  EXPECT_NEAR(r.output_rms(0), plain.output_rms(0), kOffsetRmsRelTol * plain.output_rms(0));
  EXPECT_EQ(r.output_rms.size(), kOutputs);
}

TEST(EstimateMarkov, ReportsNotUsableWhenPcgHitsTheIterationLimit) {
  Fixture f = simultaneous(20000);
  f.v[0].col(1) = 0.999 * f.v[0].col(0) + 0.001 * f.v[0].col(1);  // nearly dependent inputs
  f.q[0] = simulate(f.ss, f.v[0]);
  MarkovOptions o = options(Method::kLeastSquares);
  o.max_iterations = 2;
  const MarkovResult r = estimate_markov(f.views(), o);
  EXPECT_FALSE(r.report.usable);
  EXPECT_EQ(r.iterations, 2);
  EXPECT_THAT(r.report.termination, HasSubstr("PCG stopped at max_iterations = 2"));
}

// ---- error paths ----------------------------------------------------------

std::string error_of(const std::vector<ExperimentView>& x, const MarkovOptions& o) {
  try {
    estimate_markov(x, o);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(MarkovOptions, RejectsNonPositiveLagsToleranceOutsideUnitIntervalAndNoIterations) {
  MarkovOptions o;
  EXPECT_THROW(o.validate(), InputError);
  o.num_lags = 5;
  EXPECT_NO_THROW(o.validate());
  auto message = [](const MarkovOptions& x) {
    try {
      x.validate();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no InputError");
  };
  MarkovOptions bad = o;
  bad.num_lags = 0;
  EXPECT_THAT(message(bad), HasSubstr("num_lags = 0; it must be > 0"));
  bad = o;
  bad.tolerance = 0.0;
  EXPECT_THAT(message(bad), HasSubstr("tolerance = 0; it must be in (0, 1)"));
  bad.tolerance = std::nan("");
  EXPECT_THAT(message(bad), HasSubstr("it must be in (0, 1)"));
  bad = o;
  bad.max_iterations = 0;
  EXPECT_THAT(message(bad), HasSubstr("max_iterations = 0; it must be > 0"));
}

TEST(EstimateMarkov, RejectsNoExperiments) {
  EXPECT_THAT(error_of({}, options(Method::kLeastSquares)), HasSubstr("no experiments"));
}

TEST(EstimateMarkov, RejectsExcitationAndOutputOfDifferentLength) {
  const Eigen::MatrixXd v = Eigen::MatrixXd::Ones(1000, 3), q = Eigen::MatrixXd::Ones(999, 3);
  EXPECT_THAT(error_of({{v, q}}, options(Method::kLeastSquares, 10)),
              HasSubstr("experiment 1: excitation has 1000 samples and output has 999"));
}

TEST(EstimateMarkov, RejectsChannelCountsThatDifferBetweenExperiments) {
  std::mt19937_64 rng(kExcitationSeed);
  const Eigen::MatrixXd v = white(1000, 3, rng), q = white(1000, 3, rng), q2 = white(1000, 2, rng);
  EXPECT_THAT(error_of({{v, q}, {v, q2}}, options(Method::kLeastSquares, 10)),
              HasSubstr("experiment 2 has 3 excitation and 2 output channels, experiment 1 has 3 and 3"));
}

TEST(EstimateMarkov, RejectsNonFiniteSamplesNamingTheFirst) {
  std::mt19937_64 rng(kExcitationSeed);
  Eigen::MatrixXd v = white(1000, 3, rng), q = white(1000, 3, rng);
  q(17, 2) = std::numeric_limits<double>::infinity();
  EXPECT_THAT(error_of({{v, q}}, options(Method::kLeastSquares, 10)),
              HasSubstr("experiment 1: output(18, 3) = inf; every sample must be finite"));
  q(17, 2) = 0.0;
  v(3, 0) = std::nan("");
  EXPECT_THAT(error_of({{v, q}}, options(Method::kCorrelation, 10)),
              HasSubstr("excitation(4, 1) = nan"));
}

TEST(EstimateMarkov, RejectsRecordsTooShortForTheLags) {
  std::mt19937_64 rng(kExcitationSeed);
  const Eigen::MatrixXd v = white(100, 3, rng), q = white(100, 3, rng);
  EXPECT_THAT(error_of({{v, q}}, options(Method::kLeastSquares, 100)),
              HasSubstr("experiment 1 has N = 100 samples for num_lags = 100; each record needs N > num_lags"));
  EXPECT_THAT(error_of({{v, q}}, options(Method::kLeastSquares, 20)),
              HasSubstr("100 samples in all for 3 inputs and num_lags = 20; the rule is total samples >= 2 * inputs * (num_lags + 1) = 126"));
}

TEST(EstimateMarkov, RejectsAnInputThatIsNeverExcited) {
  std::mt19937_64 rng(kExcitationSeed);
  Eigen::MatrixXd v = white(1000, 3, rng), q = white(1000, 3, rng);
  v.col(1).setConstant(2.5);  // constant: zero after mean removal
  EXPECT_THAT(error_of({{v, q}, {v, q}}, options(Method::kLeastSquares, 10, true)),
              HasSubstr("excitation input 2 is constant (zero after mean removal) in every experiment"));
  v.col(1).setZero();
  EXPECT_THAT(error_of({{v, q}}, options(Method::kCorrelation, 10)),
              HasSubstr("excitation input 2 is constant"));
}

TEST(EstimateMarkov, RejectsIdenticalInputsNamingThem) {
  std::mt19937_64 rng(kExcitationSeed);
  Eigen::MatrixXd v = white(1000, 3, rng), q = white(1000, 3, rng);
  v.col(2) = v.col(0);
  EXPECT_THAT(error_of({{v, q}}, options(Method::kLeastSquares, 10)),
              HasSubstr("excitation inputs [1, 3] are linearly dependent over all experiments"));
}

// The default horizon in samples (no sample time needed): min(N_shortest/4, N_total/(4m)).
TEST(DefaultMarkovLags, IsTheLongestHorizonTheRecordsSupportInSamples) {
  EXPECT_EQ(default_markov_lags(1024, 1024, 1), 256);    // the DaISy robot arm, Ts unknown
  EXPECT_EQ(default_markov_lags(2000, 6000, 3), 500);    // the golden logs: 3 x 2 s at 1 kHz
  EXPECT_EQ(default_markov_lags(2000, 2000, 3), 166);    // one log, three inputs: 4 samples per unknown
  EXPECT_EQ(default_markov_lags(64, 64, 1), kMinDefaultMarkovLags);
  // Long records: the work bound, 2000 lags (2 s at 1 kHz), not a quarter of 30 s.
  EXPECT_EQ(default_markov_lags(30000, 90000, 3), kMaxDefaultMarkovLags);
  EXPECT_EQ(default_markov_lags(8523, 8523, 2), 1065);  // the DaISy steel subframe: 4 samples per unknown
  // Every lag count it returns is one estimate_markov accepts (N > L, total >= 2 m (L + 1)).
  for (Index n : {64, 100, 1000, 4097})
    for (Index m : {1, 2, 3}) {
      if (n / (4 * m) < kMinDefaultMarkovLags) continue;
      const Index L = default_markov_lags(n, n, m);
      EXPECT_LT(L, n);
      EXPECT_GE(n, 2 * m * (L + 1)) << n << " " << m;
    }
}

TEST(DefaultMarkovLags, RefusesARecordTooShortSayingWhatWouldDo) {
  auto error = [](Index shortest, Index total, Index m) {
    try {
      default_markov_lags(shortest, total, m);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  // 63 samples: 15 lags < 16; the fix it names (64 samples) does give 16.
  EXPECT_EQ(error(63, 63, 1), "a record of 63 samples supports only 15 lags by default (a quarter of the shortest "
                              "record), fewer than 16; record at least 64 samples, or give --lags");
  EXPECT_EQ(default_markov_lags(64, 64, 1), 16);
  EXPECT_EQ(error(100, 100, 2), "100 samples in all for 2 excitation columns support only 12 lags by default (4 "
                                "samples per unknown), fewer than 16; record at least 128 samples in all, or give "
                                "--lags");
  EXPECT_EQ(default_markov_lags(100, 128, 2), 16);
}

}  // namespace markov_test
}  // namespace lpvid
