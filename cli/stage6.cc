// lpvid stage6 — grey-box identification of the 6-DOF maglev stage (seed 001)
// from a closed-loop log: `fit` (m, H, force constant, and the chosen effects),
// `diagnose` (which stage effect is missing, ranked by BIC).  Numerics in
// idlib/stage6/stage6_fit.h; the log is the one `simulate stage6 --experiment`
// writes (t, v1..v6, u1..u6, q1..q6).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/history.h"
#include "idlib/core/error.h"
#include "idlib/stage6/stage6_fit.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid simulate stage6 --experiment --out exp --effects gap --seed 3
  lpvid stage6 diagnose --log exp/exp_stage6.csv                 # which effect is missing?
  lpvid stage6 fit --log exp/exp_stage6.csv --effects gap --out stage.json
  lpvid history --model stage.json
The log's u1..u6 are the commanded body wrench (F_x F_y F_z tau_x tau_y tau_z) and q1..q6
the measured configuration (x y z psi theta phi).  The fit is an equation error on the
sampled equations of motion (docs/math.md, the 6-DOF stage); the mass is held at 5.47 kg
and the force constant fitted (--fit-mass: the other way round; only their ratio is
identifiable).  Effects: com (centre-of-mass offset), gap (gap-dependent force constant
alpha(z)), lag (motor electrical lag with back-EMF).  diagnose refits the model given by
--effects with each effect it lacks added alone and ranks them by BIC; an effect is
significant when it lowers BIC by more than 10.)";

struct Stage6IdOptions {
  std::string log, out;
  std::vector<std::string> effects;
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

nlohmann::json result_json(const stage6::StageFitResult& r) {
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
          {"rms_residual", r.rms_residual},
          {"rms_per_row", {{"F_x", r.rms_per_row(0)}, {"F_y", r.rms_per_row(1)}, {"F_z", r.rms_per_row(2)},
                           {"tau_x", r.rms_per_row(3)}, {"tau_y", r.rms_per_row(4)}, {"tau_z", r.rms_per_row(5)}}},
          {"bic", r.bic}};
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

void run_fit(const Stage6IdOptions& o) {
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
  nlohmann::json summary = result_json(r);
  summary["log"] = o.log;
  std::string text = fmt::format("stage6 fit ({}) to {}:\n", r.model.name(), o.log) + result_text(r);
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
              if (!diagnose) sub->add_option("--out", o->out, "write the fitted parameters (JSON) and their history");
              sub->add_flag("--json", o->json, "print the summary as JSON");
              sub->callback([o, diagnose] { diagnose ? run_diagnose(*o) : run_fit(*o); });
            }
          }};
}

}  // namespace lpvid::cli
