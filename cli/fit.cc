// lpvid fit — fit a physical (grey-box) model, LPV in the beam position x_b,
// jointly to responses measured at several x_b (seed 000, Fig. 13).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "cli/common.h"
#include "cli/fit_inputs.h"
#include "cli/mechanical_time.h"
#include "cli/output_set.h"
#include "cli/progress_line.h"
#include "cli/registry.h"
#include "cli/responses.h"
#include "cli/stage6_time.h"
#include "formats/io/atomic_file.h"
#include "formats/io/history.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/table_csv.h"
#include "formats/plot/bode_plot.h"
#include "idlib/core/error.h"
#include "idlib/fit/fit.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {
namespace {

constexpr const char* kFitExample = R"(
Example:
  lpvid model init --out start.json
  lpvid fit --model start.json --rate-hz 1000 --data P_left.csv@-0.1 --data P_mid.csv@0 --data P_right.csv@0.1 \
            --out fitted.json --plot fit.png --bands bands.csv
Each --data is FILE@X_B: a plant FRD (.csv, .mat) or a state-space model (.json, evaluated
on --grid-count log-spaced frequencies from --grid-lo to --grid-hi rad/s), and the beam
position x_b in metres at which it was measured.  The free parameters of the model file
are fitted jointly to all files: NLopt BOBYQA from the start and --starts - 1 random points
(a global start on a subsample), then Ceres Levenberg-Marquardt on all data.  The error is
the complex relative error per channel and frequency (docs/math.md, "Physical fit").
--rate-hz: the data were identified from samples at this rate, so the model's ZOH response
is fitted (default: the rate of a discrete data model or of the controller, else continuous).
Closed-loop-aware: fit the closed-loop data through the known controller instead of the
recovered plant:
  lpvid fit --model start.json --target S --controller controller.json --data S_mid.csv@0 ... --out fitted.json
The fitted model file gets a "fit" section (estimates, standard errors, correlation, flags,
per-channel figures, cost, AIC/BIC).  --bands writes the model's magnitude and phase with
their delta-method standard deviations at the data frequencies; the plot shows +-2 sigma.
Time domain (base stage6): fit to a closed-loop log by output error (--method equation|both):
  lpvid fit --model stage.json --log exp/exp_stage6.csv --out fitted.json
Time domain (a mechanical base: every DOF's position logged with the inputs): the force
error M q'' + D q' + K q + friction + offset = B_w w, sample by sample (docs/math.md):
  lpvid fit --model axis.json --log run.csv --out fitted.json [--window-s 0.02])";

struct FitCliOptions {
  FitInputOptions in;
  std::string out, plot, bands;
  std::string log, method;  // the stage's time-domain route (cli/stage6_time.h)
  double window_s = 0.0;     // a mechanical base's force-error route (cli/mechanical_time.h)
  bool json = false;
  std::vector<std::string> frequency_given;  // the frequency route's options given (refused with --log)
};

std::string fmt_value(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : "n/a"; }

// The time-domain routes of --log: the force-error route of a mechanical base
// (cli/mechanical_time.h) or the stage's output/equation-error route (cli/stage6_time.h), by
// BaseInfo::time_route.
void run_fit_on_log(const FitCliOptions& o) {
  if (o.log.empty())
    throw InputError("fit --method: the method is for the time-domain fit; give --log RUN.csv (a stage6 model)");
  if (!o.in.data.empty() || !o.in.datasets.empty())
    throw InputError("fit: give either --log (time domain) or --data/--datasets (frequency domain), not both");
  refuse_frequency_options(o.frequency_given, "fit");
  PhysicalModel model = read_physical_model(o.in.model);
  if (model.base_info().time_route == BaseInfo::TimeRoute::kForceError) {
    if (!o.method.empty())
      throw InputError("fit --method: a mechanical base's time route has one method, the force error; drop --method");
    if (!o.bands.empty())
      throw InputError("fit --log: --bands is for the frequency route; the force-error route shows where the fit "
                       "fails in time with --plot F.png");
    MechanicalTimeRequest req = mechanical_time_request(std::move(model), o.in.model, o.log, o.out, o.window_s,
                                                        o.in.measured_input, o.json);
    req.png = o.plot;
    return run_mechanical_time_fit(req);
  }
  if (!o.plot.empty() || !o.bands.empty())
    throw InputError("fit --log: --plot and --bands are for the frequency route; see where the fitted model fails "
                     "in time with lpvid compare --log RUN.csv --model FITTED.json --out-png F.png");
  if (o.window_s > 0.0)
    throw InputError("fit --window-s: the smoothing window is the force-error route's (a mechanical base)");
  StageTimeFitRequest req;
  {
    OutputSet guard;  // the model is an input: never overwritten by --out
    guard.input(o.in.model);
    guard.file("--out", o.out);
    guard.check();
  }
  req.start = read_physical_model(o.in.model);
  req.model_label = o.in.model;
  req.log = o.log;
  req.out = o.out;
  req.method = o.method.empty() ? "output" : o.method;
  req.command = "fit";
  req.history_from = history_path_for(o.in.model);
  req.json = o.json;
  return run_stage_time_fit(req);
}

// The fit section of the model file.
nlohmann::json fit_section_json(const FitInputs& in, const FitResult& r) {
  const FitOptions& options = in.options;
  nlohmann::json params = nlohmann::json::object();
  std::vector<std::string> names;
  for (const auto& e : r.parameters) {
    names.push_back(e.name);
    params[e.name] = {{"start", e.start}, {"estimate", e.estimate}, {"std_error", e.std_error},
                      {"unit", e.unit},   {"flags", e.flags}};
    if (e.prior_sigma > 0.0)
      params[e.name]["prior"] = {{"mean", e.prior_mean},
                                 {"sigma", e.prior_sigma},
                                 {"pull_sigmas", (e.estimate - e.prior_mean) / e.prior_sigma}};
  }
  nlohmann::json corr = nlohmann::json::array();
  for (Index a = 0; a < r.correlation.rows(); ++a) {
    std::vector<double> row;
    for (Index b = 0; b < r.correlation.cols(); ++b) row.push_back(r.correlation(a, b));
    corr.push_back(row);
  }
  const auto& outs = r.output_names;
  const auto& ins = r.input_names;
  nlohmann::json channels = nlohmann::json::array();
  for (const auto& c : r.channels)
    channels.push_back({{"output", outs[static_cast<std::size_t>(c.output)]},
                        {"input", ins[static_cast<std::size_t>(c.input)]},
                        {"relative_rms_error", c.relative_rms_error},
                        {"noise_floor", std::isfinite(c.noise_floor) ? nlohmann::json(c.noise_floor) : nlohmann::json()},
                        {"per_dataset", c.per_dataset}});
  nlohmann::json used = nlohmann::json::array();
  for (const auto& s : in.specs) used.push_back({{"files", s.files}, {"x_b_m", s.beam_position_m}});
  return {
      {"target", target_name(options.target)},
      {"sample_period_s", options.sample_period_s},
      {"data", used},
      {"controller", in.controller_path},
      {"band_rad_s", {options.band_min_rad_s, std::isfinite(options.band_max_rad_s)
                                                  ? nlohmann::json(options.band_max_rad_s)
                                                  : nlohmann::json()}},
      {"error", r.error},
      {"noise_floor", std::isfinite(r.noise_floor) ? nlohmann::json(r.noise_floor) : nlohmann::json()},
      {"noise_source", r.noise_source},
      {"cost_start", r.cost_start},
      {"cost_after_global_start", r.cost_global},
      {"cost_final", r.cost_final},
      {"restarts", r.restarts},
      {"weighting",
       {{"model_error", r.model_error_weight},
        {"noise_weighted_error", std::isfinite(r.noise_weighted_error) ? nlohmann::json(r.noise_weighted_error)
                                                                       : nlohmann::json()},
        {"reweightings", r.reweightings}}},
      {"residuals", r.residual_count},
      {"sigma2", r.sigma2},
      {"aic", r.aic},
      {"bic", r.bic},
      {"iterations", r.iterations},
      {"termination", r.report.termination},
      {"warnings", r.report.warnings},
      {"parameters", params},
      {"correlation", {{"names", names}, {"matrix", corr}}},
      {"relative_singular_values", std::vector<double>(r.singular_values.data(),
                                                       r.singular_values.data() + r.singular_values.size())},
      {"identifiability", r.identifiability},
      {"channels", channels},
  };
}

// --bands and --plot: the fitted model's response with its delta-method bands at the
// data frequencies of each x_b; 2σ in the plot.
void stage_fit_bands(OutputSet& outputs, const FitCliOptions& o, const FitInputs& in, const FitResult& r) {
  const FitOptions& options = in.options;
  const auto& outs = r.output_names;
  const auto& ins = r.input_names;
  constexpr double kPlotSigmas = 2.0;
  std::vector<BodeSeries> series;
  std::vector<std::vector<double>> rows;
  for (const auto& d : in.data) {
    const ResponseBand band = response_band(r.model, r.covariance, d.beam_position_m, d.response.omega_rad_s, options);
    // a base without a scheduling variable: the data set's name (as diagnose's figure)
    const std::string tag =
        std::isnan(d.beam_position_m) ? d.label : fmt::format("x_b = {:g} m", d.beam_position_m);
    BodeSeries measured{tag + " data", d.response, BodeSeries::Style::kMarkers};
    BodeSeries model{tag + " model", band.response, BodeSeries::Style::kLine};
    BodeSeries lower{tag + " model -2 sigma", band.response, BodeSeries::Style::kDashed};
    BodeSeries upper{tag + " model +2 sigma", band.response, BodeSeries::Style::kDashed};
    for (std::size_t k = 0; k < band.response.response.size(); ++k) {
      for (Index i = 0; i < band.response.response[k].rows(); ++i)
        for (Index j = 0; j < band.response.response[k].cols(); ++j) {
          const Complex v = band.response.response[k](i, j);
          const double mag = std::abs(v), sm = band.magnitude_sigma[k](i, j);
          const Complex unit = mag > 0 ? v / mag : Complex(1.0, 0.0);
          lower.response.response[k](i, j) = unit * std::max(mag - kPlotSigmas * sm, 0.0);
          upper.response.response[k](i, j) = unit * (mag + kPlotSigmas * sm);
          rows.push_back({d.beam_position_m, band.response.omega_rad_s(static_cast<Index>(k)) / (2 * M_PI),
                          static_cast<double>(i + 1), static_cast<double>(j + 1), mag, sm,
                          std::max(mag - kPlotSigmas * sm, 0.0), mag + kPlotSigmas * sm,
                          std::arg(v) * 180.0 / M_PI, band.phase_sigma_rad[k](i, j) * 180.0 / M_PI});
        }
    }
    series.push_back(std::move(measured));
    series.push_back(std::move(model));
    series.push_back(std::move(lower));
    series.push_back(std::move(upper));
  }
  if (!o.bands.empty()) {
    Eigen::MatrixXd table(static_cast<Index>(rows.size()), 10);
    for (std::size_t i = 0; i < rows.size(); ++i)
      for (int c = 0; c < 10; ++c) table(static_cast<Index>(i), c) = rows[i][static_cast<std::size_t>(c)];
    write_table_csv(outputs.stage(o.bands),
                    {"x_b_m", "freq_hz", "output", "input", "magnitude", "magnitude_sigma", "magnitude_lower",
                     "magnitude_upper", "phase_deg", "phase_sigma_deg"},
                    table,
                    {"lpvid fit: fitted model response with delta-method standard deviations (docs/formats.md)",
                     fmt::format("target {}; output 1..{} = {}; input 1..{} = {}", target_name(options.target),
                                 outs.size(), fmt::join(outs, ","), ins.size(), fmt::join(ins, ",")),
                     "magnitude_lower/upper = magnitude -/+ 2 magnitude_sigma (lower clamped at 0)"});
  }
  if (!o.plot.empty()) {
    BodePlotOptions plot;
    plot.title = fmt::format("lpvid fit: {} model (lines, +-2 sigma dashed) over data (markers)",
                             target_name(options.target));
    const auto bytes = bode_png(series, plot);
    outputs.stage(o.plot, bytes);
  }
}

// The report printed after the files are published.
std::string fit_summary_text(const FitCliOptions& o, const FitInputs& in, const FitResult& r) {
  const FitOptions& options = in.options;
  const double ts = options.sample_period_s;
  const auto& outs = r.output_names;
  const auto& ins = r.input_names;
  const int restarts = r.restarts;
  const double first_final = r.cost_first_round;
  std::string text = fmt::format("fit: {} free parameters to {} data sets ({} target, {}), {} residuals\n",
                                 r.parameters.size(), in.data.size(), target_name(options.target),
                                 ts > 0 ? fmt::format("ZOH at Ts = {} s from {}", ts, in.sample_period_source)
                                        : "continuous",
                                 r.residual_count);
  text += fmt::format("cost: start {:.4g}, after global start {:.4g}, final {:.4g}; AIC {:.1f}, BIC {:.1f}\n",
                      r.cost_start, r.cost_global, r.cost_final, r.aic, r.bic);
  if (restarts > 0)
    text += fmt::format("(the first round ended at cost {:.4g}; {} more round{} from the estimate lowered it)\n",
                        first_final, restarts, restarts > 1 ? "s" : "");
  if (std::isfinite(r.noise_weighted_error)) {
    if (r.model_error_weight > 0.0)
      text += fmt::format(
          "weights: the noise-weighted fit left {:.4g} % against a floor of {:.4g} %, a model error, not noise; "
          "refitted with each line weighed by its noise plus a model error of {:.3g} % of its response ({} "
          "round{}), which the error figure measures: {:.4g} %; the costs above are under these weights\n",
          100.0 * r.noise_weighted_error, 100.0 * r.noise_floor, 100.0 * r.model_error_weight, r.reweightings,
          r.reweightings > 1 ? "s" : "", 100.0 * r.error);
    else
      text += fmt::format("weights: the noise-weighted fit left {:.4g} % against a floor of {:.4g} %; refitting "
                          "with the model error in the weights ({} round{}) did not lower the error figure, so the "
                          "noise-weighted fit stands\n",
                          100.0 * r.noise_weighted_error, 100.0 * r.noise_floor, r.reweightings,
                          r.reweightings == 1 ? "" : "s");
  }
  std::size_t name_width = 26;  // names of user-defined effects' parameters can be longer
  for (const auto& e : r.parameters) name_width = std::max(name_width, e.name.size());
  text += fmt::format("{:<{}} {:>12} {:>12} {:>11} {:>9}  {}\n", "parameter", name_width, "start", "estimate",
                      "std error", "unit", "flags");
  for (const auto& e : r.parameters) {
    std::string flags;
    if (e.prior_sigma > 0.0) flags = fmt::format("prior {:g} ± {:g}", e.prior_mean, e.prior_sigma);
    for (const auto& f : e.flags) flags += (flags.empty() ? "" : "; ") + f;
    text += fmt::format("{:<{}} {:>12} {:>12} {:>11} {:>9}  {}\n", e.name, name_width, fmt_value(e.start),
                        fmt_value(e.estimate), fmt_value(e.std_error), e.unit, flags);
  }
  text += fmt::format("error {:.4g} % (rms over the channels of the relative rms error); noise floor {} ({}){}\n",
                      100.0 * r.error,
                      std::isfinite(r.noise_floor) ? fmt::format("{:.4g} %", 100.0 * r.noise_floor) : "unknown",
                      r.noise_source,
                      std::isfinite(r.noise_floor) && r.error <= 1.5 * r.noise_floor ? ": within the noise" : "");
  const std::string& schedule = in.start.base_info().schedule_symbol;
  text += fmt::format("per-channel relative rms error (%), pooled over {}:\n",
                      schedule.empty() ? "the data sets" : schedule);
  for (std::size_t i = 0; i < outs.size(); ++i) {
    text += fmt::format("  {:<8}", outs[i]);
    for (std::size_t j = 0; j < ins.size(); ++j)
      text += fmt::format("  {}: {:8.3f}", ins[j], 100.0 * r.channels[i * ins.size() + j].relative_rms_error);
    text += "\n";
  }
  for (const auto& w : r.identifiability) text += "identifiability: " + w + "\n";
  for (const auto& w : r.report.warnings) text += "warning: " + w + "\n";
  text += fmt::format("{} in {:.2f} s; wrote {} (history: {})\n", r.report.termination, r.seconds, o.out, history_path_for(o.out));
  // a fit that stopped on its iteration limit: say exactly how to go on (issue 25)
  if (r.iterations >= o.in.max_iterations && r.report.termination.rfind("stopped", 0) == 0 && o.out != "-")
    text += fmt::format("to continue from where it stopped: lpvid fit --model {} ... --out NEXT.json (the same data; "
                        "it starts at these estimates), or rerun with --max-iterations {}\n",
                        o.out, 2 * o.in.max_iterations);
  return text;
}

void run(const FitCliOptions& o) {
  if (!o.log.empty() || !o.method.empty()) return run_fit_on_log(o);
  if (o.out == "-")
    throw InputError("fit --out '-': the fit history is written beside --out, so --out must be a file; give a file "
                     "path (or --json to print the fit)");
  // Every output, with the history beside --out; the start model's history is read.
  OutputSet outputs;
  outputs.file("--out", o.out);
  outputs.file("--plot", o.plot);
  outputs.file("--bands", o.bands);
  outputs.file("--out (its history)", history_path_for(o.out));
  outputs.input(history_path_for(o.in.model));
  const FitInputs in = load_fit_inputs(o.in, outputs);
  const FitOptions& options = in.options;

  // Global start + Levenberg–Marquardt, then again from the estimate while that lowers
  // the cost (at most 2 more rounds, FitOptions::restarts).  A model with an undamped
  // resonance has a cost that ripples as the resonance moves between FRF lines, and
  // one round can stop in a ripple: the independent stage's gap seed 104, refitted
  // after `model add gap_dependence`, stopped at 6.39 % with gamma 224.1 for a true
  // 306.3; a second round reached 4.03 % (floor 4.12 %) and 306.59.
  FitOptions rounds = options;
  rounds.restarts = 2;
  rounds.model_error_weighting = o.in.weighting == "auto";
  TerminalProgress progress;  // on a terminal only (cli/progress_line.h)
  rounds.progress = progress.get();
  const FitResult r = fit_physical_model(in.start, in.data, rounds);
  progress.finish();

  const nlohmann::json fit_section = fit_section_json(in, r);
  outputs.stage(o.out, physical_model_to_json(r.model, fit_section));
  if (!o.bands.empty() || !o.plot.empty()) stage_fit_bands(outputs, o, in, r);
  // The fit history beside the fitted model (formats/io/history.h): the start
  // model's history, if it has one, then this fit, so that `lpvid history` on the
  // newest model shows the whole lineage, model by model.
  outputs.stage(history_path_for(o.out),
                fit_history_text(o.in.model, o.out, r, r.output_names, r.input_names,
                                 fmt::format("fit of {} to {} data sets ({} target)", o.in.model, in.data.size(),
                                             target_name(options.target))));
  outputs.commit();

  const std::string text = fit_summary_text(o, in, r);
  nlohmann::json summary = fit_section;
  summary["out"] = o.out;
  summary["seconds"] = r.seconds;
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_fit_command() {
  return {"fit", "fit a physical LPV model to responses at several x_b", [](CLI::App& parent) {
            auto o = std::make_shared<FitCliOptions>();
            auto* app = parent.add_subcommand("fit", "Fit a physical model's free parameters to responses at several "
                                                     "beam positions" + std::string(kFitExample));
            add_fit_input_options(*app, o->in);
            app->add_option("--out", o->out, "fitted model file to write (JSON, with a \"fit\" section)")->required();
            app->add_option("--log", o->log,
                            "time domain: fit to a log instead of responses (base stage6: t, v1..v6, u1..u6, q1..q6; a "
                            "mechanical base: t and its input and output columns, the force-error route)");
            add_window_option(app, &o->window_s);
            app->add_option("--method", o->method,
                            "with --log: output (default; output error started from the equation error, unbiased "
                            "with sensor noise, standard errors), equation, or both (prints the two, writes output)");
            app->add_option("--plot", o->plot, "Bode PNG of the model (with +-2 sigma) over the data; with --log on a mechanical base, the "
                            "force and the model's over time and the residual, failing windows shaded");
            app->add_option("--bands", o->bands, "CSV of the model's magnitude/phase and their standard deviations");
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o, app] {
              o->frequency_given = frequency_options_given(*app);
              run(*o);
            });
          }};
}

}  // namespace lpvid::cli
