// lpvid diagnose — which physical effect is missing?  Refits the model with each
// effect it could add (library and user-defined), judges each against the noise
// floor of the data (idlib/diagnose/diagnose.h), and says plainly what is missing,
// or that nothing is, or describes what no effect explains.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <memory>

#include "cli/common.h"
#include "cli/stage6_time.h"
#include "cli/fit_inputs.h"
#include "cli/mechanical_time.h"
#include "formats/io/history.h"
#include "cli/output_set.h"
#include "cli/progress_line.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/physical_model_json.h"
#include "formats/plot/compare_plot.h"
#include "idlib/core/error.h"
#include "idlib/diagnose/diagnose.h"

namespace lpvid::cli {
namespace {

constexpr const char* kDiagnoseExample = R"(
Example:
  lpvid diagnose --model fit1.json --datasets data.json --png where-it-fails.png --report report.json
  lpvid model add input_delay --model fit1.json --from-diagnosis report.json --out start2.json
  lpvid fit --model start2.json --datasets data.json --out fit2.json   # add what it names (from where
                                                                       # diagnose ended), then refit
Refits the model as it is (the baseline), then once per effect it could add (the library's,
lpvid model effects, and the file's user-defined ones; --candidates to choose), each from
starting points read off the failing bands.  A candidate is significant when it lowers
BIC by more than --delta-bic (10) AND explains at least half of the excess error above
the noise floor AND removes at least half of the failing-band points AND none of its own
parameters ends on a bound (an effect used as a patch).  The noise floor comes from the
data: their variance, or coherence with its number of averages ('# averages: K' in the
files, or --averages), or --noise-level; without any of them diagnose stops and says so.
The report says where the model fails (distinct phenomena: frequency, channels, data
sets, size, signature), what is missing and how much of the excess it explains, the
error before and after, and "explained" only when what remains is within 1.5x the noise
floor.  Significant candidates rank by BIC; others that also leave only noise and whose
BIC on the data is within --delta-bic of the winner's are named as indistinguishable on
these data, or as separated by the priors when their estimates contradict the model's
priors (design values with ±sigma, which may be given for an effect not yet added) by
more than --delta-bic; ones the likelihood separates are said to bring the error within
the noise too.  When no single effect leaves only noise, pairs
(and triples) are tried and named together when each member is needed.  An effect the model
already has but the data do not need (refitted without it, the error does not rise and
BIC does not worsen) is reported as idle, with the 'lpvid model remove' line.  When nothing explains it, the residual is described by a resonance or lag in one
output row or input column (--out-effect writes that user-defined effect for 'lpvid
model define').  --out writes the winning candidate's fitted model; --png draws where the
model fails (data and model, the error over the noise band, failing bands red).
Time domain (base stage6): rank com_offset, gap_dependence, electrical_lag by BIC on a log,
judged by the output error against its noise floor (nothing missing within 1.5x):
  lpvid diagnose --model stage.json --log exp/exp_stage6.csv
Time domain (a mechanical base): the time-only effects it lacks (coulomb_friction,
force_offset, stribeck_friction, input_saturation, position_ripple and, once it is in,
position_ripple_2) and their pairs, judged
against the force error's noise floor (docs/math.md 9b):
  lpvid diagnose --model axis.json --log run.csv --out next.json --report report.json)";

struct DiagnoseCliOptions {
  FitInputOptions in;
  std::string candidates, out, png, out_effect, report;
  std::string log;  // the stage's time-domain route (cli/stage6_time.h)
  double window_s = 0.0;  // a mechanical base's force-error route (cli/mechanical_time.h)
  double delta_bic = 10.0;
  bool json = false;
  std::vector<std::string> frequency_given;  // the frequency route's options given (refused with --log)
};


std::string name_of(const std::vector<std::string>& names, Index i) {
  return i < static_cast<Index>(names.size()) ? names[static_cast<std::size_t>(i)] : std::to_string(i + 1);
}

nlohmann::json bands_json(const std::vector<std::vector<FailingBand>>& sets, const std::vector<FitDataset>& data,
                          const FitResult& fit) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& set : sets)
    for (const FailingBand& b : set)
      out.push_back({{"x_b_m", data[static_cast<std::size_t>(b.data_index)].beam_position_m},
                     {"output", name_of(fit.output_names, b.output)},
                     {"input", name_of(fit.input_names, b.input)},
                     {"lo_rad_s", b.lo_rad_s},
                     {"hi_rad_s", b.hi_rad_s},
                     {"relative_percent_max", b.relative_percent_max},
                     {"scaled_percent_max", b.scaled_percent_max},
                     {"error_share", b.error_share},
                     {"gain_db_max", number_or_null(b.gain_db_max)},
                     {"phase_deg_max", number_or_null(b.phase_deg_max)},
                     {"max_sigma_ratio", b.max_sigma_ratio},
                     {"signature", b.signature},
                     {"hint", b.hint}});
  return out;
}

nlohmann::json phenomena_json(const std::vector<Phenomenon>& phenomena, const std::vector<FitDataset>& data) {
  nlohmann::json out = nlohmann::json::array();
  for (const Phenomenon& p : phenomena) {
    std::vector<double> xb;
    for (Index d : p.data_sets) xb.push_back(data[static_cast<std::size_t>(d)].beam_position_m);
    const FailingBand& b = p.bands.front();
    out.push_back({{"omega_rad_s", p.omega_rad_s},
                   {"where", p.where},
                   {"x_b_m", xb},
                   {"bands", p.bands.size()},
                   {"relative_percent_max", b.relative_percent_max},
                   {"scaled_percent_max", b.scaled_percent_max},
                   {"error_share", p.error_share},
                   {"max_sigma_ratio", p.max_sigma_ratio},
                   {"signature", b.signature},
                   {"hint", b.hint}});
  }
  return out;
}

// The time-domain routes of --log: the force-error route of a mechanical base
// (cli/mechanical_time.h) or the stage's route (cli/stage6_time.h), by BaseInfo::time_route.
void run_diagnose_on_log(const DiagnoseCliOptions& o) {
  if (!o.in.data.empty() || !o.in.datasets.empty())
    throw InputError("diagnose: give either --log (time domain) or --data/--datasets (frequency domain), not both");
  refuse_frequency_options(o.frequency_given, "diagnose");
  PhysicalModel model = read_physical_model(o.in.model);
  if (model.base_info().time_route == BaseInfo::TimeRoute::kForceError) {
    if (!o.out_effect.empty())
      throw InputError("diagnose --log: --out-effect is for the frequency route; the force-error route writes --out "
                       "(the named effect fitted), --report and --png");
    MechanicalTimeRequest req = mechanical_time_request(std::move(model), o.in.model, o.log, o.out, o.window_s,
                                                        o.in.measured_input, o.json);
    req.report = o.report;
    req.png = o.png;
    req.png_flag = "--png";
    if (!o.candidates.empty()) req.candidates = split_names(o.candidates, "--candidates");
    req.delta_bic = o.delta_bic;
    return run_mechanical_time_diagnose(req);
  }
  if (o.window_s > 0.0)
    throw InputError("diagnose --window-s: the smoothing window is the force-error route's (a mechanical base)");
  if (!o.png.empty() || !o.out_effect.empty() || !o.report.empty())
    throw InputError("diagnose --log: --png, --out-effect and --report are for the frequency route; see where the model "
                     "fails in time with lpvid compare --log RUN.csv --model MODEL.json --out-png F.png");
  {
    OutputSet guard;
    guard.input(o.in.model);
    guard.file("--out", o.out);
    guard.check();
  }
  StageTimeDiagnoseRequest req;
  req.current = read_physical_model(o.in.model);
  req.model_label = o.in.model;
  req.log = o.log;
  req.out = o.out;
  req.command = "diagnose";
  if (!o.candidates.empty()) req.candidates = split_names(o.candidates, "--candidates");
  req.delta_bic = o.delta_bic;
  req.json = o.json;
  return run_stage_time_diagnose(req);
}

// Every candidate (and combination) with its fitted values: `lpvid model add
// EFFECT --from-diagnosis REPORT.json` starts the user's refit from them, so the
// refit reaches what diagnose reported (issue 25).
nlohmann::json diagnose_outcome_json(const CandidateOutcome& c) {
  nlohmann::json params = nlohmann::json::array();
  for (const ParameterEstimate& p : c.effect_parameters)
    params.push_back({{"name", p.name}, {"estimate", p.estimate}, {"std_error", number_or_null(p.std_error)},
                      {"unit", p.unit}, {"at_bound", p.at_bound}});
  nlohmann::json values = nlohmann::json::object();
  if (c.fitted)
    for (const PhysicalParameter& p : c.fit.model.parameters) values[p.name] = p.value;
  nlohmann::json j = {{"effect", c.effect},
                      {"members", c.members},
                      {"fitted", c.fitted},
                      {"failure", c.failure},
                      {"error", c.fitted ? number_or_null(c.error) : nlohmann::json(nullptr)},
                      {"noise_weighted_error", number_or_null(c.noise_weighted_error)},
                      {"excess_share", c.fitted ? number_or_null(c.excess_share) : nlohmann::json(nullptr)},
                      {"band_share", c.fitted ? number_or_null(c.band_share) : nlohmann::json(nullptr)},
                      {"delta_bic", c.fitted ? number_or_null(c.delta_bic) : nlohmann::json(nullptr)},
                      {"delta_aic", c.fitted ? number_or_null(c.delta_aic) : nlohmann::json(nullptr)},
                      {"own_parameter_at_bound", c.own_parameter_at_bound},
                      {"significant", c.significant},
                      {"verdict", c.verdict},
                      {"seconds", c.fitted ? c.fit.seconds : 0.0},
                      {"parameters", params},
                      {"values", values}};
  if (c.members.size() > 1) {
    j["member_shares"] = c.member_shares;
    j["member_needed"] = c.member_needed;
    nlohmann::json we = nlohmann::json::array(), wb = nlohmann::json::array();
    for (std::size_t k = 0; k < c.members.size(); ++k) {
      we.push_back(number_or_null(c.member_without_error[k]));
      wb.push_back(number_or_null(c.member_without_delta_bic[k]));
    }
    j["member_without_error"] = we;
    j["member_without_delta_bic"] = wb;
  }
  return j;
}

// The candidates and combinations for the report, and their table for the summary.
struct DiagnoseCandidates {
  nlohmann::json ranked = nlohmann::json::array(), combinations = nlohmann::json::array();
  std::string table;
};

DiagnoseCandidates diagnose_candidates(const Diagnosis& d) {
  DiagnoseCandidates out;
  std::string& table = out.table;
  table = fmt::format("{:<4} {:<34} {:>10} {:>8} {:>9} {:>9} {:>10}  {}\n", "rank", "candidate", "error %",
                      "x lower", "% excess", "% bands", "ΔBIC", "verdict");
  auto row = [&](int rank, const CandidateOutcome& c) {
    if (c.fitted)
      table += fmt::format("{:<4} {:<34} {:>10.4g} {:>8.3g} {:>9.0f} {:>9.0f} {:>10.1f}  {}\n", rank, c.effect,
                           100.0 * c.error, c.error > 0 ? d.baseline_error / c.error : INFINITY,
                           100.0 * c.excess_share, 100.0 * c.band_share, c.delta_bic, c.verdict);
    else
      table += fmt::format("{:<4} {:<34} {:>10} {:>8} {:>9} {:>9} {:>10}  refit failed: {}\n", rank, c.effect, "-", "-",
                           "-", "-", "-", c.failure);
  };
  int rank = 0;
  for (const CandidateOutcome& c : d.ranked) {
    out.ranked.push_back(diagnose_outcome_json(c));
    row(++rank, c);
  }
  if (!d.combinations.empty()) {
    table += "combinations (no single effect left only noise; each refitted, every member tested against the rest):\n";
    rank = 0;
    for (const CandidateOutcome& c : d.combinations) {
      out.combinations.push_back(diagnose_outcome_json(c));
      row(++rank, c);
    }
  }
  return out;
}

// An output the result cannot fill (--out with nothing significant, --out-effect with
// nothing described) is not written, and the summary says so and why; the run still
// succeeds (the diagnosis is the result: nothing is missing, or nothing in the library
// explains the rest) and writes the outputs it can fill — as the time routes do.
struct DiagnoseUnmet {
  std::string out, out_effect;  // why each is not written; empty: it is written (or not asked for)
};

DiagnoseUnmet diagnose_unmet(const DiagnoseCliOptions& o, const Diagnosis& d) {
  DiagnoseUnmet unmet;
  if (!o.out.empty() && d.missing.empty()) unmet.out = "no candidate is significant, so there is no model to write";
  if (!o.out_effect.empty() && d.descriptions.empty())
    unmet.out_effect = d.explained ? fmt::format("{} explains the error within the noise, so there is no effect to "
                                                 "describe",
                                                 d.missing)
                                   : std::string("the residual was not described, so there is no effect to write");
  return unmet;
}

// Where the baseline fails: data and refitted model per x_b, the error over the
// noise band, the failing bands shaded (formats/plot/compare_plot.h).
std::vector<unsigned char> diagnose_png(const Diagnosis& d, const FitInputs& in, const DiagnoseOptions& options) {
  const ModelErrorSet mes = model_errors(d.baseline.model, in.data, options.fit, options.model_error);
  std::vector<CompareSeries> series;
  std::vector<CompareBandMark> marks;
  for (std::size_t k = 0; k < in.data.size(); ++k) {
    const ModelErrorModel& mem = mes.models[k];
    // a base without a scheduling variable: the data set's name
    series.push_back({std::isnan(in.data[k].beam_position_m) ? in.data[k].label
                                                             : fmt::format("x_b = {:g} m", in.data[k].beam_position_m),
                      mem.omega_rad_s, mem.data, mem.model,
                      mem.radius, mem.scale, mem.skipped});
  }
  for (const auto& set : d.baseline_failures)
    for (const FailingBand& b : set) marks.push_back({b.output, b.input, b.lo_rad_s, b.hi_rad_s});
  ComparePlotOptions po;
  po.title = fmt::format("lpvid diagnose: where the model fails ({} target; red: failing bands){}",
                         target_name(options.fit.target), d.missing.empty() ? "" : "; missing: " + d.missing);
  po.same_model = false;
  po.input_labels = d.baseline.input_names;
  po.output_labels = d.baseline.output_names;
  return compare_png(series, marks, po);
}

// The report (--report, --json).
nlohmann::json diagnose_summary(const DiagnoseCliOptions& o, const Diagnosis& d, const std::vector<FitDataset>& data,
                                const DiagnoseCandidates& candidates) {
  nlohmann::json descriptions = nlohmann::json::array();
  for (const ResidualDescription& r : d.descriptions)
    descriptions.push_back({{"text", r.text},
                            {"kind", r.kind},
                            {"side", r.side},
                            {"channel", r.channel},
                            {"error", r.error},
                            {"excess_share", r.excess_share},
                            {"effect", nlohmann::json::parse(effect_definition_json(r.effect).dump())},
                            {"effect_name", r.effect.name}});
  nlohmann::json hints = nlohmann::json::array();
  for (const DesignHint& h : d.design_hints)
    hints.push_back({{"parameter", h.parameter},
                     {"bound", h.bound},
                     {"lower", h.lower},
                     {"upper", h.upper},
                     {"wanted", number_or_null(h.wanted)},
                     {"design", h.design.empty() ? nlohmann::json(nullptr) : nlohmann::json(h.design)},
                     {"design_value", h.design.empty() ? nlohmann::json(nullptr) : number_or_null(h.design_value)},
                     {"suggested", h.design.empty() ? nlohmann::json(nullptr) : number_or_null(h.suggested)},
                     {"effects", h.effects}});
  nlohmann::json idle = nlohmann::json::array();
  for (const IdleEffect& e : d.idle_effects)
    idle.push_back({{"effect", e.effect},
                    {"why_tried", e.why_tried},
                    {"error_without", e.error_without},
                    {"delta_bic", e.delta_bic}});
  return {
      {"explained", d.explained},
      {"indistinguishable", d.indistinguishable},
      {"separated_by_priors", d.separated_by_priors},
      {"also_explain", d.also_explain},
      {"missing", d.missing.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.missing)},
      {"missing_effects", d.missing_effects},
      {"noise_floor", number_or_null(d.noise_floor)},
      {"effective_floor", d.effective_floor},
      {"noise_source", d.noise_source},
      {"weighting", {{"model_error", d.model_error_weight},
                     {"noise_weighted_baseline_error", number_or_null(d.noise_weighted_baseline_error)}}},
      {"baseline", {{"error", d.baseline_error}, {"bic", d.baseline.bic}, {"aic", d.baseline.aic},
                    {"free_parameters", d.baseline.parameters.size()}, {"residuals", d.baseline.residual_count},
                    {"failing_band_points", d.baseline_band_points}}},
      {"phenomena", phenomena_json(d.phenomena, data)},
      {"baseline_failures", bands_json(d.baseline_failures, data, d.baseline)},
      {"remaining_phenomena", phenomena_json(d.remaining_phenomena, data)},
      {"remaining_failures", bands_json(d.remaining_failures, data, d.baseline)},
      {"candidates", candidates.ranked},
      {"combinations", candidates.combinations},
      {"descriptions", descriptions},
      {"design_hints", hints},
      {"idle_effects", idle},
      {"widened_error", d.design_hints.empty() ? nlohmann::json(nullptr) : number_or_null(d.widened_error)},
      {"delta_bic_threshold", o.delta_bic},
      {"summary", d.summary},
      {"out", o.out}};
}

