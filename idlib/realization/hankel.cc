#include "idlib/realization/hankel.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <Spectra/SymEigsSolver.h>
#include <algorithm>

#include "idlib/core/error.h"

namespace lpvid {

namespace {

// Below this size on the smaller side a full BDCSVD costs less than ~30 ms and
// is simpler and exact; above it Lanczos on the Gram matrix wins (BUILD-NOTES:
// top-30 of 1500^2 in 0.12 s against 1-3 s for the full SVD).
constexpr Index kDenseSvdMaxDim = 300;
// Lanczos is no bargain when more than a third of the spectrum is wanted.
constexpr Index kDenseFraction = 3;
// Spectra's own default; the Rayleigh-Ritz step afterwards restores the
// precision of the values, so this only sets the accuracy of the subspace.
constexpr double kLanczosTolerance = 1e-10;
constexpr Index kLanczosMaxRestarts = 1000;
// Shift added to the Gram matrix in the second run, relative to its largest
// eigenvalue.  Spectra's stopping test is resid < tol * max(|lambda|, eps^(2/3)):
// for an exactly zero eigenvalue (rank-deficient, noise-free H) that asks for a
// residual below rounding and never converges.  With the shift the floor is
// 1e-10 * 1e-5 = 1e-15 of the largest eigenvalue, at the rounding level of the
// products; eigenvectors are unchanged by a shift.
constexpr double kGramShift = 1e-5;

// y = G x + shift x with G = H^T H (tall or square H) or H H^T (wide H): the Gram
// matrix of the smaller side.
class GramOp {
 public:
  using Scalar = double;
  GramOp(const Eigen::MatrixXd& H, double shift)
      : H_(H), tall_(H.rows() >= H.cols()), shift_(shift), cache_(tall_ ? H.rows() : H.cols()) {}
  Index rows() const { return tall_ ? H_.cols() : H_.rows(); }
  Index cols() const { return rows(); }
  void perform_op(const double* x_in, double* y_out) const {
    Eigen::Map<const Eigen::VectorXd> x(x_in, rows());
    Eigen::Map<Eigen::VectorXd> y(y_out, rows());
    if (tall_) {
      cache_.noalias() = H_ * x;
      y.noalias() = H_.transpose() * cache_;
    } else {
      cache_.noalias() = H_.transpose() * x;
      y.noalias() = H_ * cache_;
    }
    if (shift_ != 0.0) y += shift_ * x;
  }

