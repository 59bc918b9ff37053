// Small helpers for the realization tests: synthetic systems with known poles,
// their exact Markov parameters and frequency responses.  Kept here (not in
// idlib/lti) so that these tests depend only on the module under test.
#pragma once

#include <Eigen/Core>
#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid::testing {

// A continuous pole for the modal construction: a real pole (imag == 0) or the
// pair s, conj(s) (imag > 0); `weight` scales that mode's input gain.
struct Mode {
  std::complex<double> s_rad_s;
  double weight = 1.0;
};

// Discrete system x[k+1] = A x + B u, y = C x + D u, p outputs, m inputs, whose
// poles are exp(s T) for the given modes; B and C Gaussian from `seed`, then a
// random orthogonal change of basis (so that nothing in A is diagonal by luck).
inline StateSpace modal_system(const std::vector<Mode>& modes, double sample_period_s, Eigen::Index p, Eigen::Index m,
                               std::uint64_t seed, bool with_feedthrough = true) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Index n = 0;
  for (const auto& mode : modes) n += mode.s_rad_s.imag() > 0 ? 2 : 1;
  StateSpace sys;
  sys.A = Eigen::MatrixXd::Zero(n, n);
  sys.B.resize(n, m);
  sys.C.resize(p, n);
  sys.D.resize(p, m);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < m; ++j) sys.B(i, j) = normal(rng);
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j < n; ++j) sys.C(i, j) = normal(rng);
  for (Eigen::Index i = 0; i < p; ++i)
    for (Eigen::Index j = 0; j < m; ++j) sys.D(i, j) = with_feedthrough ? normal(rng) : 0.0;
  Eigen::Index at = 0;
  for (const auto& mode : modes) {
    const std::complex<double> z = std::exp(mode.s_rad_s * sample_period_s);
    if (mode.s_rad_s.imag() > 0) {
      sys.A.block(at, at, 2, 2) << z.real(), z.imag(), -z.imag(), z.real();
      sys.B.middleRows(at, 2) *= mode.weight;
      at += 2;
    } else {
      sys.A(at, at) = z.real();
      sys.B.row(at) *= mode.weight;
      at += 1;
    }
  }
  Eigen::MatrixXd M(n, n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < n; ++j) M(i, j) = normal(rng);
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(M).householderQ();
  sys.A = Q * sys.A * Q.transpose();
  sys.B = Q * sys.B;
  sys.C = sys.C * Q.transpose();
  sys.sample_period_s = sample_period_s;
  return sys;
}

// g[0] = D, g[k] = C A^(k-1) B for k = 1..last_lag.
inline MarkovSequence markov_of(const StateSpace& sys, Eigen::Index last_lag) {
  MarkovSequence g(static_cast<std::size_t>(last_lag + 1));
  g[0] = sys.D;
  Eigen::MatrixXd AkB = sys.B;
  for (Eigen::Index k = 1; k <= last_lag; ++k) {
    g[static_cast<std::size_t>(k)] = sys.C * AkB;
    AkB = sys.A * AkB;
  }
  return g;
}

// G(e^{j w T}) = C (zI - A)^-1 B + D.
inline Eigen::MatrixXcd response_at(const StateSpace& sys, double omega_rad_s) {
  const Eigen::Index n = sys.order();
  const std::complex<double> z = std::exp(std::complex<double>(0.0, omega_rad_s * sys.sample_period_s));
  const Eigen::MatrixXcd zI_A = z * Eigen::MatrixXcd::Identity(n, n) - sys.A.cast<std::complex<double>>();
  return sys.C.cast<std::complex<double>>() * zI_A.partialPivLu().solve(sys.B.cast<std::complex<double>>()) +
         sys.D.cast<std::complex<double>>();
}

// Log-spaced frequencies from omega_lo to just below Nyquist.
inline std::vector<double> frequency_grid(double omega_lo_rad_s, double sample_period_s, int count = 200) {
  const double omega_hi = 0.95 * M_PI / sample_period_s;
  std::vector<double> w(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i)
    w[static_cast<std::size_t>(i)] = omega_lo_rad_s * std::pow(omega_hi / omega_lo_rad_s, i / (count - 1.0));
  return w;
}

// max_w |G(i,j) - G_ref(i,j)| / max_w |G_ref(i,j)| over the grid, for one entry
// (i, j) or (all < 0) the worst entry: the error relative to the entry's peak,
// which stays meaningful near notches.
inline double response_error(const StateSpace& model, const StateSpace& truth, const std::vector<double>& grid,
                             Eigen::Index only_output = -1) {
  const Eigen::Index p = truth.num_outputs();
  const Eigen::Index m = truth.num_inputs();
  Eigen::MatrixXd worst_err = Eigen::MatrixXd::Zero(p, m);
  Eigen::MatrixXd peak = Eigen::MatrixXd::Zero(p, m);
  for (double w : grid) {
    const Eigen::MatrixXcd G = response_at(model, w);
    const Eigen::MatrixXcd G0 = response_at(truth, w);
    worst_err = worst_err.cwiseMax((G - G0).cwiseAbs());
    peak = peak.cwiseMax(G0.cwiseAbs());
  }
  const Eigen::MatrixXd rel = worst_err.cwiseQuotient(peak);
  if (only_output >= 0) return rel.row(only_output).maxCoeff();
  return rel.maxCoeff();
}

// max_k ||g_model[k] - g[k]||_F / max_k ||g[k]||_F over k = 1..last_lag.
inline double markov_error(const StateSpace& model, const StateSpace& truth, Eigen::Index last_lag) {
  const MarkovSequence a = markov_of(model, last_lag);
  const MarkovSequence b = markov_of(truth, last_lag);
  double err = 0.0, peak = 0.0;
  for (std::size_t k = 1; k < a.size(); ++k) {
    err = std::max(err, (a[k] - b[k]).norm());
    peak = std::max(peak, b[k].norm());
  }
  return err / peak;
}

// Adds white Gaussian noise of std std_dev(i, j) to every g[k], k >= 0.
inline MarkovSequence add_noise(MarkovSequence g, const Eigen::MatrixXd& std_dev, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (auto& gk : g)
    for (Eigen::Index j = 0; j < gk.cols(); ++j)
      for (Eigen::Index i = 0; i < gk.rows(); ++i) gk(i, j) += std_dev(i, j) * normal(rng);
  return g;
}

// Peak |g[k](i, j)| over k >= 1, per entry.
inline Eigen::MatrixXd peak_entries(const MarkovSequence& g) {
  Eigen::MatrixXd peak = Eigen::MatrixXd::Zero(g.front().rows(), g.front().cols());
  for (std::size_t k = 1; k < g.size(); ++k) peak = peak.cwiseMax(g[k].cwiseAbs());
  return peak;
}

}  // namespace lpvid::testing
