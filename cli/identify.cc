// lpvid identify — the whole time-domain chain in one call (seed 000, eqs 10–14):
// logs -> Markov parameters -> Hankel SVD and order -> closed loop G -> plant P,
// with the Hankel singular values, a Bode plot and a report beside the models.
#include <CLI/CLI.hpp>
#include <limits>
#include <optional>
#include <algorithm>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "cli/progress_line.h"
#include "cli/registry.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/frd_csv.h"
#include "formats/io/markov_csv.h"
#include "formats/io/model_json.h"
#include "formats/io/table_csv.h"
#include "formats/plot/bode_plot.h"
#include "formats/plot/sv_plot.h"
#include "idlib/core/error.h"
#include "idlib/identify/direct.h"
#include "idlib/identify/identify.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/validate/frequency_error.h"
#include "idlib/identify/output_error.h"
#include "idlib/validate/nonlinearity.h"
#include "idlib/validate/time_fit.h"

namespace lpvid::cli {
namespace {

constexpr const char* kIdentifyExample = R"(
Example:
  lpvid identify --controller controller.json --excitation v1,v2,v3 --output q1,q2,q3 \
                 --out result exp_T_psi.csv exp_T_theta.csv exp_F_z.csv
writes result/closed_loop.json, result/plant.json, result/markov.csv, result/hankel_sv.csv,
result/hankel_sv.png, result/bode.png and result/report.json (order chosen and why,
singular values, fit figures).  Open-loop data (the excitation IS the plant's input):
  lpvid identify --open-loop --excitation u --output y --out result robot_arm.csv
(no closed_loop.json then: the plant is the model of the logs themselves).  Excited through
the setpoint (e = r - q, one reference per output):
  lpvid identify --controller C.json --excitation r --excitation-at reference --output q --out result axis.csv
(the references enter as the plant-input excitation v = C r: closed_loop.json is v -> q).  With --truth PLANT.json the report and the plot also
compare the identified plant with a known one (weighted matrix error, 1-400 rad/s).
Nothing is written unless every step succeeds.)";

struct IdentifyCliOptions {
  std::vector<std::string> logs;
  LogLayoutCli layout;
  std::string controller, excitation, output, out, truth, weights;
  std::string method = "structured";
  Index lags = 0, order = 0, plant_order = 0;
  double horizon_s = 0.0, fit_band_max = 0.0;
  double band_min = 1.0, band_max = 400.0;
  bool json = false;
  bool open_loop = false;
  std::string excitation_at = "input";
  bool band_given = false;  // --band-min or --band-max on the command line
  bool no_refine = false;
  std::string initial_state = "auto";
  bool no_order_check = false;
  bool no_direct = false;
};

nlohmann::json matrix_json(const Eigen::MatrixXd& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (Index i = 0; i < m.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json poles_json(const StateSpace& s) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& z : poles(s)) out.push_back({z.real(), z.imag()});
  return out;
}

// The band drawn in bode.png: |Ĥ| ± kBandRadiusPerSigma σ (idlib/identify/identify.h).
constexpr const char* kBandLevel = "95 %";

nlohmann::json structured_report(const IdentifyResult& r) {
  const IdentifyChoices& ch = r.choices;
  nlohmann::json candidates = nlohmann::json::array();
  for (const auto& c : ch.order_candidates)
    candidates.push_back({{"order", c.order}, {"cost", c.cost}, {"dof", c.dof}, {"stable_loop", c.stable}, {"screened", c.screened}});
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& s : ch.stages)
    stages.push_back({{"lags", s.lags}, {"bins", s.bins}, {"iterations", s.iterations}, {"cost", s.cost}});
  nlohmann::json rounds = nlohmann::json::array();
  for (const auto& t : ch.tail_rounds) rounds.push_back({{"cost", t.cost}, {"relative_change", t.change}});
  return {{"band_rad_s", {0.0, ch.fit_band_max_rad_s}},
          {"bins", ch.fit_bins},
          {"band_reason", ch.band_reason},
          {"start_lags", ch.plant_horizon},
          {"start_reason", ch.start_reason},
          {"order", ch.plant_order},
          {"order_reason", ch.order_reason},
          {"order_candidates", candidates},
          {"stages", stages},
          {"tail_rounds", rounds},
          {"tail_reason", ch.tail_reason},
          {"bands_reason", ch.bands_reason},
          {"excitation_reason", ch.excitation_reason},
          {"replicates", r.fit.replicates},
          {"cost", r.fit.cost},
          {"residuals", r.fit.residuals},
          {"parameters", r.fit.parameters},
          {"noise_scale", r.fit.noise_scale}};
}

// MATLAB compare's figure on the logs (output_error.h simulation_fit_percent): from zero
// state (compare's 'z') or with each record's initial state fitted (compare's default
// 'e').  Null when the simulation diverges (an unstable model).
nlohmann::json simulation_fit_json(const StateSpace& model, const ExperimentSet& set, bool fit_initial_states) {
  const Eigen::VectorXd fit = simulation_fit_percent(model, set.views(), fit_initial_states);
  if (fit.size() == 0) return nullptr;
  return std::vector<double>(fit.data(), fit.data() + fit.size());
}

// The nonlinearity tests (idlib/validate/nonlinearity.h) on `model`'s simulation
// residual, each log's initial state fitted, the logs stacked; not run (reason) when the
// model diverges.
NonlinearityResult nonlinearity_on_logs(const StateSpace& model, const ExperimentSet& set) {
  Index rows = 0;
  for (const ExperimentView& v : set.views()) rows += v.output.rows();
  const Index p = model.num_outputs();
  Eigen::MatrixXd e(rows, p), yhat(rows, p);
  Index at = 0;
  for (const ExperimentView& v : set.views()) {
    const SimulatedOutput s = simulate_with_fitted_start(model, v.excitation, v.output, true);
    if (s.predicted.size() == 0) {
      NonlinearityResult none;
      none.reason = "not tested: the model's response diverges on the logs";
      return none;
    }
    e.middleRows(at, v.output.rows()) = v.output - s.predicted;
    yhat.middleRows(at, v.output.rows()) = s.predicted;
    at += v.output.rows();
  }
  return nonlinearity_tests(e, yhat);
}

// The band's relative width above which the plant counts as not pinned down by the data.
constexpr double kSupportThreshold = 0.1;

std::string support_sentence(const BandSupport& b, double band_min, double band_max, bool open_loop) {
  const std::string what = fmt::format("the {} band is within +-{:.0f} % of the plant", kBandLevel, 100 * b.threshold);
  if (b.supported == b.points) return fmt::format("supported: {} over {:.3g}-{:.3g} rad/s", what, band_min, band_max);
  const std::string why =
      fmt::format("it widens to +-{:.0f} % at {:.3g} rad/s: there the logs hold too little of the plant{} to pin it down "
                  "(the model extrapolates); a longer record or more excitation at those frequencies would",
                  100 * b.worst_relative, b.omega_at_worst_rad_s, open_loop ? "" : " (the loop's gain hides it)");
  if (b.supported == 0)
    return fmt::format("NOT supported: nowhere in {:.3g}-{:.3g} rad/s is {}; {}", band_min, band_max, what, why);
  return fmt::format("partly supported: {} at {} of {} frequencies in {:.3g}-{:.3g} rad/s ({:.3g}-{:.3g} rad/s); {}", what, b.supported,
                     b.points, band_min, band_max, b.lowest_supported_rad_s, b.highest_supported_rad_s, why);
}

// What the logs say of an unstable plant (instability_evidence); nothing for a stable one.
std::optional<InstabilityEvidence> instability_of(const StateSpace& plant, const std::optional<BandSupport>& support) {
  if (is_stable(plant)) return std::nullopt;
  return instability_evidence(plant, support ? &*support : nullptr);
}

// The plant's stability in words: stable; unstable as the logs show it; or unstable only
// by a pole the logs cannot tell from an integrator.
std::string stability_words(const std::optional<InstabilityEvidence>& e, const std::optional<BandSupport>& support) {
  if (!e) return "stable";
  if (e->proven)
    return fmt::format("unstable (as the logs say: {} pole(s) outside, growing at up to {:.3g} rad/s)", e->unstable_poles,
                       e->growth_rate_rad_s);
  return fmt::format("unstable only by {} pole(s) growing at up to {:.3g} rad/s (|z| {:.6g}), under {:.0f} % of the "
                     "lowest frequency the logs support ({:.3g} rad/s), where such a pole moves the response less "
                     "than the band: these logs cannot tell it from an integrator (z = 1) and do not prove instability",
                     e->unstable_poles, e->growth_rate_rad_s, e->largest_magnitude, 100 * support->threshold,
                     support->lowest_supported_rad_s);
}

// report.plant.instability (an unstable plant only).
void add_instability(nlohmann::json& report, const std::optional<InstabilityEvidence>& e) {
  if (!e) return;
  report["plant"]["instability"] = {{"unstable_poles", e->unstable_poles},
                                    {"growth_rate_rad_s", e->growth_rate_rad_s},
                                    {"largest_pole_magnitude", e->largest_magnitude},
                                    {"proven_by_the_logs", e->proven}};
}

// The command line checked and turned into the library's options and the column names.
struct IdentifyRoute {
  IdentifyOptions options;
  bool era = false;
  std::vector<std::string> excitation, output;
  bool at_reference = false;
};

IdentifyRoute identify_route(const IdentifyCliOptions& o) {
  IdentifyRoute route;
  IdentifyOptions& options = route.options;
  if (o.method == "structured")
    options.method = IdentifyMethod::kStructured;
  else if (o.method == "era")
    options.method = IdentifyMethod::kEra;
  else
    throw InputError(fmt::format("--method {}: use 'structured' (default) or 'era' (the paper's recipe)", o.method));
  route.era = options.method == IdentifyMethod::kEra;
  options.num_lags = o.lags;
  options.markov_horizon_s = o.horizon_s;
  options.closed_loop_order = o.order;
  options.plant_order = o.plant_order;
  options.fit_band_max_rad_s = o.fit_band_max;
  options.refine_output_error = !o.no_refine;
  if (o.initial_state == "auto")
    options.initial_states = IdentifyOptions::InitialStates::kAuto;
  else if (o.initial_state == "zero")
    options.initial_states = IdentifyOptions::InitialStates::kZero;
  else if (o.initial_state == "estimate")
    options.initial_states = IdentifyOptions::InitialStates::kEstimate;
  else
    throw InputError(fmt::format("--initial-state {}: use 'auto' (default: fitted where Akaike's criterion says it "
                                 "pays), 'zero' (the records start from rest) or 'estimate'",
                                 o.initial_state));
  if (o.initial_state != "auto" && (route.era || o.no_refine))
    throw InputError(fmt::format("--initial-state {} sets the output-error refinement's initial states, and {} runs "
                                 "none; drop one of the two",
                                 o.initial_state, route.era ? "--method era" : "--no-refine"));
  options.check_order_held_out = !o.no_order_check;
  if (!route.era && o.order > 0)
    throw InputError("--order is the closed-loop order of --method era; with the structured method give --plant-order");
  options.validate();
  if (!(o.band_min > 0 && o.band_max > o.band_min))
    throw InputError(fmt::format("--band-min {} is not below --band-max {} (rad/s); give --band-min below --band-max",
                                 o.band_min, o.band_max));
  if (o.open_loop == !o.controller.empty())
    throw InputError(o.open_loop ? "--open-loop and --controller both given; give --controller for closed-loop logs "
                                   "(the plant is unlooped with it) or --open-loop when the excitation is the plant's "
                                   "input, not both"
                                 : "no controller: give --controller C.json (the controller that ran, for closed-loop "
                                   "logs) or --open-loop (the excitation is the plant's input)");
  route.excitation = split_names(o.excitation, "--excitation");
  route.output = split_names(o.output, "--output");
  route.at_reference = o.excitation_at == "reference";
  if (!route.at_reference && o.excitation_at != "input")
    throw InputError(fmt::format("--excitation-at {}: use 'input' (default: v is added to the plant's input, u = u_c + "
                                 "v) or 'reference' (r is the setpoint, e = r - q)",
                                 o.excitation_at));
  if (route.at_reference && o.open_loop)
    throw InputError("--excitation-at reference needs the loop's controller: give --controller C.json, not --open-loop");
  if (route.at_reference && route.excitation.size() != route.output.size())
    throw InputError(fmt::format("--excitation-at reference: {} reference column(s) for {} output(s); give one "
                                 "reference per --output, in the same order (e = r - q)",
                                 route.excitation.size(), route.output.size()));
  return route;
}

// Every output is checked before anything is read; the directory is created
// only when the files are published.
void check_identify_outputs(OutputSet& outputs, const IdentifyCliOptions& o) {
  outputs.inputs(o.logs);
  if (!o.open_loop) outputs.input(o.controller);
  outputs.input(o.truth);
  outputs.directory("--out", o.out);
  if (!o.open_loop) outputs.file_in(o.out, "closed_loop.json");
  for (const char* name : {"plant.json", "plant_frd.csv", "markov.csv", "hankel_sv.csv",
                           "hankel_sv.png", "bode.png", "report.json"})
    outputs.file_in(o.out, name);
  outputs.check();
}

// What identify reads: the controller, the known plant, the error weights and the logs.
struct IdentifyInputs {
  StateSpace controller;
  std::optional<StateSpace> truth;
  Eigen::VectorXd weights;
  ExperimentSet set;
  std::vector<std::string> loop_inputs;  // the inputs of v -> q
  // --excitation-at reference: the references as logged (the direct route's e = r - q).
  std::vector<Eigen::MatrixXd> references;
  // The direct route ran (identify_direct): why, and what it found; null otherwise.
  nlohmann::json direct;
};

IdentifyInputs read_identify_inputs(const IdentifyCliOptions& o, const IdentifyRoute& route) {
  IdentifyInputs in;
  const auto& excitation = route.excitation;
  const auto& output = route.output;
  if (!o.open_loop) in.controller = read_controller(o.controller);
  const StateSpace& controller = in.controller;
  if (!o.truth.empty()) in.truth = read_state_space(o.truth);
  in.weights = Eigen::VectorXd::Ones(static_cast<Index>(output.size()));
  if (!o.weights.empty()) {
    const auto w = split_numbers(o.weights, "--error-weights", "an output weight");
    if (w.size() != output.size())
      throw InputError(fmt::format("--error-weights has {} values for {} outputs; give one weight per --output",
                                   w.size(), output.size()));
    for (std::size_t i = 0; i < w.size(); ++i) in.weights(static_cast<Index>(i)) = w[i];
  }
  in.set = read_experiments(o.logs, excitation, output, o.layout.read_options());
  if (!o.open_loop)
    check_controller_matches(controller, in.set.sample_period_s, static_cast<Index>(output.size()),
                             route.at_reference ? controller.num_outputs() : static_cast<Index>(excitation.size()),
                             route.options.sample_period_tolerance);
  // The references act as the plant-input excitation v = C r (identify.h): from here on
  // the logs' excitation is v, and everything downstream (closed loop, simulation fit)
  // is v -> q.
  in.loop_inputs = excitation;
  if (route.at_reference) {
    in.references = in.set.excitations;
    for (auto& x : in.set.excitations) x = reference_as_input_excitation(controller, x);
    in.loop_inputs.clear();
    for (Index j = 0; j < controller.num_outputs(); ++j)
      in.loop_inputs.push_back(controller.output_names.size() == static_cast<std::size_t>(controller.num_outputs())
                                   ? "C*r->" + controller.output_names[static_cast<std::size_t>(j)]
                                   : fmt::format("v{}", j + 1));
  }
  return in;
}

IdentifyResult identify_from_logs(const IdentifyCliOptions& o, const IdentifyRoute& route, const IdentifyInputs& in) {
  IdentifyOptions options = route.options;  // with this run's progress line
  const StateSpace& controller = in.controller;
  TerminalProgress progress;  // on a terminal only (cli/progress_line.h)
  options.progress = progress.get();
  // Open loop is the closed loop with C = 0 (G(P) = P): the same route and defaults.
  IdentifyResult r = o.open_loop ? identify_open_loop(in.set.views(), in.set.sample_period_s, options)
                                 : identify_closed_loop(in.set.views(), in.set.sample_period_s, controller, options);
  progress.finish();
  r.closed_loop.input_names = in.loop_inputs;
  r.closed_loop.output_names = route.output;
  r.plant.input_names = !controller.output_names.empty() ? controller.output_names
                        : route.at_reference           ? in.loop_inputs
                                                       : route.excitation;
  r.plant.output_names = route.output;
  if (route.era) {
    r.era.model.input_names = r.closed_loop.input_names;
    r.era.model.output_names = r.closed_loop.output_names;
  }
  return r;
}

// report.json's part that depends on the method: the ERA's order rule and unlooping,
// or the structured fit (and, open loop, its refinement).
void add_identify_method_report(nlohmann::json& report, const IdentifyCliOptions& o, const IdentifyResult& r,
                                bool era) {
  if (era) {
    const auto& sel = r.era.selection;
    const Index shown = std::min<Index>(sel.singular_values.size(), 30);
    report["closed_loop"].update({{"order_rule", sel.rule},
                                  {"order_reason", sel.reason},
                                  {"noise_floor", sel.noise_floor},
                                  {"singular_values", std::vector<double>(sel.singular_values.data(),
                                                                          sel.singular_values.data() + shown)},
                                  {"block_rows", r.era.block_rows},
                                  {"block_cols", r.era.block_cols},
                                  {"stride", r.era.stride}});
    report["plant"].update({{"interconnection_order", r.unloop.interconnection_order},
                            {"removed_modes", r.unloop.removed_poles.size()},
                            {"termination", r.unloop.report.termination}});
    const auto list = [](const Eigen::VectorXd& v) {
      return v.size() == 0 ? nlohmann::json(nullptr) : nlohmann::json(std::vector<double>(v.data(), v.data() + v.size()));
    };
    report["plant"]["reclosed_simulation_fit_percent"] = list(r.reclosed_fit_percent);
  } else {
    report["fit"] = structured_report(r);
    if (o.open_loop) report["fit"]["feedthrough_reason"] = r.choices.feedthrough_reason;
    {
      report["fit"]["refinement_reason"] = r.choices.refinement_reason;
      // `fit` above is the structured fit; when the refinement is kept, the plant and
      // its bands are the refinement's, described here.
      const IdentifyChoices::Refinement& rf = r.choices.refinement;
      report["refinement"] =
          rf.ran ? nlohmann::json{{"kept", rf.kept},
                                  {"initial_states_fitted", rf.initial_states_fitted},
                                  {"start_cost", rf.start_cost},
                                  {"cost", rf.cost},
                                  {"iterations", rf.iterations},
                                  {"parameters", rf.parameters},
                                  {"residuals", rf.residuals},
                                  {"replicates", rf.replicates},
                                  {"form", rf.form},
                                  {"poles_on_bound", rf.poles_on_bound},
                                  {"reason", r.choices.refinement_reason}}
                 : nlohmann::json(nullptr);
      const IdentifyChoices::HeldOutOrder& h = r.choices.held_out;
      nlohmann::json rows = nlohmann::json::array();
      for (const auto& row : h.rows)
        rows.push_back(row.ok ? nlohmann::json{{"order", row.order}, {"fit_percent", row.fit_percent}, {"cost", row.cost}}
                              : nlohmann::json{{"order", row.order}, {"failure", row.failure}});
      report["held_out_order"] = h.reason.empty() ? nlohmann::json(nullptr)
                                                  : nlohmann::json{{"ran", h.ran},
                                                                   {"ladder_order", h.ladder_order},
                                                                   {"chosen_order", h.chosen_order},
                                                                   {"orders", rows},
                                                                   {"reason", h.reason}};
    }
    // where the plant (and its bands) come from: one place
    const bool refined = r.choices.refinement.kept;
    report["plant"]["source"] = refined ? "output-error refinement (report.refinement)" : "structured fit (report.fit)";
    report["plant"]["termination"] = r.fit.report.termination;
  }
}

// report.json (the support of the plant's band is added by identify_bode).
nlohmann::json identify_report(const IdentifyCliOptions& o, const IdentifyRoute& route, const IdentifyInputs& in,
                               const IdentifyResult& r) {
  const bool era = route.era;
  const ExperimentSet& set = in.set;
  const double Ts = set.sample_period_s;
  nlohmann::json report = {
      {"logs", set.paths},
      {"log_findings", set.findings},
      {"controller", o.open_loop ? nlohmann::json(nullptr) : nlohmann::json(o.controller)},
      {"route", o.open_loop            ? "open loop: the excitation is the plant's input (C = 0, G = P)"
                : route.at_reference ? "closed loop with the known controller, excited at the reference (v = C r)"
                                     : "closed loop with the known controller"},
      {"excitation_at", o.open_loop ? "input" : o.excitation_at},
      {"loop_inputs", in.loop_inputs},
      {"sample_period_s", Ts},
      {"excitation", route.excitation},
      {"output", route.output},
      {"method", era ? "era" : "structured"},
      {"markov",
       {{"lags", r.num_lags},
        {"horizon_s", static_cast<double>(r.num_lags) * Ts},
        {"horizon_reason", era ? std::string(o.lags > 0 || o.horizon_s > 0 ? "given" : "the paper's 2 s")
                               : r.choices.horizon_reason},
        {"iterations", r.markov.iterations},
        {"samples", r.markov.total_samples},
        {"termination", r.markov.report.termination}}},
      {"closed_loop",
       {{"order", r.closed_loop.order()},
        {"stable", is_stable(r.closed_loop)},
        {"poles", poles_json(r.closed_loop)},
        {"markov_fit_percent", matrix_json(markov_fit_percent(r.closed_loop, r.markov.g))},
        {"simulation_fit_percent", simulation_fit_json(r.closed_loop, set, false)},
        {"simulation_fit_initial_state_percent", simulation_fit_json(r.closed_loop, set, true)},
        {"nonlinearity", nonlinearity_json(nonlinearity_on_logs(r.closed_loop, set), route.output)}}},
      {"plant",
       {{"order", r.plant.order()}, {"stable", is_stable(r.plant)}, {"poles", poles_json(r.plant)}}},
      {"warnings", r.warnings},
  };
  add_identify_method_report(report, o, r, era);
  const Eigen::VectorXd band = log_frequency_grid(o.band_min, o.band_max, 200);
  if (in.truth) {
    const StateSpace& truth = *in.truth;
    if (truth.num_inputs() != r.plant.num_inputs() || truth.num_outputs() != r.plant.num_outputs())
      throw InputError(fmt::format("--truth {} is {}x{} but the identified plant is {}x{}; give the true plant of these outputs and inputs", o.truth,
                                   truth.num_outputs(), truth.num_inputs(), r.plant.num_outputs(),
                                   r.plant.num_inputs()));
    const auto est = evaluate_response(r.plant, band);
    const auto ref = evaluate_response(truth, band);
    const ErrorSummary e = weighted_error_over(est, ref, band, in.weights, in.weights);
    report["truth"] = {{"model", o.truth},
                       {"band_rad_s", {o.band_min, o.band_max}},
                       {"weights", std::vector<double>(in.weights.data(), in.weights.data() + in.weights.size())},
                       {"weighted_error_mean", e.mean},
                       {"weighted_error_max", e.max},
                       {"omega_at_max_rad_s", e.omega_at_max_rad_s}};
  }
  return report;
}

// The plant's response with its variance, its band and what the data support (in the
// report), and bode.png drawn from them.
struct IdentifyBode {
  FrequencyResponse plant_frd;
  std::optional<BandSupport> support;
  std::vector<unsigned char> png;
};

// The band |Ĥ| ± kBandRadiusPerSigma σ (structured only): its edges drawn in bode.png, and
// what the data support written into the report.
void add_identify_band(IdentifyBode& b, std::vector<BodeSeries>& series, nlohmann::json& report,
                       const IdentifyCliOptions& o, const IdentifyResult& r, const Eigen::VectorXd& omega,
                       double nyquist) {
  FrequencyResponse& plant_frd = b.plant_frd;
  plant_frd.variance = plant_response_variance(r.fit, omega);
  if (r.feedthrough_variance.size() > 0)
    for (auto& v : plant_frd.variance) v += r.feedthrough_variance;
  FrequencyResponse upper = plant_frd, lower = plant_frd;
  upper.variance.clear();
  lower.variance.clear();
  for (std::size_t k = 0; k < plant_frd.response.size(); ++k) {
    const Eigen::MatrixXcd& H = plant_frd.response[k];
    for (Index i = 0; i < H.rows(); ++i)
      for (Index j = 0; j < H.cols(); ++j) {
        const double a = std::abs(H(i, j)), d = kBandRadiusPerSigma * std::sqrt(plant_frd.variance[k](i, j));
        const std::complex<double> unit = a > 0 ? H(i, j) / a : std::complex<double>(1.0, 0.0);
        upper.response[k](i, j) = unit * (a + d);
        // Where the band reaches zero its lower edge has no magnitude: a gap, not a plunge.
        lower.response[k](i, j) = a > d ? unit * (a - d) : std::complex<double>(std::numeric_limits<double>::quiet_NaN(), 0.0);
      }
  }
  // What the data support: within --band-min..--band-max when given; otherwise over the
  // plotted grid up to the top of the fitted band (beyond it the logs hold no signal
  // by construction; the default error band 1-400 rad/s may lie beyond the Nyquist
  // frequency of a log whose sample time is unknown).
  const double s_lo = o.band_given ? o.band_min : omega(0);
  const double s_hi = o.band_given ? o.band_max : std::min(0.999 * nyquist, r.choices.fit_band_max_rad_s);
  std::vector<Eigen::MatrixXcd> in_band;
  std::vector<Eigen::MatrixXd> var_in_band;
  std::vector<double> w_in_band;
  for (Index k = 0; k < omega.size(); ++k)
    if (omega(k) >= s_lo && omega(k) <= s_hi) {
      in_band.push_back(plant_frd.response[static_cast<std::size_t>(k)]);
      var_in_band.push_back(plant_frd.variance[static_cast<std::size_t>(k)]);
      w_in_band.push_back(omega(k));
    }
  if (!w_in_band.empty()) {
    b.support = band_support(in_band, var_in_band,
                             Eigen::Map<const Eigen::VectorXd>(w_in_band.data(), static_cast<Index>(w_in_band.size())),
                             kSupportThreshold);
    const BandSupport& support = *b.support;
    report["plant"]["support"] = {{"threshold", support.threshold},
                                  {"band_rad_s", {s_lo, s_hi}},
                                  {"points", support.points},
                                  {"supported", support.supported},
                                  {"lowest_supported_rad_s", support.lowest_supported_rad_s},
                                  {"highest_supported_rad_s", support.highest_supported_rad_s},
                                  {"worst_relative_band", support.worst_relative},
                                  {"omega_at_worst_rad_s", support.omega_at_worst_rad_s}};
  }
  series.push_back({std::string(kBandLevel) + " band (upper)", upper, BodeSeries::Style::kDashed, false});
  series.push_back({std::string(kBandLevel) + " band (lower)", lower, BodeSeries::Style::kDashed, false});
}

IdentifyBode identify_bode(nlohmann::json& report, const IdentifyCliOptions& o, const IdentifyRoute& route,
                           const IdentifyInputs& in, const IdentifyResult& r) {
  IdentifyBode b;
  // The plant's response with its variance (structured: the fit's covariance by the
  // delta method) on a log grid up to Nyquist: plant_frd.csv, and the band in bode.png.
  const double nyquist = M_PI / in.set.sample_period_s;
  // From 1 rad/s (or --band-min), but at least three decades below Nyquist: a log whose
  // sample time is unknown (t = sample index, Nyquist pi rad/s) has its dynamics below 1.
  const Eigen::VectorXd omega =
      log_frequency_grid(std::min({1.0, o.band_min, 1e-3 * nyquist}), 0.999 * nyquist, 400);
  b.plant_frd = frequency_response(r.plant, omega);
  std::vector<BodeSeries> series;
  series.push_back({"identified plant", b.plant_frd, BodeSeries::Style::kLine});
  if (!route.era) add_identify_band(b, series, report, o, r, omega, nyquist);
  if (in.truth) series.push_back({"true plant", frequency_response(*in.truth, omega), BodeSeries::Style::kDashed});
  BodePlotOptions bode;
  bode.title = fmt::format("Plant identified from {} experiment(s), order {}", in.set.paths.size(), r.plant.order());
  b.png = bode_png(series, bode);
  return b;
}

// Stages every file (the caller commits them together); returns the list of the
// files written, for the summary.
std::string stage_identify_outputs(OutputSet& files, const IdentifyCliOptions& o, const IdentifyRoute& route,
                                   const IdentifyInputs& in, const IdentifyResult& r, const IdentifyBode& b,
                                   const nlohmann::json& report) {
  const bool era = route.era;
  MarkovFile mf;
  mf.g = r.markov.g;
  mf.sample_period_s = in.set.sample_period_s;
  // The Markov parameters are of v -> q: under --excitation-at reference v = C r, so
  // the inputs are loop_inputs, not the reference columns.
  mf.inputs = in.loop_inputs;
  mf.outputs = route.output;
  mf.noise_std = r.markov.noise_std;
  mf.input_rms = r.markov.excitation_rms;
  mf.output_rms = r.markov.output_rms;
  const nlohmann::json provenance = {
      {"command", "lpvid identify"},
      {"logs", in.set.paths},
      {"controller", o.open_loop ? nlohmann::json("none (--open-loop)") : nlohmann::json(o.controller)}};
  files.stage(join_path(o.out, "markov.csv"), markov_csv_text(mf, join_path(o.out, "markov.csv")));
  std::string written = o.open_loop ? "plant.json, plant_frd.csv, markov.csv, bode.png, report.json"
                                    : "closed_loop.json, plant.json, plant_frd.csv, markov.csv, bode.png, report.json";
  if (era) {
    const auto& sel = r.era.selection;
    SingularValuePlotOptions svo;
    svo.count = std::min<Index>(20, sel.singular_values.size());
    svo.chosen_order = sel.order;
    svo.noise_floor = sel.noise_floor;
    svo.title = "Largest Hankel singular values of G (scaled channels)";
    const auto sv_bytes = singular_values_png(sel.singular_values, svo);
    Eigen::MatrixXd table(sel.singular_values.size(), 3);
    for (Index i = 0; i < table.rows(); ++i)
      table.row(i) << static_cast<double>(i + 1), sel.singular_values(i), sel.singular_values(i) > sel.noise_floor;
    write_table_csv(files.stage(join_path(o.out, "hankel_sv.csv")), {"index", "singular_value", "above_noise_floor"},
                    table, {"lpvid identify: Hankel singular values of G (scaled channels)", "rule: " + sel.reason});
    files.stage(join_path(o.out, "hankel_sv.png"),
                sv_bytes);
    written += ", hankel_sv.csv, hankel_sv.png";
  }
  write_frd_csv(files.stage(join_path(o.out, "plant_frd.csv")), b.plant_frd, "P",
                {"lpvid identify: identified plant u -> q",
                 era ? std::string("no variance: --method era has no covariance")
                     : r.choices.refinement.kept
                           ? fmt::format("var_<i>_<j>: E|P^ - P|^2 from the output-error refinement's covariance, a "
                                         "sandwich over {} record segments (delta method)",
                                         r.fit.replicates)
                     : r.fit.replicates > 0
                           ? fmt::format("var_<i>_<j>: E|P^ - P|^2 from the fit's covariance, a sandwich over {} "
                                         "replicates of the Markov estimate's error (delta method)",
                                         r.fit.replicates)
                           : std::string("var_<i>_<j>: E|P^ - P|^2 from the fit's covariance under its noise model "
                                         "(delta method; too few record segments for replicates)")});
  files.stage(join_path(o.out, "bode.png"), b.png);
  if (!o.open_loop)
    files.stage(join_path(o.out, "closed_loop.json"), state_space_to_json(r.closed_loop, {{"provenance", provenance}}));
  files.stage(join_path(o.out, "plant.json"), state_space_to_json(r.plant, {{"provenance", provenance}}));
  files.stage(join_path(o.out, "report.json"), json_text(report));
  return written;
}

// The summary printed after the files are published.
std::string identify_text(const IdentifyCliOptions& o, const IdentifyRoute& route, const IdentifyInputs& in,
                          const IdentifyResult& r, const std::optional<BandSupport>& support,
                          const std::optional<InstabilityEvidence>& instability, const nlohmann::json& report,
                          const std::string& written) {
  const bool era = route.era;
  const auto& output = route.output;
  const double Ts = in.set.sample_period_s;
  std::string text = fmt::format("identify ({}{}): {} experiment(s), Ts = {:.6g} s\n", era ? "era" : "structured",
                                 !in.direct.is_null() ? ", direct" : o.open_loop ? ", open loop" : "",
                                 in.set.paths.size(), Ts);
  if (!in.direct.is_null())
    text += fmt::format("  route: direct — {}; the plant fitted to {} and the outputs\n",
                        in.direct["why"].get<std::string>(), in.direct["input"].get<std::string>());
  if (!in.direct.is_null() && !in.direct["friction"].is_null())
    text += "  friction: " + in.direct["friction"]["sentence"].get<std::string>() + "\n";
  if (era) {
    text += fmt::format("  horizon: {} lags ({:.4g} s)\n  closed loop: order {} ({})\n  plant: order {} ({} modes removed), {}\n",
                        r.num_lags, static_cast<double>(r.num_lags) * Ts, r.closed_loop.order(), r.era.selection.reason,
                        r.plant.order(), r.unloop.removed_poles.size(), is_stable(r.plant) ? "stable" : "UNSTABLE");
    if (!r.reclosed_reason.empty()) text += "  plant in its loop: " + r.reclosed_reason + "\n";
  } else {
    const IdentifyChoices& ch = r.choices;
    if (route.at_reference)
      text += fmt::format("  excitation at the reference: v = C (r - r°), the controller's response to {} about its "
                          "operating point r° (the first setpoint if the log starts at rest there, else the mean), "
                          "is the plant-input excitation (e = r - q)\n",
                          fmt::join(route.excitation, ","));
    text += fmt::format("  excitation: {}\n", ch.excitation_reason);
    text += fmt::format("  {}\n  fit band: {}\n  start: {}\n  plant order {}: {}\n  tail: {}\n  bands: {}\n  plant: {}, "
                        "{}\n",
                        ch.horizon_reason, ch.band_reason, ch.start_reason, ch.plant_order, ch.order_reason,
                        ch.tail_reason, ch.bands_reason, stability_words(instability, support),
                        o.open_loop ? "open loop" : "closed loop stable");
    if (o.open_loop) text += "  feedthrough: " + ch.feedthrough_reason + "\n";
    text += "  refinement: " + ch.refinement_reason + "\n";
    if (o.open_loop && !ch.held_out.reason.empty()) text += "  order on held-out data: " + ch.held_out.reason + "\n";
    if (support)
      text += "  " + support_sentence(*support, report["plant"]["support"]["band_rad_s"][0].get<double>(),
                                      report["plant"]["support"]["band_rad_s"][1].get<double>(), o.open_loop) +
              "\n";
  }
  {
    const nlohmann::json& sim = report["closed_loop"]["simulation_fit_percent"];
    const nlohmann::json& sim_e = report["closed_loop"]["simulation_fit_initial_state_percent"];
    std::vector<std::string> figures;
    for (std::size_t i = 0; i < output.size() && !sim.is_null(); ++i)
      figures.push_back(fmt::format("{} {:.1f} %", output[i], sim[i].get<double>()));
    std::vector<std::string> figures_e;
    for (std::size_t i = 0; i < output.size() && !sim_e.is_null(); ++i)
      figures_e.push_back(fmt::format("{} {:.1f} %", output[i], sim_e[i].get<double>()));
    text += sim.is_null() ? std::string("  simulation fit on the logs: the model's response diverges\n")
                          : fmt::format("  simulation fit on the logs ({}, from zero state): {}; with each log's "
                                        "initial state fitted: {}\n",
                                        o.open_loop ? "u -> y" : "v -> q", fmt::join(figures, ", "),
                                        fmt::join(figures_e, ", "));
    text += "  nonlinearity: " + report["closed_loop"]["nonlinearity"]["sentence"].get<std::string>() + "\n";
    if (!in.direct.is_null() && !in.direct["friction"].is_null())
      text += "  (the fits and the nonlinearity above are of the linear part's loop alone: the friction fitted beside "
              "it is what they miss)\n";
  }
  if (in.truth)
    text += fmt::format("  against {}: weighted error mean {:.3f} %, max {:.3f} % ({}-{} rad/s)\n", o.truth,
                        100 * report["truth"]["weighted_error_mean"].get<double>(),
                        100 * report["truth"]["weighted_error_max"].get<double>(), o.band_min, o.band_max);
  for (const auto& w : r.warnings) text += "warning: " + w + "\n";
  text += fmt::format("  wrote {}/{{{}}}\n", o.out, written);
  return text;
}

// The direct route (issue 24: a closed loop exercised by point-to-point moves, or logged
// with the drive's command as its "excitation"): when the route through the loop's
// response finds no plant, the plant is fitted where such logs determine it (direct.h).
// References: low-order starts fitted to the input the loop applied, u = C(r - q), and q,
// each refined by output error in its loop (simulated from v, so the output noise the
// feedback returns to u does not bias it).  An input-side excitation: the columns read
// as the plant's own input (a drive's logged command: v is u), fitted as open-loop data
// (D = 0) and kept when the plant closes a stable loop with the controller.  Said so in
// the report; no plant: the closed-loop route's failure stands, with what the direct
// route found.
// The friction the direct route fitted beside the plant (direct.h DirectFriction), in
// the plant input's units, and a sentence for the summary.
nlohmann::json friction_json(const DirectFriction& f, const std::vector<std::string>& inputs,
                             const std::vector<std::string>& outputs) {
  std::vector<std::string> parts;
  for (Index i = 0; i < f.coulomb.rows(); ++i) {
    const std::string in = i < static_cast<Index>(inputs.size()) ? inputs[static_cast<std::size_t>(i)]
                                                                  : fmt::format("u{}", i + 1);
    for (Index j = 0; j < f.coulomb.cols(); ++j) {
      if (f.coulomb.size() > 1 && i != j) continue;  // the diagonal: each input's own axis
      const std::string out = j < static_cast<Index>(outputs.size()) ? outputs[static_cast<std::size_t>(j)]
                                                                      : fmt::format("y{}", j + 1);
      const double c = f.coulomb(i, j);
      parts.push_back(fmt::format("{:.4g} on {} {} {}'s motion", std::abs(c), in, c < 0 ? "against" : "WITH", out));
    }
  }
  nlohmann::json coulomb = nlohmann::json::array();
  for (Index i = 0; i < f.coulomb.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (Index j = 0; j < f.coulomb.cols(); ++j) row.push_back(f.coulomb(i, j));
    coulomb.push_back(row);
  }
  return {{"coulomb", coulomb},
          {"sentence",
           fmt::format("the linear plant's residual followed the sign of the velocity, so the plant was fitted with "
                       "friction beside it (Coulomb-like and a constant force while it moves; the rests, where a stuck "
                       "axis holds whatever balances it, left out): {} (forces at the input, in its units); the plant is "
                       "the linear part; the constant force is not given: the logs cannot tell it from the encoder's "
                       "offset (for the offset as a parameter, fit the physics with `fit --log`)",
                       fmt::join(parts, ", "))}};
}

IdentifyResult identify_direct(IdentifyCliOptions& o, IdentifyRoute& route, IdentifyInputs& in,
                               const std::string& failure) {
  const StateSpace& C = in.controller;
  // One reading per way the excitation enters: references — the loop as declared, u =
  // C(r - q), refined in its loop; an input-side column — the plant's own input (a
  // drive's command), refined as open-loop data.  The declared input-side loop (u = v +
  // C(-q)) is not fitted: where the route through the loop's response fails on such
  // logs, a linear fit of it can still close a stable loop — measured on a friction axis
  // whose drive command was given as the excitation: an order-3 plant with a pole at
  // +1150 rad/s, 100 % off the axis, bands "supported" — where the refusal was the honest
  // answer.
  const bool in_loop = route.at_reference;
  const std::string name = in_loop ? "applied" : "excitation is the input";
  const std::string sentence =
      in_loop ? "u = C(r - q), the input the loop applied"
              : "u = v, the excitation columns as the plant's own input (a drive's logged command)";
  IdentifyInputs data = in;
  if (in_loop) {
    data.loop_inputs.clear();
    for (Index j = 0; j < C.num_outputs(); ++j)
      data.loop_inputs.push_back(C.output_names.size() == static_cast<std::size_t>(C.num_outputs())
                                     ? C.output_names[static_cast<std::size_t>(j)]
                                     : fmt::format("u{}", j + 1));
    for (std::size_t e = 0; e < in.set.outputs.size(); ++e)
      data.set.excitations[e] =
          applied_plant_input(C, Eigen::MatrixXd(0, 0), in.references[e], in.set.outputs[e]);
  }
  // The Markov estimate and the report's fields from the open-loop route on (u, q),
  // unrefined; the plant from the ARX ladder (direct.h).
  IdentifyCliOptions oo = o;
  oo.open_loop = true;
  IdentifyRoute rr = route;
  rr.at_reference = false;
  rr.options.open_loop_feedthrough = false;
  rr.excitation = data.loop_inputs;
  IdentifyRoute base_route = rr;
  base_route.options.refine_output_error = false;
  base_route.options.check_order_held_out = false;
  std::string outcome;
  nlohmann::json friction;  // null: the plant alone
  std::string friction_tried;  // why friction was sought and not found
  std::optional<IdentifyResult> r;
  try {
    IdentifyResult base = identify_from_logs(oo, base_route, data);
    const IdentifyResult unfitted = base;
    const std::vector<ExperimentView> loop = in_loop ? in.set.views() : std::vector<ExperimentView>{};
    DirectLadder ladder =
        identify_direct_in_loop(loop, data.set.views(), in.set.sample_period_s, C, kDirectMaxOrder, base);
    // Friction: when the linear plant's residual follows the sign of the velocity (the
    // test of the summary's nonlinearity line, judged over record segments), the ladder
    // again with friction beside the plant, up to the linear one's order (direct.h).
    // When no linear plant closes a stable loop, with friction too (up to the largest order).
    bool flips = !ladder.found;
    if (ladder.found) {
      const NonlinearityResult nl = nonlinearity_on_logs(base.closed_loop, in_loop ? in.set : data.set);
      flips = std::any_of(nl.significant.begin(), nl.significant.end(), [&](Index i) {
        return nl.tests[static_cast<std::size_t>(i)].feature == "sign of the rate";
      });
    }
    if (flips) {
      IdentifyResult with = unfitted;
      const DirectLadder lf = identify_direct_in_loop(loop, data.set.views(), in.set.sample_period_s, C,
                                                      ladder.found ? ladder.arx_order : kDirectMaxOrder, with, true);
      if (lf.found) {
        base = std::move(with);
        ladder = lf;
      } else if (ladder.found) {
        friction_tried = fmt::format("the residual follows the sign of the velocity, and no plant with friction "
                                     "beside it was found ({}): the plant is the best linear approximation",
                                     lf.reason);
      } else {
        ladder.reason += fmt::format("; nor with friction beside the plant: {}", lf.reason);
      }
    }
    if (ladder.found) {
      r = std::move(base);
      outcome = fmt::format("{}: order {} refined {}, normalised squared simulation error {:.4g}", sentence,
                            r->plant.order(), in_loop ? "in its loop" : "as open-loop data",
                            r->choices.refinement.cost);
      if (ladder.friction) {
        friction = friction_json(*ladder.friction, data.loop_inputs, route.output);
        outcome += "; " + friction["sentence"].get<std::string>();
      } else if (!friction_tried.empty()) {
        outcome += "; " + friction_tried;
      }
    } else {
      outcome = fmt::format("{}: {}", sentence, ladder.reason);
    }
  } catch (const NumericalError& e) {
    outcome = fmt::format("{}: no plant ({})", sentence, e.what());
  }
  if (!r)
    throw NumericalError(fmt::format("{}; nor did the direct route (the plant fitted to the input the loop applied): {}",
                                     failure, outcome));
  if (in_loop) {  // reported inside its loop, on the loop's own data
    r->closed_loop.input_names = in.loop_inputs;
    r->closed_loop.output_names = route.output;
  } else {
    in = std::move(data);
    o = oo;
    route = rr;
  }
  in.direct = {{"why", "the route through the loop's response found no plant: " + failure},
               {"reading", name},
               {"input", sentence},
               {"readings", {outcome}},
               {"friction", friction}};
  r->warnings.push_back(
      fmt::format("identify: the closed-loop route found no plant; the direct route took {} ({})", sentence, outcome));
  return std::move(*r);
}

void run(const IdentifyCliOptions& given) {
  IdentifyCliOptions o = given;
  IdentifyRoute route = identify_route(o);
  OutputSet outputs;
  check_identify_outputs(outputs, o);
  IdentifyInputs in = read_identify_inputs(o, route);
  IdentifyResult r;
  try {
    r = identify_from_logs(o, route, in);
  } catch (const NumericalError& e) {
    if (route.era || o.open_loop || o.no_direct) throw;
    r = identify_direct(o, route, in, e.what());
  }
  nlohmann::json report = identify_report(o, route, in, r);
  if (!in.direct.is_null()) {
    report["route"] = "direct: the closed-loop route found no plant; the plant from the input the loop applied";
    report["controller"] = given.controller;
    report["direct"] = in.direct;
  }
  const IdentifyBode bode = identify_bode(report, o, route, in, r);
  const std::optional<InstabilityEvidence> instability = instability_of(r.plant, bode.support);
  add_instability(report, instability);

  // Every computation succeeded: now write, each file atomically.  All files are staged
  // and renamed into place together at the end: a failure while writing leaves none of them.
  const std::string written = stage_identify_outputs(outputs, o, route, in, r, bode, report);
  outputs.commit();
  print_log_findings(in.set);
  print_summary(o.json, report, identify_text(o, route, in, r, bode.support, instability, report, written));
}

}  // namespace