// The summary printed after the files are published.
std::string diagnose_text(const DiagnoseCliOptions& o, const Diagnosis& d, const std::string& table,
                          const DiagnoseUnmet& unmet) {
  std::string text;
  for (const std::string& line : d.summary) text += line + "\n";
  text += "\ncandidates (each refitted with all free parameters; significant first by ΔBIC, then by error):\n" + table;
  if (!o.out.empty())
    text += unmet.out.empty() ? fmt::format("wrote {} (the model with {})\n", o.out, d.missing)
                              : fmt::format("nothing named: {} not written ({})\n", o.out, unmet.out);
  if (!o.out_effect.empty())
    text += unmet.out_effect.empty()
                ? fmt::format("wrote {} (user-defined effect '{}': lpvid model define --model ... --from {} --add)\n",
                              o.out_effect, d.descriptions.front().effect.name, o.out_effect)
                : fmt::format("nothing described: {} not written ({})\n", o.out_effect, unmet.out_effect);
  if (!o.png.empty()) text += fmt::format("wrote {} (where the model fails)\n", o.png);
  if (!o.report.empty())
    text += fmt::format("wrote {} (the report as JSON: lpvid model add {} --model ... --from-diagnosis {})\n", o.report,
                        d.missing_effects.empty() ? std::string("EFFECT")
                                                  : fmt::format("{}", fmt::join(d.missing_effects, ",")),
                        o.report);
  return text;
}

