// lpvid stage6 — thin aliases of the shared stage route: `stage6 fit` is
// `lpvid fit --model M --log RUN.csv` and `stage6 diagnose` is `lpvid diagnose
// --model M --log RUN.csv`, with M the stage6 base plus the effects named by
// --effects (com -> com_offset, gap -> gap_dependence, lag -> electrical_lag).
// One implementation (cli/stage6_time.h); the output file is a stage6 physical
// model file, as `lpvid fit` writes.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <memory>

#include "cli/common.h"
#include "cli/registry.h"
#include "cli/stage6_time.h"
#include "formats/io/history.h"
#include "idlib/core/error.h"
#include "idlib/stage6/stage6_time.h"

namespace lpvid::cli {
namespace {

constexpr const char* kStage6Example = R"(
Example:
  lpvid simulate stage6 --experiment --out exp --effects gap --seed 3
  lpvid stage6 diagnose --log exp/exp_stage6.csv                 # which effect is missing?
  lpvid stage6 fit --log exp/exp_stage6.csv --effects gap --out stage.json
  lpvid history --model stage.json
  lpvid stage6 fit --log exp/exp_stage6.csv --effects gap --method both   # equation and output error
These are aliases of the shared commands on a stage6 model file:
  lpvid model init --base stage6 --out m.json && lpvid model add gap_dependence --model m.json --out m.json
  lpvid fit --model m.json --log exp/exp_stage6.csv --out stage.json
  lpvid diagnose --model m.json --log exp/exp_stage6.csv
  lpvid compare --model stage.json --log exp/exp_stage6.csv --out-png where.png   # failing time windows
The log's u1..u6 are the commanded body wrench (F_x F_y F_z tau_x tau_y tau_z) and q1..q6
the measured configuration (x y z psi theta phi).  --method equation fits the sampled
equations of motion (docs/math.md, the 6-DOF stage); the mass is held at 5.47 kg and the
force constant fitted (--fit-mass: the other way round; only their ratio is
identifiable).  --method output (the default, as fit --log) refines it by output error
(simulated 0.3 s windows of the logged wrench against the measured q, each window with its
own initial state), which removes the equation error's bias towards low inertias on noisy
logs and reports standard errors; --method both prints the two.  Effects: com (centre-of-mass offset), gap
(gap-dependent force constant alpha(z)), lag (motor electrical lag with back-EMF).
diagnose refits the model given by --effects with each effect it lacks added alone and
ranks them by BIC; an effect is significant when it lowers BIC by more than 10.)";

struct Stage6IdOptions {
  std::string log, out;
  std::vector<std::string> effects;
  std::string method = "output";  // fit: equation | output | both (fit --log's default)
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

PhysicalModel start_model(const Stage6IdOptions& o) {
  return stage6_model_of(model_of(o.effects), !o.fit_mass);
}

std::string label_of(const Stage6IdOptions& o) {
  std::string e;
  for (const auto& x : o.effects) e += (e.empty() ? "" : ",") + x;
  return e.empty() ? "the stage6 base" : "the stage6 base with --effects " + e;
}

void run_fit(const Stage6IdOptions& o) {
  StageTimeFitRequest req;
  req.start = start_model(o);
  req.model_label = label_of(o);
  req.log = o.log;
  req.out = o.out;
  req.method = o.method;
  req.command = "stage6 fit";
  if (!o.out.empty()) req.history_from = history_path_for(o.out);
  req.json = o.json;
  run_stage_time_fit(req);
}

void run_diagnose(const Stage6IdOptions& o) {
  StageTimeDiagnoseRequest req;
  req.current = start_model(o);
  req.model_label = label_of(o);
  req.log = o.log;
  req.command = "stage6 diagnose";
  req.json = o.json;
  run_stage_time_diagnose(req);
}

}  // namespace

Command make_stage6_command() {
  return {"stage6", "grey-box fit and diagnosis of the 6-DOF maglev stage from a log", [](CLI::App& parent) {
            auto* app = parent.add_subcommand(
                "stage6", "Identify the 6-DOF maglev stage (seed 001) from a closed-loop log" + std::string(kStage6Example));
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
                sub->add_option("--out", o->out, "write the fitted stage6 model file (as lpvid fit) and its history");
                sub->add_option("--method", o->method,
                                "output (default, as fit --log): output error started from the equation error (unbiased "
                                "with sensor noise, standard errors); equation: equation error only; both: print the two");
              }
              sub->add_flag("--json", o->json, "print the summary as JSON");
              sub->callback([o, diagnose] { diagnose ? run_diagnose(*o) : run_fit(*o); });
            }
          }};
}

}  // namespace lpvid::cli
