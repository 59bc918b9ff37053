// Excitation signals: each property checked against a computation of its own
// (a plain O(L^2) DFT, Parseval, the m-sequence autocorrelation, H^T H), never
// against the generator's FFT.
#include "idlib/signal/excitation.h"
#include "idlib/core/eigen_decompositions.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <set>

#include "idlib/core/error.h"

namespace lpvid {
namespace excitation_test {

using ::testing::HasSubstr;

constexpr double kPi = std::numbers::pi;

// The DFT of x[0..L) at bin k, summed directly (the independent truth).
Complex plain_dft(const double* x, Index L, Index k) {
  Complex sum(0, 0);
  for (Index t = 0; t < L; ++t) {
    // (k t) mod L in integers keeps the angle exact for large k t.
    const double angle = -2 * kPi * static_cast<double>((k * t) % L) / static_cast<double>(L);
    sum += x[t] * Complex(std::cos(angle), std::sin(angle));
  }
  return sum;
}

ExcitationSpec small_multisine() {
  ExcitationSpec s;
  s.kind = ExcitationKind::kMultisine;
  s.sample_rate_hz = 1000;
  s.period_samples = 250;
  s.periods = 2;
  s.transient_periods = 1;
  s.band_lo_hz = 20;
  s.band_hi_hz = 300;
  s.rms = {0.5};
  s.seed = 7;
  return s;
}

// Checks the spectrum of one period of column j starting at row `start`:
// amplitude A = rms sqrt(2 / K) on the bins, <= 1e-12 relative elsewhere.
void expect_designed_spectrum(const Eigen::MatrixXd& x, Index j, Index start, Index L, const std::vector<Index>& bins,
                              double rms) {
  const double A = rms * std::sqrt(2.0 / static_cast<double>(bins.size()));
  const std::set<Index> excited(bins.begin(), bins.end());
  // Round-off of an FFT of L = 250 points and of the plain DFT: ~1e-15 of A per
  // bin; 1e-12 leaves room without hiding a leaked line (which would be ~A).
  constexpr double kRelTolerance = 1e-12;
  for (Index k = 0; k <= L / 2; ++k) {
    const double amplitude = 2 * std::abs(plain_dft(x.col(j).data() + start, L, k)) / static_cast<double>(L);
    if (excited.count(k) != 0)
      EXPECT_NEAR(amplitude, A, kRelTolerance * A) << "bin " << k;
    else
      EXPECT_LE(amplitude, kRelTolerance * A) << "bin " << k;
  }
}

TEST(Multisine, OnePeriodHasTheDesignedAmplitudeOnTheExcitedBinsAndNothingElsewhere) {
  ExcitationSpec s = small_multisine();
  const ExcitationSignal x = generate_excitation(s);
  // Bins k with 20 <= 4k <= 300 and k < 125: k = 5..75.
  std::vector<Index> expected;
  for (Index k = 5; k <= 75; ++k) expected.push_back(k);
  ASSERT_EQ(x.excited_bins.size(), 1u);
  EXPECT_EQ(x.excited_bins[0], expected);
  ASSERT_EQ(x.samples.rows(), (1 + 2) * 250);
  expect_designed_spectrum(x.samples, 0, 250, 250, expected, 0.5);
}

TEST(Multisine, MinimisedCrestFactorKeepsTheSpectrumExactlyAndLowersTheCrest) {
  ExcitationSpec s = small_multisine();
  s.minimise_crest = true;
  s.crest_iterations = 100;
  const ExcitationSignal x = generate_excitation(s);
  expect_designed_spectrum(x.samples, 0, 0, 250, x.excited_bins[0], 0.5);
  EXPECT_LT(x.crest_factor(0), x.crest_factor_initial(0));
  // The crest factor reported is the measured one.
  const Eigen::VectorXd period = x.samples.col(0).head(250);
  EXPECT_NEAR(x.crest_factor(0), crest_factor(period), 1e-12);
}

// A shaped spectrum: points (10 Hz, 1) and (100 Hz, 0.01) are a(f) = (f / 10)^-2 between
// them (a straight line of slope -2 in log-log), 1 below 10 Hz and 0.01 above 100 Hz
// (constant beyond the ends).  The truth is that closed form, not the interpolator.
double closed_form_shape(double f_hz) {
  if (f_hz <= 10) return 1.0;
  if (f_hz >= 100) return 0.01;
  return std::pow(f_hz / 10.0, -2.0);
}

TEST(Multisine, AmplitudeShapeIsLogLogLinearInsideAndConstantBeyondTheEnds) {
  const std::vector<double> f = {1, 10, 20, 31.6227766, 50, 99.9, 100, 1000};
  const std::vector<double> a = amplitude_shape_at({10, 100}, {1, 0.01}, f);
  // pow/log round-off: a few ulp.
  for (std::size_t i = 0; i < f.size(); ++i) EXPECT_NEAR(a[i], closed_form_shape(f[i]), 1e-14) << f[i];
  // No points: flat.
  EXPECT_EQ(amplitude_shape_at({}, {}, f), std::vector<double>(f.size(), 1.0));
}

// The plain DFT of one period has amplitude c a(f_k) on every excited bin (c from the
// RMS: sum_k (c a_k)^2 / 2 = rms^2, Parseval) and nothing elsewhere, with the crest
// factor minimised (which must keep the shape), and line_amplitudes says the same.
TEST(Multisine, ShapedSpectrumHasTheRequestedRelativeAmplitudesOnEveryLine) {
  ExcitationSpec s = small_multisine();  // 4 Hz lines from 20 to 300 Hz
  s.shape_f_hz = {10, 100};
  s.shape_amplitude = {1, 0.01};
  s.minimise_crest = true;
  s.crest_iterations = 50;
  const ExcitationSignal x = generate_excitation(s);
  const std::vector<Index>& bins = x.excited_bins[0];
  double sum = 0;
  for (Index k : bins) sum += 0.5 * std::pow(closed_form_shape(4.0 * static_cast<double>(k)), 2);
  const double c = 0.5 / std::sqrt(sum);
  const std::set<Index> excited(bins.begin(), bins.end());
  // As expect_designed_spectrum: ~1e-15 of the largest line of round-off in the FFT
  // and the plain DFT; the smallest line is 1/25 of the largest (0.01 vs 0.25 at
  // 20 Hz), so 1e-12 of each line still bounds the round-off by ~1000x.
  constexpr double kRelTolerance = 1e-12;
  ASSERT_EQ(x.line_amplitudes.size(), 1u);
  ASSERT_EQ(x.line_amplitudes[0].size(), bins.size());
  std::size_t i = 0;
  for (Index k = 0; k <= 125; ++k) {
    const double amplitude = 2 * std::abs(plain_dft(x.samples.col(0).data() + 250, 250, k)) / 250.0;
    if (excited.count(k) != 0) {
      const double want = c * closed_form_shape(4.0 * static_cast<double>(k));
      EXPECT_NEAR(amplitude, want, kRelTolerance * want) << "bin " << k;
      EXPECT_NEAR(x.line_amplitudes[0][i++], want, kRelTolerance * want) << "bin " << k;
    } else {
      EXPECT_LE(amplitude, kRelTolerance * c * 0.01) << "bin " << k;
    }
  }
  EXPECT_LT(x.crest_factor(0), x.crest_factor_initial(0));
}

TEST(ExcitationSpec, AmplitudeSpectrumBreakingItsRulesIsRefused) {
  auto refused = [](std::vector<double> f, std::vector<double> a, ExcitationKind kind, const char* text) {
    ExcitationSpec s = small_multisine();
    s.kind = kind;
    if (kind == ExcitationKind::kNoise) s.period_samples = 0, s.samples = 100, s.transient_periods = 0, s.periods = 1;
    s.shape_f_hz = std::move(f);
    s.shape_amplitude = std::move(a);
    try {
      s.validate();
      ADD_FAILURE() << text;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  };
  refused({10}, {1}, ExcitationKind::kMultisine, "give at least 2 points");
  refused({10, 10}, {1, 2}, ExcitationKind::kMultisine, "point 2: frequency 10 Hz");
  refused({10, 20}, {1, 0}, ExcitationKind::kMultisine, "point 2: amplitude 0");
  refused({10, 20}, {1, 2}, ExcitationKind::kNoise, "a noise has no lines");
}

TEST(Multisine, LogGridStepsByTheRatioWithoutDuplicatesAndWithinTheBand) {
  ExcitationSpec s = small_multisine();
  s.period_samples = 10000;  // 0.1 Hz resolution
  s.band_lo_hz = 0.1;
  s.band_hi_hz = 400;
  s.grid = LineGrid::kLog;
  s.lines_per_decade = 10;
  const std::vector<Index> bins = multisine_grid(s);
  ASSERT_GE(bins.size(), 2u);
  EXPECT_EQ(bins.front(), 1);
  EXPECT_LE(bins.back(), 4000);
  const double ratio = std::pow(10.0, 0.1);
  for (std::size_t i = 1; i < bins.size(); ++i) {
    EXPECT_GT(bins[i], bins[i - 1]);
    // Each step is max(k + 1, round(k ratio)): never more than the ratio plus rounding.
    EXPECT_LE(bins[i], std::max<Index>(bins[i - 1] + 1, std::llround(bins[i - 1] * ratio)));
    if (bins[i - 1] >= 20) {
      EXPECT_NEAR(static_cast<double>(bins[i]) / bins[i - 1], ratio, 0.5 / bins[i - 1] + 1e-12);
    }
  }
  // About 10 lines per decade over the 3.6 decades where the ratio exceeds one bin.
  EXPECT_GT(bins.size(), 30u);
  EXPECT_LT(bins.size(), 60u);
}

TEST(Multisine, LinearGridTakesEveryMthBin) {
  ExcitationSpec s = small_multisine();
  s.every = 3;
  const std::vector<Index> bins = multisine_grid(s);
  for (std::size_t i = 0; i < bins.size(); ++i) EXPECT_EQ(bins[i], 5 + 3 * static_cast<Index>(i));
  EXPECT_LE(bins.back(), 75);
}

TEST(Multisine, PeriodsRepeatToTheLastBitAndBlocksFollowTheLayout) {
  ExcitationSpec s = small_multisine();
  s.channels = 3;
  s.mimo = MimoDesign::kOneAtATime;
  s.realisations = 2;
  s.rms = {0.1, 0.2, 0.3};
  const ExcitationSignal x = generate_excitation(s);
  const Index L = 250, block = 3 * L, E = 3;
  ASSERT_EQ(x.samples.rows(), 2 * E * block);
  for (Index b = 0; b < 2 * E; ++b)
    for (Index p = 1; p < 3; ++p)
      for (Index j = 0; j < 3; ++j)
        ASSERT_TRUE(x.samples.col(j).segment(b * block + p * L, L) ==
                    x.samples.col(j).segment(b * block + (p - 1) * L, L))
            << "block " << b << " period " << p << " input " << j;
  // One at a time: in experiment e only input e is non-zero.
  for (Index r = 0; r < 2; ++r)
    for (Index e = 0; e < E; ++e)
      for (Index j = 0; j < 3; ++j) {
        const double energy = x.samples.col(j).segment((r * E + e) * block, block).squaredNorm();
        if (j == e)
          EXPECT_GT(energy, 0);
        else
          EXPECT_EQ(energy, 0);
      }
  // A new realisation draws new phases: same amplitudes, different samples.
  EXPECT_FALSE(x.samples.col(0).segment(0, L) == x.samples.col(0).segment(E * block, L));
  expect_designed_spectrum(x.samples, 0, E * block, L, x.excited_bins[0], 0.1);
}

TEST(Multisine, RmsAndPeakLimitsAreMetWithTheTighterOneExact) {
  ExcitationSpec s = small_multisine();
  s.channels = 2;
  s.mimo = MimoDesign::kHadamard;
  s.rms = {1.0, 1.0};
  s.peak = {100.0, 1.5};  // input 0: the RMS binds; input 1: the peak binds (crest ~3 > 1.5)
  const ExcitationSignal x = generate_excitation(s);
  // Round-off of sums over 250 samples: 1e-12 relative.
  constexpr double kTol = 1e-12;
  for (Index j = 0; j < 2; ++j) {
    const Eigen::VectorXd period = x.samples.col(j).segment(250, 250);
    const double rms = std::sqrt(period.squaredNorm() / 250), peak = x.samples.col(j).cwiseAbs().maxCoeff();
    EXPECT_LE(rms, s.rms[static_cast<std::size_t>(j)] * (1 + kTol));
    EXPECT_LE(peak, s.peak[static_cast<std::size_t>(j)] * (1 + kTol));
    EXPECT_NEAR(x.rms(j), rms, kTol * rms);
    EXPECT_NEAR(x.peak(j), peak, kTol * peak);
  }
  EXPECT_NEAR(x.rms(0), 1.0, kTol);
  EXPECT_NEAR(x.peak(1), 1.5, kTol);
}

TEST(Multisine, SchroederPhasesHaveALowerCrestFactorThanRandomPhasesOnAverage) {
  ExcitationSpec s = small_multisine();
  s.period_samples = 1000;
  s.band_lo_hz = 1;
  s.band_hi_hz = 200;  // 200 lines
  s.phase = PhaseChoice::kSchroeder;
  const double schroeder = generate_excitation(s).crest_factor(0);
  s.phase = PhaseChoice::kRandom;
  double random_sum = 0;
  constexpr int kSeeds = 10;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    s.seed = static_cast<std::uint64_t>(seed);
    random_sum += generate_excitation(s).crest_factor(0);
  }
  // Schroeder's flat-spectrum phases give ~1.7 for many lines; random phases ~3 to 4
  // (a Gaussian-like sum over 1000 samples); the margin is large.
  EXPECT_LT(schroeder, 2.0);
  EXPECT_LT(schroeder, random_sum / kSeeds);
}

TEST(Multisine, SameSeedGivesTheSameSamplesAndAnotherSeedOthers) {
  ExcitationSpec s = small_multisine();
  const Eigen::MatrixXd a = generate_excitation(s).samples;
  const Eigen::MatrixXd b = generate_excitation(s).samples;
  EXPECT_TRUE(a == b);
  s.seed = 8;
  EXPECT_FALSE(a == generate_excitation(s).samples);
}

TEST(Mimo, HadamardCodingIsOrthogonalAndEveryLineMatrixHasFullRank) {
  for (Index n : {1, 2, 3, 5, 6}) {
    const Eigen::MatrixXd H = hadamard_coding(n);
    const Index ne = H.rows();
    EXPECT_GE(ne, n);
    EXPECT_EQ(ne & (ne - 1), 0) << "power of two";
    EXPECT_TRUE((H.array().abs() == 1.0).all());
    // Columns (inputs) orthogonal over the experiments: H^T H = n_e I, exactly in integers.
    EXPECT_TRUE(H.transpose() * H == ne * Eigen::MatrixXd::Identity(n, n)) << n;
  }
  ExcitationSpec s = small_multisine();
  s.channels = 3;
  s.mimo = MimoDesign::kHadamard;
  s.rms = {1.0};
  const ExcitationSignal x = generate_excitation(s);
  ASSERT_EQ(x.experiments, 4);
  const Index L = 250, block = 3 * L;
  // Per excited line, the n x n_e matrix U(k) of the inputs' DFTs over the
  // experiments (plain DFT of one steady period of each block) has full rank:
  // its smallest singular value is close to the largest (flat amplitudes).
  for (Index k : {x.excited_bins[0].front(), x.excited_bins[0][30], x.excited_bins[0].back()}) {
    Eigen::MatrixXcd U(3, 4);
    for (Index e = 0; e < 4; ++e)
      for (Index j = 0; j < 3; ++j) U(j, e) = plain_dft(x.samples.col(j).data() + e * block + L, L, k);
    const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXcd>(U).singularValues();
    // Equal amplitudes and orthogonal codes: U U^H = 4 |U_j|^2 I, all singular values
    // equal; 1e-9 for round-off.
    EXPECT_NEAR(sv(2) / sv(0), 1.0, 1e-9) << "bin " << k;
  }
}

TEST(Mimo, ZipperBinsAreDisjointAndCoverTheGrid) {
  ExcitationSpec s = small_multisine();
  s.channels = 3;
  s.mimo = MimoDesign::kZipper;
  s.rms = {1.0};
  const ExcitationSignal x = generate_excitation(s);
  EXPECT_EQ(x.experiments, 1);
  const std::vector<Index> grid = multisine_grid(s);
  std::multiset<Index> all;
  for (const auto& bins : x.excited_bins) all.insert(bins.begin(), bins.end());
  EXPECT_EQ(all.size(), grid.size());                                  // disjoint: no bin twice
  EXPECT_EQ(std::set<Index>(all.begin(), all.end()), std::set<Index>(grid.begin(), grid.end()));  // covering
  for (Index j = 0; j < 3; ++j) expect_designed_spectrum(x.samples, j, 0, 250, x.excited_bins[static_cast<std::size_t>(j)], 1.0);
}

TEST(Prbs, MaximumLengthSequencesHavePeriodTwoToTheMMinusOneAndTwoValuedAutocorrelation) {
  for (int m = 2; m <= 20; ++m) {
    const std::vector<signed char> s = mls_sequence(m);
    const Index M = (Index{1} << m) - 1;
    ASSERT_EQ(static_cast<Index>(s.size()), M);
    // Balance: one more +1 than -1 (2^(m-1) ones in a period).
    Index sum = 0;
    for (signed char v : s) sum += v;
    EXPECT_EQ(sum, 1) << m;
    // Periodic autocorrelation M at lag 0 and -1 at every other lag: checked at
    // every lag for m <= 10, at 16 lags above (the sum is O(M) per lag; cheap under ASan).
    const Index step = m <= 10 ? 1 : std::max<Index>(1, M / 16);
    for (Index lag = 1; lag < M; lag += step) {
      Index r = 0;
      for (Index t = 0; t < M; ++t) r += s[static_cast<std::size_t>(t)] * s[static_cast<std::size_t>((t + lag) % M)];
      ASSERT_EQ(r, -1) << "m " << m << " lag " << lag;
    }
  }
}

TEST(Prbs, PeriodicPrbsRepeatsWithTheDividerAndMeetsTheLimits) {
  ExcitationSpec s;
  s.kind = ExcitationKind::kPrbs;
  s.period_samples = 2 * 127;
  s.clock_divider = 2;
  s.periods = 3;
  s.rms = {0.25};
  const ExcitationSignal x = generate_excitation(s);
  EXPECT_EQ(x.prbs_order, 7);
  const Index L = 254;
  ASSERT_EQ(x.samples.rows(), 3 * L);  // T = 0 (the default), P = 3
  for (Index p = 1; p < 3; ++p) EXPECT_TRUE(x.samples.col(0).segment(p * L, L) == x.samples.col(0).segment(0, L));
  EXPECT_TRUE((x.samples.array().abs() == 0.25).all());
  for (Index t = 0; t < L; t += 2) EXPECT_EQ(x.samples(t, 0), x.samples(t + 1, 0));
  // The held sequence's spectrum is zero at the multiples of 127 (bin 127 only here)
  // and non-zero at the listed bins.
  EXPECT_LT(std::abs(plain_dft(x.samples.col(0).data(), L, 127)), 1e-9);
  const std::vector<Index>& bins = x.excited_bins[0];
  EXPECT_EQ(std::count(bins.begin(), bins.end(), 127), 0);
  // Closed form on the listed bins: |S| = sqrt(M + 1) (two-valued autocorrelation)
  // times the hold's |sin(pi k / M) / sin(pi k / L)|; 1e-9 for the O(L^2) sum's round-off.
  for (Index k : bins) {
    const double expected = 0.25 * std::sqrt(128.0) * std::abs(std::sin(kPi * k / 127.0) / std::sin(kPi * k / 254.0));
    EXPECT_NEAR(std::abs(plain_dft(x.samples.col(0).data(), L, k)), expected, 1e-9 * expected) << k;
  }
}

TEST(Prbs, PeriodNotOfTheFormDTimesTwoToTheMMinusOneIsRefusedWithTheNearestOnes) {
  ExcitationSpec s;
  s.kind = ExcitationKind::kPrbs;
  s.period_samples = 1000;
  s.rms = {1};
  try {
    s.validate();
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("511 (m = 9) or 1023 (m = 10)"));
  }
}

TEST(Noise, RmsIsExactAndSameSeedSameSamples) {
  ExcitationSpec s;
  s.kind = ExcitationKind::kNoise;
  s.samples = 5000;
  s.channels = 2;
  s.rms = {0.3, 2.0};
  const ExcitationSignal x = generate_excitation(s);
  ASSERT_EQ(x.samples.rows(), 5000);
  for (Index j = 0; j < 2; ++j)
    EXPECT_NEAR(std::sqrt(x.samples.col(j).squaredNorm() / 5000), s.rms[static_cast<std::size_t>(j)], 1e-12);
  // Independent inputs: sample correlation ~ N^-1/2 = 0.014; 0.06 is > 4 sigma.
  const double corr = x.samples.col(0).dot(x.samples.col(1)) / (x.samples.col(0).norm() * x.samples.col(1).norm());
  EXPECT_LT(std::abs(corr), 0.06);
  EXPECT_TRUE(generate_excitation(s).samples == x.samples);
}

TEST(ExcitationSpec, DesignsThatCannotWorkAreRefusedSayingWhatToDo) {
  auto expect_error = [](ExcitationSpec s, const std::string& text) {
    try {
      s.validate();
      ADD_FAILURE() << "no error for " << text;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  };
  ExcitationSpec s = small_multisine();
  s.band_hi_hz = 500;  // = fs / 2
  expect_error(s, "0 < low <= high < fs/2 = 500 Hz");
  s = small_multisine();
  s.band_lo_hz = 1, s.band_hi_hz = 3;  // resolution 4 Hz
  expect_error(s, "holds no DFT line");
  s = small_multisine();
  s.period_samples = 2;
  expect_error(s, "at least 3 samples");
  s = small_multisine();
  s.channels = 2;
  s.phase = PhaseChoice::kSchroeder;
  expect_error(s, "same signal");
  s = small_multisine();
  s.rms.clear();
  expect_error(s, "no amplitude");
  s = small_multisine();
  s.channels = 3, s.rms = {1, 2};
  expect_error(s, "2 values for 3 inputs");
  s = small_multisine();
  s.channels = 200, s.mimo = MimoDesign::kZipper;
  expect_error(s, "at least one line per input");
  ExcitationSpec n;
  n.kind = ExcitationKind::kNoise;
  n.samples = 100;
  n.rms = {1};
  n.channels = 2;
  n.mimo = MimoDesign::kHadamard;
  expect_error(n, "needs a periodic signal");
}

TEST(Schroeder, PhasesFollowTheFormula) {
  const std::vector<double> p = schroeder_phases(5);
  for (Index i = 1; i <= 5; ++i) {
    const double expected = -kPi * static_cast<double>(i * (i - 1)) / 5.0;
    // Compared modulo 2 pi (the code reduces i (i - 1) mod 2K first).
    EXPECT_NEAR(std::remainder(p[static_cast<std::size_t>(i - 1)] - expected, 2 * kPi), 0.0, 1e-12);
  }
}

}  // namespace excitation_test
}  // namespace lpvid
