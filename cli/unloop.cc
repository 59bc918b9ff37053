// lpvid unloop — the plant from the identified closed loop and the known
// controller: P = G (I - C G)^-1 (seed 000, eq 14), reduced to a minimal
// realisation by removing the modes at the controller's poles.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <optional>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/model_json.h"
#include "cli/responses.h"
#include "formats/io/frd_csv.h"
#include "idlib/closedloop/sensitivity.h"
#include "idlib/closedloop/unloop.h"
#include "idlib/core/error.h"
#include "idlib/fit/fit.h"
#include "idlib/lti/analysis.h"

namespace lpvid::cli {
namespace {

constexpr const char* kUnloopExample = R"(
Example:
  lpvid unloop --closed-loop closed_loop.json --controller controller.json --out plant.json
The interconnection G (I - C G)^-1 has order n_G + n_C; the controller's modes cancel
only nearly in an estimated G (they may sit just outside the unit circle), so they are
removed by an ordered Schur form and decoupling, leaving order n_G - n_C (6 for the
3-DOF platform) unless --order says otherwise.
Frequency-domain data (per frequency, no model order involved):
  lpvid unloop --sensitivity S.csv --controller controller.json --out P.csv
  lpvid unloop --sensitivity S_v1.csv S_v2.csv S_v3.csv --controller controller.json --out P.csv
  lpvid unloop --closed-loop G.csv --controller controller.json --out P.csv
P = C^-1 (S^-1 - I) from the input sensitivity S (v -> u; the paper's printed eq 15,
C^-1 (S - I)^-1, is wrong: see docs/math.md), or P = G (I - C G)^-1 from closed-loop data,
with C evaluated at z = exp(j w Ts), or C measured: --controller C.csv (an FRD of C, p inputs,
m outputs, on exactly the data's frequencies).  Files that each hold one excited input are merged.
Frequencies where C or S^-1 - I is ill-conditioned, the loop gain (sigma_min of S^-1 - I) is
below --min-loop-gain, or the coherence is low, are flagged
in the output (column flag) and counted in the summary.)";

struct UnloopCliOptions {
  std::string closed_loop, controller, out;
  std::vector<std::string> sensitivity;
  double max_condition = 1e6, min_coherence = 0.5, min_loop_gain = SensitivityUnloopOptions{}.min_loop_gain;
  Index order = 0;
  bool json = false;
};

// Per-frequency route: S (or G: closed_loop) data and the controller -> plant FRD.
// The controller: a model (JSON), or its measured response on the data's lines.
void run_frd(const UnloopCliOptions& o, OutputSet& outputs, const FrequencyResponse* closed_loop) {
  std::optional<StateSpace> model;
  std::optional<FrequencyResponse> measured;
  if (is_measured_controller(o.controller)) {
    measured = read_measured_controller(o.controller);
  } else {
    model = read_controller(o.controller);
  }
  const KnownController c = model ? KnownController(*model) : KnownController(*measured);
  SensitivityUnloopOptions options;
  options.max_condition = o.max_condition;
  options.min_coherence = o.min_coherence;
  options.min_loop_gain = o.min_loop_gain;
  options.validate();
  FrequencyResponse plant;
  Index flagged = 0;
  std::vector<std::string> warnings;
  std::string route, variance_note;
  if (!o.sensitivity.empty()) {
    const FrequencyResponse s = load_frd_merged(o.sensitivity);
    // Analyzer exports hold one excited input per file: a missing file leaves S
    // with fewer columns than the controller has outputs.
    if (s.num_inputs() != c.num_outputs() && s.num_outputs() == c.num_outputs())
      throw InputError(fmt::format(
          "--sensitivity: the file(s) hold S for {} excited input(s) but the controller has {} outputs; give the "
          "file of every excited input (e.g. S_v1.csv S_v2.csv S_v3.csv) or one file with every pair",
          s.num_inputs(), c.num_outputs()));
    const SensitivityUnloopResult r = plant_from_sensitivity(s, c, options);
    plant = r.plant;
    flagged = r.flagged_count;
    warnings = r.report.warnings;
    route = "P = C^-1 (S^-1 - I)";
    // P's variance from S's: its own variance column, or its coherence with the number of
    // averages (the noise the fit and diagnose read from data, idlib/fit data_sigma).
    bool known = false;
    std::string source;
    const std::vector<Eigen::MatrixXd> sigma = data_sigma(s, NoiseOptions{}, &source, &known);
    if (known) {
      std::vector<Eigen::MatrixXd> s_variance;
      for (const Eigen::MatrixXd& sg : sigma) s_variance.push_back(2.0 * sg.cwiseAbs2());  // both real parts
      std::vector<Eigen::MatrixXd> variance = plant_variance_from_sensitivity(s, s_variance, c);
      Index unknown = 0;
      for (const Eigen::MatrixXd& v : variance) unknown += v.allFinite() ? 0 : 1;
      if (unknown == 0) {
        plant.variance = std::move(variance);
        variance_note = "var_<i>_<j>: E|P^ - P|^2 propagated from the " + source +
                        " of S (first order, entries of S independent)";
      } else {
        warnings.push_back(fmt::format("no variance written: at {} frequencies S or C is singular or S's noise is "
                                       "unknown, so nothing is known of P there",
                                       unknown));
      }
    }
  } else {
    plant = plant_from_closed_loop_frd(*closed_loop, c);
    for (bool f : plant.flagged) flagged += f ? 1 : 0;
    route = "P = G (I - C G)^-1";
  }
  // The plant's outputs are the measured q; the controller's inputs are their
  // errors e = -q, conventionally named e_<q> (as lpvid simulate writes them).
  for (auto& name : plant.output_names)
    if (name.rfind("e_", 0) == 0) name = name.substr(2);
  std::vector<std::string> comments = {"lpvid unloop: " + route + " per frequency"};
  if (!variance_note.empty()) comments.push_back(variance_note);
  write_frd_csv(outputs.stage(o.out), plant, "P", comments);
  outputs.commit();
  nlohmann::json summary = {{"route", route},         {"frequencies", plant.num_frequencies()},
                            {"flagged", flagged},     {"variance", !plant.variance.empty()},
                            {"warnings", warnings},   {"out", o.out}};
  std::string text = fmt::format("unloop: {} at {} frequencies, {} flagged as untrustworthy\n", route,
                                 plant.num_frequencies(), flagged);
  if (!variance_note.empty()) text += "  with the variance of P (" + variance_note.substr(variance_note.find("from")) + ")\n";
  for (const auto& w : warnings) text += "warning: " + w + "\n";
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

void run(const UnloopCliOptions& o) {
  if (!o.sensitivity.empty() && !o.closed_loop.empty())
    throw InputError("give either --sensitivity (S data) or --closed-loop (G), not both");
  if (o.sensitivity.empty() && o.closed_loop.empty())
    throw InputError("give --closed-loop G.json (or G data) or --sensitivity S.csv");
  OutputSet outputs;
  outputs.inputs(o.sensitivity);
  outputs.input(o.closed_loop);
  outputs.input(o.controller);
  outputs.file("--out", o.out);
  outputs.check();
  // G as a model or as data; "-" (stdin) by its content.
  std::optional<LoadedResponse> loaded;
  if (!o.closed_loop.empty()) loaded = load_response(o.closed_loop);
  if (!loaded || !loaded->model) return run_frd(o, outputs, loaded ? &*loaded->frd : nullptr);
  const StateSpace& g = *loaded->model;
  if (is_measured_controller(o.controller))
    throw InputError(fmt::format("--controller {}: a measured controller (FRD) serves the per-frequency routes only; "
                                 "give G or S as data (--closed-loop G.csv, --sensitivity S.csv), or the controller "
                                 "as a model (JSON)",
                                 o.controller));
  const StateSpace c = read_controller(o.controller);
  UnloopOptions options;
  options.plant_order = o.order;
  const UnloopResult r = plant_from_closed_loop(g, c, options);
  outputs.stage(o.out, state_space_to_json(r.plant, {{"provenance", {{"command", "lpvid unloop"},
                                                                     {"closed_loop", o.closed_loop},
                                                                     {"controller", o.controller}}}}));
  outputs.commit();
  const bool stable = is_stable(r.plant);
  nlohmann::json summary = {{"order", r.plant.order()},
                            {"interconnection_order", r.interconnection_order},
                            {"removed_modes", r.removed_poles.size()},
                            {"stable", stable},
                            {"termination", r.report.termination},
                            {"warnings", r.report.warnings},
                            {"out", o.out}};
  std::string text = fmt::format("unloop: plant of order {} from an interconnection of order {} ({} modes removed); {}\n",
                                 r.plant.order(), r.interconnection_order, r.removed_poles.size(), r.report.termination);
  for (const auto& w : r.report.warnings) text += "warning: " + w + "\n";
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_unloop_command() {
  return {"unloop", "plant from closed-loop model and controller", [](CLI::App& parent) {
            auto o = std::make_shared<UnloopCliOptions>();
            auto* app = parent.add_subcommand("unloop", "Plant P = G (I - C G)^-1 from the closed loop G and controller C" +
                                                            std::string(kUnloopExample));
            app->add_option("--closed-loop", o->closed_loop,
                            "closed-loop G (v -> q): state-space JSON, or FRD data (.csv, .mat)");
            app->add_option("--sensitivity", o->sensitivity,
                            "input sensitivity S (v -> u) FRD file(s) (.csv, .mat); several are merged");
            app->add_option("--max-condition", o->max_condition,
                            "flag frequencies where C or S^-1 - I has a larger condition number")
                ->check(number_in(1, INFINITY, "the largest condition number", true));
            app->add_option("--min-coherence", o->min_coherence, "flag frequencies with lower coherence")
                ->check(number_in(0, 1, "the smallest coherence"));
            app->add_option("--min-loop-gain", o->min_loop_gain,
                            "flag frequencies where sigma_min(S^-1 - I) = sigma_min(C P) is below this (0 = off)")
                ->check(number_in(0, INFINITY, "the smallest loop gain"));
            app->add_option("--controller", o->controller, "controller C (e = -q -> u_c): state-space or transfer-function JSON, or its measured response (FRD .csv/.mat, data routes only, on the data's frequencies)")->required();
            app->add_option("--out", o->out, "plant to write: model JSON, or FRD CSV for data ('-' = stdout)")
                ->required();
            app->add_option("--order", o->order, "plant order (default: closed-loop order minus controller order)")
                ->check(integer_in(1, kMaxModelStates, "the plant order"));
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