void run(const DiagnoseCliOptions& o) {
  if (!o.log.empty()) return run_diagnose_on_log(o);
  DiagnoseOptions options;
  options.significance_delta_bic = o.delta_bic;
  options.model_error_weighting = o.in.weighting == "auto";
  if (!o.candidates.empty()) options.candidates = split_names(o.candidates, "--candidates");
  OutputSet outputs;
  outputs.file("--out", o.out);
  // The refit's history beside --out continues the model's lineage (as fit --out does).
  const bool history = !o.out.empty() && o.out != "-";
  if (history) {
    outputs.file("--out (its history)", history_path_for(o.out));
    outputs.input(history_path_for(o.in.model));
  }
  outputs.file("--out-effect", o.out_effect);
  outputs.file("--png", o.png);
  outputs.file("--report", o.report);
  const FitInputs in = load_fit_inputs(o.in, outputs);
  options.fit = in.options;
  for (const std::string& c : options.candidates)
    if (in.start.effect_info(c) == nullptr) {
      const auto absent = in.start.absent_effects();
      throw InputError(fmt::format("--candidates: unknown effect '{}'; use one the model could add: {}", c,
                                   fmt::join(absent, ", ")));
    }
  TerminalProgress progress;  // on a terminal only (cli/progress_line.h)
  options.progress = progress.get();
  const Diagnosis d = diagnose(in.start, in.data, options);
  progress.finish();

  const DiagnoseCandidates candidates = diagnose_candidates(d);
  const DiagnoseUnmet unmet = diagnose_unmet(o, d);
  // standard output asked for a model or an effect there is none of: nothing to print
  // in its place, so the run fails and writes nothing
  if (o.out == "-" && !unmet.out.empty())
    throw NumericalError(fmt::format("diagnose: {} to --out -; nothing was written", unmet.out));
  if (o.out_effect == "-" && !unmet.out_effect.empty())
    throw NumericalError(fmt::format("diagnose: {} to --out-effect -; nothing was written", unmet.out_effect));
  if (unmet.out.empty() && !o.out.empty()) {
    const FitResult& won = d.winner()->fit;
    outputs.stage(o.out, physical_model_to_json(won.model, nlohmann::json()));
    if (history)
      outputs.stage(history_path_for(o.out),
                    fit_history_text(o.in.model, o.out, won, won.output_names, won.input_names,
                                     fmt::format("diagnose of {}: the refit with {}", o.in.model, d.missing)));
  }
  if (unmet.out_effect.empty() && !o.out_effect.empty())
    outputs.stage(o.out_effect, effect_definition_file(d.descriptions.front().effect));
  if (!o.png.empty()) outputs.stage(o.png, diagnose_png(d, in, options));
  nlohmann::json summary = diagnose_summary(o, d, in.data, candidates);
  summary["out_written"] = !o.out.empty() && unmet.out.empty();
  if (!o.report.empty()) outputs.stage(o.report, json_text(summary));
  outputs.commit();

  const std::string text = diagnose_text(o, d, candidates.table, unmet);
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_diagnose_command() {
  return {"diagnose", "which physical effect is missing (refit per candidate, judged against the noise floor)",
          [](CLI::App& parent) {
            auto o = std::make_shared<DiagnoseCliOptions>();
            auto* app = parent.add_subcommand(
                "diagnose", "Which physical effect is the model missing?" + std::string(kDiagnoseExample));
            add_fit_input_options(*app, o->in);
            app->add_option("--log", o->log,
                            "time domain: diagnose on a log (base stage6: t, v1..v6, u1..u6, q1..q6, by the "
                            "equation error's BIC; a mechanical base: t and its input and output columns, the "
                            "force-error route)");
            add_window_option(app, &o->window_s);
            app->add_option("--candidates", o->candidates, "effects to try, comma separated (default: all it lacks)");
            app->add_option("--delta-bic", o->delta_bic, "BIC decrease a candidate needs besides (default 10)")
                ->check(positive_up_to(1e9, "the BIC decrease"));
            app->add_option("--out", o->out, "write the winning candidate's fitted model here");
            app->add_option("--out-effect", o->out_effect,
                            "write the user-defined effect describing an unexplained residual (JSON)");
            app->add_option("--png", o->png, "figure: data and model per x_b, the error over the noise band, failing bands in red; with "
                            "--log on a mechanical base, the force and the model's over time and the residual, "
                            "failing windows shaded");
            app->add_option("--report", o->report,
                            "also write the report as JSON here (for model add --from-diagnosis)");
            app->add_flag("--json", o->json, "print the report as JSON");
            app->callback([o, app] {
              o->frequency_given = frequency_options_given(*app);
              run(*o);
            });
          }};
}

}  // namespace lpvid::cli
