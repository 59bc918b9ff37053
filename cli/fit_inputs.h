// The inputs shared by `fit`, `diagnose` and `compare --model M.json` with a
// physical model: a model file, the data (FILE@X_B flags, or a dataset manifest
// given once), the target (plant, G or S), the controller, the noise of the data,
// the frequency band and the fit options.  Parsing and loading only (STYLE.md
// item 8).
//
// Dataset manifest (--datasets FILE): formats/io/dataset_manifest.h and
// docs/formats.md "Data-set manifest"; every key but "datasets" is optional and a
// flag on the command line wins over it.
#pragma once

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "idlib/fit/fit.h"
#include "idlib/physical/physical_model.h"

namespace CLI {
class App;
}

namespace lpvid::cli {

class OutputSet;

inline constexpr double kUnset = std::numeric_limits<double>::quiet_NaN();

struct FitInputOptions {
  std::string model, controller, target, datasets;
  std::vector<std::string> data;  // FILE@X_B
  // NaN: not given on the command line (the manifest's value, or the default)
  double rate_hz = kUnset, averages = kUnset, noise_level = kUnset, band_min = kUnset, band_max = kUnset;
  double grid_lo = 1.0, grid_hi = 600.0;
  Index grid_count = 200;
  int starts = 8, max_iterations = 200;
  unsigned seed = 1;
  bool no_global = false;
  // the plant's input was measured (a force at an impedance head), not a held command:
  // the continuous response is the right one, and the ZOH warning does not apply
  bool measured_input = false;
  // --weighting: "noise" (the default) or "auto", the model's error in the weights when
  // it fails beyond 1.5x the floor (FitOptions / DiagnoseOptions::model_error_weighting)
  std::string weighting = "noise";
};

// Declares --model, --data, --datasets, --target, --controller, --rate-hz,
// --averages, --noise-level, --band-min, --band-max, --starts, --no-global, --seed,
// --max-iterations, --grid-lo/-hi/-count, --weighting on app.
void add_fit_input_options(CLI::App& app, FitInputOptions& o);

// The frequency route's options of add_fit_input_options given on app's command line (as
// written: "--starts"), after parsing; --model, --data, --datasets and --measured-input
// are not among them (the time routes read or refuse those themselves).
std::vector<std::string> frequency_options_given(const CLI::App& app);
// @throws InputError  `given` is not empty: "COMMAND --log: --starts and --band-min are
//   options of the frequency route ...; drop them" (a time route would ignore them).
void refuse_frequency_options(const std::vector<std::string>& given, const std::string& command);

struct FitDataSpec {
  std::vector<std::string> files;  // one file, or one per excited input (merged)
  double beam_position_m = 0.0;
  std::string label;               // as the user wrote it
};

// "P_left.csv@-0.1" -> {P_left.csv, -0.1}; "A.csv,B.csv,C.csv@0" -> three files.
// @throws InputError  no @x_b tag, or the tag is not a finite number.
FitDataSpec parse_data_spec(const std::string& spec);

struct FitInputs {
  PhysicalModel start;
  FitOptions options;
  std::vector<FitDataset> data;
  std::vector<FitDataSpec> specs;
  std::string sample_period_source;  // where options.sample_period_s came from ("" = continuous)
  std::string controller_path;       // "" = none
  std::vector<std::string> inputs;   // every file read (for output guards)
};

// Validates the options first (before reading anything), registers every input
// (the manifest, then the model, data and controller it names) with `outputs`
// (whose outputs the caller has registered) and checks them all
// (cli/output_set.h), then reads the model, controller and data.  The sample
// period: --rate-hz (or the manifest's), else a discrete data model's, else the
// controller's; none while an FRD records its log's rate: the warning of
// recorded_rate_warning, else none with a measured controller for G or S: the
// warning of measured_controller_rate_warning, on stderr after every input check.
// @throws InputError  as the readers, OutputSet::check and FitOptions::validate;
//   --data and --datasets both or neither given.
FitInputs load_fit_inputs(const FitInputOptions& o, OutputSet& outputs);

// The one stderr line load_fit_inputs prints when a measured controller (FRD) is used
// for G or S with no sample period from --rate-hz, the manifest or a discrete data
// model: the continuous response is then fitted, wrong for a sampled loop.
std::string measured_controller_rate_warning(const std::string& controller_path);

// The one stderr line load_fit_inputs prints instead when no sample period was given
// (--rate-hz, the manifest, a discrete data model or controller) but an FRD it read
// records the rate of the log it was estimated from (lpvid frf's '# sample_rate_hz:'):
// the first such file (path), its rate, and how many more files record one.  A
// sample period given that differs from a recorded rate by more than 1e-6 relative is
// an InputError naming the file and both rates.
std::string recorded_rate_warning(const std::string& path, double rate_hz, std::size_t more);

// The fit history written beside a fitted model (formats/io/history.h): the start
// model's history (start_model's .history.jsonl, when it exists), then one record of
// `r` saved as `out` with `note`, as JSON lines.  `fit --out` and `diagnose --out` (the
// winning candidate's refit) both write it, so that `lpvid history` on the newest model
// shows the whole lineage.  outs/ins: the response's channel names.
std::string fit_history_text(const std::string& start_model, const std::string& out, const FitResult& r,
                             const std::vector<std::string>& outs, const std::vector<std::string>& ins,
                             const std::string& note);

}  // namespace lpvid::cli
