// fir_residual_spectrum (idlib/signal/noise_spectrum.h) against spectra known in closed
// form: white noise of a given covariance, and first-order autoregressive noise
// e(t) = a e(t−1) + w(t) whose density is σ_w² / |1 − a e^{−jω}|², both behind a known
// FIR response to a white excitation, with a constant offset and a known output part
// that the correction argument must remove.  Seeded draws.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "idlib/core/error.h"
#include "idlib/signal/markov.h"
#include "idlib/signal/noise_spectrum.h"

namespace lpvid {
namespace noise_spectrum_test {

constexpr std::uint64_t kSeed = 77;
constexpr Index kRecord = 1 << 16;  // per experiment
constexpr Index kSegment = 256;
constexpr Index kBins = kSegment / 2 + 1;
// Welch with a Hann window and 50 % overlap over 2 records of 2^16 samples: ~1020
// segments, ~1/sqrt(0.95 * 1020) = 3.2 % relative standard deviation per bin of a
// density; 6 sigma per bin, and the mean over all bins to ~0.5 % (adjacent bins are
// correlated through the window) plus the window's bias on the smooth AR(1) density.
constexpr double kPerBinTolerance = 0.2;
constexpr double kMeanTolerance = 0.02;

struct Data {
  std::vector<Eigen::MatrixXd> v, q, correction;
  std::vector<ExperimentView> views() const {
    std::vector<ExperimentView> out;
    for (std::size_t e = 0; e < v.size(); ++e) out.push_back({v[e], q[e]});
    return out;
  }
};

// Known FIR g[0..3] from 1 input to 2 outputs.
MarkovSequence fir() {
  MarkovSequence g(4, Eigen::MatrixXd::Zero(2, 1));
  g[1] << 0.5, -0.2;
  g[2] << 0.25, 0.1;
  g[3] << -0.1, 0.05;
  return g;
}

// q = g * v + noise + offset + s (s a known sinusoid, also returned as the correction).
// noise: output 0 = AR(1) with coefficient ar of unit innovations; output 1 = white with
// variance 4, correlated with output 0's innovations by rho.
Data make(double ar, double rho) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> n01(0.0, 1.0);
  const MarkovSequence g = fir();
  Data d;
  for (int e = 0; e < 2; ++e) {
    Eigen::MatrixXd v(kRecord, 1), q(kRecord, 2), s(kRecord, 2);
    for (Index t = 0; t < kRecord; ++t) v(t, 0) = n01(rng);
    double state = 0;
    for (Index t = 0; t < kRecord; ++t) {
      const double w0 = n01(rng), w1 = rho * w0 + std::sqrt(1.0 - rho * rho) * n01(rng);
      state = ar * state + w0;
      Eigen::Vector2d y(state + 3.0, 2.0 * w1 - 1.0);  // constant offsets per output
      for (Index k = 0; k < static_cast<Index>(g.size()) && k <= t; ++k) y += g[static_cast<std::size_t>(k)] * v(t - k, 0);
      s(t, 0) = 5.0 * std::sin(0.3 * static_cast<double>(t));
      s(t, 1) = -2.0 * std::cos(0.05 * static_cast<double>(t));
      q.row(t) = (y + s.row(t).transpose()).transpose();
    }
    d.v.push_back(v);
    d.q.push_back(q);
    d.correction.push_back(s);
  }
  return d;
}

TEST(FirResidualSpectrum, WhiteNoiseBehindAKnownFirHasItsCovarianceAtEveryBin) {
  constexpr double kRho = 0.6;
  const Data d = make(0.0, kRho);
  const auto psd = fir_residual_spectrum(d.views(), fir(), kSegment, kBins, d.correction);
  ASSERT_EQ(static_cast<Index>(psd.size()), kBins);
  Eigen::Matrix2d sigma;  // covariance of (w0, 2 w1)
  sigma << 1.0, 2.0 * kRho, 2.0 * kRho, 4.0;
  Eigen::Matrix2d mean = Eigen::Matrix2d::Zero();
  for (Index f = 1; f < kBins - 1; ++f) {  // DC and Nyquist hold half the averages
    const Eigen::MatrixXcd& s = psd[static_cast<std::size_t>(f)];
    EXPECT_LE((s - s.adjoint()).norm(), 1e-12 * s.norm()) << "bin " << f << " not Hermitian";
    for (Index i = 0; i < 2; ++i)
      EXPECT_NEAR(s(i, i).real() / sigma(i, i), 1.0, kPerBinTolerance) << "bin " << f << " output " << i;
    mean += s.real() / static_cast<double>(kBins - 2);
  }
  EXPECT_LE((mean - sigma).cwiseAbs().maxCoeff(), kMeanTolerance * sigma.maxCoeff()) << mean;
}

TEST(FirResidualSpectrum, AutoregressiveNoiseHasTheClosedFormDensity) {
  constexpr double kAr = 0.5;
  const Data d = make(kAr, 0.0);
  const auto psd = fir_residual_spectrum(d.views(), fir(), kSegment, kBins, d.correction);
  double mean_ratio = 0;
  for (Index f = 1; f < kBins - 1; ++f) {
    const double omega = 2.0 * M_PI * static_cast<double>(f) / static_cast<double>(kSegment);
    const double truth = 1.0 / std::norm(1.0 - kAr * std::polar(1.0, -omega));
    const double ratio = psd[static_cast<std::size_t>(f)](0, 0).real() / truth;
    EXPECT_NEAR(ratio, 1.0, kPerBinTolerance) << "bin " << f;
    mean_ratio += ratio / static_cast<double>(kBins - 2);
  }
  EXPECT_NEAR(mean_ratio, 1.0, kMeanTolerance);
}

TEST(FirResidualSpectrum, WithoutTheCorrectionTheKnownSinusoidShowsAtItsBin) {
  // s(t, 0) = 5 sin(0.3 t): 0.3 rad/sample is bin 0.3 * 256 / (2π) ≈ 12.2.
  const Data d = make(0.0, 0.0);
  const auto with = fir_residual_spectrum(d.views(), fir(), kSegment, kBins, d.correction);
  const auto without = fir_residual_spectrum(d.views(), fir(), kSegment, kBins);
  EXPECT_GT(without[12](0, 0).real(), 100.0 * with[12](0, 0).real());
}

TEST(FirResidualSpectrum, RejectsASegmentLongerThanARecordAndTooManyBins) {
  const Data d = make(0.0, 0.0);
  try {
    fir_residual_spectrum(d.views(), fir(), 2 * kRecord, kBins);
    FAIL() << "segment longer than the record accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "residual spectrum: experiment 0 has 65536 samples, fewer than a segment of 131072");
  }
  try {
    fir_residual_spectrum(d.views(), fir(), kSegment, kBins + 1);
    FAIL() << "too many bins accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "residual spectrum: 130 bins asked of 256-sample segments; 1..129 are available");
  }
}

// markov_error_replicates against the scatter of the estimate itself: a known FIR behind
// a white excitation, AR(1) noise (a = 0.95, correlated over ~20 lags) on output 0 and
// white noise on output 1, kDraws independent draws.  Truth: the DFT bins of ĝ − g over
// the draws (the FIR and the noise are generated here, not by the code under test).
// Predicted: the mean over draws of Σ_s |δG_s|² at each bin.  Checked per third of the
// band and for the sum over all bins (a smooth combination, sensitive to correlation
// between bins).  With 300 draws an empirical variance has a relative standard
// deviation of 1/sqrt(300) = 5.8 %; ±25 % is ~4 sigma.  Segments of 256 samples, 13
// correlation times of the AR noise: each replicate cuts e at its segment's edges, which
// leaks the strong low-frequency noise into the weak high bins (measured: with 64-sample
// segments the top third of output 0 is over-predicted by 30 %; with 256, by < 10 %).
TEST(MarkovErrorReplicates, PredictTheScatterOfTheEstimateOverDraws) {
  constexpr int kDraws = 300;
  constexpr Index kN = 1 << 13, kLags = 64, kSeg = 256, kF = kLags / 2 + 1;
  const MarkovSequence g = fir();
  std::mt19937_64 rng(kSeed + 1);
  std::normal_distribution<double> n01(0.0, 1.0);
  Eigen::ArrayXXd emp = Eigen::ArrayXXd::Zero(kF, 2), pred = Eigen::ArrayXXd::Zero(kF, 2);
  Eigen::Array2d emp_sum = Eigen::Array2d::Zero(), pred_sum = Eigen::Array2d::Zero();
  double worst_zero_sum = 0;
  Index replicates = 0;
  for (int draw = 0; draw < kDraws; ++draw) {
    std::vector<Eigen::MatrixXd> v, q;
    for (int e = 0; e < 2; ++e) {
      Eigen::MatrixXd ve(kN, 1), qe(kN, 2);
      for (Index t = 0; t < kN; ++t) ve(t, 0) = n01(rng);
      double state = 0;
      for (Index t = 0; t < kN; ++t) {
        state = 0.95 * state + n01(rng);
        Eigen::Vector2d y(state, 0.5 * n01(rng));
        for (Index k = 0; k < static_cast<Index>(g.size()) && k <= t; ++k) y += g[static_cast<std::size_t>(k)] * ve(t - k, 0);
        qe.row(t) = y.transpose();
      }
      v.push_back(ve);
      q.push_back(qe);
    }
    std::vector<ExperimentView> views;
    for (int e = 0; e < 2; ++e) views.push_back({v[static_cast<std::size_t>(e)], q[static_cast<std::size_t>(e)]});
    MarkovOptions mo;
    mo.num_lags = kLags;
    const MarkovResult mr = estimate_markov(views, mo);
    Eigen::MatrixXd R0 = Eigen::MatrixXd::Zero(1, 1);
    for (const auto& x : views) R0 += x.excitation.transpose() * x.excitation;
    const auto reps = markov_error_replicates(views, mr.g, R0, kSeg, kLags, kF);
    replicates = static_cast<Index>(reps.size());
    Eigen::ArrayXcd err_sum = Eigen::ArrayXcd::Zero(2);
    std::vector<Eigen::ArrayXcd> rep_sum(reps.size(), Eigen::ArrayXcd::Zero(2));
    for (Index f = 0; f < kF; ++f) {
      const double w = 2.0 * M_PI * static_cast<double>(f) / static_cast<double>(kLags);
      for (Index i = 0; i < 2; ++i) {
        std::complex<double> err = 0, total = 0;
        for (Index k = 1; k <= kLags; ++k) {
          const double truth = k < static_cast<Index>(g.size()) ? g[static_cast<std::size_t>(k)](i, 0) : 0.0;
          err += (mr.g[static_cast<std::size_t>(k)](i, 0) - truth) * std::polar(1.0, -w * static_cast<double>(k));
        }
        emp(f, i) += std::norm(err) / kDraws;
        err_sum(i) += err;
        for (std::size_t s = 0; s < reps.size(); ++s) {
          const std::complex<double> r = reps[s][static_cast<std::size_t>(f)](i, 0);
          pred(f, i) += std::norm(r) / kDraws;
          rep_sum[s](i) += r;
          total += r;
        }
        worst_zero_sum = std::max(worst_zero_sum, std::abs(total) / std::sqrt(pred(f, i) * kDraws / (draw + 1)));
      }
    }
    emp_sum += err_sum.abs2() / kDraws;
    for (const auto& r : rep_sum) pred_sum += r.abs2() / kDraws;
  }
  EXPECT_EQ(replicates, 2 * (kN / kSeg));
  // Σ_s δg_s = 0 (the residual is orthogonal to the regressors), up to the offset.
  EXPECT_LE(worst_zero_sum, 1e-6);
  for (Index i = 0; i < 2; ++i) {
    for (Index part = 0; part < 3; ++part) {
      const Index f0 = part * kF / 3, f1 = (part + 1) * kF / 3;
      const double ratio = pred.col(i).segment(f0, f1 - f0).sum() / emp.col(i).segment(f0, f1 - f0).sum();
      std::printf("output %ld bins %ld..%ld: predicted / empirical variance %.3f\n", static_cast<long>(i),
                  static_cast<long>(f0), static_cast<long>(f1 - 1), ratio);
      EXPECT_NEAR(ratio, 1.0, 0.25) << "output " << i << ", bins " << f0 << ".." << f1 - 1;
    }
    std::printf("output %ld, sum over all bins: predicted / empirical variance %.3f\n", static_cast<long>(i),
                pred_sum(i) / emp_sum(i));
    EXPECT_NEAR(pred_sum(i) / emp_sum(i), 1.0, 0.25) << "output " << i << ": the sum over all bins";
  }
}

TEST(MarkovErrorReplicates, RejectsASingularExcitationAndTooManyBins) {
  const Data d = make(0.0, 0.0);
  const Eigen::MatrixXd R0 = Eigen::MatrixXd::Zero(1, 1);
  EXPECT_THROW(markov_error_replicates(d.views(), fir(), R0, 256, 64, 33), InputError);
  EXPECT_THROW(markov_error_replicates(d.views(), fir(), Eigen::MatrixXd::Identity(1, 1), 256, 64, 34), InputError);
}

}  // namespace noise_spectrum_test
}  // namespace lpvid
