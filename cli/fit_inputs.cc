#include "cli/fit_inputs.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {

void add_fit_input_options(CLI::App& app, FitInputOptions& o) {
  app.add_option("--model", o.model, "start model file (lpvid model init)")->required();
  app.add_option("--data", o.data, "FILE@X_B: FRD (.csv/.mat; A.csv,B.csv,C.csv@X_B merges one file per excited input) or state-space .json, x_b in m (repeat)")->required();
  app.add_option("--target", o.target, "what the data are: plant (default), G (v -> q) or S (v -> u)");
  app.add_option("--controller", o.controller, "controller C (e = -q -> u_c), state-space JSON; for G and S");
  app.add_option("--rate-hz", o.rate_hz, "sample rate of the data's experiment: fit the ZOH response")
      ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz (omit it to use the data's or controller's)"));
  app.add_option("--starts", o.starts, "global start: number of BOBYQA starts (default 8)")
      ->check(integer_in(1, 1000, "the number of global starts"));
  app.add_flag("--no-global", o.no_global, "skip the global start (Levenberg-Marquardt from the start only)");
  app.add_option("--seed", o.seed, "seed of the global start's random points (default 1)")
      ->check(integer_in(0, 4'294'967'295, "the seed"));
  app.add_option("--max-iterations", o.max_iterations, "Levenberg-Marquardt iterations (default 200)")
      ->check(integer_in(1, 10'000, "the number of iterations"));
  app.add_option("--grid-lo", o.grid_lo, "model data: lowest frequency in rad/s (default 1)")
      ->check(positive_up_to(kMaxFrequency, "the lowest frequency in rad/s"));
  app.add_option("--grid-hi", o.grid_hi, "model data: highest frequency in rad/s (default 600)")
      ->check(positive_up_to(kMaxFrequency, "the highest frequency in rad/s"));
  app.add_option("--grid-count", o.grid_count, "model data: number of frequencies (default 200)")
      ->check(integer_in(2, kMaxFrequencyPoints, "the number of frequencies"));
}

FitDataSpec parse_data_spec(const std::string& spec) {
  const size_t at = spec.rfind('@');
  if (at == std::string::npos || at == 0)
    throw InputError(fmt::format("--data '{}': missing @x_b tag; write FILE@X_B with the beam position in metres, "
                                 "e.g. P_left.csv@-0.1",
                                 spec));
  FitDataSpec d;
  d.path = spec.substr(0, at);
  const std::string xb = spec.substr(at + 1);
  if (!parse_decimal(xb, d.beam_position_m))
    throw InputError(fmt::format("--data '{}': the x_b tag '{}' is not a number; write FILE@X_B with x_b in metres, "
                                 "e.g. P_left.csv@-0.1",
                                 spec, xb));
  return d;
}

FitInputs load_fit_inputs(const FitInputOptions& o, OutputSet& outputs) {
  FitInputs in;
  FitOptions& options = in.options;
  options.target = parse_target(o.target);
  options.global_start = !o.no_global;
  options.global_starts = o.starts;
  options.max_iterations = o.max_iterations;
  options.seed = o.seed;
  if (!(o.grid_hi > o.grid_lo))
    throw InputError(fmt::format("--grid-lo {} is not below --grid-hi {} (rad/s); give --grid-lo below --grid-hi",
                                 o.grid_lo, o.grid_hi));
  if (o.data.empty()) throw InputError("give at least one --data FILE@X_B");
  for (const auto& s : o.data) in.specs.push_back(parse_data_spec(s));
  if (options.target != FitTarget::kPlant && o.controller.empty())
    throw InputError(fmt::format("--target {} needs the controller; give --controller C.json (the known controller, e = -q -> u_c)",
                                 o.target));
  outputs.input(o.model);
  for (const auto& s : in.specs)
    for (const auto& part : split_names(s.path, "--data")) outputs.input(part);
  outputs.input(o.controller);
  outputs.check();

  in.start = read_physical_model(o.model);
  if (!o.controller.empty()) options.controller = read_controller(o.controller);
  std::vector<LoadedResponse> loaded;
  for (const auto& s : in.specs) {
    // "S_v1.csv,S_v2.csv,S_v3.csv@0": one file per excited input, merged.
    if (s.path.find(',') != std::string::npos) {
      LoadedResponse merged;
      merged.path = s.path;
      merged.frd = load_frd_merged(split_names(s.path, "--data"));
      loaded.push_back(std::move(merged));
    } else {
      loaded.push_back(load_response(s.path));
    }
  }
  // Sample period: flag, else a discrete data model's, else the controller's.
  double ts = o.rate_hz > 0 ? 1.0 / o.rate_hz : 0.0;
  in.sample_period_source = o.rate_hz > 0 ? "--rate-hz" : "";
  for (const auto& l : loaded)
    if (ts == 0.0 && l.model && l.model->is_discrete()) {
      ts = l.model->sample_period_s;
      in.sample_period_source = l.path;
    }
  if (ts == 0.0 && options.controller && options.controller->is_discrete()) {
    ts = options.controller->sample_period_s;
    in.sample_period_source = o.controller;
  }
  options.sample_period_s = ts;
  options.validate();

  for (std::size_t i = 0; i < in.specs.size(); ++i) {
    FitDataset d;
    d.beam_position_m = in.specs[i].beam_position_m;
    d.label = in.specs[i].path;
    if (loaded[i].model) {
      double hi = o.grid_hi;
      const double period = loaded[i].model->sample_period_s;
      // Below 0.9 of the data model's Nyquist frequency.
      if (period > 0) hi = std::min(hi, 0.9 * M_PI / period);
      d.response = frequency_response(*loaded[i].model, log_frequency_grid(o.grid_lo, hi, o.grid_count));
    } else {
      d.response = *loaded[i].frd;
    }
    in.data.push_back(std::move(d));
  }
  return in;
}

}  // namespace lpvid::cli