 private:
  const Eigen::MatrixXd& H_;
  bool tall_;
  double shift_;
  mutable Eigen::VectorXd cache_;
};

PartialSvd dense_leading_svd(const Eigen::MatrixXd& H, Index k) {
  Eigen::BDCSVD<Eigen::MatrixXd> svd(H, Eigen::ComputeThinU | Eigen::ComputeThinV);
  PartialSvd out;
  out.singular_values = svd.singularValues().head(k);
  out.U = svd.matrixU().leftCols(k);
  out.V = svd.matrixV().leftCols(k);
  return out;
}

// Runs Lanczos; returns true with the k leading eigenvectors of the Gram matrix in
// `vectors` when all k converged.  `largest` receives the largest converged
// eigenvalue (0 when none).
bool lanczos(const Eigen::MatrixXd& H, Index k, double shift, Eigen::MatrixXd& vectors, double& largest) {
  GramOp op(H, shift);
  const Index dim = op.rows();
  // Spectra requires nev < ncv <= dim; 2k + 1 (ARPACK's advice) with room for
  // clusters of noise singular values.
  const Index ncv = std::min(dim, std::max<Index>(2 * k + 1, k + 20));
  Spectra::SymEigsSolver<GramOp> eigs(op, k, ncv);
  eigs.init();
  eigs.compute(Spectra::SortRule::LargestAlge, kLanczosMaxRestarts, kLanczosTolerance);
  const Eigen::VectorXd values = eigs.eigenvalues();
  largest = values.size() > 0 ? values.maxCoeff() - shift : 0.0;
  if (eigs.info() != Spectra::CompInfo::Successful || values.size() < k) return false;
  vectors = eigs.eigenvectors(k);
  return true;
}

}  // namespace

Eigen::MatrixXd block_hankel(const MarkovSequence& g, Index block_rows, Index block_cols, Index first, Index stride) {
  if (g.empty()) throw InputError("block_hankel: the Markov sequence is empty; pass at least one lag");
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  for (std::size_t k = 0; k < g.size(); ++k)
    if (g[k].rows() != p || g[k].cols() != m)
      throw InputError(fmt::format("block_hankel: g[{}] is {}x{} but g[0] is {}x{}; every lag must have one shape",
                                   k, g[k].rows(), g[k].cols(), p, m));
  if (block_rows < 1 || block_cols < 1)
    throw InputError(fmt::format("block_hankel: block_rows = {}, block_cols = {}; both must be at least 1",
                                 block_rows, block_cols));
  if (stride < 1) throw InputError(fmt::format("block_hankel: stride = {}; it must be at least 1", stride));
  if (first < 0) throw InputError(fmt::format("block_hankel: first = {}; it must be at least 0", first));
  const Index last_lag = first + (block_rows + block_cols - 2) * stride;
  const Index have = static_cast<Index>(g.size());
  if (last_lag >= have)
    throw InputError(fmt::format(
        "block_hankel: g has {} lags (0..{}) but {}x{} blocks from lag {} with stride {} need lags up to {} "
        "({} lags); pass a longer sequence or fewer blocks or a smaller stride",
        have, have - 1, block_rows, block_cols, first, stride, last_lag, last_lag + 1));
  Eigen::MatrixXd H(block_rows * p, block_cols * m);
  for (Index j = 0; j < block_cols; ++j)
    for (Index i = 0; i < block_rows; ++i)
      H.block(i * p, j * m, p, m) = g[static_cast<std::size_t>(first + (i + j) * stride)];
  return H;
}

PartialSvd leading_svd(const Eigen::MatrixXd& H, Index k) {
  const Index small = std::min(H.rows(), H.cols());
  if (small == 0) throw InputError("leading_svd: the matrix is empty; pass a matrix with at least one row and column");
  if (k < 1 || k > small)
    throw InputError(fmt::format("leading_svd: k = {} singular triplets asked of a {}x{} matrix; k must be in 1..{}", k,
                                 H.rows(), H.cols(), small));
  if (!H.allFinite()) throw InputError("leading_svd: the matrix holds NaN or Inf; every entry must be finite");
  if (small <= kDenseSvdMaxDim || k * kDenseFraction > small) return dense_leading_svd(H, k);

  Eigen::MatrixXd basis;
  double largest = 0.0;
  if (!lanczos(H, k, 0.0, basis, largest)) {
    if (!(largest > 0.0)) largest = H.squaredNorm();  // bounds the largest eigenvalue
    if (!(largest > 0.0)) {                           // H == 0: any orthonormal basis
      PartialSvd zero;
      zero.singular_values = Eigen::VectorXd::Zero(k);
      zero.U = Eigen::MatrixXd::Identity(H.rows(), k);
      zero.V = Eigen::MatrixXd::Identity(H.cols(), k);
      return zero;
    }
    if (!lanczos(H, k, kGramShift * largest, basis, largest)) return dense_leading_svd(H, k);
  }
  // Rayleigh-Ritz on the found subspace: H (basis) = W S Q^T, thin and exact.
  const bool tall = H.rows() >= H.cols();
  const Eigen::MatrixXd image = tall ? Eigen::MatrixXd(H * basis) : Eigen::MatrixXd(H.transpose() * basis);
  Eigen::BDCSVD<Eigen::MatrixXd> small_svd(image, Eigen::ComputeThinU | Eigen::ComputeThinV);
  PartialSvd out;
  out.singular_values = small_svd.singularValues();
  if (tall) {
    out.U = small_svd.matrixU();
    out.V = basis * small_svd.matrixV();
  } else {
    out.V = small_svd.matrixU();
    out.U = basis * small_svd.matrixV();
  }
  return out;
}

}  // namespace lpvid
