// lpvid identify — the whole time-domain chain in one call (seed 000, eqs 10–14):
// logs -> Markov parameters -> Hankel SVD and order -> closed loop G -> plant P,
// with the Hankel singular values, a Bode plot and a report beside the models.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/markov_csv.h"
#include "formats/io/model_json.h"
#include "formats/io/table_csv.h"
#include "formats/plot/bode_plot.h"
#include "formats/plot/sv_plot.h"
#include "idlib/core/error.h"
#include "idlib/identify/identify.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/validate/frequency_error.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid identify --controller controller.json --excitation v1,v2,v3 --output q1,q2,q3 \
                 --out result exp_T_psi.csv exp_T_theta.csv exp_F_z.csv
writes result/closed_loop.json, result/plant.json, result/markov.csv, result/hankel_sv.csv,
result/hankel_sv.png, result/bode.png and result/report.json (order chosen and why,
singular values, fit figures).  With --truth PLANT.json the report and the plot also
compare the identified plant with a known one (weighted matrix error, 1-400 rad/s).
Nothing is written unless every step succeeds.)";

struct IdentifyCliOptions {
  std::vector<std::string> logs;
  std::string controller, excitation, output, out, truth, weights;
  Index lags = 0, order = 0, plant_order = 0;
  double horizon_s = 2.0;
  double band_min = 1.0, band_max = 400.0;
  bool json = false;
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

void run(const IdentifyCliOptions& o) {
  IdentifyOptions options;
  options.num_lags = o.lags;
  options.markov_horizon_s = o.horizon_s;
  options.closed_loop_order = o.order;
  options.plant_order = o.plant_order;
  options.validate();
  if (!(o.band_min > 0 && o.band_max > o.band_min))
    throw InputError(fmt::format("--band-min {} is not below --band-max {} (rad/s); give --band-min below --band-max",
                                 o.band_min, o.band_max));
  const auto excitation = split_names(o.excitation, "--excitation");
  const auto output = split_names(o.output, "--output");
  // Every output is checked before anything is read; the directory is created
  // only when the files are published.
  OutputSet outputs;
  outputs.inputs(o.logs);
  outputs.input(o.controller);
  outputs.input(o.truth);
  outputs.directory("--out", o.out);
  for (const char* name : {"closed_loop.json", "plant.json", "markov.csv", "hankel_sv.csv", "hankel_sv.png", "bode.png",
                           "report.json"})
    outputs.file_in(o.out, name);
  outputs.check();

  const StateSpace controller = read_controller(o.controller);
  std::optional<StateSpace> truth;
  if (!o.truth.empty()) truth = read_state_space(o.truth);
  Eigen::VectorXd weights = Eigen::VectorXd::Ones(static_cast<Index>(output.size()));
  if (!o.weights.empty()) {
    const auto w = split_numbers(o.weights, "--error-weights", "an output weight");
    if (w.size() != output.size())
      throw InputError(fmt::format("--error-weights has {} values for {} outputs; give one weight per --output",
                                   w.size(), output.size()));
    for (std::size_t i = 0; i < w.size(); ++i) weights(static_cast<Index>(i)) = w[i];
  }
  const ExperimentSet set = read_experiments(o.logs, excitation, output);
  check_controller_matches(controller, set.sample_period_s, static_cast<Index>(output.size()),
                           static_cast<Index>(excitation.size()), options.sample_period_tolerance);

  IdentifyResult r = identify_closed_loop(set.views(), set.sample_period_s, controller, options);
  r.closed_loop.model.input_names = excitation;
  r.closed_loop.model.output_names = output;
  r.plant.plant.input_names = controller.output_names.empty() ? excitation : controller.output_names;
  r.plant.plant.output_names = output;

  // Report.
  const auto& sel = r.closed_loop.selection;
  const Index shown = std::min<Index>(sel.singular_values.size(), 30);
  nlohmann::json report = {
      {"logs", set.paths},
      {"controller", o.controller},
      {"sample_period_s", set.sample_period_s},
      {"excitation", excitation},
      {"output", output},
      {"markov", {{"lags", r.num_lags}, {"iterations", r.markov.iterations}, {"samples", r.markov.total_samples},
                  {"termination", r.markov.report.termination}}},
      {"closed_loop",
       {{"order", r.closed_loop.model.order()},
        {"order_rule", sel.rule},
        {"order_reason", sel.reason},
        {"noise_floor", sel.noise_floor},
        {"singular_values", std::vector<double>(sel.singular_values.data(), sel.singular_values.data() + shown)},
        {"block_rows", r.closed_loop.block_rows},
        {"block_cols", r.closed_loop.block_cols},
        {"stride", r.closed_loop.stride},
        {"stable", is_stable(r.closed_loop.model)},
        {"poles", poles_json(r.closed_loop.model)},
        {"markov_fit_percent", matrix_json(markov_fit_percent(r.closed_loop.model, r.markov.g))}}},
      {"plant",
       {{"order", r.plant.plant.order()},
        {"interconnection_order", r.plant.interconnection_order},
        {"removed_modes", r.plant.removed_poles.size()},
        {"stable", is_stable(r.plant.plant)},
        {"poles", poles_json(r.plant.plant)},
        {"termination", r.plant.report.termination}}},
      {"warnings", r.warnings},
  };
  const Eigen::VectorXd band = log_frequency_grid(o.band_min, o.band_max, 200);
  if (truth) {
    if (truth->num_inputs() != r.plant.plant.num_inputs() || truth->num_outputs() != r.plant.plant.num_outputs())
      throw InputError(fmt::format("--truth {} is {}x{} but the identified plant is {}x{}; give the true plant of these outputs and inputs", o.truth,
                                   truth->num_outputs(), truth->num_inputs(), r.plant.plant.num_outputs(),
                                   r.plant.plant.num_inputs()));
    const auto est = evaluate_response(r.plant.plant, band);
    const auto ref = evaluate_response(*truth, band);
    const ErrorSummary e = weighted_error_over(est, ref, band, weights, weights);
    report["truth"] = {{"model", o.truth},
                       {"band_rad_s", {o.band_min, o.band_max}},
                       {"weights", std::vector<double>(weights.data(), weights.data() + weights.size())},
                       {"weighted_error_mean", e.mean},
                       {"weighted_error_max", e.max},
                       {"omega_at_max_rad_s", e.omega_at_max_rad_s}};
  }

  // Plots.
  const double nyquist = M_PI / set.sample_period_s;
  const Eigen::VectorXd omega = log_frequency_grid(std::min(1.0, o.band_min), 0.999 * nyquist, 400);
  std::vector<BodeSeries> series;
  series.push_back({"identified plant", frequency_response(r.plant.plant, omega), BodeSeries::Style::kLine});
  if (truth) series.push_back({"true plant", frequency_response(*truth, omega), BodeSeries::Style::kDashed});
  BodePlotOptions bode;
  bode.title = fmt::format("Plant identified from {} experiment(s), order {}", set.paths.size(), r.plant.plant.order());
  const auto bode_bytes = bode_png(series, bode);
  SingularValuePlotOptions svo;
  svo.count = std::min<Index>(20, sel.singular_values.size());
  svo.chosen_order = sel.order;
  svo.noise_floor = sel.noise_floor;
  svo.title = "Largest Hankel singular values of G (scaled channels)";
  const auto sv_bytes = singular_values_png(sel.singular_values, svo);

  // Every computation succeeded: now write, each file atomically.
  Eigen::MatrixXd table(sel.singular_values.size(), 3);
  for (Index i = 0; i < table.rows(); ++i)
    table.row(i) << static_cast<double>(i + 1), sel.singular_values(i), sel.singular_values(i) > sel.noise_floor;
  MarkovFile mf;
  mf.g = r.markov.g;
  mf.sample_period_s = set.sample_period_s;
  mf.inputs = excitation;
  mf.outputs = output;
  mf.noise_std = r.markov.noise_std;
  mf.input_rms = r.markov.excitation_rms;
  mf.output_rms = r.markov.output_rms;
  const nlohmann::json provenance = {{"command", "lpvid identify"}, {"logs", set.paths}, {"controller", o.controller}};
  // All files are staged and renamed into place together at the end: a failure
  // while writing leaves none of them.
  OutputSet& files = outputs;
  files.stage(join_path(o.out, "markov.csv"), markov_csv_text(mf, join_path(o.out, "markov.csv")));
  write_table_csv(files.stage(join_path(o.out, "hankel_sv.csv")), {"index", "singular_value", "above_noise_floor"},
                  table, {"lpvid identify: Hankel singular values of G (scaled channels)", "rule: " + sel.reason});
  files.stage(join_path(o.out, "hankel_sv.png"), sv_bytes);
  files.stage(join_path(o.out, "bode.png"), bode_bytes);
  files.stage(join_path(o.out, "closed_loop.json"), state_space_to_json(r.closed_loop.model, {{"provenance", provenance}}));
  files.stage(join_path(o.out, "plant.json"), state_space_to_json(r.plant.plant, {{"provenance", provenance}}));
  files.stage(join_path(o.out, "report.json"), json_text(report));
  files.commit();

  std::string text = fmt::format(
      "identify: {} experiment(s), Ts = {:.6g} s, {} lags\n"
      "  closed loop: order {} ({})\n"
      "  plant: order {} ({} modes removed), {}\n",
      set.paths.size(), set.sample_period_s, r.num_lags, r.closed_loop.model.order(), sel.reason,
      r.plant.plant.order(), r.plant.removed_poles.size(), is_stable(r.plant.plant) ? "stable" : "UNSTABLE");
  if (truth)
    text += fmt::format("  against {}: weighted error mean {:.3f} %, max {:.3f} % ({}-{} rad/s)\n", o.truth,
                        100 * report["truth"]["weighted_error_mean"].get<double>(),
                        100 * report["truth"]["weighted_error_max"].get<double>(), o.band_min, o.band_max);
  for (const auto& w : r.warnings) text += "warning: " + w + "\n";
  text += fmt::format("  wrote {}/{{closed_loop.json, plant.json, markov.csv, hankel_sv.csv, hankel_sv.png, bode.png, "
                      "report.json}}\n",
                      o.out);
  print_summary(o.json, report, text);
}

}  // namespace

