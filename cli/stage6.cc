// lpvid stage6 — grey-box identification of the 6-DOF maglev stage (seed 001)
// from a closed-loop log: `fit` (m, H, force constant, and the chosen effects;
// equation error, output error, or both: --method), `diagnose` (which stage
// effect is missing, ranked by BIC).  Numerics in idlib/stage6/stage6_fit.h and
// idlib/stage6/stage6_output_error.h; the log is the one `simulate stage6 --experiment`
// writes (t, v1..v6, u1..u6, q1..q6).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/history.h"
#include "idlib/core/error.h"
#include "idlib/stage6/stage6_fit.h"
#include "idlib/stage6/stage6_output_error.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid simulate stage6 --experiment --out exp --effects gap --seed 3
  lpvid stage6 diagnose --log exp/exp_stage6.csv                 # which effect is missing?
  lpvid stage6 fit --log exp/exp_stage6.csv --effects gap --out stage.json
  lpvid history --model stage.json
  lpvid stage6 fit --log exp/exp_stage6.csv --effects gap --method both   # equation and output error
The log's u1..u6 are the commanded body wrench (F_x F_y F_z tau_x tau_y tau_z) and q1..q6
the measured configuration (x y z psi theta phi).  The fit is an equation error on the
sampled equations of motion (docs/math.md, the 6-DOF stage); the mass is held at 5.47 kg
and the force constant fitted (--fit-mass: the other way round; only their ratio is
identifiable).  --method output refines the equation-error fit by output error
(simulated 0.3 s windows of the logged wrench against the measured q, each window
with its own initial state), which removes the equation error's bias towards low
inertias on noisy logs and reports standard errors and the rms output error per
channel and window; --method both prints the two.  Effects: com (centre-of-mass offset), gap (gap-dependent force constant
alpha(z)), lag (motor electrical lag with back-EMF).  diagnose refits the model given by
--effects with each effect it lacks added alone and ranks them by BIC; an effect is
significant when it lowers BIC by more than 10.)";

struct Stage6IdOptions {
  std::string log, out;
  std::vector<std::string> effects;
  std::string method = "equation";  // fit: equation | output | both
  bool fit_mass = false, json = false;
};

stage6::StageFitModel model_of(const std::vector<std::string>& effects) {
  stage6::StageFitModel m;
  m.com_offset = false;
  for (const std::string& e : effects) {
    if (e == "com") m.com_offset = true;
    else if (e == "gap") m.gap_dependence = true;
    else if (e == "lag") m.electrical_lag = true;
    else throw InputError(fmt::format("--effects: unknown stage effect '{}'; use com, gap or lag", e));
  }
  return m;
}

struct LoadedStageLog {
  Eigen::MatrixXd u, q;
  double sample_period_s = 0;
};

LoadedStageLog load(const std::string& path) {
  const Log log = read_log(path);
  LoadedStageLog out;
  out.u.resize(log.num_samples(), 6);
  out.q.resize(log.num_samples(), 6);
  for (int c = 0; c < 6; ++c) {
    out.u.col(c) = log.data.col(log.column(fmt::format("u{}", c + 1)));
    out.q.col(c) = log.data.col(log.column(fmt::format("q{}", c + 1)));
  }
  out.sample_period_s = log.sample_period_s;
  return out;
}

std::vector<std::string> effect_names(const stage6::StageFitModel& m) {
  std::vector<std::string> e;
  if (m.com_offset) e.push_back("com");
  if (m.gap_dependence) e.push_back("gap");
  if (m.electrical_lag) e.push_back("lag");
  return e;
}

