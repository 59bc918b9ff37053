#include "idlib/identify/identify.h"
#include "idlib/identify/output_error.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {

namespace {

// ---- horizon ----
// The paper recipe's (kEra) default horizon: 2 s covers a slowest closed-loop pole at
// −3 rad/s to 2.5e-3 of its peak (the foundation's choice; kept for that method).
constexpr double kEraDefaultHorizon_s = 2.0;

}  // namespace

namespace identify_detail {

// The output-error refinement of a structured result on its own logs — open loop
// (controller nullptr: the plant from u) or in the loop with the known controller (from
// v) — from rest first, then with each log's initial state (the plant's, or the loop's)
// fitted, kept only when Akaike's criterion says the extra values earn their place
// (N p ln(V_rest / V_free) > 2 n_x E): a record that starts from rest is fitted without
// them.  Fills r.choices.refinement(_reason); when kept, the plant, the fit's covariance
// (the bands) and, in closed loop, the closed loop.
void refine_on_logs(const std::vector<ExperimentView>& experiments, const StateSpace* controller, IdentifyResult& r,
                    const std::vector<Eigen::VectorXd>& residual_weights, IdentifyOptions::InitialStates initial) {
  using Initial = IdentifyOptions::InitialStates;
  const bool closed = controller != nullptr;
  const auto refine = [&](const StateSpace& start, const OutputErrorOptions& o) {
    return closed ? refine_output_error_closed_loop(experiments, start, *controller, o)
                  : refine_output_error(experiments, start, o);
  };
  OutputErrorOptions rest, with_states;
  rest.estimate_initial_states = false;
  rest.residual_weights = with_states.residual_weights = residual_weights;
  if (closed) rest.max_jacobian_entries = with_states.max_jacobian_entries = kClosedLoopRefinementEntries;
  const OutputErrorResult at_rest = refine(r.plant, rest);
  const OutputErrorResult free = initial == Initial::kZero
                                     ? OutputErrorResult{}
                                     : refine(at_rest.accepted ? at_rest.model : r.plant, with_states);
  const Index loop_states = r.plant.order() + (closed ? controller->order() : 0);
  const double extra = 2.0 * static_cast<double>(loop_states * static_cast<Index>(experiments.size()));
  const bool use_free =
      free.accepted && (initial == Initial::kEstimate || !at_rest.accepted ||
                        static_cast<double>(free.residuals) * std::log(at_rest.cost / free.cost) > extra);
  OutputErrorResult oe = use_free ? free : at_rest;
  if (oe.accepted)
    oe.reason = fmt::format(
        "output error on the logs{} (Levenberg-Marquardt, Ceres): the outputs' normalised squared simulation error "
        "{:.4g} (the structured fit, from rest) -> {:.4g} from rest{}; {}{}{}",
        closed ? " of the loop with the controller" : "", at_rest.start_cost,
        at_rest.accepted ? at_rest.cost : at_rest.start_cost,
        initial == Initial::kZero ? std::string(" (the initial states held at zero, as asked: --initial-state zero)")
        : use_free && initial == Initial::kEstimate
            ? fmt::format(" -> {:.4g} with each log's initial state fitted (as asked: --initial-state estimate)",
                          free.cost)
        : use_free ? fmt::format(" -> {:.4g} with each log's initial state fitted (kept: Akaike's criterion, a "
                                 "factor {:.4g} for {:g} more values)",
                                 free.cost, at_rest.accepted ? at_rest.cost / free.cost : 0.0, extra / 2)
                   : fmt::format(" (fitting the initial states too{} does not pay by Akaike's criterion)",
                                 free.accepted ? fmt::format(" lowers it by a factor {:.4g} only", at_rest.cost / free.cost)
                                               : std::string("")),
        closed ? "the loop stable" : "stable", oe.iterations >= 200 ? "; stopped at the iteration limit" : "",
        oe.form == "modal"
            ? fmt::format("; in modal form with C and D eliminated ({}){}", oe.form_reason,
                          oe.poles_on_bound > 0
                              ? fmt::format(", {} pole(s) on its stability bound: the logs cannot tell them from "
                                            "undamped or integrating ones (a drift, or a line in the outputs)",
                                            oe.poles_on_bound)
                              : std::string())
            : std::string());
  r.choices.refinement_reason = oe.reason;
  IdentifyChoices::Refinement& rf = r.choices.refinement;
  rf.ran = true;
  rf.kept = oe.accepted;
  rf.initial_states_fitted = use_free;
  rf.start_cost = at_rest.start_cost;
  rf.cost = oe.accepted ? oe.cost : at_rest.start_cost;
  rf.iterations = use_free ? at_rest.iterations + free.iterations : at_rest.iterations;
  rf.parameters = oe.parameters;
  rf.residuals = oe.residuals;
  rf.replicates = oe.accepted ? oe.replicates : 0;
  rf.form = oe.form;
  rf.poles_on_bound = oe.accepted ? oe.poles_on_bound : 0;
  if (!oe.accepted) return;
  r.plant = oe.model;
  r.fit.plant = oe.model;
  r.fit.plant.D.setZero();
  r.fit.covariance = oe.covariance;
  r.fit.replicates = oe.replicates;
  if (!closed && !r.plant.D.isZero(0.0)) r.feedthrough_variance = oe.feedthrough_variance;
  if (closed) r.closed_loop = closed_loop_output(r.plant, *controller);
  r.choices.bands_reason =
      fmt::format("covariance of the output-error refinement: a sandwich over {} record segments", oe.replicates);
}


bool reclosed_loop_misses_far_more(double era_fit_percent, double reclosed_fit_percent) {
  constexpr double kWorseFactor = 2.0, kMinPoints = 1.0;
  const double e_era = std::max(1e-12, 100.0 - era_fit_percent), e_back = 100.0 - reclosed_fit_percent;
  return e_back > kWorseFactor * e_era && e_back - e_era > kMinPoints;
}

}  // namespace identify_detail

