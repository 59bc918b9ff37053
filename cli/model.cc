// lpvid model — physical model files: create one, list, add, remove and define
// effects, export the model at an operating point (the platform: a beam position)
// as a state-space JSON.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/diagnosis_json.h"
#include "formats/io/history.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"

namespace lpvid::cli {
namespace {

constexpr const char* kModelExample = R"(
Example:
  lpvid model init --out model.json                  (the platform base with beam gravity)
  lpvid model init --out model.json --set k_torque_low_Nm_per_rad=45 --set beam_height_m=0.06
                                                     (with the design values you know)
  lpvid model init --base mechanical --from axis.json --out axis_model.json
                                                     (a stage you describe: DOFs, M, D, K, actuator and
                                                      sensor maps; docs/formats.md)
  lpvid model set --model model.json --set platform_mass_kg=5.3±0.05
                                                     (a weighed mass: a prior for fit and diagnose)
  lpvid model effects                                (the effect library: parameters, units, bounds)
  lpvid model add input_delay --model fit1.json --out start2.json
                                                     (a new file; its fit history continues fit1's)
  lpvid diagnose --model fit1.json --datasets data.json --json > report.json
  lpvid model add com_offset,actuator_lag --model fit1.json --from-diagnosis report.json --out start2.json
                                                     (what diagnose named, starting from its fitted values)
  lpvid model remove input_delay --model start2.json (in place)
  lpvid model define --model fit1.json --from theta_mount.json [--add]
                                                     (a user-defined effect from building blocks)
  lpvid model export --model fitted.json --xb 0.05 --rate-hz 1000 --out P_005.json
'model set/add/remove/define' rewrite the model file in place unless --out names a new one
(atomically: a failed run leaves it unchanged); they drop the "fit" section, which no longer
describes the model, and --out copies the fit history so that 'lpvid history' shows the
whole lineage.  'model export' writes the state-space JSON at x_b: continuous without
--rate-hz (input delays are then not in the matrices; the summary gives them), exactly
sampled with it (delays, fractional ones too, realised as extra states).  See docs/effects.md.)";

struct ModelCliOptions {
  std::string out, model, effect, base = "platform", from, from_diagnosis;
  std::vector<std::string> sets, fix, free;  // model set: --set, --fix, --free
  double xb = std::numeric_limits<double>::quiet_NaN(), rate_hz = 0.0;  // xb NaN: not given
  bool bare = false, json = false, add_defined = false;
};

// --set NAME=VALUE: a parameter's value (its bounds must hold it);
// --set NAME=VALUE±SIGMA (or +-SIGMA): also a Gaussian prior on it, the design value
// known to ±SIGMA (fit and diagnose estimate the MAP value; docs/formats.md).
void apply_sets(PhysicalModel& m, const std::vector<std::string>& sets) {
  for (const std::string& s : sets) {
    const size_t eq = s.find('=');
    if (eq == std::string::npos || eq == 0)
      throw InputError(fmt::format("--set '{}': write NAME=VALUE or NAME=VALUE±SIGMA, e.g. --set "
                                   "k_torque_low_Nm_per_rad=45 or --set platform_mass_kg=5.3±0.05",
                                   s));
    const std::string name = s.substr(0, eq);
    std::string text = s.substr(eq + 1), sigma_text;
    bool with_prior = false;  // a ± (or +-) was written, with or without a number after it
    for (const char* pm : {"\u00b1", "+-"}) {
      const size_t at = text.find(pm);
      if (at != std::string::npos) {
        with_prior = true;
        sigma_text = text.substr(at + std::strlen(pm));
        text = text.substr(0, at);
        break;
      }
    }
    double v = NAN;
    if (!parse_decimal(text, v))
      throw InputError(fmt::format("--set '{}': '{}' is not a number; give the value in the parameter's unit", s, text));
    // a parameter of an effect the model lacks: a design value for when it is added
    PhysicalParameter& p = m.parameter_or_design_value(name);
    if (v < p.lower || v > p.upper)
      throw InputError(fmt::format("--set '{}': {} is outside the bounds [{}, {}] {} of {}; give a value inside them",
                                   s, v, p.lower, p.upper, p.unit, name));
    p.value = v;
    if (with_prior) {
      double sigma = NAN;
      if (!parse_decimal(sigma_text, sigma) || !(sigma > 0.0) || !std::isfinite(sigma))
        throw InputError(fmt::format("--set '{}': the uncertainty '{}' is not a number > 0; write NAME=VALUE±SIGMA in "
                                     "the parameter's unit ({})",
                                     s, sigma_text, p.unit));
      p.prior_mean = v;
      p.prior_sigma = sigma;
    }
  }
  m.validate();
}

// The base named by --base: the library's, or a user-described one read from --from.
PhysicalModel model_of_base(const ModelCliOptions& o) {
  if (o.base == "mechanical") {
    if (o.from.empty())
      throw InputError("--base mechanical: give the stage's description with --from DESCRIPTION.json (dofs, inputs, "
                       "outputs, parameters, mass, damping, stiffness, input_map, output_map; docs/formats.md)");
    return PhysicalModel::bare(make_mechanical_base(read_mechanical_description(o.from)));
  }
  if (!o.from.empty())
    throw InputError(fmt::format("--from describes a user's base; it goes with --base mechanical, not --base {}",
                                 o.base));
  return o.bare ? PhysicalModel::bare(o.base) : PhysicalModel::initial(o.base);
}

void run_init(const ModelCliOptions& o) {
  OutputSet outputs;
  outputs.file("--out", o.out);
  outputs.check();
  PhysicalModel m = model_of_base(o);
  apply_sets(m, o.sets);
  outputs.stage(o.out, physical_model_to_json(m));
  outputs.commit();
  if (!outputs.to_stdout())
    print_summary(o.json,
                  {{"out", o.out}, {"base", m.base}, {"effects", m.effects}, {"parameters", m.parameters.size()}},
                  fmt::format("model init: wrote {} (base {}; effects: {})\n", o.out, m.base,
                              m.effects.empty() ? std::string("none") : fmt::format("{}", fmt::join(m.effects, ", "))));
}

// add/remove/define: every input and output, checked before the model is read.
// The model is rewritten in place unless --out names a new file; then the
// source's fit history, if any, continues beside --out (a file; '-' prints the
// model alone).
void check_changed(const ModelCliOptions& o, OutputSet& outputs) {
  const bool in_place = o.out.empty() || o.out == o.model;
  if (in_place && o.model == "-")
    throw InputError("--model '-' is read from standard input and cannot be rewritten in place; give --out FILE "
                     "(or --out - to print the result)");
  outputs.input(o.model);
  outputs.input(o.from);
  if (in_place) {
    outputs.rewrite("--model", o.model);
  } else {
    outputs.input(history_path_for(o.model));
    outputs.file("--out", o.out);
    if (o.out != "-") outputs.file("--out (its history)", history_path_for(o.out));
  }
  outputs.check();
}

// Stages the changed model (in place or --out, with the lineage) and commits;
// returns the file written.
std::string write_changed(const ModelCliOptions& o, OutputSet& outputs, const PhysicalModel& m) {
  const std::string target = o.out.empty() ? o.model : o.out;
  outputs.stage(target, physical_model_to_json(m));
  // the lineage: the source's fit history continues in the new file's
  if (target != o.model && target != "-" && std::filesystem::exists(history_path_for(o.model))) {
    std::string text;  // never continue a broken history: every record checked, then copied byte for byte
    read_history(history_path_for(o.model), &text);
    outputs.stage(history_path_for(o.out), text);
  }
  outputs.commit();
  return target;
}

void run_set(const ModelCliOptions& o) {
  OutputSet outputs;
  check_changed(o, outputs);
  PhysicalModel m = read_physical_model(o.model);
  if (o.sets.empty() && o.fix.empty() && o.free.empty())
    throw InputError("model set: nothing to do; give --set NAME=VALUE, --fix NAME or --free NAME");
  apply_sets(m, o.sets);
  // --fix / --free: held at its value by fit and diagnose, or estimated (names checked
  // before anything changes; one name in both is refused)
  std::vector<std::string> fixed, freed;
  for (const std::string& list : o.fix)
    for (const std::string& n : split_names(list, "--fix")) fixed.push_back(n);
  for (const std::string& list : o.free)
    for (const std::string& n : split_names(list, "--free")) freed.push_back(n);
  for (const std::string& n : fixed)
    if (std::find(freed.begin(), freed.end(), n) != freed.end())
      throw InputError(fmt::format("model set: {} is given to both --fix and --free; give it to one", n));
  for (const std::string& n : fixed) m.parameter_or_design_value(n).free = false;
  for (const std::string& n : freed) m.parameter_or_design_value(n).free = true;
  const std::string written = write_changed(o, outputs, m);
  if (!outputs.to_stdout()) {
    std::vector<std::string> lines;
    for (const std::string& s : o.sets) {
      const PhysicalParameter& p = m.parameter_or_design_value(s.substr(0, s.find('=')));
      const std::string when = m.index_of(p.name) < 0 ? " (a design value, used when its effect is added)" : "";
      lines.push_back(p.has_prior() ? fmt::format("{} = {:g} {} (prior {:g} ± {:g}){}", p.name, p.value, p.unit,
                                                  p.prior_mean, p.prior_sigma, when)
                                    : fmt::format("{} = {:g} {}{}", p.name, p.value, p.unit, when));
    }
    if (!fixed.empty()) lines.push_back(fmt::format("fixed {}", fmt::join(fixed, ", ")));
    if (!freed.empty()) lines.push_back(fmt::format("free {}", fmt::join(freed, ", ")));
    print_summary(o.json, {{"model", written}, {"set", o.sets}, {"fixed", fixed}, {"freed", freed}},
                  fmt::format("model set: {}{}\n", fmt::join(lines, ", "),
                              written == o.model ? " in " + o.model : fmt::format(", wrote {} from {}", written, o.model)));
  }
}

// EFFECT or EFFECT,EFFECT (a combination diagnose named); --from-diagnosis: every
// parameter from the values diagnose fitted for that candidate, so the refit
// starts where diagnose ended and reaches (at least) the error it reported.
void run_add(const ModelCliOptions& o) {
  OutputSet outputs;
  outputs.input(o.from_diagnosis);
  check_changed(o, outputs);
  const std::vector<std::string> effects = split_names(o.effect, "the effect");
  PhysicalModel m = read_physical_model(o.model);
  for (const std::string& e : effects) m.add_effect(e);
  std::string start;
  if (!o.from_diagnosis.empty()) {
    const DiagnosisStart d = read_diagnosis_start(o.from_diagnosis, effects);
    // the report must be of this model with these effects: the same parameters
    std::vector<std::string> missing, extra;
    for (const auto& [name, value] : d.values)
      if (m.index_of(name) < 0) extra.push_back(name);
    for (const PhysicalParameter& p : m.parameters) {
      bool found = false;
      for (const auto& [name, value] : d.values) found = found || name == p.name;
      if (!found) missing.push_back(p.name);
    }
    if (!missing.empty() || !extra.empty())
      throw InputError(fmt::format(
          "--from-diagnosis {}: candidate '{}' was fitted on another model ({}{}{}); diagnose {} again and add from "
          "that report",
          o.from_diagnosis, d.candidate, missing.empty() ? "" : fmt::format("it lacks {}", fmt::join(missing, ", ")),
          !missing.empty() && !extra.empty() ? "; " : "",
          extra.empty() ? "" : fmt::format("it has {} that {} lacks", fmt::join(extra, ", "), o.model), o.model));
    for (const auto& [name, value] : d.values) {
      PhysicalParameter& p = m.parameter(name);
      if (value < p.lower || value > p.upper)
        throw InputError(fmt::format("--from-diagnosis {}: {} = {} is outside its bounds [{}, {}] {}; the report was "
                                     "made with other bounds: diagnose again",
                                     o.from_diagnosis, name, value, p.lower, p.upper, p.unit));
      p.value = value;
    }
    m.validate();
    start = fmt::format("; every parameter from {}'s fit of '{}' (diagnose reached {:.4g} %{})", o.from_diagnosis,
                        d.candidate, 100.0 * d.error, d.significant ? "" : "; " + d.verdict);
  }
  const std::string written = write_changed(o, outputs, m);
  if (!outputs.to_stdout())
    print_summary(o.json,
                  {{"model", written}, {"added", effects}, {"effects", m.effects}, {"from_diagnosis", o.from_diagnosis}},
                  fmt::format("model add: {} added{} (effects now: {}){}\n", fmt::join(effects, ", "),
                              written == o.model ? " to " + o.model : fmt::format(" to {} from {}", written, o.model),
                              fmt::join(m.effects, ", "), start));
}

void run_remove(const ModelCliOptions& o) {
  OutputSet outputs;
  check_changed(o, outputs);
  PhysicalModel m = read_physical_model(o.model);
  m.remove_effect(o.effect);
  const std::string written = write_changed(o, outputs, m);
  if (!outputs.to_stdout())
    print_summary(o.json, {{"model", written}, {"removed", o.effect}, {"effects", m.effects}},
                  fmt::format("model remove: {} removed{} (effects now: {})\n", o.effect,
                              written == o.model ? " from " + o.model : fmt::format(", wrote {} from {}", written, o.model),
                              m.effects.empty() ? std::string("none") : fmt::format("{}", fmt::join(m.effects, ", "))));
}

void run_define(const ModelCliOptions& o) {
  OutputSet outputs;
  check_changed(o, outputs);
  PhysicalModel m = read_physical_model(o.model);
  const EffectInfo e = read_effect_definition(o.from);
  m.define_effect(e);
  if (o.add_defined) m.add_effect(e.name);
  const std::string written = write_changed(o, outputs, m);
  if (!outputs.to_stdout())
    print_summary(o.json, {{"model", written}, {"defined", e.name}, {"added", o.add_defined}, {"effects", m.effects}},
                  fmt::format("model define: {} defined{} in {} ({} block(s), {} parameter(s))\n", e.name,
                              o.add_defined ? " and added" : "", written, e.blocks.size(), e.parameters.size()));
}

void run_export(const ModelCliOptions& o) {
  OutputSet outputs;
  outputs.input(o.model);
  outputs.file("--out", o.out);
  outputs.check();
  const PhysicalModel m = read_physical_model(o.model);
  if (std::isnan(o.xb) && !m.base_info().schedule_name.empty())
    throw InputError(fmt::format("--xb is required: base '{}' is scheduled by its {} ({}); give the operating point",
                                 m.base, m.base_info().schedule_name, m.base_info().schedule_unit));
  const double ts = o.rate_hz > 0 ? 1.0 / o.rate_hz : 0.0;
  const PhysicalStateSpace ss = physical_state_space(m, o.xb, ts);
  outputs.stage(o.out, state_space_to_json(ss.system, {{"provenance",
                                                        {{"command", "lpvid model export"}, {"model", o.model},
                                                         {"x_b_m", o.xb}, {"effects", m.effects},
                                                         {"input_delay_s", ss.input_delay_s},
                                                         {"delay_in_matrices_samples", ss.delay_samples}}}}));
  outputs.commit();
  const BaseInfo& base = m.base_info();
  const std::string at = base.schedule_name.empty()
                             ? std::string()
                             : fmt::format(" at {} = {} {}", base.schedule_name, o.xb, base.schedule_unit);
  std::string text = fmt::format("model export: {}{}, order {}, {}\n", o.model, at, ss.system.order(),
                                 ts > 0 ? fmt::format("sampled (ZOH) at {} Hz", o.rate_hz) : "continuous");
  double largest = 0;
  for (double t : ss.input_delay_s) largest = std::max(largest, t);
  if (largest > 0)
    text += ts > 0 ? fmt::format("input delays {} s realised with {} samples of registers\n",
                                 fmt::join(ss.input_delay_s, ", "), ss.delay_samples + 1)
                   : fmt::format("note: input delays {} s are not in the continuous matrices; apply exp(-s tau)\n",
                                 fmt::join(ss.input_delay_s, ", "));
  if (!outputs.to_stdout())
    print_summary(o.json, {{"out", o.out}, {"order", ss.system.order()}, {"sample_period_s", ts},
                           {"input_delay_s", ss.input_delay_s}, {"delay_samples", ss.delay_samples}},
                  text);
}

void run_effects(const ModelCliOptions& o) {
  const PhysicalModel m = model_of_base(o);
  const BaseInfo& b = m.base_info();
  nlohmann::json list = nlohmann::json::array();
  std::string text = fmt::format("base {}: {}\n", b.name, b.description);
  for (const auto& p : b.parameters)
    text += fmt::format("  {} = {:.10g} {} in [{:.10g}, {:.10g}]{}\n", p.name, p.value, p.unit, p.lower, p.upper,
                        p.free ? " (free)" : " (fixed)");
  text += fmt::format("inputs {}; outputs {}; model init adds {}\n\n", fmt::join(b.input_names, ", "),
                      fmt::join(b.output_names, ", "),
                      b.default_effects.empty() ? std::string("no effect") : fmt::format("{}", fmt::join(b.default_effects, ", ")));
  for (const auto& e : m.library()) {
    nlohmann::json params = nlohmann::json::array();
    text += fmt::format("{}{}: {}\n  changes: {}\n  residual signature: {}\n", e.name,
                        e.time_only ? " (time domain only: fit --log, diagnose --log)" : "", e.description, e.changes,
                        e.signature);
    for (const auto& p : e.parameters) {
      params.push_back({{"name", p.name}, {"unit", p.unit}, {"value", p.value}, {"lower", p.lower},
                        {"upper", p.upper}, {"free", p.free}});
      text += fmt::format("  {} = {:.10g} {} in [{:.10g}, {:.10g}]{}\n", p.name, p.value, p.unit, p.lower, p.upper,
                          p.free ? " (free)" : " (fixed)");
    }
    list.push_back({{"name", e.name}, {"description", e.description}, {"changes", e.changes},
                    {"signature", e.signature}, {"physics_of_the_base", e.blocks.empty() && !e.time_only},
                    {"time_only", e.time_only}, {"parameters", params}});
  }
  text += "\nuser-defined effects: building blocks delay, first_order, second_order, resonance, gain, coupling, mode "
          "(docs/effects.md; lpvid model define)\n";
  print_summary(o.json, {{"base", b.name}, {"effects", list}}, text);
}

}  // namespace

Command make_model_command() {
  return {"model", "physical model files: init, effects, add, remove, define, export", [](CLI::App& parent) {
            auto o = std::make_shared<ModelCliOptions>();
            auto* app = parent.add_subcommand("model", "Physical (grey-box) model files" + std::string(kModelExample));
            app->require_subcommand(1);
            auto* init = app->add_subcommand("init", "write a model file: a base with its default effects");
            init->add_option("--out", o->out, "model file to write")->required();
            init->add_option("--base", o->base,
                             "the base: platform, stage6, or mechanical (a stage you describe; with --from)");
            init->add_option("--from", o->from,
                             "--base mechanical: the stage's description (JSON: DOFs, M, D, K, actuator and sensor maps; "
                             "docs/formats.md)");
            init->add_option("--set", o->sets,
                             "NAME=VALUE: a design value you know; NAME=VALUE±SIGMA: also its uncertainty, a prior "
                             "for fit and diagnose (repeat)");
            init->add_flag("--bare", o->bare, "the base alone (no effect)");
            init->add_flag("--json", o->json, "print the summary as JSON");
            init->callback([o] { run_init(*o); });
            auto* set = app->add_subcommand("set", "set design values (and priors) of a model file's parameters");
            set->add_option("--model", o->model, "model file to read")->required();
            set->add_option("--set", o->sets, "NAME=VALUE or NAME=VALUE±SIGMA (a prior; repeat)");
            set->add_option("--fix", o->fix,
                            "NAME (or NAME,NAME): hold the parameter at its value in fit and diagnose (a datasheet "
                            "value; repeat)");
            set->add_option("--free", o->free, "NAME (or NAME,NAME): estimate the parameter in fit and diagnose (repeat)");
            set->add_option("--out", o->out, "write here (a new file continuing the fit history) instead of in place");
            set->add_flag("--json", o->json, "print the summary as JSON");
            set->callback([o] { run_set(*o); });
            auto* add = app->add_subcommand("add", "add an effect (with its defaults) to a model file");
            add->add_option("effect", o->effect,
                            "effect name (see 'lpvid model effects'), or several separated by commas")
                ->required();
            add->add_option("--model", o->model, "model file to read")->required();
            add->add_option("--from-diagnosis", o->from_diagnosis,
                            "start from the values 'lpvid diagnose --json' fitted for this effect (or combination)");
            add->add_option("--out", o->out, "write here (a new file continuing the fit history) instead of in place");
            add->add_flag("--json", o->json, "print the summary as JSON");
            add->callback([o] { run_add(*o); });
            auto* rem = app->add_subcommand("remove", "remove an effect and its parameters from a model file");
            rem->add_option("effect", o->effect, "effect name")->required();
            rem->add_option("--model", o->model, "model file to read")->required();
            rem->add_option("--out", o->out, "write here (a new file continuing the fit history) instead of in place");
            rem->add_flag("--json", o->json, "print the summary as JSON");
            rem->callback([o] { run_remove(*o); });
            auto* def = app->add_subcommand("define", "declare a user-defined effect (building blocks) in a model file");
            def->add_option("--model", o->model, "model file to read")->required();
            def->add_option("--from", o->from, "effect definition file (JSON; lpvid diagnose --out-effect writes one)")
                ->required();
            def->add_flag("--add", o->add_defined, "also add the effect to the model");
            def->add_option("--out", o->out, "write here (a new file continuing the fit history) instead of in place");
            def->add_flag("--json", o->json, "print the summary as JSON");
            def->callback([o] { run_define(*o); });
            auto* exp = app->add_subcommand("export", "the model at one x_b as a state-space JSON");
            exp->add_option("--model", o->model, "model file")->required();
            exp->add_option("--xb", o->xb,
                            "the operating point: beam position x_b in m (platform), hover height above the "
                            "reference gap in m (stage6); none for a base without one (mechanical)")
                ->check(number_in(-1e3, 1e3, "the operating point in m"));
            exp->add_option("--rate-hz", o->rate_hz, "sample (ZOH) at this rate (default: continuous)")
                ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz (omit it for continuous time)"));
            exp->add_option("--out", o->out, "state-space JSON to write ('-' = stdout)")->required();
            exp->add_flag("--json", o->json, "print the summary as JSON");
            exp->callback([o] { run_export(*o); });
            auto* eff = app->add_subcommand("effects", "list a base's parameters and its effect library");
            eff->add_option("--base", o->base, "the base (default platform; mechanical with --from)");
            eff->add_option("--from", o->from, "--base mechanical: the stage's description (JSON)");
            eff->add_flag("--json", o->json, "print the list as JSON");
            eff->callback([o] { run_effects(*o); });
          }};
}

}  // namespace lpvid::cli
