#include "idlib/lti/frequency_response.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

// Solves (λI − H) X = R in place (R becomes X) for upper Hessenberg H by
// Gaussian elimination with partial pivoting between adjacent rows.  Returns
// false when a pivot is exactly zero (λ is an eigenvalue of H).
bool solve_shifted_hessenberg(const Eigen::MatrixXd& H, Complex lambda, Eigen::MatrixXcd& M, Eigen::MatrixXcd& R) {
  const Index n = H.rows();
  M = (-H).cast<Complex>();
  M.diagonal().array() += lambda;
  for (Index k = 0; k + 1 < n; ++k) {
    if (std::abs(M(k + 1, k)) > std::abs(M(k, k))) {
      M.row(k).tail(n - k).swap(M.row(k + 1).tail(n - k));
      R.row(k).swap(R.row(k + 1));
    }
    if (M(k, k) == Complex(0.0)) return false;
    const Complex l = M(k + 1, k) / M(k, k);
    if (l != Complex(0.0)) {
      M.row(k + 1).tail(n - k - 1) -= l * M.row(k).tail(n - k - 1);
      R.row(k + 1) -= l * R.row(k);
    }
    M(k + 1, k) = 0.0;
  }
  if (n > 0 && M(n - 1, n - 1) == Complex(0.0)) return false;
  R = M.triangularView<Eigen::Upper>().solve(R);
  return true;
}

}  // namespace

std::vector<Eigen::MatrixXcd> evaluate_response(const StateSpace& sys, const Eigen::VectorXd& omega_rad_s) {
  sys.validate();
  if (!omega_rad_s.allFinite())
    throw InputError("frequency response: a frequency is NaN or Inf; every ω must be finite");
  const Index n = sys.order();
  std::vector<Eigen::MatrixXcd> out(static_cast<size_t>(omega_rad_s.size()));
  Eigen::MatrixXd H, Bt, Ct;
  if (n > 0) {
    Eigen::HessenbergDecomposition<Eigen::MatrixXd> hess(sys.A);
    const Eigen::MatrixXd Q = hess.matrixQ();
    H = hess.matrixH();
    Bt = Q.transpose() * sys.B;
    Ct = sys.C * Q;
  }
  const Eigen::MatrixXcd Bc = Bt.cast<Complex>();
  const Eigen::MatrixXcd Cc = Ct.cast<Complex>();
  const Eigen::MatrixXcd Dc = sys.D.cast<Complex>();
  Eigen::MatrixXcd M, X;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s[k];
    const Complex lambda = sys.is_discrete() ? std::polar(1.0, w * sys.sample_period_s) : Complex(0.0, w);
    if (n == 0) {
      out[static_cast<size_t>(k)] = Dc;
      continue;
    }
    X = Bc;
    if (!solve_shifted_hessenberg(H, lambda, M, X))
      throw InputError(fmt::format(
          "frequency response: ω = {} rad/s hits a pole of the model exactly (λ = {}{:+}j); leave this frequency out of the grid",
          w, lambda.real(), lambda.imag()));
    out[static_cast<size_t>(k)] = Cc * X + Dc;
  }
  return out;
}

FrequencyResponse frequency_response(const StateSpace& sys, const Eigen::VectorXd& omega_rad_s) {
  FrequencyResponse frd;
  frd.response = evaluate_response(sys, omega_rad_s);
  frd.omega_rad_s = omega_rad_s;
  frd.input_names = sys.input_names;
  frd.output_names = sys.output_names;
  return frd;
}

Eigen::VectorXd log_frequency_grid(double lo_rad_s, double hi_rad_s, Index count) {
  if (!std::isfinite(lo_rad_s) || !std::isfinite(hi_rad_s) || !(lo_rad_s > 0.0) || hi_rad_s < lo_rad_s)
    throw InputError(fmt::format("frequency grid: [{}, {}] rad/s; need 0 < lo <= hi, both finite", lo_rad_s, hi_rad_s));
  if (count < 1) throw InputError(fmt::format("frequency grid: count = {}; need at least 1 frequency", count));
  Eigen::VectorXd grid(count);
  if (count == 1) {
    grid[0] = lo_rad_s;
    return grid;
  }
  const double a = std::log10(lo_rad_s), b = std::log10(hi_rad_s);
  for (Index k = 0; k < count; ++k) grid[k] = std::pow(10.0, a + (b - a) * static_cast<double>(k) / static_cast<double>(count - 1));
  grid[count - 1] = hi_rad_s;
  return grid;
}

}  // namespace lpvid
