// Test-only periodic excitation: a random-phase multisine with flat amplitude at
// chosen bins of an L-sample period (written here, independent of lpvid excite).
//   x(t) = Σ_{k in bins} A cos(2π k t / L + φ_k),  φ_k ~ U[0, 2π),  A = rms · sqrt(2 / K)
// so that the rms over a period is exactly `rms`.
#pragma once

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid::testing {

inline Eigen::VectorXd multisine(Index L, const std::vector<Index>& bins, double rms, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  const double A = rms * std::sqrt(2.0 / static_cast<double>(bins.size()));
  Eigen::VectorXd x = Eigen::VectorXd::Zero(L);
  for (Index k : bins) {
    const double phi = phase(rng);
    const double w = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(L);
    for (Index t = 0; t < L; ++t) x(t) += A * std::cos(w * static_cast<double>(t) + phi);
  }
  return x;
}

// bins first..last, every bin.
inline std::vector<Index> bin_range(Index first, Index last) {
  std::vector<Index> b;
  for (Index k = first; k <= last; ++k) b.push_back(k);
  return b;
}

// One period repeated `times` times.
inline Eigen::VectorXd repeat(const Eigen::VectorXd& period, Index times) {
  Eigen::VectorXd x(period.size() * times);
  for (Index p = 0; p < times; ++p) x.segment(p * period.size(), period.size()) = period;
  return x;
}

// The upper quantile of F(2, d2): P(F > x) = (1 + 2x/d2)^(−d2/2) for F = (χ²_2/2)/(χ²_d2/d2),
// so x = (d2/2)((1 − q)^(−2/d2) − 1) for the q-quantile.  |δ|²/σ̂² of a circular complex
// Gaussian error against a variance estimated with d2/2 complex degrees of freedom is
// F(2, d2)-distributed.
inline double f2_quantile(double q, double d2) { return 0.5 * d2 * (std::pow(1.0 - q, -2.0 / d2) - 1.0); }

}  // namespace lpvid::testing
