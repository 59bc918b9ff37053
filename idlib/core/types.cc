#include "idlib/core/types.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {

void StateSpace::validate() const {
  const Index n = A.rows();
  if (A.cols() != n) throw InputError(fmt::format("state-space model: A is {}x{}, must be square", A.rows(), A.cols()));
  const Index m = D.cols();
  const Index p = D.rows();
  if (B.rows() != n || B.cols() != m)
    throw InputError(fmt::format("state-space model: B is {}x{}, must be {}x{} (states x inputs)", B.rows(), B.cols(), n, m));
  if (C.rows() != p || C.cols() != n)
    throw InputError(fmt::format("state-space model: C is {}x{}, must be {}x{} (outputs x states)", C.rows(), C.cols(), p, n));
  if (!A.allFinite() || !B.allFinite() || !C.allFinite() || !D.allFinite())
    throw InputError("state-space model: a matrix holds NaN or Inf; every entry must be finite");
  if (!(sample_period_s >= 0.0) || !std::isfinite(sample_period_s))
    throw InputError(fmt::format("state-space model: ts = {} s; it must be 0 (continuous) or a positive sample period", sample_period_s));
  if (!input_names.empty() && static_cast<Index>(input_names.size()) != m)
    throw InputError(fmt::format("state-space model: {} input names for {} inputs", input_names.size(), m));
  if (!output_names.empty() && static_cast<Index>(output_names.size()) != p)
    throw InputError(fmt::format("state-space model: {} output names for {} outputs", output_names.size(), p));
}

std::vector<Eigen::MatrixXd> response_scales(const std::vector<Eigen::MatrixXcd>& h, double floor) {
  std::vector<Eigen::MatrixXd> out;
  out.reserve(h.size());
  double largest = 0.0;
  for (const Eigen::MatrixXcd& r : h) {
    Eigen::MatrixXd s(r.rows(), r.cols());
    const bool square = r.rows() == r.cols();
    for (Index i = 0; i < r.rows(); ++i) {
      const double row_max = r.row(i).cwiseAbs().maxCoeff();
      for (Index j = 0; j < r.cols(); ++j) {
        const double diagonal = square ? std::sqrt(std::abs(r(i, i)) * std::abs(r(j, j))) : row_max;
        if (std::isfinite(diagonal)) largest = std::max(largest, diagonal);
        s(i, j) = square ? std::max(diagonal, std::abs(r(i, j))) : row_max;
      }
    }
    out.push_back(std::move(s));
  }
  for (Eigen::MatrixXd& s : out) s = s.cwiseMax(floor * largest);
  return out;
}

}  // namespace lpvid
