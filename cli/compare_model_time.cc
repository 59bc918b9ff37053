// lpvid compare --log RUN --model M.json, M a state-space or transfer-function model
// (identify's plant.json, realize's or unloop's output, a model a user wrote): any
// black-box model judged on any log, as MATLAB's compare and resid do it.
//
//   open loop (no --controller):  ŷ = M u, u the logged plant input (--input);
//   closed loop (--controller C): ŷ = M (I + C M)⁻¹ v, v the logged excitation at the
//     plant input (--excitation), or v = C (r − r°) from the logged references
//     (--excitation-at reference, as identify).
//
// Both simulated from x(0) = 0 ('z') and from the x(0) that fits the log best ('e',
// compare's default), each with a fitted constant per output (a sensor offset):
// idlib/identify/output_error.h simulate_with_fitted_start.  The residual tests,
// failing windows and overlay are those of the platform's time compare
// (idlib/validate/time_fit.h) on the 'e' prediction.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/responses.h"
#include "formats/io/csv_log.h"
#include "formats/io/model_json.h"
#include "formats/plot/canvas.h"
#include "formats/plot/time_plot.h"
#include "idlib/core/error.h"
#include "idlib/identify/identify.h"
#include "idlib/identify/output_error.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/interconnect.h"
#include "idlib/validate/nonlinearity.h"
#include "idlib/validate/time_fit.h"

namespace lpvid::cli {
namespace compare_model_time {

// The figure shows at most this many outputs (the lowest fits): a panel pair per output
// is readable up to here; a 28-output log would be a 56-panel strip.
constexpr std::size_t kMaxPlottedOutputs = 6;
// The failing windows' default length: a twentieth of the record, at least this many
// samples (the window's rms must average over more than a few noise samples).
constexpr Index kMinWindowSamples = 20;

nlohmann::json per_output(const std::vector<std::string>& names, const Eigen::VectorXd& v) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t i = 0; i < names.size(); ++i)
    j[names[i]] = v.size() > 0 && std::isfinite(v(static_cast<Index>(i))) ? nlohmann::json(v(static_cast<Index>(i)))
                                                                          : nlohmann::json(nullptr);
  return j;
}

std::vector<unsigned char> overlay_png(const Eigen::VectorXd& t, const Eigen::MatrixXd& measured,
                                       const Eigen::MatrixXd& predicted, const TimeFitResult& r,
                                       const std::vector<std::string>& names, const std::string& title) {
  // The outputs drawn: all, or the kMaxPlottedOutputs with the lowest fit, in log order.
  std::vector<Index> shown(static_cast<std::size_t>(measured.cols()));
  std::iota(shown.begin(), shown.end(), Index{0});
  if (shown.size() > kMaxPlottedOutputs) {
    std::stable_sort(shown.begin(), shown.end(), [&](Index a, Index b) { return r.fit_percent(a) < r.fit_percent(b); });
    shown.resize(kMaxPlottedOutputs);
    std::sort(shown.begin(), shown.end());
  }
  const Index k = static_cast<Index>(shown.size()), N = t.size();
  FitOverlay ov;
  ov.t_s = t;
  ov.measured.resize(N, k);
  ov.predicted.resize(N, k);
  ov.residual.resize(N, k);
  for (Index c = 0; c < k; ++c) {
    const Index i = shown[static_cast<std::size_t>(c)];
    ov.measured.col(c) = measured.col(i);
    ov.predicted.col(c) = predicted.col(i);
    ov.residual.col(c) = r.residual.col(i);
    ov.value_labels.push_back(fmt::format("{} (fit {:.1f} %)", names[static_cast<std::size_t>(i)], r.fit_percent(i)));
    ov.residual_labels.push_back(names[static_cast<std::size_t>(i)] + " residual");
  }
  for (const auto& w : r.failures) {
    const auto at = std::find(shown.begin(), shown.end(), w.channel);
    if (at != shown.end()) ov.failures.push_back({static_cast<std::size_t>(at - shown.begin()), w.t_start_s, w.t_end_s});
  }
  ov.title = measured.cols() > k ? fmt::format("{} ({} of {} outputs: the lowest fits)", title, k, measured.cols())
                                 : title;
  return fit_overlay_png(ov);
}