// The fields both fits share (StageFitResult and StageOutputErrorResult).
template <typename Result>
nlohmann::json estimates_json(const Result& r) {
  return {{"model", r.model.name()},
          {"effects", effect_names(r.model)},
          {"mass_kg", r.mass_kg},
          {"inertia_diag_kgm2", {r.inertia_diag_kgm2(0), r.inertia_diag_kgm2(1), r.inertia_diag_kgm2(2)}},
          {"force_constant_scale", r.force_constant_scale},
          {"com_offset_m", {r.com_offset_m(0), r.com_offset_m(1), r.com_offset_m(2)}},
          {"gamma_per_m", r.gamma_per_m},
          {"electrical_time_constant_s", r.electrical_time_constant_s},
          {"back_emf_damping_Ns_per_m", r.back_emf_damping_Ns_per_m},
          {"parameters", r.num_parameters},
          {"residuals", r.num_residuals},
          {"bic", r.bic}};
}

nlohmann::json result_json(const stage6::StageFitResult& r) {
  nlohmann::json j = estimates_json(r);
  j["rms_residual"] = r.rms_residual;
  j["rms_per_row"] = {{"F_x", r.rms_per_row(0)},   {"F_y", r.rms_per_row(1)},   {"F_z", r.rms_per_row(2)},
                      {"tau_x", r.rms_per_row(3)}, {"tau_y", r.rms_per_row(4)}, {"tau_z", r.rms_per_row(5)}};
  return j;
}

std::string result_text(const stage6::StageFitResult& r) {
  std::string t = fmt::format("  m = {:.6g} kg, H = diag({:.6g}, {:.6g}, {:.6g}) kg·m², force-constant scale {:.6g}\n",
                              r.mass_kg, r.inertia_diag_kgm2(0), r.inertia_diag_kgm2(1), r.inertia_diag_kgm2(2),
                              r.force_constant_scale);
  if (r.model.com_offset)
    t += fmt::format("  centre-of-mass offset ({:.4g}, {:.4g}, {:.4g}) mm\n", 1e3 * r.com_offset_m(0),
                     1e3 * r.com_offset_m(1), 1e3 * r.com_offset_m(2));
  if (r.model.gap_dependence) t += fmt::format("  gap dependence gamma = {:.6g} 1/m\n", r.gamma_per_m);
  if (r.model.electrical_lag)
    t += fmt::format("  electrical lag tau_e = {:.6g} ms, back-EMF damping {:.6g} N·s/m\n",
                     1e3 * r.electrical_time_constant_s, r.back_emf_damping_Ns_per_m);
  t += fmt::format("  rms residual {:.4g} (scaled), BIC {:.1f}, {} parameters, {} residuals\n", r.rms_residual, r.bic,
                   r.num_parameters, r.num_residuals);
  t += fmt::format("  per row (where it fails): F_x {:.3g}  F_y {:.3g}  F_z {:.3g}  tau_x {:.3g}  tau_y {:.3g}  tau_z {:.3g}\n",
                   r.rms_per_row(0), r.rms_per_row(1), r.rms_per_row(2), r.rms_per_row(3), r.rms_per_row(4),
                   r.rms_per_row(5));
  return t;
}

nlohmann::json output_error_json(const stage6::StageOutputErrorResult& r, double sample_period_s) {
  nlohmann::json j = estimates_json(r);
  j["method"] = "output";
  j["windows"] = r.num_windows;
  j["sigma2"] = r.sigma2;
  j["iterations"] = r.iterations;
  j["termination"] = r.report.termination;
  j["warnings"] = r.report.warnings;
  nlohmann::json se = nlohmann::json::object();
  for (int i = 0; i < stage6::kStageThetaSize; ++i)
    if (r.free[static_cast<std::size_t>(i)]) se[stage6::kStageThetaNames[static_cast<std::size_t>(i)]] = r.std_error(i);
  j["std_error"] = se;
  nlohmann::json rms = nlohmann::json::object(), scale = nlohmann::json::object();
  for (int c = 0; c < 6; ++c) {
    rms[stage6::kStageChannelNames[static_cast<std::size_t>(c)]] = r.rms_per_channel(c);
    scale[stage6::kStageChannelNames[static_cast<std::size_t>(c)]] = r.channel_scale(c);
  }
  j["rms_per_channel"] = rms;      // m (x, y, z) and rad (psi, theta, phi)
  j["channel_noise_scale"] = scale;
  nlohmann::json windows = nlohmann::json::array();
  for (std::size_t w = 0; w < r.window_start.size(); ++w) {
    nlohmann::json row = {{"t_start_s", static_cast<double>(r.window_start[w]) * sample_period_s}};
    for (int c = 0; c < 6; ++c)
      row[stage6::kStageChannelNames[static_cast<std::size_t>(c)]] = r.rms_per_window(static_cast<Eigen::Index>(w), c);
    windows.push_back(row);
  }
  j["rms_per_window"] = windows;
  return j;
}

