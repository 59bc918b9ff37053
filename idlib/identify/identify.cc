#include "idlib/identify/identify.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"

namespace lpvid {

void IdentifyOptions::validate() const {
  if (!(markov_horizon_s > 0.0) || !std::isfinite(markov_horizon_s))
    throw InputError(fmt::format("markov horizon {} s: must be a positive number of seconds", markov_horizon_s));
  if (num_lags < 0) throw InputError(fmt::format("lags {}: must be positive (or 0 for automatic)", num_lags));
  if (closed_loop_order < 0 || plant_order < 0)
    throw InputError("model orders must be positive (or 0 for automatic)");
  if (max_order < 1) throw InputError(fmt::format("max order {}: must be at least 1", max_order));
}

Index choose_num_lags(const IdentifyOptions& options, double sample_period_s, Index shortest_record) {
  Index lags = options.num_lags > 0 ? options.num_lags
                                    : static_cast<Index>(std::llround(options.markov_horizon_s / sample_period_s));
  if (options.num_lags == 0) lags = std::min(lags, shortest_record / 4);
  if (lags < 10 || lags >= shortest_record)
    throw InputError(fmt::format(
        "a record of {} samples is too short for {} lags; record at least {} samples (4 x the lags) or lower --lags",
        shortest_record, lags, 4 * std::max<Index>(lags, 10)));
  return lags;
}

void check_controller_matches(const StateSpace& controller, double sample_period_s, Index num_outputs,
                              Index num_excitations, double relative_tolerance) {
  if (!controller.is_discrete())
    throw InputError("controller is continuous (ts = 0); give the discrete controller that ran on the setup");
  if (std::abs(controller.sample_period_s - sample_period_s) > relative_tolerance * controller.sample_period_s)
    throw InputError(fmt::format(
        "mismatched sample rates: the logs are sampled at {:.6g} Hz (ts = {:.6g} s) but the controller has ts = {:.6g} s "
        "({:.6g} Hz); give the controller discretised at the logging rate",
        1.0 / sample_period_s, sample_period_s, controller.sample_period_s, 1.0 / controller.sample_period_s));
  if (controller.num_inputs() != num_outputs || controller.num_outputs() != num_excitations)
    throw InputError(fmt::format(
        "controller has {} inputs and {} outputs, but the loop has {} measured outputs and {} excitations; "
        "give the controller that maps the {} outputs (e = -q) to the {} plant inputs",
        controller.num_inputs(), controller.num_outputs(), num_outputs, num_excitations, num_outputs, num_excitations));
}

IdentifyResult identify_closed_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                    const StateSpace& controller, const IdentifyOptions& options) {
  options.validate();
  if (experiments.empty()) throw InputError("no experiments given; pass at least one log");
  const Index m = experiments.front().excitation.cols();
  const Index p = experiments.front().output.cols();
  controller.validate();
  check_controller_matches(controller, sample_period_s, p, m, options.sample_period_tolerance);

  Index shortest = experiments.front().excitation.rows();
  for (const auto& e : experiments) shortest = std::min<Index>(shortest, e.excitation.rows());

  IdentifyResult result;
  result.num_lags = choose_num_lags(options, sample_period_s, shortest);

  MarkovOptions markov_options;
  markov_options.num_lags = result.num_lags;
  markov_options.method = options.markov_method;
  result.markov = estimate_markov(experiments, markov_options);
  for (const auto& w : result.markov.report.warnings) result.warnings.push_back("markov: " + w);

  EraOptions era_options;
  era_options.sample_period_s = sample_period_s;
  era_options.order = options.closed_loop_order;
  era_options.max_order = options.max_order;
  era_options.input_scale = result.markov.excitation_rms;
  era_options.output_scale = result.markov.output_rms;
  era_options.markov_noise_std = result.markov.noise_std;
  // A zero-order-hold sampled plant has no direct feedthrough (D_P = 0), so
  // neither has G = P (I + C P)^-1: D_G = D_P (I + D_C D_P)^-1 = 0.
  era_options.estimate_feedthrough = false;
  result.closed_loop = realize_era(result.markov.g, era_options);
  for (const auto& w : result.closed_loop.report.warnings) result.warnings.push_back("realize: " + w);
  // The experiments ran in a stable closed loop, so an unstable model of it is
  // wrong, and inverting the loop around it would only hide that.
  if (!is_stable(result.closed_loop.model)) {
    double radius = 0;
    for (const auto& z : poles(result.closed_loop.model)) radius = std::max(radius, std::abs(z));
    throw NumericalError(fmt::format(
        "the realised closed loop (order {}) is unstable (largest pole magnitude {:.6f}) although the loop that ran "
        "was stable; the Markov parameters have not died out within the horizon or the order is wrong: try a longer "
        "--horizon-s, a longer record, or --order",
        result.closed_loop.model.order(), radius));
  }

  UnloopOptions unloop_options;
  unloop_options.plant_order = options.plant_order;
  result.plant = plant_from_closed_loop(result.closed_loop.model, controller, unloop_options);
  for (const auto& w : result.plant.report.warnings) result.warnings.push_back("unloop: " + w);
  return result;
}

}  // namespace lpvid

#include "idlib/lti/analysis.h"

namespace lpvid {

Eigen::MatrixXd markov_fit_percent(const StateSpace& model, const MarkovSequence& g) {
  if (g.size() < 2) throw InputError("markov fit needs at least two lags");
  const Index p = g.front().rows(), m = g.front().cols();
  if (model.num_outputs() != p || model.num_inputs() != m)
    throw InputError(fmt::format("model is {}x{} but the Markov parameters are {}x{}", model.num_outputs(),
                                 model.num_inputs(), p, m));
  const MarkovSequence h = markov_parameters(model, static_cast<Index>(g.size()) - 1);
  Eigen::MatrixXd err = Eigen::MatrixXd::Zero(p, m), ref = Eigen::MatrixXd::Zero(p, m);
  for (std::size_t k = 1; k < g.size(); ++k) {
    err += (g[k] - h[k]).cwiseAbs2();
    ref += g[k].cwiseAbs2();
  }
  Eigen::MatrixXd fit(p, m);
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j)
      fit(i, j) = ref(i, j) > 0 ? 100.0 * (1.0 - std::sqrt(err(i, j) / ref(i, j))) : 0.0;
  return fit;
}

}  // namespace lpvid
