#include "idlib/validate/frequency_error.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Dense>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

double norm2(const Eigen::MatrixXcd& M) {
  if (M.size() == 0) return 0.0;
  return Eigen::JacobiSVD<Eigen::MatrixXcd>(M).singularValues()(0);
}

Eigen::VectorXd weight_or_ones(const Eigen::VectorXd& w, Index n, const char* side) {
  if (w.size() == 0) return Eigen::VectorXd::Ones(n);
  if (w.size() != n)
    throw InputError(fmt::format("weighted error: {} weight has {} entries for {} {}; give one per channel or none", side, w.size(), n,
                                 side[0] == 'l' ? "outputs" : "inputs"));
  if (!w.allFinite() || (w.array() < 0.0).any())
    throw InputError(fmt::format("weighted error: a {} weight is negative or non-finite; weights must be finite and >= 0", side));
  return w;
}

}  // namespace

double weighted_matrix_error(const Eigen::MatrixXcd& estimate, const Eigen::MatrixXcd& truth, const Eigen::VectorXd& left_weight,
                             const Eigen::VectorXd& right_weight) {
  if (estimate.rows() != truth.rows() || estimate.cols() != truth.cols())
    throw InputError(fmt::format("weighted error: estimate is {}x{} but truth is {}x{}; compare responses of the same shape",
                                 estimate.rows(), estimate.cols(), truth.rows(), truth.cols()));
  if (!estimate.allFinite() || !truth.allFinite())
    throw InputError("weighted error: a response entry is NaN or Inf; responses must be finite");
  const Eigen::VectorXd wl = weight_or_ones(left_weight, truth.rows(), "left");
  const Eigen::VectorXd wr = weight_or_ones(right_weight, truth.cols(), "right");
  const Eigen::MatrixXcd Wl = wl.cast<Complex>().asDiagonal();
  const Eigen::MatrixXcd Wr = wr.cast<Complex>().asDiagonal();
  const double den = norm2(Wl * truth * Wr);
  if (!(den > 0.0))
    throw InputError("weighted error: the weighted truth is zero, so the relative error is undefined; drop this frequency or change the weights");
  return norm2(Wl * (estimate - truth) * Wr) / den;
}

ErrorSummary weighted_error_over(const std::vector<Eigen::MatrixXcd>& estimate, const std::vector<Eigen::MatrixXcd>& truth,
                                 const Eigen::VectorXd& omega_rad_s, const Eigen::VectorXd& left_weight,
                                 const Eigen::VectorXd& right_weight) {
  const size_t F = static_cast<size_t>(omega_rad_s.size());
  if (estimate.size() != F || truth.size() != F)
    throw InputError(fmt::format("weighted error: {} estimate and {} truth matrices for {} frequencies; all three must be equal",
                                 estimate.size(), truth.size(), F));
  if (F == 0) throw InputError("weighted error: no frequencies; give at least one");
  ErrorSummary s;
  s.per_frequency.resize(omega_rad_s.size());
  for (size_t k = 0; k < F; ++k) {
    try {
      s.per_frequency[static_cast<Index>(k)] = weighted_matrix_error(estimate[k], truth[k], left_weight, right_weight);
    } catch (const InputError& e) {
      throw InputError(fmt::format("at ω = {} rad/s: {}", omega_rad_s[static_cast<Index>(k)], e.what()));
    }
  }
  Index imax = 0;
  s.max = s.per_frequency.maxCoeff(&imax);
  s.mean = s.per_frequency.mean();
  s.omega_at_max_rad_s = omega_rad_s[imax];
  return s;
}

}  // namespace lpvid
