// lpvid compare — where two frequency responses differ: per channel and band,
// as a table or --json (a first version; the model-error issue grows it).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/registry.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/validate/compare.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
Example:
  lpvid compare P_from_S.csv truth_plant.json --band-min 1 --band-max 400 --weights 0.1,0.1,1
  lpvid compare P_from_S.csv P_from_G.csv --json
ESTIMATE and REFERENCE are models (.json) or FRD files (.csv, .mat); a model is evaluated on
the data's frequencies, two models on a log grid.  For each channel and band: the
largest error as a share of the weighted matrix gain (percent), the mean gain error (dB)
and the mean phase error (degrees); per band the weighted matrix error
|W(A - R)W| / |WRW| (mean, max).  Flagged frequencies of the data are skipped.
  lpvid compare --log data/sweep_1000hz/run.csv --params model.json --controller data/sweep_1000hz/controller.json \
      --out-png overlay.png --json
time domain: simulates the platform model's closed loop on the logged excitation and beam
trajectory; NRMSE fit % per output, residual whiteness and residual-input tests (99 %),
and the time windows where the model fails (channel, t_start, t_end, size).)";

struct CompareCliOptions {
  std::string estimate, reference, weights, out;
  double band_min = 0, band_max = 0, per_decade = 1;
  Index top = 9, points = 400;
  bool json = false;
};

void run(const CompareCliOptions& o) {
  if (o.estimate.empty() || o.reference.empty())
    throw InputError("compare: give ESTIMATE and REFERENCE (models or FRD files), or --log RUN.csv for the time domain");
  CompareOptions options;
  options.band_min_rad_s = o.band_min;
  options.band_max_rad_s = o.band_max;
  options.bands_per_decade = o.per_decade;
  options.validate();
  const LoadedResponse a = load_response(o.estimate), b = load_response(o.reference);
  Eigen::VectorXd omega;
  std::vector<bool> flagged;
  if (a.frd) {
    omega = a.frd->omega_rad_s;
    flagged = a.frd->flagged;
  } else if (b.frd) {
    omega = b.frd->omega_rad_s;
    flagged = b.frd->flagged;
  } else {
    const double lo = o.band_min > 0 ? o.band_min : 1.0;
    double hi = o.band_max > 0 ? o.band_max : 1e3;
    for (const auto* m : {&*a.model, &*b.model})
      if (m->is_discrete()) hi = std::min(hi, 0.999 * M_PI / m->sample_period_s);
    omega = log_frequency_grid(lo, hi, o.points);
  }
  const FrequencyResponse fa = response_on(a, omega), fb = response_on(b, omega);
  // A frequency flagged in either data set is skipped (both are on one grid here).
  if (a.frd && b.frd && !b.frd->flagged.empty()) {
    if (flagged.empty()) flagged.assign(b.frd->flagged.size(), false);
    for (std::size_t k = 0; k < flagged.size(); ++k) flagged[k] = flagged[k] || b.frd->flagged[k];
  }
  if (!o.weights.empty()) {
    const auto w = split_names(o.weights, "--weights");
    Eigen::VectorXd v(static_cast<Index>(w.size()));
    for (std::size_t i = 0; i < w.size(); ++i) {
      try {
        v(static_cast<Index>(i)) = std::stod(w[i]);
      } catch (const std::exception&) {
        throw InputError(fmt::format("--weights: '{}' is not a number", w[i]));
      }
    }
    // W (A - R) W: the same weights on outputs and inputs (square responses).
    options.left_weight = v;
    options.right_weight = v;
  }
  const CompareResult r = compare_responses(fa.response, fb.response, omega, flagged, options);
  auto name = [](const std::vector<std::string>& names, Index i) {
    return i < static_cast<Index>(names.size()) ? names[i] : std::to_string(i + 1);
  };
  nlohmann::json channels = nlohmann::json::array(), bands = nlohmann::json::array();
  for (const auto& c : r.channels)
    channels.push_back({{"output", name(fb.output_names, c.output)},
                        {"input", name(fb.input_names, c.input)},
                        {"band_rad_s", {c.band_lo_rad_s, c.band_hi_rad_s}},
                        {"share_percent", c.share_percent},
                        {"gain_db", std::isnan(c.gain_db) ? nlohmann::json(nullptr) : nlohmann::json(c.gain_db)},
                        {"phase_deg", std::isnan(c.phase_deg) ? nlohmann::json(nullptr) : nlohmann::json(c.phase_deg)}});
  for (const auto& b2 : r.bands)
    bands.push_back({{"band_rad_s", {b2.band_lo_rad_s, b2.band_hi_rad_s}},
                     {"points", b2.points},
                     {"flagged", b2.flagged},
                     {"weighted_error_mean", b2.weighted_mean},
                     {"weighted_error_max", b2.weighted_max}});
  nlohmann::json summary = {{"estimate", o.estimate},     {"reference", o.reference},
                            {"weighted_error_mean", r.weighted_mean}, {"weighted_error_max", r.weighted_max},
                            {"omega_at_max_rad_s", r.omega_at_max_rad_s}, {"bands", bands},
                            {"channels", channels}};
  std::string text = fmt::format("compare {} against {}: weighted matrix error mean {:.3f} %, max {:.3f} % at {:.4g} rad/s\n",
                                 o.estimate, o.reference, 100 * r.weighted_mean, 100 * r.weighted_max,
                                 r.omega_at_max_rad_s);
  text += "  band [rad/s]            points  flagged  mean err  max err\n";
  for (const auto& b2 : r.bands)
    text += fmt::format("  {:9.4g} - {:<9.4g}  {:7d}  {:7d}  {:7.3f} %  {:6.3f} %\n", b2.band_lo_rad_s, b2.band_hi_rad_s,
                        b2.points, b2.flagged, 100 * b2.weighted_mean, 100 * b2.weighted_max);
  text += fmt::format("  worst channels (of {}):\n  output    input     band [rad/s]           share    gain     phase\n",
                      r.channels.size());
  for (std::size_t i = 0; i < r.channels.size() && static_cast<Index>(i) < o.top; ++i) {
    const auto& c = r.channels[i];
    const std::string gp = std::isnan(c.gain_db) ? std::string("   (reference ~ 0)")
                                                 : fmt::format("{:5.2f} dB  {:5.1f} deg", c.gain_db, c.phase_deg);
    text += fmt::format("  {:<9} {:<9} {:9.4g} - {:<9.4g} {:6.3f} %  {}\n", name(fb.output_names, c.output),
                        name(fb.input_names, c.input), c.band_lo_rad_s, c.band_hi_rad_s, c.share_percent, gp);
  }
  if (!o.out.empty()) {
    check_not_overwriting({o.estimate, o.reference}, o.out);
    write_file_atomic(o.out, summary.dump(2) + "\n");
  }
  print_summary(o.json, summary, text);
}

}  // namespace