std::string output_error_text(const stage6::StageOutputErrorResult& r, double sample_period_s) {
  std::string t = fmt::format("  m = {:.6g} kg", r.mass_kg);
  if (r.free[0]) t += fmt::format(" ± {:.2g}", r.std_error(0));
  t += fmt::format(", H = diag({:.6g} ± {:.2g}, {:.6g} ± {:.2g}, {:.6g} ± {:.2g}) kg·m², force-constant scale {:.6g}",
                   r.inertia_diag_kgm2(0), r.std_error(1), r.inertia_diag_kgm2(1), r.std_error(2),
                   r.inertia_diag_kgm2(2), r.std_error(3), r.force_constant_scale);
  if (r.free[4]) t += fmt::format(" ± {:.2g}", r.std_error(4));
  t += "\n";
  if (r.model.com_offset)
    t += fmt::format("  centre-of-mass offset ({:.4g} ± {:.2g}, {:.4g} ± {:.2g}, {:.4g} ± {:.2g}) mm\n",
                     1e3 * r.com_offset_m(0), 1e3 * r.std_error(5), 1e3 * r.com_offset_m(1), 1e3 * r.std_error(6),
                     1e3 * r.com_offset_m(2), 1e3 * r.std_error(7));
  if (r.model.gap_dependence) t += fmt::format("  gap dependence gamma = {:.6g} ± {:.2g} 1/m\n", r.gamma_per_m, r.std_error(8));
  if (r.model.electrical_lag)
    t += fmt::format("  electrical lag tau_e = {:.6g} ± {:.2g} ms, back-EMF damping {:.6g} ± {:.2g} N·s/m\n",
                     1e3 * r.electrical_time_constant_s, 1e3 * r.std_error(9), r.back_emf_damping_Ns_per_m,
                     r.std_error(10));
  t += fmt::format("  rms output error (where it fails): x {:.3g} nm  y {:.3g} nm  z {:.3g} nm  psi {:.3g} urad  "
                   "theta {:.3g} urad  phi {:.3g} urad\n",
                   1e9 * r.rms_per_channel(0), 1e9 * r.rms_per_channel(1), 1e9 * r.rms_per_channel(2),
                   1e6 * r.rms_per_channel(3), 1e6 * r.rms_per_channel(4), 1e6 * r.rms_per_channel(5));
  // The window whose rms is largest relative to its channel's overall rms.
  Eigen::Index wi = 0, ci = 0;
  (r.rms_per_window.array().rowwise() / r.rms_per_channel.transpose().array().max(1e-300)).maxCoeff(&wi, &ci);
  t += fmt::format("  worst window: t = {:.3g} s, {} ({:.3g}x its channel's rms)\n",
                   static_cast<double>(r.window_start[static_cast<std::size_t>(wi)]) * sample_period_s,
                   stage6::kStageChannelNames[static_cast<std::size_t>(ci)],
                   r.rms_per_window(wi, ci) / std::max(r.rms_per_channel(ci), 1e-300));
  t += fmt::format("  sigma^2 {:.4g}, BIC {:.1f}, {} parameters + {} windows x 12 states, {} residuals\n  {}\n",
                   r.sigma2, r.bic, r.num_parameters, r.num_windows, r.num_residuals, r.report.termination);
  for (const auto& w : r.report.warnings) t += "  warning: " + w + "\n";
  return t;
}

