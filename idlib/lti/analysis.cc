#include "idlib/lti/analysis.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {

Eigen::VectorXcd poles(const StateSpace& sys) {
  sys.validate();
  if (sys.order() == 0) return Eigen::VectorXcd(0);
  Eigen::EigenSolver<Eigen::MatrixXd> es(sys.A, /*computeEigenvectors=*/false);
  if (es.info() != Eigen::Success)
    throw NumericalError(fmt::format("poles: the eigenvalue iteration did not converge for a {}x{} A", sys.order(), sys.order()));
  return es.eigenvalues();
}

bool is_stable(const StateSpace& sys, double margin) {
  if (!std::isfinite(margin) || margin < 0.0)
    throw InputError(fmt::format("stability test: margin = {}; it must be finite and >= 0", margin));
  const Eigen::VectorXcd p = poles(sys);
  for (Index i = 0; i < p.size(); ++i) {
    if (sys.is_discrete()) {
      if (!(std::abs(p[i]) < 1.0 - margin)) return false;
    } else {
      if (!(p[i].real() / std::max(1.0, std::abs(p[i])) < -margin)) return false;
    }
  }
  return true;
}

MarkovSequence markov_parameters(const StateSpace& discrete, Index last_lag) {
  discrete.validate();
  if (!discrete.is_discrete())
    throw InputError("Markov parameters: the model is continuous (ts = 0); discretise it first (discretize_zoh)");
  if (last_lag < 0) throw InputError(fmt::format("Markov parameters: last lag = {}; it must be >= 0", last_lag));
  MarkovSequence g;
  g.reserve(static_cast<size_t>(last_lag + 1));
  g.push_back(discrete.D);
  Eigen::MatrixXd AkB = discrete.B;  // A^{k−1} B
  for (Index k = 1; k <= last_lag; ++k) {
    g.push_back(discrete.C * AkB);
    if (k < last_lag) AkB = discrete.A * AkB;
  }
  return g;
}

Eigen::MatrixXd simulate_discrete(const StateSpace& discrete, const Eigen::Ref<const Eigen::MatrixXd>& u) {
  discrete.validate();
  if (!discrete.is_discrete()) throw InputError("simulate_discrete needs a discrete model (ts > 0)");
  if (u.cols() != discrete.num_inputs())
    throw InputError(fmt::format("the input has {} columns but the model has {} inputs", u.cols(),
                                 discrete.num_inputs()));
  const Index N = u.rows();
  // Time along columns inside (contiguous per step), transposed once at the end.
  const Eigen::MatrixXd ut = u.transpose();
  Eigen::MatrixXd yt(discrete.num_outputs(), N);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(discrete.order()), next(discrete.order());
  for (Index k = 0; k < N; ++k) {
    yt.col(k).noalias() = discrete.D * ut.col(k);
    if (discrete.order() == 0) continue;
    yt.col(k).noalias() += discrete.C * x;
    next.noalias() = discrete.A * x;
    next.noalias() += discrete.B * ut.col(k);
    x.swap(next);
  }
  return yt.transpose();
}

}  // namespace lpvid

