// lpvid unloop — the plant from the identified closed loop and the known
// controller: P = G (I - C G)^-1 (seed 000, eq 14), reduced to a minimal
// realisation by removing the modes at the controller's poles.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/model_json.h"
#include "idlib/closedloop/unloop.h"
#include "idlib/core/error.h"
#include "idlib/lti/analysis.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid unloop --closed-loop closed_loop.json --controller controller.json --out plant.json
The interconnection G (I - C G)^-1 has order n_G + n_C; the controller's modes cancel
only nearly in an estimated G (they may sit just outside the unit circle), so they are
removed by an ordered Schur form and decoupling, leaving order n_G - n_C (6 for the
3-DOF platform) unless --order says otherwise.)";

struct UnloopCliOptions {
  std::string closed_loop, controller, out;
  Index order = 0;
  bool json = false;
};

void run(const UnloopCliOptions& o) {
  if (o.order < 0) throw InputError(fmt::format("--order {}: must be positive (omit it for automatic)", o.order));
  check_not_overwriting({o.closed_loop, o.controller}, o.out);
  const StateSpace g = read_state_space(o.closed_loop);
  const StateSpace c = read_state_space(o.controller);
  UnloopOptions options;
  options.plant_order = o.order;
  const UnloopResult r = plant_from_closed_loop(g, c, options);
  write_state_space(o.out, r.plant,
                    {{"provenance",
                      {{"command", "lpvid unloop"}, {"closed_loop", o.closed_loop}, {"controller", o.controller}}}});
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
  if (o.out != "-") print_summary(o.json, summary, text);
}

}  // namespace

Command make_unloop_command() {
  return {"unloop", "plant from closed-loop model and controller", [](CLI::App& parent) {
            auto o = std::make_shared<UnloopCliOptions>();
            auto* app = parent.add_subcommand("unloop", "Plant P = G (I - C G)^-1 from the closed loop G and controller C" +
                                                            std::string(kExample));
            app->add_option("--closed-loop", o->closed_loop, "closed-loop model G (v -> q), state-space JSON")
                ->required();
            app->add_option("--controller", o->controller, "controller C (e = -q -> u_c), state-space JSON")->required();
            app->add_option("--out", o->out, "plant model JSON to write ('-' = stdout)")->required();
            app->add_option("--order", o->order, "plant order (default: closed-loop order minus controller order)");
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