void run_fit(const Stage6IdOptions& o) {
  if (o.method != "equation" && o.method != "output" && o.method != "both")
    throw InputError(fmt::format("--method {}: use 'equation' (default), 'output' or 'both'", o.method));
  const stage6::StageFitModel model = model_of(o.effects);
  // The history beside --out is read (if it exists) and rewritten with one more line.
  if (o.out == "-")
    throw InputError("stage6 fit --out '-': the fit history is written beside --out, so --out must be a file; give a "
                     "file path (or --json to print the estimates)");
  OutputSet outputs;
  outputs.input(o.log);
  outputs.file("--out", o.out);
  if (!o.out.empty()) {
    outputs.input(history_path_for(o.out));
    outputs.rewrite("--out (its history)", history_path_for(o.out));
  }
  outputs.check();
  const LoadedStageLog log = load(o.log);
  stage6::StageFitOptions fo;
  fo.fix_mass = !o.fit_mass;
  const stage6::StageFitResult r = stage6::fit_stage(stage6::StageParameters{}, log.u, log.q, log.sample_period_s,
                                                     model, fo);
  const bool output = o.method == "output";
  nlohmann::json summary = result_json(r);
  std::string text = fmt::format("stage6 fit ({}, equation error) to {}:\n", r.model.name(), o.log) + result_text(r);
  std::optional<stage6::StageOutputErrorResult> oe;
  if (o.method != "equation") {
    stage6::StageOutputErrorOptions oo;
    oo.fix_mass = !o.fit_mass;
    oe = stage6::fit_stage_output_error(stage6::StageParameters{}, log.u, log.q, log.sample_period_s, model, oo, &r);
    const nlohmann::json oj = output_error_json(*oe, log.sample_period_s);
    const std::string ot =
        fmt::format("stage6 fit ({}, output error) to {}:\n", oe->model.name(), o.log) + output_error_text(*oe, log.sample_period_s);
    if (output) {
      summary = oj;
      summary["equation_error_start"] = result_json(r);
      text = ot;
    } else {
      summary["output_error"] = oj;
      text += ot;
    }
  }
  summary["log"] = o.log;
  if (!o.out.empty()) {
    // The fitted stage parameters, and the fit history beside them (the start's
    // lineage is the log's model name; `lpvid history --model OUT`).
    std::vector<HistoryRecord> records;
    if (std::filesystem::exists(history_path_for(o.out))) records = read_history(history_path_for(o.out));
    HistoryRecord rec;
    rec.timestamp = utc_timestamp_now();
    rec.model = o.out;
    rec.effects = effect_names(r.model);
    rec.free_parameters = r.num_parameters;
    rec.cost = r.rms_residual * r.rms_residual * static_cast<double>(r.num_residuals);
    rec.error_mean = r.rms_residual;
    rec.error_max = r.rms_residual;
    rec.bic = r.bic;
    rec.note = fmt::format("lpvid stage6 fit of {}", o.log);
    if (output) {
      // Output error: the weighted rms (≈ 1 when the model explains all but the
      // noise; the weights are each channel's noise level, estimated).
      rec.free_parameters = oe->num_parameters;
      rec.cost = oe->sigma2 * static_cast<double>(oe->num_residuals);
      rec.error_mean = rec.error_max = std::sqrt(oe->sigma2);
      rec.bic = oe->bic;
      rec.note = fmt::format("lpvid stage6 fit --method output of {}", o.log);
    }
    std::string lines;
    for (const auto& old : records) lines += history_line(old) + "\n";
    lines += history_line(rec) + "\n";
    outputs.stage(o.out, json_text(summary));
    outputs.stage(history_path_for(o.out), lines);
    outputs.commit();
    text += fmt::format("wrote {} (history: {})\n", o.out, history_path_for(o.out));
  }
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

void run_diagnose(const Stage6IdOptions& o) {
  constexpr double kSignificantDeltaBic = 10.0;  // as lpvid diagnose (docs/math.md, "Diagnose")
  const stage6::StageFitModel model = model_of(o.effects);
  const LoadedStageLog log = load(o.log);
  stage6::StageFitOptions fo;
  fo.fix_mass = !o.fit_mass;
  const stage6::StageDiagnosis d =
      stage6::diagnose_stage_from(model, stage6::StageParameters{}, log.u, log.q, log.sample_period_s, fo);
  nlohmann::json cands = nlohmann::json::array();
  std::string table = fmt::format("{:<4} {:<16} {:>12} {:>12} {:>9}  {}\n", "rank", "model", "ΔBIC", "rms resid",
                                  "x lower", "verdict");
  int rank = 0;
  for (const auto& c : d.candidates) {
    const double dbic = c.bic - d.base.bic;
    const bool sig = dbic < -kSignificantDeltaBic;
    nlohmann::json j = result_json(c);
    j["delta_bic"] = dbic;
    j["significant"] = sig;
    cands.push_back(j);
    table += fmt::format("{:<4} {:<16} {:>12.1f} {:>12.4g} {:>9.3g}  {}\n", ++rank, c.model.name(), dbic,
                         c.rms_residual, d.base.rms_residual / c.rms_residual, sig ? "significant" : "not significant");
  }
  const bool explained = !d.candidates.empty() && d.candidates.front().bic - d.base.bic < -kSignificantDeltaBic;
  std::string missing;
  if (explained) {
    const auto have = effect_names(d.base.model), now = effect_names(d.candidates.front().model);
    for (const auto& e : now)
      if (std::find(have.begin(), have.end(), e) == have.end()) missing = e;
  }
  std::string text = fmt::format("stage6 diagnose of {} from model {}:\n", o.log, d.base.model.name()) +
                     result_text(d.base);
  if (explained)
    text += fmt::format("missing: {} (rms residual {:.4g} -> {:.4g}, {:.3g}x lower)\n", missing, d.base.rms_residual,
                        d.candidates.front().rms_residual, d.base.rms_residual / d.candidates.front().rms_residual) +
            result_text(d.candidates.front());
  else
    text += d.candidates.empty() ? "no candidate: the model has every stage effect\n"
                                 : "nothing significant: no candidate lowers BIC by more than 10\n";
  if (!d.candidates.empty()) text += "candidates:\n" + table;
  const nlohmann::json summary = {{"log", o.log},        {"base", result_json(d.base)}, {"candidates", cands},
                                  {"explained", explained}, {"missing", explained ? nlohmann::json(missing) : nullptr}};
  print_summary(o.json, summary, text);
}

}  // namespace