Command make_compare_command() {
  return {"compare", "where two responses differ, per channel and band", [](CLI::App& parent) {
            auto o = std::make_shared<CompareCliOptions>();
            auto* app = parent.add_subcommand("compare", "Distance between a response and a reference per channel and band" +
                                                             std::string(kExample));
            app->add_option("estimate", o->estimate, "model (.json) or FRD (.csv, .mat)");
            app->add_option("reference", o->reference, "model (.json) or FRD (.csv, .mat)");
            app->add_option("--band-min", o->band_min, "lowest frequency, rad/s (default: from the data)");
            app->add_option("--band-max", o->band_max, "highest frequency, rad/s (default: from the data)");
            app->add_option("--bands-per-decade", o->per_decade, "log-spaced bands per decade");
            app->add_option("--weights", o->weights, "weights W on outputs and inputs (comma separated)");
            app->add_option("--top", o->top, "how many channel rows to print");
            app->add_option("--points", o->points, "frequencies when both are models");
            app->add_option("--out", o->out, "also write the JSON summary to this file");
            app->add_flag("--json", o->json, "print the summary as JSON");
            auto t = std::make_shared<TimeCompareCliOptions>();
            add_time_compare_options(app, *t);
            app->callback([o, t] { t->active() ? run_time_compare(*t, o->out, o->json) : run(*o); });
          }};
}

}  // namespace lpvid::cli
