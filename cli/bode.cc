// lpvid bode — magnitude and phase of one or more MIMO models as a PNG: a p x m
// grid of panels with the models overlaid (seed 000, Figs 10 and 13).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <filesystem>

#include "cli/common.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/model_json.h"
#include "formats/plot/bode_plot.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid bode --out plants.png --labels "left,middle,right" left/plant.json middle/plant.json right/plant.json
  lpvid bode --out p.png --hz --min 0.1 --max 100 plant.json truth_plant.json
Discrete models are evaluated at z = exp(j w Ts) up to their Nyquist frequency,
continuous ones at s = j w.  All models must have the same numbers of inputs and outputs.)";

struct BodeCliOptions {
  std::vector<std::string> models;
  std::string out, labels, title;
  bool hz = false, no_phase = false;
  double min = 0, max = 0;
  Index points = 400;
};

void run(const BodeCliOptions& o) {
  if (o.points < 2) throw InputError(fmt::format("--points {}: must be at least 2", o.points));
  check_not_overwriting(o.models, o.out);
  std::vector<std::string> labels;
  if (!o.labels.empty()) labels = split_names(o.labels, "--labels");
  if (!labels.empty() && labels.size() != o.models.size())
    throw InputError(fmt::format("--labels has {} names for {} models; give one label per model", labels.size(),
                                 o.models.size()));
  std::vector<StateSpace> models;
  for (const auto& path : o.models) models.push_back(read_state_space(path));
  const double unit = o.hz ? 2.0 * M_PI : 1.0;  // rad/s per axis unit
  // Default range: 1 rad/s (0.1 Hz) to the lowest Nyquist frequency, or 1000 rad/s.
  double hi = 0;
  for (const auto& m : models)
    if (m.is_discrete()) hi = hi == 0 ? M_PI / m.sample_period_s : std::min(hi, M_PI / m.sample_period_s);
  if (hi == 0) hi = 1e3;
  const double lo_rad = o.min > 0 ? o.min * unit : (o.hz ? 0.1 * unit : 1.0);
  const double hi_rad = o.max > 0 ? o.max * unit : 0.999 * hi;
  if (!(hi_rad > lo_rad))
    throw InputError(fmt::format("frequency range {} .. {} is empty; give --min below --max", lo_rad / unit,
                                 hi_rad / unit));
  for (std::size_t i = 0; i < models.size(); ++i) {
    if (models[i].num_inputs() != models[0].num_inputs() || models[i].num_outputs() != models[0].num_outputs())
      throw InputError(fmt::format("{} is {}x{} but {} is {}x{}; overlaid models must have the same shape",
                                   o.models[i], models[i].num_outputs(), models[i].num_inputs(), o.models[0],
                                   models[0].num_outputs(), models[0].num_inputs()));
    if (models[i].is_discrete() && hi_rad > M_PI / models[i].sample_period_s)
      throw InputError(fmt::format("--max is above the Nyquist frequency of {} ({:.6g} rad/s)", o.models[i],
                                   M_PI / models[i].sample_period_s));
  }
  const Eigen::VectorXd omega = log_frequency_grid(lo_rad, hi_rad, o.points);
  std::vector<BodeSeries> series;
  for (std::size_t i = 0; i < models.size(); ++i) {
    BodeSeries s;
    s.label = labels.empty() ? std::filesystem::path(o.models[i]).stem().string() : labels[i];
    s.response = frequency_response(models[i], omega);
    series.push_back(std::move(s));
  }
  BodePlotOptions plot;
  plot.frequency_in_hz = o.hz;
  plot.show_phase = !o.no_phase;
  plot.title = o.title;
  const auto bytes = bode_png(series, plot);
  write_file_atomic(o.out, std::string(bytes.begin(), bytes.end()));
}

}  // namespace

Command make_bode_command() {
  return {"bode", "Bode magnitude/phase PNG of MIMO models", [](CLI::App& parent) {
            auto o = std::make_shared<BodeCliOptions>();
            auto* app = parent.add_subcommand("bode", "Bode plot (p x m grid of panels) of one or more models" +
                                                          std::string(kExample));
            app->add_option("models", o->models, "state-space JSON models to overlay")->required();
            app->add_option("--out", o->out, "PNG to write")->required();
            app->add_option("--labels", o->labels, "legend labels, comma separated (default: file names)");
            app->add_option("--title", o->title, "figure title");
            app->add_flag("--hz", o->hz, "frequency axis in Hz (default rad/s)");
            app->add_flag("--no-phase", o->no_phase, "magnitude only");
            app->add_option("--min", o->min, "lowest frequency (rad/s, or Hz with --hz)");
            app->add_option("--max", o->max, "highest frequency (rad/s, or Hz with --hz)");
            app->add_option("--points", o->points, "number of log-spaced frequencies");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
