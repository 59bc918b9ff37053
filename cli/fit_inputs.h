// The inputs shared by `fit` and `diagnose`: a start model file, data files
// tagged with their beam position (FILE@X_B), the target (plant, G or S), the
// controller and the fit options.  Parsing and loading only (STYLE.md item 8).
#pragma once

#include <string>
#include <vector>

#include "idlib/fit/fit.h"
#include "idlib/physical/physical_model.h"

namespace CLI {
class App;
}

namespace lpvid::cli {

class OutputSet;

struct FitInputOptions {
  std::string model, controller, target = "plant";
  std::vector<std::string> data;  // FILE@X_B
  double rate_hz = 0.0, grid_lo = 1.0, grid_hi = 600.0;
  Index grid_count = 200;
  int starts = 8, max_iterations = 200;
  unsigned seed = 1;
  bool no_global = false;
};

// Declares --model, --data, --target, --controller, --rate-hz, --starts,
// --no-global, --seed, --max-iterations, --grid-lo/-hi/-count on app.
void add_fit_input_options(CLI::App& app, FitInputOptions& o);

struct FitDataSpec {
  std::string path;
  double beam_position_m = 0.0;
};

// "P_left.csv@-0.1" -> {P_left.csv, -0.1}.
// @throws InputError  no @x_b tag, or the tag is not a finite number.
FitDataSpec parse_data_spec(const std::string& spec);

struct FitInputs {
  PhysicalModel start;
  FitOptions options;
  std::vector<FitDataset> data;
  std::vector<FitDataSpec> specs;
  std::string sample_period_source;  // where options.sample_period_s came from ("" = continuous)
};

// Validates the options first (before reading anything), registers every input
// with `outputs` (whose outputs the caller has registered) and checks them all
// (cli/output_set.h), then reads the model, controller and data.  The sample
// period: --rate-hz, else a discrete data model's, else the controller's.
// @throws InputError  as the readers, OutputSet::check and FitOptions::validate.
FitInputs load_fit_inputs(const FitInputOptions& o, OutputSet& outputs);

}  // namespace lpvid::cli
