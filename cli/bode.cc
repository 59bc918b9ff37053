// lpvid bode — magnitude and phase of one or more MIMO models as a PNG: a p x m
// grid of panels with the models overlaid (seed 000, Figs 10 and 13).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <filesystem>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "cli/responses.h"
#include "formats/io/model_json.h"
#include "formats/plot/bode_plot.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {
namespace {

constexpr const char* kBodeExample = R"(
Example:
  lpvid bode --out plants.png --labels "left,middle,right" left/plant.json middle/plant.json right/plant.json
  lpvid bode --out p.png --hz --min 0.1 --max 100 plant.json truth_plant.json
  lpvid bode --out fig12.png --labels "from S,from G,model" P_from_S.csv P_from_G.csv plant.json
Discrete models are evaluated at z = exp(j w Ts) up to their Nyquist frequency,
continuous ones at s = j w; FRD data (.csv, .mat) is drawn with markers, its flagged
frequencies with red crosses.  All must have the same numbers of inputs and outputs.)";

struct BodeCliOptions {
  std::vector<std::string> models;
  std::string out, labels, title;
  bool hz = false, no_phase = false;
  double min = 0, max = 0;
  Index points = 400;
};

void run(const BodeCliOptions& o) {
  OutputSet outputs;
  outputs.inputs(o.models);
  outputs.file("--out", o.out);
  outputs.check();
  std::vector<std::string> labels;
  if (!o.labels.empty()) labels = split_names(o.labels, "--labels");
  if (!labels.empty() && labels.size() != o.models.size())
    throw InputError(fmt::format("--labels has {} names for {} models; give one label per model", labels.size(),
                                 o.models.size()));
  std::vector<LoadedResponse> items;
  for (const auto& path : o.models) items.push_back(load_response(path));
  const double unit = o.hz ? 2.0 * M_PI : 1.0;  // rad/s per axis unit
  // Default range: that of the data if any is given, else 1 rad/s (0.1 Hz) to the
  // lowest Nyquist frequency of the discrete models, or 1000 rad/s.
  double hi = 0, lo = 0;
  for (const auto& it : items) {
    if (it.model && it.model->is_discrete())
      hi = hi == 0 ? M_PI / it.model->sample_period_s : std::min(hi, M_PI / it.model->sample_period_s);
    if (it.frd && it.frd->num_frequencies() > 0) {
      lo = lo == 0 ? it.frd->omega_rad_s(0) : std::min(lo, it.frd->omega_rad_s(0));
      hi = std::max(hi, it.frd->omega_rad_s(it.frd->num_frequencies() - 1));
    }
  }
  if (hi == 0) hi = 1e3;
  const double lo_rad = o.min > 0 ? o.min * unit : (lo > 0 ? lo : (o.hz ? 0.1 * unit : 1.0));
  double hi_rad = o.max > 0 ? o.max * unit : 0.999 * hi;
  if (!(hi_rad > lo_rad))
    throw InputError(fmt::format("frequency range {} .. {} is empty; give --min below --max", lo_rad / unit,
                                 hi_rad / unit));
  auto shape = [](const LoadedResponse& it) {
    return it.model ? std::make_pair(it.model->num_outputs(), it.model->num_inputs())
                    : std::make_pair(it.frd->num_outputs(), it.frd->num_inputs());
  };
  for (std::size_t i = 0; i < items.size(); ++i)
    if (shape(items[i]) != shape(items[0]))
      throw InputError(fmt::format("{} is {}x{} but {} is {}x{}; give responses of the same shape to overlay",
                                   o.models[i], shape(items[i]).first, shape(items[i]).second, o.models[0],
                                   shape(items[0]).first, shape(items[0]).second));
  std::vector<BodeSeries> series;
  for (std::size_t i = 0; i < items.size(); ++i) {
    BodeSeries s;
    s.label = labels.empty() ? std::filesystem::path(o.models[i]).stem().string() : labels[i];
    if (items[i].model) {
      const StateSpace& m = *items[i].model;
      const double top = m.is_discrete() ? std::min(hi_rad, 0.999 * M_PI / m.sample_period_s) : hi_rad;
      s.response = frequency_response(m, log_frequency_grid(lo_rad, top, o.points));
    } else {
      s.response = *items[i].frd;  // data: drawn with markers, flagged points marked
      s.style = BodeSeries::Style::kMarkers;
    }
    series.push_back(std::move(s));
  }
  BodePlotOptions plot;
  plot.frequency_in_hz = o.hz;
  plot.show_phase = !o.no_phase;
  plot.title = o.title;
  const auto bytes = bode_png(series, plot);
  outputs.stage(o.out, bytes);
  outputs.commit();
}

}  // namespace

Command make_bode_command() {
  return {"bode", "Bode magnitude/phase PNG of MIMO models", [](CLI::App& parent) {
            auto o = std::make_shared<BodeCliOptions>();
            auto* app = parent.add_subcommand("bode", "Bode plot (p x m grid of panels) of one or more models" +
                                                          std::string(kBodeExample));
            app->add_option("models", o->models, "models (.json) and FRD data (.csv, .mat) to overlay")->required();
            app->add_option("--out", o->out, "PNG to write")->required();
            app->add_option("--labels", o->labels, "legend labels, comma separated (default: file names)");
            app->add_option("--title", o->title, "figure title");
            app->add_flag("--hz", o->hz, "frequency axis in Hz (default rad/s)");
            app->add_flag("--no-phase", o->no_phase, "magnitude only");
            app->add_option("--min", o->min, "lowest frequency (rad/s, or Hz with --hz)")
                ->check(positive_up_to(kMaxFrequency, "the lowest frequency"));
            app->add_option("--max", o->max, "highest frequency (rad/s, or Hz with --hz)")
                ->check(positive_up_to(kMaxFrequency, "the highest frequency"));
            app->add_option("--points", o->points, "number of log-spaced frequencies")
                ->check(integer_in(2, kMaxFrequencyPoints, "the number of frequencies"));
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