namespace {

// The kEra plant judged by the loop it makes with the controller that ran.  unloop removes
// the modes it takes for the controller's; where the plant has poles at or near the
// controller's (a levitated stage's rigid-body integrators beside a PID's), it can remove
// the wrong ones and return a plant that looks plausible alone.  The logs ran a stable
// loop, so a plant that closes an unstable one (growing by more than 2x over the longest
// record) is refused; one whose loop fits the logs
// more than twice as badly (in 100 − fit) as the ERA closed loop it came from is warned of.
void judge_reclosed_loop(const std::vector<ExperimentView>& experiments, const StateSpace& controller,
                         IdentifyResult& result) {
  const StateSpace reclosed = closed_loop_output(result.plant, controller);
  double radius = 0;
  for (const auto& z : poles(reclosed)) radius = std::max(radius, std::abs(z));
  // Unstable as the logs would show it: growing by more than a factor 2 over the longest
  // record (a pole at z = 1 to rounding, an integrator the loop does not reach, is not).
  Index longest = 0;
  for (const ExperimentView& v : experiments) longest = std::max(longest, v.output.rows());
  if (radius > 1.0 && static_cast<double>(longest) * std::log(radius) > std::log(2.0))
    throw NumericalError(fmt::format(
        "the plant from unloop (order {}, {} modes removed) closes an UNSTABLE loop with the controller (largest "
        "pole |z| = {:.9g}) although the logs ran a stable one: unloop could not tell the controller's modes from the "
        "plant's (poles at or near z = 1 on both sides, as a levitated stage's beside a PID's); use the default "
        "--method structured, which fits the plant with the controller directly (or check --controller and its sign)",
        result.plant.order(), result.unloop.removed_poles.size(), radius));
  result.era_fit_percent = simulation_fit_percent(result.era.model, experiments, false);
  result.reclosed_fit_percent = simulation_fit_percent(reclosed, experiments, false);
  if (result.era_fit_percent.size() == 0 || result.reclosed_fit_percent.size() == 0) return;
  std::vector<std::string> figures;
  double worst = 0;
  bool misses = false;
  for (Index i = 0; i < result.era_fit_percent.size(); ++i) {
    figures.push_back(fmt::format("{:.1f} % ({:.1f} %)", result.reclosed_fit_percent(i), result.era_fit_percent(i)));
    const double e_era = std::max(1e-12, 100.0 - result.era_fit_percent(i)), e_back = 100.0 - result.reclosed_fit_percent(i);
    worst = std::max(worst, e_back / e_era);
    misses = misses || identify_detail::reclosed_loop_misses_far_more(result.era_fit_percent(i), result.reclosed_fit_percent(i));
  }
  result.reclosed_reason = fmt::format("the plant closed with the controller simulates the logs to {} per output (in "
                                       "brackets the ERA closed loop it came from)",
                                       fmt::join(figures, ", "));
  if (misses)
    result.warnings.push_back(fmt::format(
        "unloop: the plant closed with the controller misses the logs {:.3g}x as much as the ERA closed loop it came "
        "from ({}): unloop did not recover the plant (the controller's and the plant's modes near z = 1 confused, "
        "or the closed-loop order too low); the default --method structured fits the plant with the controller "
        "directly",
        worst, fmt::join(figures, ", ")));
}

// The kEra chain (the paper's recipe): Markov → ERA → unloop.
IdentifyResult identify_era(const std::vector<ExperimentView>& experiments, double sample_period_s,
                            const StateSpace& controller, const IdentifyOptions& options, Index shortest) {
  IdentifyResult result;
  result.method = IdentifyMethod::kEra;
  result.num_lags = choose_num_lags(options, sample_period_s, shortest);
  MarkovOptions markov_options;
  markov_options.num_lags = result.num_lags;
  markov_options.method = options.markov_method;
  report_progress(options.progress, {"identify", "Markov parameters", 0, 0, fmt::format("{} lags", result.num_lags)});
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
  report_progress(options.progress, {"identify", "realization", 0, 0, ""});
  result.era = realize_era(result.markov.g, era_options);
  for (const auto& w : result.era.report.warnings) result.warnings.push_back("realize: " + w);
  // The experiments ran in a stable closed loop, so an unstable model of it is
  // wrong, and inverting the loop around it would only hide that.
  if (!is_stable(result.era.model)) {
    double radius = 0;
    for (const auto& z : poles(result.era.model)) radius = std::max(radius, std::abs(z));
    throw NumericalError(fmt::format(
        "the realised closed loop (order {}) is unstable (largest pole magnitude {:.6f}) although the loop that ran "
        "was stable; the Markov parameters have not died out within the horizon or the order is wrong: try a longer "
        "--horizon-s, a longer record, --order, or the default --method structured",
        result.era.model.order(), radius));
  }
  UnloopOptions unloop_options;
  unloop_options.plant_order = options.plant_order;
  report_progress(options.progress, {"identify", "unloop", 0, 0, ""});
  result.unloop = plant_from_closed_loop(result.era.model, controller, unloop_options);
  for (const auto& w : result.unloop.report.warnings) result.warnings.push_back("unloop: " + w);
  result.closed_loop = result.era.model;
  result.plant = result.unloop.plant;
  if (controller.order() > 0 || !controller.D.isZero(0.0)) judge_reclosed_loop(experiments, controller, result);
  return result;
}

}  // namespace

