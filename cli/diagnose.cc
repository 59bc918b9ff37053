// lpvid diagnose — which physical effect is missing?  Refits the model with each
// candidate effect of the library it lacks and ranks them by BIC
// (idlib/diagnose/diagnose.h); says plainly when nothing explains the error.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "cli/common.h"
#include "cli/fit_inputs.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/physical_model_json.h"
#include "formats/plot/compare_plot.h"
#include "idlib/core/error.h"
#include "idlib/diagnose/diagnose.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid diagnose --model fitted.json --rate-hz 1000 \
                 --data P_left.csv@-0.1 --data P_mid.csv@0 --data P_right.csv@0.1
  lpvid model add input_delay --model fitted.json      # add what it names, then
  lpvid fit --model fitted.json --rate-hz 1000 --data ... --out fitted2.json
Refits the model as it is, then once per candidate effect of the library the model
lacks (lpvid model effects; --candidates to choose), each with its library defaults as
the start and the same global start + Levenberg-Marquardt as fit.  Candidates are ranked
by BIC = N ln(cost/N) + p ln N; one is significant when it lowers BIC by more than
--delta-bic (default 10, "very strong" evidence).  The report says where the model fails
(failing bands beyond the measurement noise, from the data's coherence), what is
missing, the residual signature that points to it, the error before and after and the
effect's estimated parameters with standard errors; or "nothing significant" / "not
explained" with the remaining residual described.  The data, target and controller
options are those of lpvid fit.  --out writes the winning candidate's fitted model; --png
draws where the model fails (data and model, the error over the noise band, failing bands red).)";

struct DiagnoseCliOptions {
  FitInputOptions in;
  std::string candidates, out, png;
  double delta_bic = 10.0, averages = 16;
  bool json = false;
};

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json bands_json(const std::vector<std::vector<FailingBand>>& sets, const std::vector<FitDataset>& data) {
  static const char* const kOut[3] = {"psi", "theta", "z"};
  nlohmann::json out = nlohmann::json::array();
  for (const auto& set : sets)
    for (const FailingBand& b : set)
      out.push_back({{"x_b_m", data[static_cast<std::size_t>(b.data_index)].beam_position_m},
                     {"output", b.output < 3 ? kOut[b.output] : std::to_string(b.output + 1)},
                     {"input", b.input + 1},
                     {"lo_rad_s", b.lo_rad_s},
                     {"hi_rad_s", b.hi_rad_s},
                     {"relative_percent_max", b.relative_percent_max},
                     {"gain_db_max", number_or_null(b.gain_db_max)},
                     {"phase_deg_max", number_or_null(b.phase_deg_max)},
                     {"signature", b.signature},
                     {"hint", b.hint}});
  return out;
}

