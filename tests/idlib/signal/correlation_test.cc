#include "idlib/signal/correlation.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "idlib/core/error.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {
namespace correlation_test {

using ::testing::HasSubstr;

constexpr std::uint64_t kCorrelationSeed = 20240611;
// FFT round-off: ~1e-16 * log2(block) per product, relative to sum_t |x||y| ~ N;
// the direct sum has O(sqrt(N)) magnitude, so compare against N * max|x||y|.
constexpr double kFftVsDirectRelTol = 1e-12;

Eigen::MatrixXd random_signal(Index n, Index channels, std::mt19937_64& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd x(n, channels);
  for (Index c = 0; c < channels; ++c)
    for (Index t = 0; t < n; ++t) x(t, c) = d(rng);
  return x;
}

// The O(N L) definition: R[tau](i, j) = sum_{t=0}^{N-1-tau} x(t + tau, i) y(t, j).
std::vector<Eigen::MatrixXd> direct(const Eigen::MatrixXd& x, const Eigen::MatrixXd& y, Index L) {
  const Index n = x.rows();
  std::vector<Eigen::MatrixXd> r(static_cast<size_t>(L + 1), Eigen::MatrixXd::Zero(x.cols(), y.cols()));
  for (Index tau = 0; tau <= L; ++tau)
    for (Index i = 0; i < x.cols(); ++i)
      for (Index j = 0; j < y.cols(); ++j)
        r[tau](i, j) = x.col(i).segment(tau, n - tau).dot(y.col(j).head(n - tau));
  return r;
}

double worst_error(const std::vector<Eigen::MatrixXd>& a, const std::vector<Eigen::MatrixXd>& b) {
  double w = 0.0;
  for (size_t k = 0; k < a.size(); ++k) w = std::max(w, (a[k] - b[k]).cwiseAbs().maxCoeff());
  return w;
}

void expect_matches_direct(Index n, Index nx, Index ny, Index L, std::mt19937_64& rng) {
  const Eigen::MatrixXd x = random_signal(n, nx, rng);
  const Eigen::MatrixXd y = random_signal(n, ny, rng);
  const auto fast = cross_correlation(x, y, L);
  const auto ref = direct(x, y, L);
  ASSERT_EQ(fast.size(), static_cast<size_t>(L + 1));
  ASSERT_EQ(fast[0].rows(), nx);
  ASSERT_EQ(fast[0].cols(), ny);
  const double scale = static_cast<double>(n) * x.cwiseAbs().maxCoeff() * y.cwiseAbs().maxCoeff();
  EXPECT_LE(worst_error(fast, ref), kFftVsDirectRelTol * scale) << "n=" << n << " L=" << L;
}

TEST(CrossCorrelation, EqualsDirectSumForDifferentChannelCounts) {
  std::mt19937_64 rng(kCorrelationSeed);
  expect_matches_direct(3000, 2, 3, 40, rng);
  expect_matches_direct(3000, 3, 1, 40, rng);
}

TEST(CrossCorrelation, EqualsDirectSumAcrossManyBlocks) {
  // Block FFT size is 16384 here, so 70000 samples span five blocks with a partial last one.
  std::mt19937_64 rng(kCorrelationSeed + 1);
  expect_matches_direct(70000, 2, 2, 25, rng);
}

TEST(CrossCorrelation, EqualsDirectSumWithLagsNearTheBlockSize) {
  // max_lag + 1 = 4096 and 4097 straddle the point where the FFT block grows from
  // 16384 to 32768 (4 (max_lag + 1) rounded up to a power of two).  With 16384
  // points and max_lag = 4095 a block holds 12289 samples of y: 36868 = 3 * 12289 + 1
  // leaves a one-sample last block, 36867 ends exactly on a block boundary.
  std::mt19937_64 rng(kCorrelationSeed + 2);
  expect_matches_direct(36868, 1, 2, 4095, rng);
  expect_matches_direct(36867, 2, 1, 4095, rng);
  expect_matches_direct(40000, 2, 1, 4096, rng);
}

TEST(CrossCorrelation, EqualsDirectSumForShortRecordsAndLagsUpToN) {
  std::mt19937_64 rng(kCorrelationSeed + 3);
  expect_matches_direct(1, 1, 1, 0, rng);
  expect_matches_direct(17, 2, 2, 16, rng);
  expect_matches_direct(100, 3, 3, 99, rng);
}

TEST(CrossCorrelation, AcceptsABlockOfALargerMatrix) {
  std::mt19937_64 rng(kCorrelationSeed + 4);
  const Eigen::MatrixXd big = random_signal(500, 5, rng);
  const auto fast = cross_correlation(big.middleCols(1, 2), big.rightCols(1), 30);
  const auto ref = direct(big.middleCols(1, 2), big.rightCols(1), 30);
  EXPECT_LE(worst_error(fast, ref), kFftVsDirectRelTol * 500 * big.cwiseAbs().maxCoeff() * big.cwiseAbs().maxCoeff());
}

TEST(Autocorrelation, IsCrossCorrelationWithItselfAndSymmetricAtLagZero) {
  std::mt19937_64 rng(kCorrelationSeed + 5);
  const Eigen::MatrixXd x = random_signal(2000, 3, rng);
  const auto r = autocorrelation(x, 10);
  const auto ref = direct(x, x, 10);
  EXPECT_LE(worst_error(r, ref), kFftVsDirectRelTol * 2000 * x.cwiseAbs().maxCoeff() * x.cwiseAbs().maxCoeff());
  EXPECT_EQ((r[0] - r[0].transpose()).cwiseAbs().maxCoeff(), 0.0);
}

// The blocks' and the Markov operator's transform sizes: the smallest 2^a 3^b >= n,
// checked against a direct search.
TEST(NextFftSize, IsTheSmallestTwoThreeSmoothSizeAtLeastN) {
  auto smooth = [](Index k) {
    while (k % 2 == 0) k /= 2;
    while (k % 3 == 0) k /= 3;
    return k == 1;
  };
  for (Index n = 1; n <= 5000; ++n) {
    Index want = n;
    while (!smooth(want)) ++want;
    ASSERT_EQ(signal_detail::next_fft_size(n), want) << "n = " << n;
  }
  EXPECT_EQ(signal_detail::next_fft_size(2 * 32768 + 2), 69984);  // 2^5 3^7
}

TEST(CrossCorrelation, RejectsDifferentSampleCounts) {
  const Eigen::MatrixXd x = Eigen::MatrixXd::Ones(10, 1), y = Eigen::MatrixXd::Ones(11, 1);
  try {
    cross_correlation(x, y, 2);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("x has 10 samples and y has 11"));
  }
}

TEST(CrossCorrelation, RejectsNegativeLagAndLagNotBelowN) {
  const Eigen::MatrixXd x = Eigen::MatrixXd::Ones(10, 1);
  try {
    cross_correlation(x, x, -1);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("max_lag = -1; it must be >= 0"));
  }
  try {
    cross_correlation(x, x, 10);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("max_lag must be smaller than the number of samples"));
  }
}

TEST(CrossCorrelation, RejectsNonFiniteSamplesNamingTheFirst) {
  Eigen::MatrixXd x = Eigen::MatrixXd::Ones(10, 2);
  x(7, 1) = std::numeric_limits<double>::quiet_NaN();
  try {
    cross_correlation(Eigen::MatrixXd::Ones(10, 1), x, 2);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("y(7, 1) = nan; every sample must be finite"));
  }
}

}  // namespace correlation_test
}  // namespace lpvid