void IdentifyOptions::validate() const {
  if (markov_horizon_s < 0.0 || !std::isfinite(markov_horizon_s))
    throw InputError(fmt::format("markov horizon {} s: must be a positive number of seconds (or 0 for automatic)",
                                 markov_horizon_s));
  if (num_lags < 0) throw InputError(fmt::format("lags {}: must be positive (or 0 for automatic)", num_lags));
  if (closed_loop_order < 0 || plant_order < 0)
    throw InputError("model orders must be positive (or 0 for automatic)");
  if (max_order < 1) throw InputError(fmt::format("max order {}: must be at least 1", max_order));
  if (fit_band_max_rad_s < 0.0 || !std::isfinite(fit_band_max_rad_s))
    throw InputError(fmt::format("fit band {} rad/s: must be positive (or 0 for automatic)", fit_band_max_rad_s));
  if (max_tail_rounds < 0) throw InputError(fmt::format("tail rounds {}: must be >= 0", max_tail_rounds));
}

Index choose_num_lags(const IdentifyOptions& options, double sample_period_s, Index shortest_record) {
  constexpr Index kMinLags = 10;
  if (options.num_lags > 0) {
    if (options.num_lags < kMinLags)
      throw InputError(fmt::format("--lags {}: give at least {} lags", options.num_lags, kMinLags));
    if (options.num_lags >= shortest_record)
      throw InputError(fmt::format("--lags {} needs records longer than {} samples, but the shortest has {}; give at "
                                   "most {} lags (a quarter of it) or record longer",
                                   options.num_lags, options.num_lags, shortest_record, shortest_record / 4));
    return options.num_lags;
  }
  // A horizon in seconds: it needs a known sample time (a log whose time column is the
  // sample index has Ts = 1 s, and a horizon of a few seconds is then a few lags).
  const bool given = options.markov_horizon_s > 0.0;
  const double horizon_s = given ? options.markov_horizon_s : kEraDefaultHorizon_s;
  const double raw = std::round(horizon_s / sample_period_s);
  if (raw < static_cast<double>(kMinLags))
    throw InputError(fmt::format("{} horizon of {:g} s is only {:g} lag(s) at the logs' sample time {:.6g} s, fewer "
                                 "than {}; give --lags, or a --horizon-s of at least {:.6g} s",
                                 given ? "the" : "the default", horizon_s, raw, sample_period_s, kMinLags,
                                 static_cast<double>(kMinLags) * sample_period_s));
  const Index lags = static_cast<Index>(std::min(raw, static_cast<double>(shortest_record / 4)));
  if (lags < kMinLags)
    throw InputError(fmt::format("a record of {} samples supports at most {} lags (a quarter of it), fewer than {}; "
                                 "record at least {} samples",
                                 shortest_record, shortest_record / 4, kMinLags, 4 * kMinLags));
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
  if (options.method == IdentifyMethod::kEra) return identify_era(experiments, sample_period_s, controller, options, shortest);
  if (4 * identify_detail::kMinHorizonLags > shortest && options.num_lags == 0 && options.markov_horizon_s == 0.0)
    throw InputError(fmt::format("a record of {} samples is too short for the automatic horizon (at least {} lags, 4 x "
                                 "that in samples); record longer or give --lags",
                                 shortest, identify_detail::kMinHorizonLags));
  IdentifyResult r = identify_detail::identify_structured(experiments, sample_period_s, controller, options, shortest);
  // identify_open_loop runs this with no controller (order 0, D = 0) and refines itself.
  const bool open = controller.order() == 0 && controller.D.isZero(0.0);
  if (!open && options.refine_output_error) {
    report_progress(options.progress, {"identify", "output-error refinement", 0, 0, ""});
    IdentifyResult refined = r;
    identify_detail::refine_on_logs(experiments, &controller, refined, {}, options.initial_states);
    if (!refined.choices.refinement.kept) {
      r.choices.refinement = refined.choices.refinement;
      r.choices.refinement_reason = refined.choices.refinement_reason;
      return r;
    }
    // Kept only when it predicts data it did not fit better (order_held_out.cc).
    report_progress(options.progress, {"identify", "refinement check on held-out data", 0, 0, ""});
    std::string why;
    if (identify_detail::refinement_predicts_better(experiments, sample_period_s, controller, options, r, why)) {
      r = std::move(refined);
      r.choices.refinement_reason += "; " + why;
    } else {
      r.choices.refinement = refined.choices.refinement;
      r.choices.refinement.kept = false;
      r.choices.refinement.replicates = 0;
      r.choices.refinement_reason = "not kept: " + refined.choices.refinement_reason + "; " + why;
    }
  }
  return r;
}

