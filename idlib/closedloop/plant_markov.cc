#include "idlib/closedloop/plant_markov.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>

#include "idlib/core/error.h"

namespace lpvid {

MarkovSequence plant_markov_from_closed_loop(const MarkovSequence& g, const StateSpace& controller, Index num_lags) {
  if (g.empty()) throw InputError("plant Markov parameters: the closed-loop sequence is empty");
  const Index p = g.front().rows(), m = g.front().cols();
  for (const auto& x : g)
    if (x.rows() != p || x.cols() != m)
      throw InputError("plant Markov parameters: every closed-loop lag must have one shape");
  controller.validate();
  if (!controller.is_discrete())
    throw InputError("plant Markov parameters: the controller must be discrete (the logs' controller)");
  if (controller.num_inputs() != p || controller.num_outputs() != m)
    throw InputError(fmt::format("plant Markov parameters: the controller is {}x{} but the loop needs {}x{}",
                                 controller.num_outputs(), controller.num_inputs(), m, p));
  if (num_lags < 1) throw InputError("plant Markov parameters: num_lags must be >= 1");
  const Index L = static_cast<Index>(g.size()) - 1;
  const Index K = num_lags + 1;          // lags 0..num_lags of the result
  const Index used = std::min(L, num_lags);  // ĝ[1..used] reach the result's lags
  // ĝ[1..used] side by side (p × m·used), and v[t] stacked in reverse time order
  // (m·K × m, v[t] at row block K − 1 − t), so that Σ_{i=1}^{k} ĝ[i] v[k − i] is one
  // product of ĝ's first k blocks with the contiguous rows of v[k − 1], ..., v[0].
  Eigen::MatrixXd gcat(p, m * std::max<Index>(used, 1));
  for (Index i = 1; i <= used; ++i) gcat.middleCols(m * (i - 1), m) = g[static_cast<std::size_t>(i)];
  Eigen::MatrixXd vrev = Eigen::MatrixXd::Zero(m * K, m);
  const Eigen::MatrixXd& g0 = g.front();
  const Eigen::FullPivLU<Eigen::MatrixXd> loop0(Eigen::MatrixXd::Identity(m, m) - controller.D * g0);
  if (!loop0.isInvertible())
    throw NumericalError("plant Markov parameters: I - D_K g[0] is singular (the controller's feedthrough and the "
                         "closed loop's lag-0 estimate form an algebraic loop with no solution)");
  const Index nk = controller.order();
  Eigen::MatrixXd xk = Eigen::MatrixXd::Zero(nk, m);  // the controller's state, one column per impulse input
  MarkovSequence result(static_cast<std::size_t>(K), Eigen::MatrixXd::Zero(p, m));
  Eigen::MatrixXd r(p, m), v(m, m);
  for (Index k = 0; k < K; ++k) {
    const Index span = std::min(k, used);
    if (span > 0)
      r.noalias() = gcat.leftCols(m * span) * vrev.middleRows(m * (K - k), m * span);
    else
      r.setZero();
    // v[k] = δ[k] − C_K x_K − D_K e[k], e[k] = −(ĝ[0] v[k] + r)  ⇒  (I − D_K ĝ[0]) v[k] = δ − C_K x_K + D_K r
    v = controller.D * r;
    if (nk > 0) v.noalias() -= controller.C * xk;
    if (k == 0) v += Eigen::MatrixXd::Identity(m, m);
    v = loop0.solve(v);
    const Eigen::MatrixXd q = g0 * v + r;
    result[static_cast<std::size_t>(k)] = q;
    vrev.middleRows(m * (K - 1 - k), m) = v;
    if (nk > 0) xk = controller.A * xk - controller.B * q;
  }
  return result;
}

}  // namespace lpvid