Command make_identify_command() {
  return {"identify", "the whole chain: logs -> closed loop -> plant -> Bode", [](CLI::App& parent) {
            auto o = std::make_shared<IdentifyCliOptions>();
            auto* app = parent.add_subcommand(
                "identify", "Closed-loop identification from logs to plant model and Bode plot" + std::string(kExample));
            app->add_option("logs", o->logs, "CSV logs, one experiment each")->required();
            app->add_option("--controller", o->controller, "the controller that ran (state-space JSON)")->required();
            app->add_option("--excitation", o->excitation, "excitation columns v (comma separated)")->required();
            app->add_option("--output", o->output, "measured output columns q (comma separated)")->required();
            app->add_option("--out", o->out, "output directory")->required();
            app->add_option("--lags", o->lags, "Markov lags (default: --horizon-s / Ts, at most N/4)")
                ->check(integer_in(10, kMaxLags, "the number of Markov lags"));
            app->add_option("--horizon-s", o->horizon_s, "impulse-response length in seconds")
                ->check(positive_up_to(kMaxHorizonS, "the impulse-response length in s"));
            app->add_option("--order", o->order, "closed-loop order (default: automatic)")
                ->check(integer_in(1, kMaxModelStates, "the closed-loop order"));
            app->add_option("--plant-order", o->plant_order, "plant order (default: closed-loop minus controller)")
                ->check(integer_in(1, kMaxModelStates, "the plant order"));
            app->add_option("--truth", o->truth, "a known plant to compare with (state-space JSON)");
            app->add_option("--error-weights", o->weights,
                            "output weights W for the error |W(P^-P)W| / |WPW| (comma separated, default 1)");
            app->add_option("--band-min", o->band_min, "lower end of the error band, rad/s")
                ->check(positive_up_to(kMaxFrequency, "the lower end of the band in rad/s"));
            app->add_option("--band-max", o->band_max, "upper end of the error band, rad/s")
                ->check(positive_up_to(kMaxFrequency, "the upper end of the band in rad/s"));
            app->add_flag("--json", o->json, "print the report as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