namespace {

IdentifyResult identify_open_loop_at(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                     const IdentifyOptions& options);

}  // namespace

IdentifyResult identify_open_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                  const IdentifyOptions& options) {
  IdentifyResult r = identify_open_loop_at(experiments, sample_period_s, options);
  if (options.method != IdentifyMethod::kStructured || !options.refine_output_error || options.plant_order > 0 ||
      !options.check_order_held_out)
    return r;
  report_progress(options.progress, {"identify", "order check on held-out data", 0, 0, ""});
  IdentifyChoices::HeldOutOrder h = identify_detail::check_order_held_out(experiments, sample_period_s, options, r);
  if (h.chosen_order != h.ladder_order) {
    IdentifyOptions o = options;
    o.plant_order = h.chosen_order;
    IdentifyResult chosen = identify_open_loop_at(experiments, sample_period_s, o);
    chosen.choices.order_reason = fmt::format("order {} chosen on held-out data (below); the ladder had chosen {}: {}",
                                              h.chosen_order, h.ladder_order, r.choices.order_reason);
    chosen.choices.order_candidates = r.choices.order_candidates;
    r = std::move(chosen);
  }
  r.choices.held_out = std::move(h);
  return r;
}

namespace {

IdentifyResult identify_open_loop_at(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                     const IdentifyOptions& options) {
  if (experiments.empty()) throw InputError("no experiments given; pass at least one log");
  const Index m = experiments.front().excitation.cols();
  const Index p = experiments.front().output.cols();
  // No controller: the closed loop with C = 0 is the plant, G(P) = P (I + C P)^-1 = P.
  StateSpace none;
  none.A.resize(0, 0);
  none.B.resize(0, p);
  none.C.resize(m, 0);
  none.D = Eigen::MatrixXd::Zero(m, p);
  none.sample_period_s = sample_period_s;
  IdentifyResult r = identify_closed_loop(experiments, sample_period_s, none, options);
  r.feedthrough_variance = Eigen::MatrixXd::Zero(p, m);
  if (r.method == IdentifyMethod::kEra) {
    r.plant = r.era.model;  // nothing to unloop; ERA's D is ĝ[0]
    r.plant.sample_period_s = sample_period_s;
    r.choices.feedthrough_reason = "ERA's D is the lag-0 Markov parameter";
  } else {
    // The structured fit uses lags 1..L (a sampled plant inside a loop has no
    // feedthrough). Open loop, lag 0 is the plant's direct feedthrough D (an
    // accelerometer's response to a force), estimated by least squares with the other
    // lags: kept where it stands above kFeedthroughSigmas of its standard error.
    const Eigen::MatrixXd& g0 = r.markov.g.front();
    const Eigen::MatrixXd& se = r.markov.noise_std;
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(p, m);
    Index kept = 0;
    double largest = 0.0;
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) {
        const double z = se(i, j) > 0 ? std::abs(g0(i, j)) / se(i, j) : std::numeric_limits<double>::infinity();
        largest = std::max(largest, std::isfinite(z) ? z : 0.0);
        if (z > kFeedthroughSigmas) {
          D(i, j) = g0(i, j);
          r.feedthrough_variance(i, j) = se(i, j) * se(i, j);
          ++kept;
        }
      }
    if (!options.open_loop_feedthrough) {
      D.setZero();
      r.feedthrough_variance.setZero();
      kept = 0;
    }
    r.plant.D = D;
    r.choices.feedthrough_reason =
        !options.open_loop_feedthrough
            ? std::string("no feedthrough (D = 0): the plant of a sampled loop has none, and the input the loop applied "
                          "holds the output's own noise at lag 0")
            :
        kept > 0 ? fmt::format("D from the lag-0 Markov parameter: {} of {} entries above {:g} standard errors (largest "
                               "{:.3g})",
                               kept, p * m, kFeedthroughSigmas, largest)
                 : fmt::format("no feedthrough: the lag-0 Markov parameter is within {:g} standard errors of zero "
                               "(largest {:.3g}), D = 0",
                               kFeedthroughSigmas, largest);
    if (options.refine_output_error) {
      report_progress(options.progress, {"identify", "output-error refinement", 0, 0, ""});
      identify_detail::refine_on_logs(experiments, nullptr, r, {}, options.initial_states);
    } else {
      r.choices.refinement_reason = "not refined (switched off)";
    }
  }
  r.closed_loop = r.plant;
  return r;
}

}  // namespace

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