// The log's columns for the model's channels: the names given on the command line, or
// the model's own (identify writes them).
std::vector<std::string> channel_columns(const std::string& given, const std::string& flag,
                                         const std::vector<std::string>& model_names, Index count,
                                         const std::string& what, const std::string& model_path) {
  if (given.empty()) {
    if (model_names.empty())
      throw InputError(fmt::format("{}: the model names no {}s; give {} NAME[,NAME...] (the log's column for each of "
                                   "the model's {} {}s, in order)",
                                   model_path, what, flag, count, what));
    return model_names;
  }
  std::vector<std::string> names = split_names(given, flag);
  if (static_cast<Index>(names.size()) != count)
    throw InputError(fmt::format("{} names {} column(s) but the model {} has {} {}(s); give one log column per model "
                                 "{}, in order",
                                 flag, names.size(), model_path, count, what, what));
  return names;
}

void check_model_compare_flags(const TimeCompareCliOptions& o) {
  if (!o.overrides.empty() || o.substeps != 1)
    throw InputError("compare --log with a state-space model: --set and --substeps are for the platform's physical "
                     "model; edit or re-identify the model instead");
  const bool closed = !o.controller.empty();
  const bool at_reference = o.excitation_at == "reference";
  if (!at_reference && o.excitation_at != "input")
    throw InputError(fmt::format("--excitation-at {}: use 'input' (default: the excitation is added to the plant's "
                                 "input) or 'reference' (the excitation columns are the loop's setpoints)",
                                 o.excitation_at));
  if (!closed && !o.excitation.empty())
    throw InputError("compare --log: --excitation is the closed loop's (with --controller C.json); for an open-loop "
                     "log give the plant's input columns with --input (default: the model's input names)");
  if (!closed && at_reference)
    throw InputError("compare --log: --excitation-at reference needs the loop's controller; give --controller C.json");
  if (closed && o.excitation.empty())
    throw InputError("compare --log with --controller: give --excitation NAME[,NAME...], the log's excitation columns "
                     "(added at the plant's input, or the setpoints with --excitation-at reference)");
}

// One compare of a model with a log, filled stage by stage.
struct ModelTimeCompare {
  bool closed = false, at_reference = false;
  StateSpace model;  // at the log's rate
  Log log;
  double Ts = 0;
  Index N = 0;
  std::string sampling;  // how a continuous model was sampled (empty: it was discrete)
  std::vector<std::string> out_names;
  Eigen::MatrixXd y;
  // What is simulated, from what, and what the residual is tested against.
  StateSpace simulated;
  Eigen::MatrixXd sim_input, cross_input, plant_input;
  std::vector<std::string> cross_names, in_names;
  std::string route;
  // The model's stability and its simulations.
  double radius = 0;
  bool stable = false, growing = false;
  std::string stability;
  SimulatedOutput with_x0, from_rest;
  Eigen::MatrixXd test_predicted;
  std::string tested_on;
  // The residual tests.
  TimeFitOptions fo;
  Eigen::VectorXd t;
  TimeFitResult r;
  Eigen::VectorXd fit_zero;
  NonlinearityResult nonlinear;  // on the simulation's residual (idlib/validate/nonlinearity.h)
};

// The model at the log's rate and the log's outputs.
void read_model_and_log(ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  c.model = read_state_space(o.params);
  c.log = read_log(o.log, o.layout.read_options());
  c.Ts = c.log.sample_period_s;
  c.N = c.log.num_samples();
  const double Ts = c.Ts;
  if (!c.model.is_discrete()) {
    c.model = discretize_zoh(c.model, Ts);
    c.sampling = fmt::format("a continuous model, sampled here with a zero-order hold at the log's {:.6g} s", Ts);
  } else if (std::abs(c.model.sample_period_s - Ts) > 1e-6 * Ts) {
    throw InputError(fmt::format("{}: the model samples at {:.6g} s but the log '{}' at {:.6g} s; give a model of the "
                                 "log's rate (or a continuous one, which compare samples with a zero-order hold)",
                                 o.params, c.model.sample_period_s, o.log, Ts));
  }
  c.out_names = channel_columns(o.output, "--output", c.model.output_names, c.model.num_outputs(), "output", o.params);
  c.y = c.log.columns(c.out_names);
}