Command make_identify_command() {
  return {"identify", "the whole chain: logs -> closed loop -> plant -> Bode", [](CLI::App& parent) {
            auto o = std::make_shared<IdentifyCliOptions>();
            auto* app = parent.add_subcommand(
                "identify", "Closed-loop identification from logs to plant model and Bode plot" + std::string(kIdentifyExample));
            app->add_option("logs", o->logs, "logs (CSV or .mat), one experiment each")->required();
            app->add_option("--controller", o->controller,
                                               "the controller that ran (state-space or transfer-function JSON); "
                                               "closed-loop logs");
            app->add_flag("--open-loop", o->open_loop,
                          "open-loop logs: the excitation is the plant's input (no controller; the plant is fitted "
                          "to the logs directly)");
            app->add_option("--excitation", o->excitation, "excitation columns v (comma separated)")->required();
            app->add_option("--excitation-at", o->excitation_at,
                            "input (default: v added to the plant's input, u = u_c + v) or reference (the excitation "
                            "columns are setpoints r, one per output, e = r - q)");
            app->add_option("--output", o->output, "measured output columns q (comma separated)")->required();
            add_log_layout_options(app, &o->layout);
            app->add_option("--out", o->out, "output directory")->required();
            app->add_option("--method", o->method,
                            "structured (default: the plant fitted with the known controller, every setting from the "
                            "data, with bands) or era (the paper's recipe: Markov, ERA, unloop)");
            app->add_option("--lags", o->lags, "Markov lags (default: from the data; era: --horizon-s / Ts, at most N/4)")
                ->check(integer_in(10, kMaxLags, "the number of Markov lags"));
            app->add_option("--horizon-s", o->horizon_s, "impulse-response length in seconds (default: from the data; era: 2 s)")
                ->check(positive_up_to(kMaxHorizonS, "the impulse-response length in s"));
            app->add_option("--order", o->order, "era: closed-loop order (default: automatic)")
                ->check(integer_in(1, kMaxModelStates, "the closed-loop order"));
            app->add_option("--plant-order", o->plant_order,
                            "plant order (default: structured from the data; era closed-loop minus controller)")
                ->check(integer_in(1, kMaxModelStates, "the plant order"));
            app->add_option("--fit-band-max", o->fit_band_max,
                            "structured: upper edge of the fitted band in rad/s (default: from the data)")
                ->check(positive_up_to(1e9, "the upper edge of the fitted band in rad/s"));
            app->add_option("--truth", o->truth, "a known plant to compare with (state-space JSON)");
            app->add_option("--error-weights", o->weights,
                            "output weights W for the error |W(P^-P)W| / |WPW| (comma separated, default 1)");
            app->add_option("--band-min", o->band_min, "lower end of the error band, rad/s")
                ->check(positive_up_to(kMaxFrequency, "the lower end of the band in rad/s"));
            app->add_option("--band-max", o->band_max, "upper end of the error band, rad/s")
                ->check(positive_up_to(kMaxFrequency, "the upper end of the band in rad/s"));
            app->add_flag("--json", o->json, "print the report as JSON");
            app->add_flag("--no-refine", o->no_refine,
                          "structured: keep the structured fit (no output-error refinement on the logs)");
            app->add_option("--initial-state", o->initial_state,
                            "the refinement's initial states: auto (default: each log's fitted where Akaike's "
                            "criterion says it pays), zero (the records start from rest; the model that simulates "
                            "best from zero state) or estimate (always fitted)");
            app->add_flag("--no-direct", o->no_direct,
                          "closed loop, structured: when no plant fits through the loop's response, fail instead of "
                          "taking the direct route (docs/math.md section 2b)");
            app->add_flag("--no-order-check", o->no_order_check,
                          "open loop, structured, refined: keep the ladder's order (do not check orders n-2..n+2 on "
                          "held-out halves of the logs)");
            app->callback([o, app] {
              o->band_given = app->count("--band-min") + app->count("--band-max") > 0;
              run(*o);
            });
          }};
}

}  // namespace lpvid::cli
