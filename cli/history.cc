// lpvid history — the fits of a model, one by one: the model error falling as
// effects are added (formats/io/history.h), as a table, --json, and a PNG.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/history.h"
#include "formats/plot/history_plot.h"
#include "idlib/core/error.h"

namespace lpvid::cli {
namespace {

constexpr const char* kHistoryExample = R"(
Example:
  lpvid history --model plant.json --png history.png
  lpvid history --model plant.json --json
Reads plant.json.history.jsonl (one record per fit, appended by the fit; docs/formats.md,
"Fit history") and prints the error model by model: effects, free parameters, cost, the
error figure (the number fit and diagnose print) beside the data's noise floor, the
largest channel error, AIC/BIC and the change from the previous fit.  A model whose
error is within about 1.5x its floor fits within the noise.  --png draws the error
falling: one bar per fit (log scale) with the noise floor as a green line, labelled
with the effects the fit added or removed.)";

struct HistoryCliOptions {
  std::string model, png;
  bool json = false;
};


// The error figure of a record (older records without one: the mean channel error).
double figure(const HistoryRecord& r) { return std::isfinite(r.error) ? r.error : r.error_mean; }

std::string effects_text(const HistoryRecord& r) {
  return r.effects.empty() ? std::string("(no effects)") : fmt::format("{}", fmt::join(r.effects, ", "));
}

// What changed from the previous fit: "+ delay, - damping" (or "same effects").
std::string effects_change(const HistoryRecord& before, const HistoryRecord& after) {
  std::vector<std::string> parts;
  for (const auto& e : after.effects)
    if (std::find(before.effects.begin(), before.effects.end(), e) == before.effects.end()) parts.push_back("+ " + e);
  for (const auto& e : before.effects)
    if (std::find(after.effects.begin(), after.effects.end(), e) == after.effects.end()) parts.push_back("- " + e);
  return parts.empty() ? std::string("same effects") : fmt::format("{}", fmt::join(parts, ", "));
}

void run(const HistoryCliOptions& o) {
  const std::string path = history_path_for(o.model);
  OutputSet outputs;
  outputs.input(o.model);
  outputs.input(path);
  outputs.file("--png", o.png);
  outputs.check();
  const std::vector<HistoryRecord> records = read_history(path);
  if (records.empty())
    throw InputError(fmt::format("history '{}' is empty; fit a model first (each fit appends a record)", path));
  nlohmann::json fits = nlohmann::json::array();
  std::string text = fmt::format("history of {} ({} fit{}, {}):\n", o.model, records.size(),
                                 records.size() == 1 ? "" : "s", path);
  text += "  fit  timestamp             params  cost        error      floor      max chan   change   AIC         BIC         effects\n";
  for (std::size_t k = 0; k < records.size(); ++k) {
    const HistoryRecord& r = records[k];
    const double before = k == 0 ? 0.0 : figure(records[k - 1]);
    const double change = k == 0 || before == 0 ? std::nan("") : 100.0 * (figure(r) - before) / before;
    nlohmann::json channels = nlohmann::json::array();
    for (const auto& c : r.channels)
      channels.push_back({{"output", c.output}, {"input", c.input}, {"error_mean", c.error_mean}, {"error_max", c.error_max}});
    fits.push_back({{"fit", k + 1},
                    {"timestamp", r.timestamp},
                    {"model", r.model},
                    {"effects", r.effects},
                    {"free_parameters", r.free_parameters},
                    {"cost", r.cost},
                    {"error", number_or_null(r.error)},
                    {"noise_floor", number_or_null(r.noise_floor)},
                    {"error_mean", r.error_mean},
                    {"error_max", r.error_max},
                    {"change_percent", number_or_null(change)},
                    {"aic", number_or_null(r.aic)},
                    {"bic", number_or_null(r.bic)},
                    {"channels", channels},
                    {"note", r.note}});
    auto num = [](double v) { return std::isfinite(v) ? fmt::format("{:<10.4g}", v) : std::string("-         "); };
    auto pct = [](double v) { return std::isfinite(v) ? fmt::format("{:7.3f} %", 100 * v) : std::string("      -  "); };
    text += fmt::format("  {:<4} {:<20}  {:6d}  {:<10.4g}  {}  {}  {:7.3f} %  {:>7}  {}  {}  {}{}\n", k + 1,
                        r.timestamp, r.free_parameters, r.cost, pct(figure(r)), pct(r.noise_floor), 100 * r.error_max,
                        std::isfinite(change) ? fmt::format("{:+.0f} %", change) : std::string("-"), num(r.aic),
                        num(r.bic), effects_text(r), r.note.empty() ? "" : "  (" + r.note + ")");
  }
  nlohmann::json summary = {{"model", o.model}, {"history", path}, {"fits", fits}};
  if (!o.png.empty()) {
    std::vector<HistoryBar> bars;
    for (std::size_t k = 0; k < records.size(); ++k) {
      const auto& r = records[k];
      if (!(figure(r) > 0))
        throw InputError(fmt::format("{}: fit {} has an error of 0, which a log-scale chart cannot show; use --json",
                                     path, k + 1));
      HistoryBar bar{fmt::format("{}: {}", k + 1, k == 0 ? effects_text(r) : effects_change(records[k - 1], r)),
                     100 * figure(r), 100 * std::max(r.error_max, figure(r))};
      if (std::isfinite(r.noise_floor) && r.noise_floor > 0) bar.floor_percent = 100 * r.noise_floor;
      bars.push_back(bar);
    }
    const auto png = history_png(bars, fmt::format("Model error, fit by fit: {}", o.model));
    outputs.stage(o.png, png);
    summary["png"] = o.png;
  }
  outputs.commit();
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_history_command() {
  return {"history", "the model error fit by fit (table and PNG)", [](CLI::App& parent) {
            auto o = std::make_shared<HistoryCliOptions>();
            auto* app = parent.add_subcommand("history", "The fits of a model and the error falling" + std::string(kHistoryExample));
            app->add_option("--model", o->model, "model whose history to show (reads MODEL.history.jsonl)")->required();
            app->add_option("--png", o->png, "write a chart of the error falling");
            app->add_flag("--json", o->json, "print the history as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
