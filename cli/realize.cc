// lpvid realize — Ho-Kalman / ERA state-space realisation of Markov parameters
// (seed 000, eqs 10–13 with B and C corrected; DESIGN.md item 2).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/markov_csv.h"
#include "formats/io/model_json.h"
#include "idlib/core/error.h"
#include "idlib/identify/output_error.h"
#include "idlib/lti/analysis.h"
#include "idlib/realization/era.h"

namespace lpvid::cli {
namespace {

constexpr const char* kRealizeExample = R"(
Example:
  lpvid realize g.csv --out closed_loop.json            # order chosen automatically
  lpvid realize g.csv --out closed_loop.json --order 9
The order rule: singular values must stand above the noise floor estimated from the
Markov parameters' standard errors, and the order is the largest gap among those
(see docs/subcommands.md).  The model is discrete with the logs' sample period.
An unstable realisation is refitted to the Markov parameters with every pole inside the
unit circle, and the stable model is written unless it fits them worse (then the data
point to an unstable response; --keep-unstable: always as realised).)";

struct RealizeOptions {
  std::string markov, out;
  Index order = 0, max_order = 40;
  bool json = false, keep_unstable = false;
};

double spectral_radius(const StateSpace& model) {
  return model.order() == 0 ? 0.0 : poles(model).cwiseAbs().maxCoeff();
}

void run(const RealizeOptions& o) {
  OutputSet outputs;
  outputs.input(o.markov);
  outputs.file("--out", o.out);
  outputs.check();
  const MarkovFile file = read_markov_csv(o.markov);
  EraOptions options = era_options_from(file);
  options.order = o.order;
  options.max_order = o.max_order;
  EraResult era = realize_era(file.g, options);
  // An unstable realisation (noise, or the smoothing of a regularised estimate, moved a pole
  // outside): refit it to the Markov parameters with every pole inside the unit circle, and
  // say so.  The unstable model stays when the stable one fits the Markov parameters worse
  // (the data then point to an unstable response).
  nlohmann::json stabilized = nullptr;
  std::string stabilized_text;
  const double radius = spectral_radius(era.model);
  if (radius >= 1.0 && !o.keep_unstable) {
    const MarkovStableFit fit = fit_markov_stable(file.g, era.model);
    const bool stable = fit.result.accepted && spectral_radius(fit.result.model) < 1.0;
    const bool used = stable && fit.error <= fit.start_error;
    if (stable && !used) {
      stabilized_text = fmt::format(
          "kept unstable: the best stable model fits the Markov parameters worse (relative impulse-response error "
          "{:.4g} against {:.4g}{}), so the data point to an unstable response",
          fit.error, fit.start_error, fit.grows ? "; and the response grows over the lags" : "");
    } else if (used) {
      StateSpace model = fit.result.model;
      model.input_names = era.model.input_names;
      model.output_names = era.model.output_names;
      era.model = std::move(model);
      std::erase_if(era.report.warnings, [](const std::string& w) { return w.starts_with("the realised model is unstable"); });
      stabilized_text = fmt::format(
          "stabilised: the ERA model's largest pole had |z| = {:.6g}; refitted to the Markov parameters with every "
          "pole inside the unit circle (output error in modal form): relative impulse-response error {:.4g} -> {:.4g}, "
          "largest pole now |z| = {:.6g}",
          radius, fit.start_error, fit.error, spectral_radius(era.model));
    } else {
      stabilized_text = fmt::format("kept unstable: the stable refit was not used ({})", fit.result.reason);
    }
    stabilized = {{"used", used},
                  {"start_spectral_radius", radius},
                  {"spectral_radius", spectral_radius(era.model)},
                  {"start_relative_error", fit.start_error},
                  {"relative_error", fit.error},
                  {"reason", stabilized_text}};
  }
  const nlohmann::json selection = {{"order", era.selection.order},
                                    {"rule", era.selection.rule},
                                    {"reason", era.selection.reason},
                                    {"noise_floor", era.selection.noise_floor},
                                    {"block_rows", era.block_rows},
                                    {"block_cols", era.block_cols},
                                    {"stride", era.stride}};
  outputs.stage(o.out, state_space_to_json(era.model, {{"provenance", {{"command", "lpvid realize"},
                                                                        {"markov", o.markov},
                                                                        {"selection", selection},
                                                                        {"stabilized", stabilized}}}}));
  outputs.commit();
  nlohmann::json summary = selection;
  summary["warnings"] = era.report.warnings;
  summary["stabilized"] = stabilized;
  summary["out"] = o.out;
  std::string text = fmt::format("realize: order {} ({}); Hankel {} x {} blocks, stride {}\n", era.selection.order,
                                 era.selection.reason, era.block_rows, era.block_cols, era.stride);
  if (!stabilized_text.empty()) text += "note: " + stabilized_text + "\n";
  for (const auto& w : era.report.warnings) text += "warning: " + w + "\n";
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_realize_command() {
  return {"realize", "state-space model from Markov parameters (Ho-Kalman/ERA)", [](CLI::App& parent) {
            auto o = std::make_shared<RealizeOptions>();
            auto* app = parent.add_subcommand("realize", "Ho-Kalman/ERA realisation with automatic order" +
                                                             std::string(kRealizeExample));
            app->add_option("markov", o->markov, "Markov parameter CSV written by 'lpvid markov'")->required();
            app->add_option("--out", o->out, "state-space JSON to write ('-' = stdout)")->required();
            app->add_option("--order", o->order, "model order (default: automatic)")
                ->check(integer_in(1, kMaxModelStates, "the model order"));
            app->add_option("--max-order", o->max_order, "largest order the automatic rule considers")
                ->check(integer_in(1, kMaxModelStates, "the largest order"));
            app->add_flag("--keep-unstable", o->keep_unstable,
                          "write the ERA model as realised even when it is unstable (default: an unstable model is "
                          "refitted with its poles inside the unit circle, and kept unless that fits worse)");
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