Command make_stage6_command() {
  return {"stage6", "grey-box fit and diagnosis of the 6-DOF maglev stage from a log", [](CLI::App& parent) {
            auto* app = parent.add_subcommand(
                "stage6", "Identify the 6-DOF maglev stage (seed 001) from a closed-loop log" + std::string(kExample));
            app->require_subcommand(1);
            for (const bool diagnose : {false, true}) {
              auto o = std::make_shared<Stage6IdOptions>();
              auto* sub = app->add_subcommand(diagnose ? "diagnose" : "fit",
                                              diagnose ? "which stage effect is missing (BIC)"
                                                       : "fit m, H, the force constant and the chosen effects");
              sub->add_option("--log", o->log, "closed-loop log (simulate stage6 --experiment)")->required();
              sub->add_option("--effects", o->effects, "effects in the model: com, gap, lag")->delimiter(',');
              sub->add_flag("--fit-mass", o->fit_mass, "fit the mass and hold the force constant (default: the reverse)");
              if (!diagnose) {
                sub->add_option("--out", o->out, "write the fitted parameters (JSON) and their history");
                sub->add_option("--method", o->method,
                                "equation (default): equation error; output: output error started from it (unbiased "
                                "with sensor noise, standard errors); both: print the two");
              }
              sub->add_flag("--json", o->json, "print the summary as JSON");
              sub->callback([o, diagnose] { diagnose ? run_diagnose(*o) : run_fit(*o); });
            }
          }};
}

}  // namespace lpvid::cli
