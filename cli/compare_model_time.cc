// lpvid compare --log RUN --model M.json, M a state-space or transfer-function model
// (identify's plant.json, realize's or unloop's output, a model a user wrote): any
// black-box model judged on any log, as MATLAB's compare and resid do it.
//
//   open loop (no --controller):  ŷ = M u, u the logged plant input (--input);
//   closed loop (--controller C): ŷ = M (I + C M)⁻¹ v, v the logged excitation at the
//     plant input (--excitation), or v = C (r − r̄) from the logged references
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

  TimeFitOptions fo;
  StateSpace model = read_state_space(o.params);
  const Log log = read_log(o.log, o.layout.read_options());
  const double Ts = log.sample_period_s;
  const Index N = log.num_samples();
  std::string sampling;
  if (!model.is_discrete()) {
    model = discretize_zoh(model, Ts);
    sampling = fmt::format("a continuous model, sampled here with a zero-order hold at the log's {:.6g} s", Ts);
  } else if (std::abs(model.sample_period_s - Ts) > 1e-6 * Ts) {
    throw InputError(fmt::format("{}: the model samples at {:.6g} s but the log '{}' at {:.6g} s; give a model of the "
                                 "log's rate (or a continuous one, which compare samples with a zero-order hold)",
                                 o.params, model.sample_period_s, o.log, Ts));
  }
  const Index m = model.num_inputs(), p = model.num_outputs();
  const std::vector<std::string> out_names =
      channel_columns(o.output, "--output", model.output_names, p, "output", o.params);
  const Eigen::MatrixXd y = log.columns(out_names);

  // What is simulated, from what, and what the residual is tested against.
  StateSpace simulated = model;
  Eigen::MatrixXd sim_input, cross_input, plant_input;
  std::vector<std::string> cross_names, in_names;
  std::string route;
  if (!closed) {
    in_names = channel_columns(o.input, "--input", model.input_names, m, "input", o.params);
    sim_input = log.columns(in_names);
    cross_input = sim_input;
    cross_names = in_names;
    route = fmt::format("open loop: the model simulated from the logged input {}", fmt::join(in_names, ","));
  } else {
    const StateSpace controller = read_controller(o.controller);
    cross_names = split_names(o.excitation, "--excitation");
    check_controller_matches(controller, Ts, p, at_reference ? controller.num_outputs() : static_cast<Index>(cross_names.size()),
                             1e-6);
    if (controller.num_outputs() != m || controller.num_inputs() != p)
      throw InputError(fmt::format("{}: the controller maps {} error(s) to {} input(s) but the model {} has {} input(s) "
                                   "and {} output(s); give the controller of the loop the model's plant ran in",
                                   o.controller, controller.num_inputs(), controller.num_outputs(), o.params, m, p));
    cross_input = log.columns(cross_names);
    sim_input = at_reference ? reference_as_input_excitation(controller, cross_input) : cross_input;
    simulated = closed_loop_output(model, controller);
    route = fmt::format("closed loop with {}: the model's loop simulated from the logged {} {}", o.controller,
                        at_reference ? "references" : "excitation", fmt::join(cross_names, ","));
    if (!o.input.empty()) {
      in_names = channel_columns(o.input, "--input", model.input_names, m, "input", o.params);
      plant_input = log.columns(in_names);
    }
  }

  const Eigen::VectorXcd eig = poles(model);
  const double radius = eig.size() > 0 ? eig.cwiseAbs().maxCoeff() : 0.0;
  const bool stable = is_stable(model);
  // An integrator (|z| = 1, to rounding) is simulated from a logged input as it is; only a
  // growing mode makes a simulation outside the loop meaningless.
  const bool growing = radius > 1.0 + 1e-9;
  const std::string stability =
      stable ? "stable"
             : growing ? fmt::format("UNSTABLE: largest pole |z| = {:.6g}", radius)
                       : "marginally stable: a pole on the unit circle (an integrator)";
  const SimulatedOutput with_x0 = simulate_with_fitted_start(simulated, sim_input, y, true);
  const SimulatedOutput from_rest = simulate_with_fitted_start(simulated, sim_input, y, false);
  if (with_x0.predicted.size() == 0 || from_rest.predicted.size() == 0)
    throw InputError(fmt::format(
        "{}: the {} diverges on the log '{}' ({} samples; the model's largest pole |z| = {:.6g}), so there is nothing "
        "to compare; {}",
        o.params, closed ? "model's closed loop with the controller" : "model", o.log, N, radius,
        closed ? "check that the controller is the one that ran and its sign (u = C(-q) + v)"
               : "an unstable plant can only be simulated in its loop: give --controller C.json and --excitation"));

  // The residual tests: in closed loop on the open-loop prediction from the logged plant
  // input when it is given and the plant can be simulated alone (a correct model then
  // leaves the sensor noise alone, white); otherwise on the simulation's residual.
  Eigen::MatrixXd test_predicted;
  std::string tested_on = closed ? "the closed-loop simulation's residual (the noise fed back through the loop is "
                                   "coloured: whiteness is not expected; the cross test with the excitation judges)"
                                 : "the simulation's residual";
  if (closed && plant_input.size() > 0) {
    const SimulatedOutput open = simulate_with_fitted_start(model, plant_input, y, true);
    if (!growing && open.predicted.size() > 0) {
      test_predicted = open.predicted;
      tested_on = fmt::format("the open-loop prediction from the logged plant input {} (a correct model leaves the "
                              "sensor noise alone)",
                              fmt::join(in_names, ","));
    } else {
      tested_on += "; --input not used: the plant is unstable, so it cannot be simulated outside its loop";
    }
  }

  fo.max_lag = o.max_lag;
  fo.window_threshold_percent = o.threshold_percent;
  fo.window_s = o.window_s > 0 ? o.window_s : static_cast<double>(std::max(kMinWindowSamples, N / 20)) * Ts;
  fo.validate();
  if (N < fo.max_lag + 2)
    throw InputError(fmt::format("{}: {} samples are too few for residual tests over {} lags; give --max-lag below {}",
                                 o.log, N, fo.max_lag, std::max<Index>(1, N - 2)));
  const Eigen::VectorXd t = log.data.col(log.column("t"));
  const TimeFitResult r = time_fit(y, with_x0.predicted, cross_input, t(0), Ts, fo, test_predicted);
  const Eigen::VectorXd fit_zero = nrmse_fit_percent(y, from_rest.predicted);

  nlohmann::json white = nlohmann::json::array(), cross = nlohmann::json::array(), failures = nlohmann::json::array();
  for (const auto& w : r.whiteness) white.push_back(correlation_test_json(w, out_names, cross_names));
  for (const auto& c : r.cross) cross.push_back(correlation_test_json(c, out_names, cross_names));
  for (const auto& f : r.failures)
    failures.push_back({{"channel", out_names[static_cast<std::size_t>(f.channel)]},
                        {"t_start_s", f.t_start_s},
                        {"t_end_s", f.t_end_s},
                        {"size_percent", f.size_percent}});
  const nlohmann::json summary = {
      {"log", o.log},
      {"model", o.params},
      {"controller", closed ? nlohmann::json(o.controller) : nlohmann::json(nullptr)},
      {"route", route},
      {"sampling", sampling.empty() ? nlohmann::json(nullptr) : nlohmann::json(sampling)},
      {"samples", N},
      {"sample_period_s", Ts},
      {"order", model.order()},
      {"stable", stable},
      {"stability", stability},
      {"largest_pole_magnitude", radius},
      {"outputs", out_names},
      {"inputs", closed ? cross_names : in_names},
      {"fit_percent", per_output(out_names, r.fit_percent)},
      {"fit_zero_state_percent", per_output(out_names, fit_zero)},
      {"output_offsets", per_output(out_names, with_x0.offsets)},
      {"noise_floor", per_output(out_names, r.noise_floor)},
      {"fit_ceiling_percent", per_output(out_names, r.fit_ceiling_percent)},
      {"prediction", "the model has no noise model (K = 0): its k-step prediction is its simulation, so the "
                     "prediction fit equals fit_percent"},
      {"residual_tests_on", tested_on},
      {"whiteness", white},
      {"cross_correlation", cross},
      {"failures", failures},
      {"window_s", fo.window_s},
      {"threshold_percent", fo.window_threshold_percent}};

  std::string text = fmt::format("compare {} with {} (time domain, {} samples every {:.6g} s; order {}, {})\n", o.log,
                                 o.params, N, Ts, model.order(), stability);
  text += fmt::format("  {}\n", route);
  if (!sampling.empty()) text += fmt::format("  {}\n", sampling);
  text += "  fit [%] from x(0) = 0 ('z') and with the initial state fitted ('e', compare's default), each with an offset per output:\n";
  text += fmt::format("  {:<12} {:>9} {:>9} {:>14}   whiteness (max |r|/bound at lag)\n", "output", "fit z", "fit e",
                      "noise allows");
  for (Index i = 0; i < p; ++i) {
    const auto& w = r.whiteness[static_cast<std::size_t>(i)];
    text += fmt::format("  {:<12} {:9.2f} {:9.2f} {:14.2f}   {} ({:.2f} at lag {})\n",
                        out_names[static_cast<std::size_t>(i)], fit_zero(i), r.fit_percent(i), r.fit_ceiling_percent(i),
                        w.pass ? "pass" : "FAIL", w.worst_ratio, w.worst_lag);
  }
  text += fmt::format("  residual tests on {}\n", tested_on);
  for (const auto& c : r.cross)
    if (!c.pass)
      text += fmt::format("  residual {} correlates with {}: max |r|/bound {:.2f} at lag {}{}\n",
                          out_names[static_cast<std::size_t>(c.channel)], cross_names[static_cast<std::size_t>(c.input)],
                          c.worst_ratio, c.worst_lag,
                          c.worst_lag < 0 ? " (before the input: feedback, or a non-causal error)" : "");
  if (r.failures.empty()) {
    text += fmt::format("  no window of {:.6g} s with a residual above {} % of its output's rms\n", fo.window_s,
                        fo.window_threshold_percent);
  } else {
    text += fmt::format("  failing windows ({:.6g} s): output  t_start [s]  t_end [s]  size [%]\n", fo.window_s);
    for (const auto& f : r.failures)
      text += fmt::format("                   {:<7} {:11.6g} {:10.6g} {:9.1f}\n",
                          out_names[static_cast<std::size_t>(f.channel)], f.t_start_s, f.t_end_s, f.size_percent);
  }
  text += "  (no noise model: the prediction fit equals the simulation fit 'e')\n";
  if (growing && !closed)
    text += "  the model is unstable: simulated outside its loop it runs away from the log; if the log is of a closed "
            "loop, give --controller C.json and --excitation\n";

  if (!o.out_png.empty()) {
    const auto png = overlay_png(t, y, with_x0.predicted, r, out_names, fmt::format("{}: measured vs {}", o.log, o.params));
    out.stage(o.out_png, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  }
  if (!out_json.empty()) out.stage(out_json, json_text(summary));
  out.commit();
  if (!out.to_stdout()) print_summary(json, summary, text);
}

}  // namespace lpvid::cli