// What is simulated, from what, and what the residual is tested against.
void model_compare_route(ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  const StateSpace& model = c.model;
  const Log& log = c.log;
  const Index m = model.num_inputs(), p = model.num_outputs();
  c.simulated = model;
  if (!c.closed) {
    c.in_names = channel_columns(o.input, "--input", model.input_names, m, "input", o.params);
    c.sim_input = log.columns(c.in_names);
    c.cross_input = c.sim_input;
    c.cross_names = c.in_names;
    c.route = fmt::format("open loop: the model simulated from the logged input {}", fmt::join(c.in_names, ","));
  } else {
    const StateSpace controller = read_controller(o.controller);
    c.cross_names = split_names(o.excitation, "--excitation");
    check_controller_matches(controller, c.Ts, p,
                             c.at_reference ? controller.num_outputs() : static_cast<Index>(c.cross_names.size()),
                             1e-6);
    if (controller.num_outputs() != m || controller.num_inputs() != p)
      throw InputError(fmt::format("{}: the controller maps {} error(s) to {} input(s) but the model {} has {} input(s) "
                                   "and {} output(s); give the controller of the loop the model's plant ran in",
                                   o.controller, controller.num_inputs(), controller.num_outputs(), o.params, m, p));
    c.cross_input = log.columns(c.cross_names);
    c.sim_input = c.at_reference ? reference_as_input_excitation(controller, c.cross_input) : c.cross_input;
    c.simulated = closed_loop_output(model, controller);
    c.route = fmt::format("closed loop with {}: the model's loop simulated from the logged {} {}", o.controller,
                          c.at_reference ? "references" : "excitation", fmt::join(c.cross_names, ","));
    if (!o.input.empty()) {
      c.in_names = channel_columns(o.input, "--input", model.input_names, m, "input", o.params);
      c.plant_input = log.columns(c.in_names);
    }
  }
}

// The model's stability, its simulations from rest and from the fitted start, and the
// prediction the residual tests judge.
void simulate_model_on_log(ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  const bool closed = c.closed;
  const Eigen::VectorXcd eig = poles(c.model);
  c.radius = eig.size() > 0 ? eig.cwiseAbs().maxCoeff() : 0.0;
  c.stable = is_stable(c.model);
  // An integrator (|z| = 1, to rounding) is simulated from a logged input as it is; only a
  // growing mode makes a simulation outside the loop meaningless.
  c.growing = c.radius > 1.0 + 1e-9;
  c.stability =
      c.stable ? "stable"
             : c.growing ? fmt::format("UNSTABLE: largest pole |z| = {:.6g}", c.radius)
                         : "marginally stable: a pole on the unit circle (an integrator)";
  if (closed) {
    // The log is of a loop that ran stable: a model whose loop with the controller grows
    // (by more than 2x over the log) is wrong for it, and its simulation would print
    // figures of 1e+60 % (the levitated platform's unlooped ERA plant did).
    const Eigen::VectorXcd loop = poles(c.simulated);
    const double loop_radius = loop.size() > 0 ? loop.cwiseAbs().maxCoeff() : 0.0;
    if (loop_radius > 1.0 && static_cast<double>(c.N) * std::log(loop_radius) > std::log(2.0))
      throw InputError(fmt::format(
          "{}: the model's loop with {} is unstable (largest closed-loop pole |z| = {:.9g}: it grows {:.3g}x over the "
          "log's {} samples) while the log '{}' is of a loop that ran stable, so there is nothing to compare: the model "
          "is wrong for this loop (or check that the controller is the one that ran and its sign, u = C(-q) + v)",
          o.params, o.controller, loop_radius, std::exp(std::min(700.0, static_cast<double>(c.N) * std::log(loop_radius))),
          c.N, o.log));
  }
  c.with_x0 = simulate_with_fitted_start(c.simulated, c.sim_input, c.y, true);
  c.from_rest = simulate_with_fitted_start(c.simulated, c.sim_input, c.y, false);
  if (c.with_x0.predicted.size() == 0 || c.from_rest.predicted.size() == 0)
    throw InputError(fmt::format(
        "{}: the {} diverges on the log '{}' ({} samples; the model's largest pole |z| = {:.6g}), so there is nothing "
        "to compare; {}",
        o.params, closed ? "model's closed loop with the controller" : "model", o.log, c.N, c.radius,
        closed ? "check that the controller is the one that ran and its sign (u = C(-q) + v)"
               : "an unstable plant can only be simulated in its loop: give --controller C.json and --excitation"));

  // The residual tests: in closed loop on the open-loop prediction from the logged plant
  // input when it is given and the plant can be simulated alone (a correct model then
  // leaves the sensor noise alone, white); otherwise on the simulation's residual.
  c.tested_on = closed ? "the closed-loop simulation's residual (the noise fed back through the loop is "
                         "coloured: whiteness is not expected; the cross test with the excitation judges)"
                       : "the simulation's residual";
  if (closed && c.plant_input.size() > 0) {
    const SimulatedOutput open = simulate_with_fitted_start(c.model, c.plant_input, c.y, true);
    if (!c.growing && open.predicted.size() > 0) {
      c.test_predicted = open.predicted;
      c.tested_on = fmt::format("the open-loop prediction from the logged plant input {} (a correct model leaves the "
                                "sensor noise alone)",
                                fmt::join(c.in_names, ","));
    } else {
      c.tested_on += "; --input not used: the plant is unstable, so it cannot be simulated outside its loop";
    }
  }
}

