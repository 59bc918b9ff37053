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
#include "idlib/realization/era.h"

namespace lpvid::cli {
namespace {

constexpr const char* kRealizeExample = R"(
Example:
  lpvid realize g.csv --out closed_loop.json            # order chosen automatically
  lpvid realize g.csv --out closed_loop.json --order 9
The order rule: singular values must stand above the noise floor estimated from the
Markov parameters' standard errors, and the order is the largest gap among those
(see docs/subcommands.md).  The model is discrete with the logs' sample period.)";

struct RealizeOptions {
  std::string markov, out;
  Index order = 0, max_order = 40;
  bool json = false;
};

void run(const RealizeOptions& o) {
  OutputSet outputs;
  outputs.input(o.markov);
  outputs.file("--out", o.out);
  outputs.check();
  const MarkovFile file = read_markov_csv(o.markov);
  EraOptions options = era_options_from(file);
  options.order = o.order;
  options.max_order = o.max_order;
  const EraResult era = realize_era(file.g, options);
  const nlohmann::json selection = {{"order", era.selection.order},
                                    {"rule", era.selection.rule},
                                    {"reason", era.selection.reason},
                                    {"noise_floor", era.selection.noise_floor},
                                    {"block_rows", era.block_rows},
                                    {"block_cols", era.block_cols},
                                    {"stride", era.stride}};
  outputs.stage(o.out, state_space_to_json(era.model, {{"provenance", {{"command", "lpvid realize"},
                                                                        {"markov", o.markov},
                                                                        {"selection", selection}}}}));
  outputs.commit();
  nlohmann::json summary = selection;
  summary["warnings"] = era.report.warnings;
  summary["out"] = o.out;
  std::string text = fmt::format("realize: order {} ({}); Hankel {} x {} blocks, stride {}\n", era.selection.order,
                                 era.selection.reason, era.block_rows, era.block_cols, era.stride);
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
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
