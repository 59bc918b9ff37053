// lpvid compare --log RUN.csv — the time domain: simulate the model's closed
// loop on the measured excitation and beam trajectory, and say how well it
// predicts the measured outputs (fit %, residual tests, failing windows).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/imgproc.hpp>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/mechanical_time.h"
#include "cli/output_set.h"
#include "cli/responses.h"
#include "cli/stage6_time.h"
#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "idlib/physical/platform/platform_base.h"
#include "formats/io/platform_json.h"
#include "formats/plot/canvas.h"
#include "formats/plot/time_plot.h"
#include "idlib/core/error.h"
#include "idlib/sim/moving_beam.h"
#include "idlib/validate/nonlinearity.h"
#include "idlib/validate/time_fit.h"

namespace lpvid::cli {
namespace {

const std::vector<std::string> kOutputs = {"q1", "q2", "q3"};
const std::vector<std::string> kOutputNames = {"psi", "theta", "z"};
const std::vector<std::string> kExcitations = {"v1", "v2", "v3"};
const std::vector<std::string> kPlantInputs = {"u1", "u2", "u3"};


}  // namespace

nlohmann::json correlation_test_json(const CorrelationTest& t, const std::vector<std::string>& outputs,
                                     const std::vector<std::string>& inputs) {
  nlohmann::json j = {{"channel", outputs[static_cast<std::size_t>(t.channel)]},
                      {"pass", t.pass},
                      {"worst_ratio", t.worst_ratio},
                      {"worst_lag", t.worst_lag},
                      {"bound", t.bound},
                      {"bound_per_lag", t.bound_per_lag},
                      {"lags_outside_per_lag_bound", t.lags_outside_per_lag_bound}};
  if (t.input >= 0) j["input"] = inputs[static_cast<std::size_t>(t.input)];
  return j;
}

nlohmann::json nonlinearity_json(const NonlinearityResult& r, const std::vector<std::string>& outputs) {
  nlohmann::json seen = nlohmann::json::array();
  for (const Index q : r.significant) {
    const NonlinearityTest& t = r.tests[static_cast<std::size_t>(q)];
    seen.push_back({{"residual", outputs[static_cast<std::size_t>(t.residual_channel)]},
                    {"feature", t.feature},
                    {"of", outputs[static_cast<std::size_t>(t.feature_channel)]},
                    {"r", t.r},
                    {"lag", t.lag},
                    {"t", t.t}});
  }
  return {{"ran", r.ran},
          {"segments", r.segments},
          {"threshold", r.threshold},
          {"seen", !r.significant.empty()},
          {"significant", seen},
          {"sentence", nonlinearity_sentence(r, outputs)}};
}

namespace compare_time_defaults {
// The physical routes' failing-window length (the platform's and the stage's): 0.5 s
// unless --window-s is given (the model route's default is a twentieth of the record).
double physical_route_window_s(const TimeCompareCliOptions& o) { return o.window_s > 0 ? o.window_s : 0.5; }
}  // namespace compare_time_defaults
using compare_time_defaults::physical_route_window_s;

void add_time_compare_options(CLI::App* app, TimeCompareCliOptions& o) {
  app->add_option("--log", o.log,
                  "time domain: a measured run to predict: the platform's (t, v1..v3, u1..u3, q1..q3, x_b) with its "
                  "controller, or the stage's (t, v1..v6, u1..u6, q1..q6) with a stage6 model file (--model or "
                  "--params; no controller)");
  add_log_layout_options(app, &o.layout);
  app->add_option("--params", o.params, "with --log: the model: a fitted physical model file (lpvid fit) or a platform parameter file (default: documented defaults)");
  app->add_option("--set", o.overrides, "with --log: override a model parameter, NAME=VALUE (repeatable)");
  app->add_option("--controller", o.controller,
                  "the discrete controller (JSON model): of the run with --log; for G and S data of a physical "
                  "model also its measured response (FRD .csv/.mat on the data's lines)");
  app->add_option("--input", o.input,
                  "with --log and a state-space model: the log's columns of the plant's input (default: the model's "
                  "input names); with --controller, the logged plant input for the residual tests");
  app->add_option("--output", o.output,
                  "with --log and a state-space model: the log's columns of the model's outputs (default: its names)");
  app->add_option("--excitation", o.excitation,
                  "with --log, a state-space model and --controller: the log's excitation columns (the loop is "
                  "simulated from them)");
  app->add_option("--excitation-at", o.excitation_at,
                  "with --excitation: 'input' (added to the plant input, default) or 'reference' (setpoints, e = r - q)");
  app->add_option("--window-s", o.window_s,
                  "with --log: failing-window length in s (default 0.5; a twentieth of the record for a state-space "
                  "model)")
      ->check(positive_up_to(kMaxDurationS, "the window length in s"));
  app->add_option("--threshold-percent", o.threshold_percent,
                  "with --log: a window fails when its residual rms exceeds this % of the output's rms (default 10)")
      ->check(positive_up_to(1e6, "the threshold in percent"));
  app->add_option("--max-lag", o.max_lag, "with --log: lags of the residual tests (default 25)")
      ->check(integer_in(1, 10'000, "the number of lags"));
  app->add_option("--substeps", o.substeps, "with --log: integration pieces per sample (default 1)")
      ->check(integer_in(1, 1000, "the integration pieces per sample"));
}

// Every input and output of the time-domain compare (cli/output_set.h).
void register_time_compare_files(OutputSet& outputs, const TimeCompareCliOptions& o, const std::string& out_json) {
  outputs.input(o.log);
  outputs.input(o.controller);
  outputs.input(o.params);
  outputs.file("--out-png", o.out_png);
  outputs.file("--out", out_json);
  outputs.check();  // a missing file is named before a missing flag
  if (o.controller.empty())
    throw InputError("compare --log: give --controller CONTROLLER.json, the discrete controller of the measured run "
                     "(or --model M.json with a state-space model, compared on its own logged input)");
}

void run_time_compare(const TimeCompareCliOptions& o, const std::string& out_json, bool json) {
  if (!o.params.empty() && is_state_space_file(o.params)) return run_model_time_compare(o, out_json, json);
  if (!o.input.empty() || !o.output.empty() || !o.excitation.empty() || o.excitation_at != "input")
    throw InputError(fmt::format("compare --log: --input, --output, --excitation and --excitation-at are for a "
                                 "state-space model (--model M.json with \"type\": \"state_space\" or "
                                 "\"transfer_function\"); {} is a physical model or parameter file, whose channels "
                                 "are fixed by its base",
                                 o.params.empty() ? "the default platform model" : o.params));
  if (!o.params.empty() && is_physical_model_file(o.params)) {
    // A physical model: its base's time route (BaseInfo::time_route): the force error
    // of a mechanical base (cli/mechanical_time.h), the stage's output error
    // (cli/stage6_time.h), or, for the platform, the simulation below.
    {
      OutputSet guard;
      guard.input(o.params);
      guard.input(o.log);
      guard.file("--out-png", o.out_png);
      guard.file("--out", out_json);
      guard.check();
    }
    nlohmann::json fit_section;
    PhysicalModel model = read_physical_model(o.params, &fit_section);
    const BaseInfo::TimeRoute route = model.base_info().time_route;
    if (route == BaseInfo::TimeRoute::kForceError) {
      // A mechanical base: the force error of the model as given on the log (cli/mechanical_time.h)
      if (!o.controller.empty())
        throw InputError("compare --log with a mechanical model: the force error uses the logged inputs, so no "
                         "controller is needed; leave --controller out");
      if (!o.overrides.empty() || o.substeps != 1 || o.max_lag != 25 || o.threshold_percent != 10.0)
        throw InputError("compare --log with a mechanical model: --set, --substeps, --max-lag and "
                         "--threshold-percent are for the platform's time-domain compare (edit the model with lpvid "
                         "model set; the failing windows are judged against the noise floor)");
      MechanicalTimeRequest req = mechanical_time_request(std::move(model), o.params, o.log, "", 0.0, false, json);
      use_recorded_smoothing(fit_section, req);
      req.png = o.out_png;
      req.png_flag = "--out-png";
      req.report = out_json;
      return run_mechanical_time_compare(req, o.window_s);
    }
    if (route == BaseInfo::TimeRoute::kStageOutputError) {
      if (!o.controller.empty())
        throw InputError("compare --log with a stage6 model: the model is simulated on the logged wrench (u1..u6), "
                         "so no controller is needed; leave --controller out");
      if (!o.overrides.empty() || o.substeps != 1 || o.max_lag != 25)
        throw InputError("compare --log with a stage6 model: --set, --substeps and --max-lag are for the platform's "
                         "time-domain compare; edit the model file instead");
      StageTimeCompareRequest req;
      req.model = std::move(model);
      req.model_label = o.params;
      req.log = o.log;
      req.out_png = o.out_png;
      req.out_json = out_json;
      req.window_s = physical_route_window_s(o);
      req.threshold_percent = o.threshold_percent;
      req.json = json;
      return run_stage_time_compare(req);
    }
  }
  {
    OutputSet outputs;  // checked before the parameter file is read
    register_time_compare_files(outputs, o, out_json);
  }
  PlatformParameters model = PlatformParameters::defaults();
  if (!o.params.empty()) {
    // A physical model file (lpvid model / fit) or a platform parameter file.
    std::ifstream probe(o.params, std::ios::binary);
    std::string head(512, '\0');
    probe.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(probe.gcount()));
    if (head.find("lpvid-physical-model") != std::string::npos) {
      const PhysicalModel physical = read_physical_model(o.params);
      std::vector<std::string> left_out;
      model = platform_parameters(physical, &left_out);
      if (!left_out.empty())
        std::fprintf(stderr, "lpvid compare --log: warning: %s of %s not simulated in the time domain (rigid-body "
                             "platform terms only)\n", fmt::format("{}", fmt::join(left_out, ", ")).c_str(),
                     o.params.c_str());
    } else {
      model = read_platform_parameters(o.params);
    }
  }
  apply_parameter_overrides(model, o.overrides);
  run_time_compare_with(o, model, out_json, json);
}

void run_time_compare_with(const TimeCompareCliOptions& o, const PlatformParameters& model,
                           const std::string& out_json, bool json) {
  TimeFitOptions fo;
  fo.window_s = physical_route_window_s(o);
  fo.window_threshold_percent = o.threshold_percent;
  fo.max_lag = o.max_lag;
  fo.validate();
  OutputSet outputs;
  register_time_compare_files(outputs, o, out_json);

  const StateSpace controller = read_controller(o.controller);
  const Log log = read_log(o.log, o.layout.read_options());
  const Eigen::MatrixXd v = log.columns(kExcitations), q = log.columns(kOutputs), u = log.columns(kPlantInputs);
  const Eigen::VectorXd t = log.data.col(0), xb = log.data.col(log.column("x_b"));
  check_beam_stroke(o.log, xb, model.beam_stroke_m);
  if (std::abs(controller.sample_period_s - log.sample_period_s) > 1e-6 * log.sample_period_s)
    throw InputError(fmt::format("{}: the controller samples at {} s but the log '{}' at {} s; give the run's controller",
                                 o.controller, controller.sample_period_s, o.log, log.sample_period_s));
  MovingBeamOptions mo;
  mo.sample_period_s = controller.sample_period_s;
  mo.substeps = o.substeps;
  const BeamTrajectory traj = BeamTrajectory::from_samples(t, xb);
  const MovingBeamPrediction pr = predict_moving_beam(model, controller, traj, t(0), v, mo);
  // The residual tests run on the open-loop prediction from the logged plant
  // input (a correct model leaves the sensor noise alone; idlib/sim/moving_beam.h).
  const Eigen::MatrixXd open_loop =
      predict_moving_beam_from_input(model, traj, t(0), u, mo);

  // Inputs of the cross test: the excitations and the beam position.
  Eigen::MatrixXd in(v.rows(), 4);
  in << v, xb;
  const std::vector<std::string> in_names = {"v1", "v2", "v3", "x_b"};
  const TimeFitResult r = time_fit(q, pr.q, in, t(0), log.sample_period_s, fo, open_loop);

  nlohmann::json ceiling = nlohmann::json::object(), floor = nlohmann::json::object();
  for (Index i = 0; i < 3; ++i) {
    ceiling[kOutputNames[static_cast<std::size_t>(i)]] = r.fit_ceiling_percent(i);
    floor[kOutputNames[static_cast<std::size_t>(i)]] = r.noise_floor(i);
  }
  nlohmann::json fit = nlohmann::json::object(), white = nlohmann::json::array(), cross = nlohmann::json::array(),
                 failures = nlohmann::json::array();
  for (Index i = 0; i < 3; ++i)
    fit[kOutputNames[static_cast<std::size_t>(i)]] =
        std::isfinite(r.fit_percent(i)) ? nlohmann::json(r.fit_percent(i)) : nlohmann::json(nullptr);
  for (const auto& w : r.whiteness) white.push_back(correlation_test_json(w, kOutputNames, in_names));
  for (const auto& c : r.cross) cross.push_back(correlation_test_json(c, kOutputNames, in_names));
  for (const auto& f : r.failures)
    failures.push_back({{"channel", kOutputNames[static_cast<std::size_t>(f.channel)]},
                        {"t_start_s", f.t_start_s},
                        {"t_end_s", f.t_end_s},
                        {"size_percent", f.size_percent}});
  const nlohmann::json summary = {{"log", o.log},
                                  {"samples", log.num_samples()},
                                  {"fit_percent", fit},
                                  {"noise_floor", floor},
                                  {"fit_ceiling_percent", ceiling},
                                  {"whiteness", white},
                                  {"cross_correlation", cross},
                                  {"failures", failures},
                                  {"window_s", fo.window_s},
                                  {"threshold_percent", fo.window_threshold_percent}};
  std::string text = fmt::format("compare {} (time domain, {} samples): NRMSE fit\n", o.log, log.num_samples());
  for (Index i = 0; i < 3; ++i)
    text += fmt::format("  {:<6} {:8.2f} % (noise allows {:6.2f} %)   whiteness {}  (max |r|/bound {:.2f} at lag {})\n",
                        kOutputNames[static_cast<std::size_t>(i)], r.fit_percent(i), r.fit_ceiling_percent(i),
                        r.whiteness[static_cast<std::size_t>(i)].pass ? "pass" : "FAIL",
                        r.whiteness[static_cast<std::size_t>(i)].worst_ratio,
                        r.whiteness[static_cast<std::size_t>(i)].worst_lag);
  for (const auto& c : r.cross)
    if (!c.pass)
      text += fmt::format("  residual {} correlates with {}: max |r|/bound {:.2f} at lag {}\n",
                          kOutputNames[static_cast<std::size_t>(c.channel)], in_names[static_cast<std::size_t>(c.input)],
                          c.worst_ratio, c.worst_lag);
  if (r.failures.empty()) {
    text += fmt::format("  no window of {} s with a residual above {} % of its output's rms\n", fo.window_s,
                        fo.window_threshold_percent);
  } else {
    text += "  failing windows: channel  t_start [s]  t_end [s]  size [%]\n";
    for (const auto& f : r.failures)
      text += fmt::format("                   {:<7} {:11.3f} {:10.3f} {:9.1f}\n",
                          kOutputNames[static_cast<std::size_t>(f.channel)], f.t_start_s, f.t_end_s, f.size_percent);
  }
  OutputSet& out = outputs;
  if (!o.out_png.empty()) {
    FitOverlay ov{t, q, pr.q, r.residual, {"psi [rad]", "theta [rad]", "z [m]"},
                  {"psi residual [rad]", "theta residual [rad]", "z residual [m]"}, {},
                  fmt::format("{}: measured vs model", o.log)};
    for (const auto& w : r.failures) ov.failures.push_back({static_cast<std::size_t>(w.channel), w.t_start_s, w.t_end_s});
    const auto png = fit_overlay_png(ov);
    out.stage(o.out_png, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  }
  if (!out_json.empty()) out.stage(out_json, json_text(summary));
  out.commit();
  if (!out.to_stdout()) print_summary(json, summary, text);
}

}  // namespace lpvid::cli
