// fit_markov_stable (output_error.h): a stable model for Markov parameters.
#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "idlib/core/error.h"
#include "idlib/identify/output_error.h"
#include "idlib/lti/analysis.h"

namespace lpvid {
namespace markov_stable_detail {

double relative_error(const MarkovSequence& g, const StateSpace& model) {
  const MarkovSequence h = markov_parameters(model, static_cast<Index>(g.size()) - 1);
  double num = 0.0, den = 0.0;
  for (std::size_t k = 0; k < g.size(); ++k) {
    num += (g[k] - h[k]).squaredNorm();
    den += g[k].squaredNorm();
  }
  // A start that grows so fast its response overflows over the lags (the F-16's ERA model
  // at |z| 4.7 over 2000 lags) misses them without bound: +inf, not the NaN that made
  // every comparison with it false and kept it unstable.
  if (!std::isfinite(num)) return std::numeric_limits<double>::infinity();
  return den > 0.0 ? std::sqrt(num / den) : 0.0;
}

}  // namespace markov_stable_detail

MarkovStableFit fit_markov_stable(const MarkovSequence& g, const StateSpace& start) {
  if (g.size() < 8)
    throw InputError(fmt::format("fit_markov_stable: {} Markov parameters; give at least 8 lags", g.size()));
  const Index L = static_cast<Index>(g.size()) - 1, p = g[0].rows(), m = g[0].cols();
  if (start.num_outputs() != p || start.num_inputs() != m || !start.is_discrete())
    throw InputError(fmt::format("fit_markov_stable: the start is {} -> {} ({}), the Markov parameters {} -> {}; "
                                 "give a discrete model of the same channels",
                                 start.num_inputs(), start.num_outputs(),
                                 start.is_discrete() ? "discrete" : "continuous", m, p));
  MarkovStableFit out;
  const Index quarter = std::max<Index>(1, (L + 1) / 4);
  double first = 0.0, last = 0.0;
  for (Index k = 0; k < quarter; ++k) {
    first += g[static_cast<std::size_t>(k)].squaredNorm();
    last += g[static_cast<std::size_t>(L - k)].squaredNorm();
  }
  out.start_error = markov_stable_detail::relative_error(g, start);
  out.grows = last > first;
  std::vector<Eigen::MatrixXd> inputs, outputs;
  for (Index j = 0; j < m; ++j) {
    Eigen::MatrixXd uj = Eigen::MatrixXd::Zero(L + 1, m), yj(L + 1, p);
    uj(0, j) = 1.0;
    for (Index k = 0; k <= L; ++k) yj.row(k) = g[static_cast<std::size_t>(k)].col(j).transpose();
    inputs.push_back(std::move(uj));
    outputs.push_back(std::move(yj));
  }
  std::vector<ExperimentView> views;
  for (Index j = 0; j < m; ++j) views.push_back({inputs[static_cast<std::size_t>(j)], outputs[static_cast<std::size_t>(j)]});
  OutputErrorOptions options;
  options.estimate_initial_states = false;
  out.result = refine_output_error_modal(views, start, options);
  out.error = out.result.accepted ? markov_stable_detail::relative_error(g, out.result.model) : out.start_error;
  return out;
}

}  // namespace lpvid
