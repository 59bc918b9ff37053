#include "idlib/realization/hankel.h"
#include "idlib/core/eigen_decompositions.h"

#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <random>

#include "idlib/core/error.h"

namespace lpvid {
namespace hankel_test {

constexpr std::uint64_t kRandomMatrixSeed = 500400;
// leading_svd promises ~1e-10 relative to s_1; rounding of a 500x400 product is ~1e-14.
constexpr double kSvdAgreement = 1e-9;

MarkovSequence numbered_sequence(Index lags, Index p, Index m) {
  MarkovSequence g(static_cast<std::size_t>(lags));
  for (Index k = 0; k < lags; ++k) {
    g[static_cast<std::size_t>(k)].resize(p, m);
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) g[static_cast<std::size_t>(k)](i, j) = 100.0 * k + 10.0 * i + j;
  }
  return g;
}

TEST(BlockHankel, BlockIJHoldsLagFirstPlusIPlusJTimesStride) {
  const MarkovSequence g = numbered_sequence(40, 2, 3);
  const Eigen::MatrixXd H = block_hankel(g, 4, 5, 3, 2);
  ASSERT_EQ(H.rows(), 8);
  ASSERT_EQ(H.cols(), 15);
  for (Index i = 0; i < 4; ++i)
    for (Index j = 0; j < 5; ++j) EXPECT_EQ(H.block(i * 2, j * 3, 2, 3), g[static_cast<std::size_t>(3 + (i + j) * 2)]);
}

TEST(BlockHankel, TooShortSequenceSaysHowManyLagsAreNeeded) {
  const MarkovSequence g = numbered_sequence(10, 1, 1);
  try {
    block_hankel(g, 4, 4, 1, 2);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(),
                 "block_hankel: g has 10 lags (0..9) but 4x4 blocks from lag 1 with stride 2 need lags up to 13 (14 "
                 "lags); pass a longer sequence or fewer blocks or a smaller stride");
  }
}

TEST(BlockHankel, MixedShapesAndBadCountsAreRejected) {
  MarkovSequence g = numbered_sequence(10, 2, 2);
  g[3] = Eigen::MatrixXd::Zero(2, 3);
  EXPECT_THROW(block_hankel(g, 2, 2), InputError);
  EXPECT_THROW(block_hankel(numbered_sequence(10, 1, 1), 0, 2), InputError);
  EXPECT_THROW(block_hankel(numbered_sequence(10, 1, 1), 2, 2, 1, 0), InputError);
  EXPECT_THROW(block_hankel(MarkovSequence{}, 2, 2), InputError);
}

TEST(LeadingSvd, LanczosAgreesWithFullSvdOnRandom500x400) {
  std::mt19937_64 rng(kRandomMatrixSeed);
  std::normal_distribution<double> normal(0.0, 1.0);
  // Decaying spectrum so that the leading subspaces are well separated.
  Eigen::MatrixXd M(500, 400);
  for (Index j = 0; j < 400; ++j)
    for (Index i = 0; i < 500; ++i) M(i, j) = normal(rng) * std::pow(0.98, static_cast<double>(j));
  const Index k = 20;
  const PartialSvd part = leading_svd(M, k);
  Eigen::BDCSVD<Eigen::MatrixXd> full(M, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const double s1 = full.singularValues()(0);
  EXPECT_LT((part.singular_values - full.singularValues().head(k)).cwiseAbs().maxCoeff() / s1, kSvdAgreement);
  // Subspaces: sin of the largest principal angle, via the projection residual.
  const Eigen::MatrixXd Uf = full.matrixU().leftCols(k);
  const Eigen::MatrixXd Vf = full.matrixV().leftCols(k);
  EXPECT_LT((part.U - Uf * (Uf.transpose() * part.U)).norm(), 1e-6);
  EXPECT_LT((part.V - Vf * (Vf.transpose() * part.V)).norm(), 1e-6);
  EXPECT_LT((part.U.transpose() * part.U - Eigen::MatrixXd::Identity(k, k)).norm(), kSvdAgreement);
  EXPECT_LT((M * part.V - part.U * part.singular_values.asDiagonal()).norm() / s1, kSvdAgreement);
}

TEST(LeadingSvd, ExactlyRankDeficientLargeMatrixStillGivesItsTriplets) {
  std::mt19937_64 rng(kRandomMatrixSeed + 1);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd L(600, 5), R(5, 450);
  for (Index i = 0; i < L.size(); ++i) L.data()[i] = normal(rng);
  for (Index i = 0; i < R.size(); ++i) R.data()[i] = normal(rng);
  const Eigen::MatrixXd M = L * R;  // rank 5, asked for 12
  const PartialSvd part = leading_svd(M, 12);
  Eigen::BDCSVD<Eigen::MatrixXd> full(M);
  const double s1 = full.singularValues()(0);
  EXPECT_LT((part.singular_values - full.singularValues().head(12)).cwiseAbs().maxCoeff() / s1, kSvdAgreement);
  EXPECT_LT((M * part.V.leftCols(5) - part.U.leftCols(5) * part.singular_values.head(5).asDiagonal()).norm() / s1,
            kSvdAgreement);
}

TEST(LeadingSvd, KOutOfRangeIsRejected) {
  try {
    leading_svd(Eigen::MatrixXd::Ones(3, 4), 4);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "leading_svd: k = 4 singular triplets asked of a 3x4 matrix; k must be in 1..3");
  }
}

}  // namespace hankel_test
}  // namespace lpvid
