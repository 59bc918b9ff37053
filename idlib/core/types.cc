#include "idlib/core/types.h"

#include <fmt/format.h>

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

}  // namespace lpvid
