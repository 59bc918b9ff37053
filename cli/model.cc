// lpvid model — physical model files: create one, list and add effects, export
// the model at any beam position as a state-space JSON (the LPV model frozen at x_b).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <memory>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid model init --out start.json                 (platform + rod_twist, com_offset, beam_gravity)
  lpvid model init --bare --out base.json           (the base model of eqs 2-8 alone)
  lpvid model effects                               (the effect library: parameters, units, bounds)
  lpvid model add input_delay --model start.json    (adds the effect with its defaults)
  lpvid model export --model fitted.json --xb 0.05 --rate-hz 1000 --out P_005.json
'model add' reads and rewrites the same file on purpose (atomically: a failed run leaves it
unchanged); it drops the file's "fit" section, which no longer describes the model.
'model export' writes the state-space JSON at x_b: continuous without --rate-hz (an input
delay is then not in the matrices; the summary gives it), ZOH-discretised with it (a delay is
rounded to whole samples and realised as extra states).  See docs/effects.md.)";

struct ModelCliOptions {
  std::string out, model, effect;
  double xb = 0.0, rate_hz = 0.0;
  bool bare = false, json = false;
};

void run_init(const ModelCliOptions& o) {
  OutputSet outputs;
  outputs.file("--out", o.out);
  outputs.check();
  const PhysicalModel m = o.bare ? PhysicalModel::bare_platform() : PhysicalModel::default_platform();
  outputs.stage(o.out, physical_model_to_json(m));
  outputs.commit();
  std::string effects;
  for (const auto& e : m.effects) effects += (effects.empty() ? "" : ", ") + e;
  if (!outputs.to_stdout())
    print_summary(o.json, {{"out", o.out}, {"effects", m.effects}, {"parameters", m.parameters.size()}},
                  fmt::format("model init: wrote {} (base platform; effects: {})\n", o.out,
                              effects.empty() ? "none" : effects));
}

void run_add(const ModelCliOptions& o) {
  OutputSet outputs;  // the model file is read and rewritten on purpose
  outputs.input(o.model);
  outputs.rewrite("--model", o.model);
  outputs.check();
  PhysicalModel m = read_physical_model(o.model);
  m.add_effect(o.effect);
  outputs.stage(o.model, physical_model_to_json(m));
  outputs.commit();
  print_summary(o.json, {{"model", o.model}, {"added", o.effect}, {"effects", m.effects}},
                fmt::format("model add: {} added to {} (effects now: {})\n", o.effect, o.model,
                            fmt::join(m.effects, ", ")));
}

void run_export(const ModelCliOptions& o) {
  OutputSet outputs;
  outputs.input(o.model);
  outputs.file("--out", o.out);
  outputs.check();
  const PhysicalModel m = read_physical_model(o.model);
  const double ts = o.rate_hz > 0 ? 1.0 / o.rate_hz : 0.0;
  const PhysicalStateSpace ss = physical_state_space(m, o.xb, ts);
  outputs.stage(o.out, state_space_to_json(ss.system, {{"provenance",
                                                        {{"command", "lpvid model export"}, {"model", o.model},
                                                         {"x_b_m", o.xb}, {"effects", m.effects},
                                                         {"input_delay_s", ss.input_delay_s},
                                                         {"delay_in_matrices_samples", ss.delay_samples}}}}));
  outputs.commit();
  std::string text = fmt::format("model export: {} at x_b = {} m, order {}, {}\n", o.model, o.xb, ss.system.order(),
                                 ts > 0 ? fmt::format("ZOH at {} Hz", o.rate_hz) : "continuous");
  if (ss.input_delay_s > 0)
    text += ts > 0 ? fmt::format("input delay {} s realised as {} samples of extra states\n", ss.input_delay_s,
                                 ss.delay_samples)
                   : fmt::format("note: input delay {} s is not in the continuous matrices; apply exp(-s tau)\n",
                                 ss.input_delay_s);
  if (!outputs.to_stdout())
    print_summary(o.json, {{"out", o.out}, {"order", ss.system.order()}, {"sample_period_s", ts},
                           {"input_delay_s", ss.input_delay_s}, {"delay_samples", ss.delay_samples}},
                  text);
}

void run_effects(const ModelCliOptions& o) {
  nlohmann::json list = nlohmann::json::array();
  std::string text;
  for (const auto& e : effect_library()) {
    nlohmann::json params = nlohmann::json::array();
    text += fmt::format("{}: {}\n  changes: {}\n  residual signature: {}\n", e.name, e.description, e.changes,
                        e.signature);
    for (const auto& p : e.parameters) {
      params.push_back({{"name", p.name}, {"unit", p.unit}, {"value", p.value}, {"lower", p.lower},
                        {"upper", p.upper}, {"free", p.free}});
      text += fmt::format("  {} = {} {} in [{}, {}]{}\n", p.name, p.value, p.unit, p.lower, p.upper,
                          p.free ? " (free)" : " (fixed)");
    }
    list.push_back({{"name", e.name}, {"description", e.description}, {"changes", e.changes},
                    {"signature", e.signature}, {"parameters", params}});
  }
  print_summary(o.json, {{"effects", list}}, text);
}

}  // namespace

Command make_model_command() {
  return {"model", "physical model files: init, effects, add, export", [](CLI::App& parent) {
            auto o = std::make_shared<ModelCliOptions>();
            auto* app = parent.add_subcommand("model", "Physical (grey-box) model files" + std::string(kExample));
            app->require_subcommand(1);
            auto* init = app->add_subcommand("init", "write the default platform model file");
            init->add_option("--out", o->out, "model file to write")->required();
            init->add_flag("--bare", o->bare, "the base model only (no effect)");
            init->add_flag("--json", o->json, "print the summary as JSON");
            init->callback([o] { run_init(*o); });
            auto* add = app->add_subcommand("add", "add an effect (with its defaults) to a model file, in place");
            add->add_option("effect", o->effect, "effect name (see 'lpvid model effects')")->required();
            add->add_option("--model", o->model, "model file to read and rewrite")->required();
            add->add_flag("--json", o->json, "print the summary as JSON");
            add->callback([o] { run_add(*o); });
            auto* exp = app->add_subcommand("export", "the model at one x_b as a state-space JSON");
            exp->add_option("--model", o->model, "model file")->required();
            exp->add_option("--xb", o->xb, "beam position x_b in m")
                ->required()
                ->check(number_in(-1e3, 1e3, "the beam position in m"));
            exp->add_option("--rate-hz", o->rate_hz, "ZOH-discretise at this rate (default: continuous)")
                ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz (omit it for continuous time)"));
            exp->add_option("--out", o->out, "state-space JSON to write ('-' = stdout)")->required();
            exp->add_flag("--json", o->json, "print the summary as JSON");
            exp->callback([o] { run_export(*o); });
            auto* eff = app->add_subcommand("effects", "list the effect library");
            eff->add_flag("--json", o->json, "print the list as JSON");
            eff->callback([o] { run_effects(*o); });
          }};
}

}  // namespace lpvid::cli