Eigen::MatrixXd reference_as_input_excitation(const StateSpace& controller,
                                              const Eigen::Ref<const Eigen::MatrixXd>& reference) {
  controller.validate();
  if (reference.cols() != controller.num_inputs())
    throw InputError(fmt::format("reference excitation: {} reference column(s) for a controller with {} input(s) (one "
                                 "reference per measured output, e = r - q)",
                                 reference.cols(), controller.num_inputs()));
  if (!reference.allFinite()) throw InputError("reference excitation: a reference value is not finite");
  // The operating point: the first setpoint when the references hold still there (a log
  // that starts at rest before its moves: the loop stood at r(0)), else each reference's
  // mean.  Filtering r minus anything else from rest adds the controller's step response
  // to the difference — a derivative's kick at the first sample that the loop never
  // applied (measured: a point-to-point log starting 0.1 m below its mean put 10⁴ A into
  // v's first sample, whose broadband power outweighed the moves' above a few hertz), and
  // a ramp through an integral action.  The constant left in v is removed downstream.
  if (reference.rows() == 0) return Eigen::MatrixXd::Zero(0, controller.num_outputs());
  const Index n = reference.rows(), still = std::max<Index>(kReferenceAtRestSamples, n / 200);
  bool at_rest = n > still;
  for (Index j = 0; j < reference.cols() && at_rest; ++j) {
    const double range = reference.col(j).maxCoeff() - reference.col(j).minCoeff();
    at_rest = (reference.col(j).head(still).array() - reference(0, j)).abs().maxCoeff() <= 1e-6 * range;
  }
  const Eigen::RowVectorXd operating = at_rest ? Eigen::RowVectorXd(reference.row(0)) : reference.colwise().mean();
  const Eigen::MatrixXd deviation = reference.rowwise() - operating;
  return simulate_discrete(controller, deviation);
}