void model_compare_residual_tests(ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  TimeFitOptions& fo = c.fo;
  const Index N = c.N;
  fo.max_lag = o.max_lag;
  fo.window_threshold_percent = o.threshold_percent;
  fo.window_s = o.window_s > 0 ? o.window_s : static_cast<double>(std::max(kMinWindowSamples, N / 20)) * c.Ts;
  fo.validate();
  if (N < fo.max_lag + 2)
    throw InputError(fmt::format("{}: {} samples are too few for residual tests over {} lags; give --max-lag below {}",
                                 o.log, N, fo.max_lag, std::max<Index>(1, N - 2)));
  c.t = c.log.data.col(c.log.column("t"));
  c.r = time_fit(c.y, c.with_x0.predicted, c.cross_input, c.t(0), c.Ts, fo, c.test_predicted);
  c.fit_zero = nrmse_fit_percent(c.y, c.from_rest.predicted);
  c.nonlinear = nonlinearity_tests(c.y - c.with_x0.predicted, c.with_x0.predicted);
}

nlohmann::json model_compare_summary(const ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  const TimeFitResult& r = c.r;
  const auto& out_names = c.out_names;
  const auto& cross_names = c.cross_names;
  nlohmann::json white = nlohmann::json::array(), cross = nlohmann::json::array(), failures = nlohmann::json::array();
  for (const auto& w : r.whiteness) white.push_back(correlation_test_json(w, out_names, cross_names));
  for (const auto& x : r.cross) cross.push_back(correlation_test_json(x, out_names, cross_names));
  for (const auto& f : r.failures)
    failures.push_back({{"channel", out_names[static_cast<std::size_t>(f.channel)]},
                        {"t_start_s", f.t_start_s},
                        {"t_end_s", f.t_end_s},
                        {"size_percent", f.size_percent}});
  return {
      {"log", o.log},
      {"model", o.params},
      {"controller", c.closed ? nlohmann::json(o.controller) : nlohmann::json(nullptr)},
      {"route", c.route},
      {"sampling", c.sampling.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.sampling)},
      {"samples", c.N},
      {"sample_period_s", c.Ts},
      {"order", c.model.order()},
      {"stable", c.stable},
      {"stability", c.stability},
      {"largest_pole_magnitude", c.radius},
      {"outputs", out_names},
      {"inputs", c.closed ? cross_names : c.in_names},
      {"fit_percent", per_output(out_names, r.fit_percent)},
      {"fit_zero_state_percent", per_output(out_names, c.fit_zero)},
      {"output_offsets", per_output(out_names, c.with_x0.offsets)},
      {"noise_floor", per_output(out_names, r.noise_floor)},
      {"fit_ceiling_percent", per_output(out_names, r.fit_ceiling_percent)},
      {"prediction", "the model has no noise model (K = 0): its k-step prediction is its simulation, so the "
                     "prediction fit equals fit_percent"},
      {"residual_tests_on", c.tested_on},
      {"whiteness", white},
      {"cross_correlation", cross},
      {"failures", failures},
      {"nonlinearity", nonlinearity_json(c.nonlinear, out_names)},
      {"window_s", c.fo.window_s},
      {"threshold_percent", c.fo.window_threshold_percent}};
}

