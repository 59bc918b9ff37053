// lpvid — the inverse of a small matrix by Gauss–Jordan elimination without
// pivoting, templated on the scalar (double, or ceres::Jet in idlib/fit for exact
// derivatives, where pivoting would make the derivatives jump): for matrices whose
// diagonal stays a safe pivot — symmetric positive definite ones (the bases' mass
// matrices) and ones near a positive diagonal (the stage's true-over-designed
// allocation A(r − c) A(r)⁺, within a few per cent of κα I).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "idlib/core/types.h"

namespace lpvid::physical_detail {

// inv = M⁻¹; false when a pivot is not above min_pivot (positive pivots only) or,
// with positive_only = false, when its size is not above min_pivot.  `value` gives
// the double value of a scalar.
template <class T>
bool gauss_jordan_inverse(const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& M,
                          Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>& inv, double (*value)(const T&),
                          bool positive_only, double min_pivot) {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  const Index n = M.rows();
  Mat a = M;
  inv = Mat::Identity(n, n);
  for (Index k = 0; k < n; ++k) {
    const T piv = a(k, k);
    const double v = value(piv);
    if (!(positive_only ? v > min_pivot : std::abs(v) > min_pivot)) return false;
    for (Index j = 0; j < n; ++j) {
      a(k, j) /= piv;
      inv(k, j) /= piv;
    }
    for (Index i = 0; i < n; ++i) {
      if (i == k) continue;
      const T f = a(i, k);
      for (Index j = 0; j < n; ++j) {
        a(i, j) -= f * a(k, j);
        inv(i, j) -= f * inv(k, j);
      }
    }
  }
  return true;
}

}  // namespace lpvid::physical_detail