Eigen::MatrixXd applied_plant_input(const StateSpace& controller, const Eigen::Ref<const Eigen::MatrixXd>& added,
                                    const Eigen::Ref<const Eigen::MatrixXd>& reference,
                                    const Eigen::Ref<const Eigen::MatrixXd>& output) {
  controller.validate();
  const Index n = output.rows(), p = controller.num_inputs(), m = controller.num_outputs();
  if (output.cols() != p || (reference.size() > 0 && (reference.rows() != n || reference.cols() != p)) ||
      (added.size() > 0 && (added.rows() != n || added.cols() != m)))
    throw InputError(fmt::format("plant input: a controller of {} input(s) and {} output(s) for {} x {} outputs, {} x "
                                 "{} references and {} x {} added excitations",
                                 p, m, output.rows(), output.cols(), reference.rows(), reference.cols(), added.rows(),
                                 added.cols()));
  if (!output.allFinite() || !reference.allFinite() || !added.allFinite())
    throw InputError("plant input: a logged value is not finite");
  if (n == 0) return Eigen::MatrixXd::Zero(0, m);
  Eigen::MatrixXd e = -output;
  if (reference.size() > 0) e += reference;
  e.rowwise() -= Eigen::RowVectorXd(e.row(0));
  Eigen::MatrixXd u = simulate_discrete(controller, e);
  if (added.size() > 0) u += added;
  return u;
}

BandSupport band_support(const std::vector<Eigen::MatrixXcd>& response, const std::vector<Eigen::MatrixXd>& variance,
                         const Eigen::VectorXd& omega_rad_s, double threshold) {
  const auto F = static_cast<std::size_t>(omega_rad_s.size());
  if (response.size() != F || variance.size() != F)
    throw InputError(fmt::format("band support: {} responses and {} variances for {} frequencies", response.size(),
                                 variance.size(), F));
  if (!(threshold > 0)) throw InputError(fmt::format("band support: threshold {} must be > 0", threshold));
  BandSupport b;
  b.threshold = threshold;
  b.points = omega_rad_s.size();
  for (std::size_t k = 0; k < F; ++k) {
    if (variance[k].rows() != response[k].rows() || variance[k].cols() != response[k].cols())
      throw InputError("band support: a variance's shape differs from its response's");
    const double norm = response[k].norm();
    const double r = norm > 0 ? kBandRadiusPerSigma * std::sqrt(std::max(0.0, variance[k].sum())) / norm
                              : std::numeric_limits<double>::infinity();
    const double w = omega_rad_s(static_cast<Index>(k));
    if (r > b.worst_relative) b.worst_relative = r, b.omega_at_worst_rad_s = w;
    if (r <= threshold) {
      if (b.supported == 0) b.lowest_supported_rad_s = w;
      b.highest_supported_rad_s = w;
      ++b.supported;
    }
  }
  return b;
}

InstabilityEvidence instability_evidence(const StateSpace& plant, const BandSupport* support) {
  InstabilityEvidence e;
  if (plant.order() == 0) return e;
  const Eigen::VectorXcd poles = Eigen::EigenSolver<Eigen::MatrixXd>(plant.A, false).eigenvalues();
  const bool discrete = plant.is_discrete();
  e.largest_magnitude = discrete ? 0.0 : -std::numeric_limits<double>::infinity();
  for (Index i = 0; i < poles.size(); ++i) {
    const double size = discrete ? std::abs(poles(i)) : poles(i).real();
    e.largest_magnitude = std::max(e.largest_magnitude, size);
    const bool outside = discrete ? size > 1.0 : size > 0.0;
    if (!outside) continue;
    ++e.unstable_poles;
    e.growth_rate_rad_s = std::max(e.growth_rate_rad_s, discrete ? std::log(size) / plant.sample_period_s : size);
  }
  if (e.unstable_poles == 0) return e;
  e.proven = support == nullptr || !(support->lowest_supported_rad_s > 0) ||
             e.growth_rate_rad_s > support->threshold * support->lowest_supported_rad_s;
  return e;
}

}  // namespace lpvid
