// lpvid — block Hankel matrices of Markov parameters and their leading
// singular triplets (the linear algebra under Ho-Kalman / ERA, era.h).
//
// Data layout: idlib/core/types.h (g[k] is outputs x inputs at lag k).
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid {

// Block Hankel matrix of a Markov sequence, optionally strided:
//
//   H(i, j) = g[first + (i + j) * stride],   i < block_rows, j < block_cols,
//
// (block (i, j) occupies rows i*p..i*p+p-1 and columns j*m..j*m+m-1).  For a
// system g[k] = C A^(k-1) B (k >= 1) this is H = O_d R_d with the strided
// observability O_d = [C; C A^d; C A^2d; ...] A^(first-1) and controllability
// R_d = [B, A^d B, A^2d B, ...]: the Hankel matrix spans
// (block_rows + block_cols - 1) * stride lags at a size that does not grow with
// the stride.
//
// | argument / result | shape |
// |-------------------|-------|
// | g[k]              | p x m, k = 0..L (all the same shape) |
// | result            | (block_rows * p) x (block_cols * m) |
//
// Preconditions: block_rows, block_cols, stride >= 1, first >= 0, g not empty and
// all g[k] of one shape (programming errors are reported as InputError too,
// since the numbers usually come from options).
//
// @throws InputError  g empty or of mixed shapes; a block count or stride < 1 or
//                     first < 0; g too short: it must hold lags up to
//                     first + (block_rows + block_cols - 2) * stride, and the
//                     message says how many lags that is.
Eigen::MatrixXd block_hankel(const MarkovSequence& g, Index block_rows, Index block_cols, Index first = 1,
                             Index stride = 1);

// The leading k singular triplets of H = U diag(singular_values) V^T.
//
// | member          | shape |
// |-----------------|-------|
// | singular_values | k, descending, >= 0 |
// | U               | rows(H) x k, orthonormal columns |
// | V               | cols(H) x k, orthonormal columns |
struct PartialSvd {
  Eigen::VectorXd singular_values;
  Eigen::MatrixXd U, V;
};

// Leading k singular triplets of H (1 <= k <= min(rows, cols)).
//
// Method: when min(rows, cols) <= kDenseSvdMaxDim (= 300), or k is more than a
// third of it, a full Eigen BDCSVD.  Otherwise Lanczos (Spectra::SymEigsSolver,
// tolerance 1e-10) on the Gram matrix of the smaller side (H^T H or H H^T),
// followed by a Rayleigh-Ritz step: the SVD of the thin product H V_k (or
// H^T U_k), which restores full relative precision of the singular values that
// squaring lost.  An exactly rank-deficient H (noise-free data) is handled by a
// second Lanczos run on a slightly shifted Gram matrix, and by a full SVD if
// Lanczos still does not converge.  Agreement with a full SVD: ~1e-10 relative
// to the largest singular value (values) and in subspace angle.
//
// @throws InputError  H empty or non-finite; k < 1 or k > min(rows, cols).
PartialSvd leading_svd(const Eigen::MatrixXd& H, Index k);

}  // namespace lpvid
