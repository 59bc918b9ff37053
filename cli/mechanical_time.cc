#include "cli/mechanical_time.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "formats/io/history.h"
#include "formats/io/physical_model_json.h"
#include "formats/plot/time_plot.h"
#include "idlib/core/error.h"
#include "idlib/fit/force_error.h"

namespace lpvid::cli {
namespace {

struct Loaded {
  ExperimentSet set;
  ForceErrorData data;
};

Loaded load(const MechanicalTimeRequest& r) {
  const BaseInfo& b = r.model.base_info();
  Loaded l;
  l.set = read_experiments({r.log}, b.input_names, b.output_names);
  ForceErrorOptions o;
  o.window_s = r.window_s;
  o.held_input = !r.measured_input;
  l.data = prepare_force_error(r.model, l.set.excitations[0], l.set.outputs[0], l.set.sample_period_s, o);
  return l;
}

std::string effects_text(const PhysicalModel& m) {
  return m.effects.empty() ? std::string("the base alone") : fmt::format("{}", fmt::join(m.effects, ", "));
}

std::string value_text(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : "n/a"; }

nlohmann::json fit_json(const ForceErrorFit& f, const BaseInfo& b) {
  nlohmann::json params = nlohmann::json::array();
  for (const auto& p : f.parameters)
    params.push_back({{"name", p.name},
                      {"value", p.value},
                      {"std_error", std::isfinite(p.std_error) ? nlohmann::json(p.std_error) : nlohmann::json()},
                      {"unit", p.unit},
                      {"at_bound", p.at_bound}});
  nlohmann::json dofs = nlohmann::json::array();
  for (Index i = 0; i < f.error_per_dof.size(); ++i)
    dofs.push_back({{"dof", b.dof_names[static_cast<std::size_t>(i)]},
                    {"error_percent", f.error_per_dof(i)},
                    {"noise_floor_percent", f.floor_per_dof(i)}});
  return {{"parameters", params},     {"error_percent", f.error}, {"noise_floor_percent", f.floor},
          {"per_dof", dofs},          {"bic", f.bic},             {"effective_samples", f.n_eff},
          {"unidentifiable", f.unidentifiable}};
}

// The error per DOF and over the DOFs against the floor; within 1.5x the floor `within`,
// else "N.Nx" followed by `beyond`; `tail` ends the last line.
std::string error_lines(const ForceErrorFit& f, const BaseInfo& b, const std::string& within,
                        const std::string& beyond, const std::string& tail) {
  std::string t;
  for (Index i = 0; i < f.error_per_dof.size(); ++i)
    t += fmt::format("  force error on {}: {:.3g} % of rms(B_w w) (noise floor {:.3g} %)\n",
                     b.dof_names[static_cast<std::size_t>(i)], f.error_per_dof(i), f.floor_per_dof(i));
  t += fmt::format("  error {:.3g} % (noise floor {:.3g} %): {}{}\n", f.error, f.floor,
                   f.error <= kForceErrorExplainedRatio * f.floor
                       ? within
                       : fmt::format("{:.1f}{}", f.error / std::max(f.floor, 1e-300), beyond),
                   tail);
  return t;
}

std::string fit_text(const ForceErrorFit& f, const BaseInfo& b) {
  std::string t;
  for (const auto& p : f.parameters)
    t += fmt::format("  {} = {} ± {} {}{}\n", p.name, value_text(p.value), value_text(p.std_error), p.unit,
                     p.at_bound ? "  (on its bound)" : "");
  t += error_lines(f, b, fmt::format("within {}x the floor, the model fits within the noise", kForceErrorExplainedRatio),
                   "x the floor, something is missing (lpvid diagnose --log)", fmt::format("; BIC {:.1f}", f.bic));
  for (const auto& u : f.unidentifiable) t += "  warning: " + u + "\n";
  return t;
}

std::string data_text(const MechanicalTimeRequest& r, const Loaded& l) {
  return fmt::format("{} samples of {} used at {:.6g} Hz ({} near standstill or a reversal left out), smoothing "
                     "window {} samples ({:.3g} s), input {}",
                     l.data.n(), r.log, 1.0 / l.data.sample_period_s, l.data.standstill, l.data.window,
                     static_cast<double>(l.data.window) * l.data.sample_period_s,
                     r.measured_input ? "measured" : "held over each sample") +
         (r.smoothing_source.empty() ? std::string() : " (" + r.smoothing_source + ")");
}

// Where the model fails in time (fit --plot, diagnose --png): per DOF the actuators'
// force B_w w and the model's force (both smoothed by the route's kernel), then the
// force residual with the windows failing beyond 1.5x the larger of the floor and the
// record's rms shaded; samples left out near standstill are gaps; then per DOF the
// residual against the DOF's position.
std::vector<unsigned char> force_overlay_png(const ForceErrorFit& f, const ForceErrorData& d, const BaseInfo& b,
                                             const std::string& title) {
  const Index nd = f.residual.cols();
  const Index first = d.sample(0), last = d.sample(d.n() - 1), N = last - first + 1;
  FitOverlay ov;
  ov.t_s.resize(N);
  for (Index k = 0; k < N; ++k) ov.t_s(k) = static_cast<double>(first + k) * d.sample_period_s;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ov.measured = Eigen::MatrixXd::Constant(N, nd, nan);
  ov.predicted = ov.measured;
  ov.residual = ov.measured;
  for (Index r = 0; r < d.n(); ++r) {
    const Index k = d.sample(r) - first;
    ov.measured.row(k) = f.applied.row(r);
    ov.predicted.row(k) = f.applied.row(r) - f.residual.row(r);
    ov.residual.row(k) = f.residual.row(r);
  }
  for (Index i = 0; i < nd; ++i) {
    const std::string& dof = b.dof_names[static_cast<std::size_t>(i)];
    ov.value_labels.push_back(fmt::format("{}: force B_w w", dof));
    ov.residual_labels.push_back(fmt::format("{}: residual", dof));
  }
  for (const auto& w : force_error_failing_windows(f, d))
    ov.failures.push_back({static_cast<std::size_t>(w.dof), w.t_start_s, w.t_end_s});
  ov.title = title;
  // and per DOF the residual against the position: a ripple (position_ripple) is a wave
  // there, which the time axis hides
  std::vector<ResidualAgainst> below;
  for (Index i = 0; i < nd; ++i) {
    const std::string& dof = b.dof_names[static_cast<std::size_t>(i)];
    const std::string unit = static_cast<std::size_t>(i) < b.dof_units.size() ? b.dof_units[static_cast<std::size_t>(i)] : "";
    below.push_back({fmt::format("position {} [{}]", dof, unit), fmt::format("{}: residual", dof), d.q.col(i),
                     f.residual.col(i)});
  }
  return fit_overlay_png(ov, below);
}

// With r.png given: the force overlay of f staged there, titled "<what>: force error ...
// (floor ...); <effects>" (what empty: "diagnose, the baseline"), the figures first so
// that a long list of effects is what a narrow title cuts; the line that says so, else "".
std::string stage_overlay(OutputSet& outputs, const MechanicalTimeRequest& r, const ForceErrorFit& f,
                          const ForceErrorData& d, const std::string& what) {
  if (r.png.empty()) return {};
  outputs.stage(r.png, force_overlay_png(f, d, r.model.base_info(),
                                         fmt::format("{}: force error {:.3g} % (floor {:.3g} %); {}",
                                                     what.empty() ? "diagnose, the baseline" : what, f.error, f.floor,
                                                     effects_text(f.model))));
  return fmt::format(
      "wrote {} (the force and the model's, the residual over time with failing windows shaded, and against the "
      "position)\n",
      r.png);
}

// The fitted model and its history line, staged (not committed).
void stage_fitted(OutputSet& outputs, const MechanicalTimeRequest& r, const ForceErrorFit& f, const BaseInfo& b,
                  const std::string& note, nlohmann::json section) {
  std::vector<HistoryRecord> records;
  if (!r.history_from.empty() && std::filesystem::exists(r.history_from)) records = read_history(r.history_from);
  HistoryRecord rec;
  rec.timestamp = utc_timestamp_now();
  rec.model = r.out;
  rec.effects = f.model.effects;
  rec.free_parameters = static_cast<Index>(f.parameters.size());
  rec.cost = f.rss;
  rec.error = f.error / 100.0;
  rec.noise_floor = f.floor / 100.0;
  rec.error_mean = rec.error_max = 0.0;
  for (Index i = 0; i < f.error_per_dof.size(); ++i) {
    const double e = f.error_per_dof(i) / 100.0;
    rec.error_mean += e / static_cast<double>(f.error_per_dof.size());
    rec.error_max = std::max(rec.error_max, e);
    rec.channels.push_back({b.dof_names[static_cast<std::size_t>(i)], "force", e, e});
  }
  rec.bic = f.bic;
  rec.note = note;
  std::string lines;
  for (const auto& old : records) lines += history_line(old) + "\n";
  lines += history_line(rec) + "\n";
  section["route"] = "force error";
  // what compare needs to check the model on another log as it was fitted
  section["smoothing"] = {{"window_s", r.window_s > 0.0 ? r.window_s : kForceErrorDefaultWindowS},
                          {"input", r.measured_input ? "measured" : "held"}};
  outputs.stage(r.out, physical_model_to_json(f.model, section));
  outputs.stage(history_path_for(r.out), lines);
}

void register_out(OutputSet& outputs, const MechanicalTimeRequest& r) {
  if (r.out == "-")
    throw InputError("--out '-': the fit history is written beside --out, so --out must be a file; give a file path "
                     "(or --json to print the fit)");
  outputs.input(r.log);
  outputs.file("--out", r.out);
  outputs.file(r.png_flag, r.png);
  if (!r.out.empty()) {
    if (!r.history_from.empty()) outputs.input(r.history_from);
    if (r.history_from == history_path_for(r.out))
      outputs.rewrite("--out (its history)", history_path_for(r.out));
    else
      outputs.file("--out (its history)", history_path_for(r.out));
  }
}

}  // namespace

MechanicalTimeRequest mechanical_time_request(PhysicalModel model, const std::string& model_path,
                                              const std::string& log, const std::string& out, double window_s,
                                              bool measured_input, bool json) {
  MechanicalTimeRequest r;
  r.model = std::move(model);
  r.model_label = model_path;
  r.log = log;
  r.out = out;
  r.history_from = history_path_for(model_path);
  r.window_s = window_s;
  r.measured_input = measured_input;
  r.json = json;
  return r;
}

void use_recorded_smoothing(const nlohmann::json& fit_section, MechanicalTimeRequest& r) {
  const auto* sm = fit_section.is_object() && fit_section.contains("smoothing") ? &fit_section["smoothing"] : nullptr;
  if (sm == nullptr) {
    r.window_s = 0.0;
    r.measured_input = false;
    r.smoothing_source = fmt::format("the defaults: {} records no force-error fit", r.model_label);
    return;
  }
  // (its shape checked by the reader, formats/io/physical_model_json.h)
  r.window_s = (*sm)["window_s"].get<double>();
  r.measured_input = (*sm)["input"] == "measured";
  r.smoothing_source = fmt::format("as the fit that wrote {}", r.model_label);
}

void add_window_option(CLI::App* app, double* window_s) {
  app->add_option("--window-s", *window_s,
                  "with --log on a mechanical base: the smoothing window of the derivatives, seconds (default 0.02)")
      ->check(CLI::PositiveNumber);
}

void run_mechanical_time_fit(const MechanicalTimeRequest& r) {
  OutputSet outputs;
  register_out(outputs, r);
  outputs.check();
  const Loaded l = load(r);
  const ForceErrorFit f = fit_force_error(r.model, l.data);
  const BaseInfo& b = r.model.base_info();
  nlohmann::json summary = fit_json(f, b);
  summary["route"] = "force error";
  summary["log"] = r.log;
  summary["window_samples"] = l.data.window;
  summary["samples_used"] = l.data.n();
  summary["samples_left_out_at_standstill"] = l.data.standstill;
  std::string text = fmt::format("fit ({}: {}; force error, idlib/fit/force_error.h) to {}:\n  {}\n", r.model_label,
                                 effects_text(r.model), r.log, data_text(r, l)) +
                     fit_text(f, b);
  text += stage_overlay(outputs, r, f, l.data, "fit");
  if (!r.out.empty()) {
    stage_fitted(outputs, r, f, b, fmt::format("lpvid fit --log {} (force error)", r.log), summary);
    text += fmt::format("wrote {} (history: {})\n", r.out, history_path_for(r.out));
  }
  outputs.commit();
  print_log_findings(l.set);
  print_summary(r.json, summary, text);
}

void run_mechanical_time_compare(const MechanicalTimeRequest& r, double failing_window_s) {
  OutputSet outputs;
  outputs.input(r.log);
  outputs.file("--out-png", r.png);
  outputs.file("--out", r.report);
  outputs.check();
  const Loaded l = load(r);
  const ForceErrorFit f = evaluate_force_error(r.model, l.data);
  const BaseInfo& b = r.model.base_info();
  const double span = failing_window_s > 0.0 ? failing_window_s : 0.25;
  const std::vector<ForceErrorWindow> failing = force_error_failing_windows(f, l.data, span);
  std::string text = fmt::format("compare ({}: {}; force error of the model as given, nothing refitted) on {}:\n  {}\n",
                                 r.model_label, effects_text(r.model), r.log, data_text(r, l));
  text += error_lines(f, b, fmt::format("within {}x the floor: the model explains this log", kForceErrorExplainedRatio),
                      "x the floor: something is missing or has changed (lpvid diagnose --log on this log names what)",
                      "");
  nlohmann::json windows = nlohmann::json::array();
  if (failing.empty()) {
    text += fmt::format("  no {:.3g}-s window fails beyond 1.5x the larger of the floor and the record's residual rms\n",
                        span);
  } else {
    text += fmt::format("  where it fails most ({:.3g}-s windows beyond 1.5x the larger of the floor and the record's "
                        "residual rms):\n",
                        span);
    for (const auto& w : failing) {
      const std::string& dof = b.dof_names[static_cast<std::size_t>(w.dof)];
      text += fmt::format("    {}: t {:.3f}-{:.3f} s, residual rms {:.3g}\n", dof, w.t_start_s, w.t_end_s, w.rms);
      windows.push_back({{"dof", dof}, {"t_start_s", w.t_start_s}, {"t_end_s", w.t_end_s}, {"rms", w.rms}});
    }
  }
  nlohmann::json summary = fit_json(f, b);
  summary.erase("parameters");
  summary.erase("unidentifiable");
  summary["route"] = "force error";
  summary["refitted"] = false;
  summary["model"] = r.model_label;
  summary["log"] = r.log;
  summary["failing_windows"] = windows;
  summary["window_samples"] = l.data.window;
  summary["samples_used"] = l.data.n();
  summary["samples_left_out_at_standstill"] = l.data.standstill;
  text += stage_overlay(outputs, r, f, l.data, "compare");
  if (!r.report.empty()) {
    outputs.stage(r.report, summary.dump(2) + "\n");
    text += fmt::format("wrote {}\n", r.report);
  }
  outputs.commit();
  print_log_findings(l.set);
  print_summary(r.json, summary, text);
}

void run_mechanical_time_diagnose(const MechanicalTimeRequest& r) {
  OutputSet outputs;
  register_out(outputs, r);
  outputs.file("--report", r.report);
  outputs.check();
  const Loaded l = load(r);
  ForceErrorDiagnoseOptions o;
  o.candidates = r.candidates;
  o.delta_bic = r.delta_bic;
  const ForceErrorDiagnosis d = diagnose_force_error(r.model, l.data, o);
  const BaseInfo& b = r.model.base_info();
  std::string text = fmt::format("diagnose ({}: {}; force error) on {}:\n  {}\nbaseline:\n", r.model_label,
                                 effects_text(r.model), r.log, data_text(r, l)) +
                     fit_text(d.baseline, b);
  nlohmann::json cands = nlohmann::json::array();
  if (!d.candidates.empty()) {
    text += fmt::format("candidates (each refitted; ΔBIC > {} and at least {:.0f} % of the excess over the floor):\n",
                        r.delta_bic, 100.0 * ForceErrorDiagnoseOptions{}.min_excess_share);
    text += fmt::format("  {:<38} {:>9} {:>9} {:>9} {:>7}  verdict\n", "effects", "error %", "floor %", "ΔBIC",
                        "excess");
  }
  for (const auto& c : d.candidates) {
    const std::string name = fmt::format("{}", fmt::join(c.effects, " + "));
    text += fmt::format("  {:<38} {:>9.3g} {:>9.3g} {:>9.1f} {:>6.0f}%  {}\n", name, c.fit.error, c.fit.floor,
                        c.delta_bic, 100.0 * c.excess_share, c.verdict);
    nlohmann::json j = fit_json(c.fit, b);
    j["effects"] = c.effects;
    j["delta_bic"] = c.delta_bic;
    j["excess_share"] = c.excess_share;
    j["significant"] = c.significant;
    j["explained"] = c.explained;
    j["verdict"] = c.verdict;
    cands.push_back(j);
  }
  for (const auto& s : d.not_tried) text += "  not tried: " + s + "\n";
  if (!d.signatures.empty()) {
    text += "the baseline's residual:\n";
    for (const auto& s : d.signatures) text += "  " + s + "\n";
  }
  for (const auto& s : d.cannot_separate) text += "cannot separate: " + s + "\n";
  text += d.summary + "\n";
  nlohmann::json summary{{"route", "force error"},
                         {"log", r.log},
                         {"baseline", fit_json(d.baseline, b)},
                         {"candidates", cands},
                         {"signatures", d.signatures},
                         {"cannot_separate", d.cannot_separate},
                         {"not_tried", d.not_tried},
                         {"baseline_explained", d.baseline_explained},
                         {"summary", d.summary}};
  if (d.named >= 0) {
    const ForceErrorCandidate& c = d.candidates[static_cast<std::size_t>(d.named)];
    summary["named"] = c.effects;
    std::string add;
    for (const auto& e : c.effects) add += fmt::format("lpvid model add {} --model MODEL.json; ", e);
    text += fmt::format("next: {}then lpvid fit --model MODEL.json --log {} --out FITTED.json{}\n", add, r.log,
                        r.out.empty() ? "" : fmt::format(" (or continue from --out {})", r.out));
  } else {
    summary["named"] = nlohmann::json::array();
  }
  if (!r.out.empty()) {
    if (d.named < 0 && r.out == "-")
      throw NumericalError("diagnose --log: nothing is named, so there is no model to write to --out -; nothing was "
                           "written");
    if (d.named < 0)
      text += fmt::format("nothing named: {} not written (no candidate is significant, so there is no model to "
                          "write)\n",
                          r.out);
    else {
      const ForceErrorCandidate& c = d.candidates[static_cast<std::size_t>(d.named)];
      stage_fitted(outputs, r, c.fit, b,
                   fmt::format("lpvid diagnose --log {}: {} added (force error)", r.log, fmt::join(c.effects, " + ")),
                   fit_json(c.fit, b));
      text += fmt::format("wrote {} (the model with {}, fitted; history: {})\n", r.out, fmt::join(c.effects, " + "),
                          history_path_for(r.out));
    }
  }
  summary["out_written"] = !r.out.empty() && d.named >= 0;  // as the frequency route's
  if (!r.report.empty()) outputs.stage(r.report, summary.dump(2) + "\n");
  text += stage_overlay(outputs, r, d.baseline, l.data, "");
  outputs.commit();
  print_log_findings(l.set);
  print_summary(r.json, summary, text);
}

}  // namespace lpvid::cli