void run(const DiagnoseCliOptions& o) {
  DiagnoseOptions options;
  options.significance_delta_bic = o.delta_bic;
  options.model_error.averages = o.averages;
  if (!o.candidates.empty()) options.candidates = split_names(o.candidates, "--candidates");
  OutputSet outputs;
  outputs.file("--out", o.out);
  outputs.file("--png", o.png);
  const FitInputs in = load_fit_inputs(o.in, outputs);
  options.fit = in.options;
  for (const std::string& c : options.candidates)
    if (find_effect(c) == nullptr) {
      std::string known;
      for (const EffectInfo& e : effect_library()) known += (known.empty() ? "" : ", ") + e.name;
      throw InputError(fmt::format("--candidates: unknown effect '{}'; use one of {}", c, known));
    }
  const Diagnosis d = diagnose(in.start, in.data, options);

  nlohmann::json ranked = nlohmann::json::array();
  std::string table = fmt::format("{:<4} {:<16} {:>10} {:>10} {:>10}  {}\n", "rank", "candidate", "ΔBIC", "error %",
                                  "x lower", "verdict");
  int rank = 0;
  for (const CandidateOutcome& c : d.ranked) {
    ++rank;
    nlohmann::json params = nlohmann::json::array();
    for (const ParameterEstimate& p : c.effect_parameters)
      params.push_back({{"name", p.name}, {"estimate", p.estimate}, {"std_error", number_or_null(p.std_error)},
                        {"unit", p.unit}});
    ranked.push_back({{"effect", c.effect},
                      {"fitted", c.fitted},
                      {"failure", c.failure},
                      {"delta_bic", c.fitted ? number_or_null(c.delta_bic) : nlohmann::json(nullptr)},
                      {"delta_aic", c.fitted ? number_or_null(c.delta_aic) : nlohmann::json(nullptr)},
                      {"error", c.fitted ? number_or_null(c.error) : nlohmann::json(nullptr)},
                      {"significant", c.significant},
                      {"seconds", c.fitted ? c.fit.seconds : 0.0},
                      {"parameters", params}});
    if (c.fitted)
      table += fmt::format("{:<4} {:<16} {:>10.1f} {:>10.4g} {:>10.3g}  {}\n", rank, c.effect, c.delta_bic,
                           100.0 * c.error, c.error > 0 ? d.baseline_error / c.error : INFINITY,
                           c.significant ? "significant" : "not significant");
    else
      table += fmt::format("{:<4} {:<16} {:>10} {:>10} {:>10}  refit failed: {}\n", rank, c.effect, "-", "-", "-",
                           c.failure);
  }

  if (!o.out.empty() && !d.explained)
    throw NumericalError(
        "diagnose: no candidate is significant, so there is no model to write to --out; nothing was written");
  if (!o.out.empty()) outputs.stage(o.out, physical_model_to_json(d.ranked.front().fit.model, nlohmann::json()));
  if (!o.png.empty()) {
    // Where the baseline fails: data and refitted model per x_b, the error over the
    // noise band, the failing bands shaded (formats/plot/compare_plot.h).
    std::vector<CompareSeries> series;
    std::vector<CompareBandMark> marks;
    for (std::size_t k = 0; k < in.data.size(); ++k) {
      const FitDataset& ds = in.data[k];
      const FrequencyResponse model =
          target_response(d.baseline.model, ds.beam_position_m, ds.response.omega_rad_s, options.fit);
      const ModelErrorModel mem = model_error(ds.response, model.response, options.model_error);
      series.push_back({fmt::format("x_b = {:g} m", ds.beam_position_m), mem.omega_rad_s, mem.data, mem.model,
                        mem.radius, mem.skipped});
    }
    for (const auto& set : d.baseline_failures)
      for (const FailingBand& b : set) marks.push_back({b.output, b.input, b.lo_rad_s, b.hi_rad_s});
    ComparePlotOptions po;
    po.title = fmt::format("lpvid diagnose: where the model fails ({} target; red: failing bands){}",
                           target_name(options.fit.target),
                           d.explained ? "; missing: " + d.ranked.front().effect : "");
    po.same_model = false;
    const FrequencyResponse& first = in.data.front().response;
    if (static_cast<Index>(first.input_names.size()) == first.num_inputs()) po.input_labels = first.input_names;
    if (static_cast<Index>(first.output_names.size()) == first.num_outputs()) po.output_labels = first.output_names;
    const auto bytes = compare_png(series, marks, po);
    outputs.stage(o.png, bytes);
  }
  outputs.commit();

  std::string text;
  for (const std::string& line : d.summary) text += line + "\n";
  text += "\ncandidates (refitted with all free parameters; BIC = N ln(cost/N) + p ln N):\n" + table;
  if (!o.out.empty()) text += fmt::format("wrote {} (the model with {})\n", o.out, d.ranked.front().effect);
  if (!o.png.empty()) text += fmt::format("wrote {} (where the model fails)\n", o.png);
  const nlohmann::json summary = {
      {"explained", d.explained},
      {"missing", d.explained ? nlohmann::json(d.ranked.front().effect) : nlohmann::json(nullptr)},
      {"baseline", {{"error", d.baseline_error}, {"bic", d.baseline.bic}, {"aic", d.baseline.aic},
                    {"free_parameters", d.baseline.parameters.size()}, {"residuals", d.baseline.residual_count}}},
      {"baseline_failures", bands_json(d.baseline_failures, in.data)},
      {"remaining_failures", bands_json(d.remaining_failures, in.data)},
      {"candidates", ranked},
      {"delta_bic_threshold", o.delta_bic},
      {"summary", d.summary},
      {"out", o.out}};
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_diagnose_command() {
  return {"diagnose", "which physical effect is missing (refit per candidate, ranked by BIC)", [](CLI::App& parent) {
            auto o = std::make_shared<DiagnoseCliOptions>();
            auto* app = parent.add_subcommand(
                "diagnose", "Which physical effect is the model missing?" + std::string(kExample));
            add_fit_input_options(*app, o->in);
            app->add_option("--candidates", o->candidates, "effects to try, comma separated (default: all it lacks)");
            app->add_option("--delta-bic", o->delta_bic, "BIC decrease a candidate needs to be significant (default 10)")
                ->check(positive_up_to(1e9, "the BIC decrease"));
            app->add_option("--averages", o->averages, "independent averages of the H1 data, for the noise (default 16)")
                ->check(number_in(1, 1e9, "the number of averages"));
            app->add_option("--out", o->out, "write the winning candidate's fitted model here");
            app->add_option("--png", o->png, "figure: data and model per x_b, the error over the noise band, failing bands in red");
            app->add_flag("--json", o->json, "print the report as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
