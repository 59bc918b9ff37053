// lpvid — sample cross-correlation of multichannel signals by blocked FFT.
//
// Signals follow the layout of idlib/core/types.h: N x channels, time along rows.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

// Raw (unnormalised) sample cross-correlation for lags 0..max_lag:
//
//   R[tau](i, j) = sum_{t : 0 <= t, t + tau < N} x(t + tau, i) * y(t, j),   tau = 0..max_lag
//
// i.e. R[tau] = sum_t x(t + tau) y(t)^T; with x = output q and y = excitation v this
// is R_qv(tau) = sum_t q(t) v(t - tau)^T.  No mean removal and no division by N.
//
// | argument / result | shape                                         |
// |-------------------|-----------------------------------------------|
// | x                 | N x nx                                        |
// | y                 | N x ny                                        |
// | result            | max_lag + 1 matrices, each nx x ny            |
//
// Units: product of the units of x and y (summed over samples).
// Algorithm: overlap-save in FFT blocks of max(16384, 4 (max_lag + 1)) points
// (rounded up to the next 2^a 3^b; one power-of-two block for short records), FFTW r2c/c2r with
// FFTW_ESTIMATE plans made once per call; the cross-spectra of all blocks are summed
// and inverted once per channel pair.  Cost O(N (nx + ny) log max_lag + nx ny N);
// memory O(block (nx ny)), no copy of the data.  Relative error ~1e-15 * log2(block)
// of sum_t |x||y|.  The blocks run as two tasks on the cores (idlib/core/parallel.h;
// the result does not depend on the schedule).  Thread-safe (FFTW planning is
// serialised by a mutex).
//
// @throws InputError if x and y have different numbers of rows, max_lag < 0,
//         max_lag >= N, or an entry is NaN/Inf.
std::vector<Eigen::MatrixXd> cross_correlation(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                               const Eigen::Ref<const Eigen::MatrixXd>& y,
                                               Index max_lag);

// autocorrelation(x, L) == cross_correlation(x, x, L): R[tau] = sum_t x(t + tau) x(t)^T,
// each nx x nx; R[0] is symmetric.  Same contract and errors as cross_correlation.
std::vector<Eigen::MatrixXd> autocorrelation(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                             Index max_lag);

}  // namespace lpvid