std::string model_compare_text(const ModelTimeCompare& c, const TimeCompareCliOptions& o) {
  const TimeFitResult& r = c.r;
  const TimeFitOptions& fo = c.fo;
  const auto& out_names = c.out_names;
  std::string text = fmt::format("compare {} with {} (time domain, {} samples every {:.6g} s; order {}, {})\n", o.log,
                                 o.params, c.N, c.Ts, c.model.order(), c.stability);
  text += fmt::format("  {}\n", c.route);
  if (!c.sampling.empty()) text += fmt::format("  {}\n", c.sampling);
  text += "  fit [%] from x(0) = 0 ('z') and with the initial state fitted ('e', compare's default), each with an offset per output:\n";
  text += fmt::format("  {:<12} {:>9} {:>9} {:>14}   whiteness (max |r|/bound at lag)\n", "output", "fit z", "fit e",
                      "noise allows");
  for (Index i = 0; i < c.model.num_outputs(); ++i) {
    const auto& w = r.whiteness[static_cast<std::size_t>(i)];
    text += fmt::format("  {:<12} {:9.2f} {:9.2f} {:14.2f}   {} ({:.2f} at lag {})\n",
                        out_names[static_cast<std::size_t>(i)], c.fit_zero(i), r.fit_percent(i),
                        r.fit_ceiling_percent(i),
                        w.pass ? "pass" : "FAIL", w.worst_ratio, w.worst_lag);
  }
  text += fmt::format("  residual tests on {}\n", c.tested_on);
  for (const auto& x : r.cross)
    if (!x.pass)
      text += fmt::format("  residual {} correlates with {}: max |r|/bound {:.2f} at lag {}{}\n",
                          out_names[static_cast<std::size_t>(x.channel)],
                          c.cross_names[static_cast<std::size_t>(x.input)],
                          x.worst_ratio, x.worst_lag,
                          x.worst_lag < 0 ? " (before the input: feedback, or a non-causal error)" : "");
  if (r.failures.empty()) {
    text += fmt::format("  no window of {:.6g} s with a residual above {} % of its output's rms\n", fo.window_s,
                        fo.window_threshold_percent);
  } else {
    text += fmt::format("  failing windows ({:.6g} s): output  t_start [s]  t_end [s]  size [%]\n", fo.window_s);
    for (const auto& f : r.failures)
      text += fmt::format("                   {:<7} {:11.6g} {:10.6g} {:9.1f}\n",
                          out_names[static_cast<std::size_t>(f.channel)], f.t_start_s, f.t_end_s, f.size_percent);
  }
  text += "  nonlinearity: " + nonlinearity_sentence(c.nonlinear, out_names) + "\n";
  text += "  (no noise model: the prediction fit equals the simulation fit 'e')\n";
  if (c.growing && !c.closed)
    text += "  the model is unstable: simulated outside its loop it runs away from the log; if the log is of a closed "
            "loop, give --controller C.json and --excitation\n";
  return text;
}

}  // namespace compare_model_time

void run_model_time_compare(const TimeCompareCliOptions& o, const std::string& out_json, bool json) {
  using namespace compare_model_time;
  OutputSet out;  // nothing is read before every output is checked
  out.input(o.log);
  out.input(o.params);
  out.input(o.controller);
  out.file("--out-png", o.out_png);
  out.file("--out", out_json);
  out.check();
  check_model_compare_flags(o);

  ModelTimeCompare c;
  c.closed = !o.controller.empty();
  c.at_reference = o.excitation_at == "reference";
  read_model_and_log(c, o);
  model_compare_route(c, o);
  simulate_model_on_log(c, o);
  model_compare_residual_tests(c, o);
  const nlohmann::json summary = model_compare_summary(c, o);
  const std::string text = model_compare_text(c, o);

  if (!o.out_png.empty()) {
    const auto png = overlay_png(c.t, c.y, c.with_x0.predicted, c.r, c.out_names,
                                 fmt::format("{}: measured vs {}", o.log, o.params));
    out.stage(o.out_png, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  }
  if (!out_json.empty()) out.stage(out_json, json_text(summary));
  out.commit();
  if (!out.to_stdout()) print_summary(json, summary, text);
}

}  // namespace lpvid::cli
