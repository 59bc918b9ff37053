// The moving-beam parts of `simulate platform` (--trajectory / --profile) and of
// `compare` (--log: the time domain), kept apart from simulate.cc and compare.cc,
// which call them.  No mathematics here (STYLE.md item 8).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/logs.h"
#include "idlib/plants/platform/platform.h"

namespace lpvid {
struct CorrelationTest;     // idlib/validate/time_fit.h
struct NonlinearityResult;  // idlib/validate/nonlinearity.h
}

namespace CLI {
class App;
}

namespace lpvid::cli {

// ----------------------------------------------------- simulate platform --
struct TrajectoryCliOptions {
  std::string trajectory;      // CSV with columns t, x_b
  std::string profile;         // built-in profile name ("sweep")
  std::string excite = "none"; // none, all, T_psi, T_theta, F_z
  int substeps = 1;
  bool active() const { return !trajectory.empty() || !profile.empty(); }
};

// Adds --trajectory, --profile, --excite, --substeps to `simulate platform`.
void add_trajectory_options(CLI::App* platform, TrajectoryCliOptions& o);

// The settings of `simulate platform` that a moving-beam run shares.
struct SimulateShared {
  std::string out_dir;
  std::vector<double> rates_hz;
  double duration_s = 60.0;
  std::uint64_t seed = 1;
  double noise_scale = 1.0;
  bool json = false;
};

// Writes OUT/<name>_<rate>hz/{run.csv, controller.json, truth_parameters.json}
// per rate; <name> is the profile name or the trajectory file's stem.
void run_simulate_trajectory(const TrajectoryCliOptions& o, const PlatformParameters& params,
                             const SimulateShared& shared);

// --------------------------------------------------------------- compare --
struct TimeCompareCliOptions {
  std::string log;         // measured run: t, v1..v3, q1..q3, x_b
  std::string params;      // parameter file (formats/io/platform_json.h)
  std::vector<std::string> overrides;  // --set NAME=VALUE
  std::string controller;  // discrete controller model (JSON)
  std::string out_png;
  // A state-space model (--model M.json): the log's columns for its channels (default:
  // the model's names), and with --controller the loop's excitation (cli/compare_model_time.cc).
  std::string input, output, excitation, excitation_at = "input";
  double window_s = 0;  // 0: the route's default (0.5 s; a twentieth of the record for a state-space model)
  double threshold_percent = 10.0;
  long max_lag = 25;
  int substeps = 1;
  LogLayoutCli layout;  // --log-columns, --log-rate (a .mat log of one unnamed matrix)
  bool active() const { return !log.empty(); }
};

// Adds --log, --log-columns, --log-rate, --params, --set, --controller, --out-png, --window-s,
// --threshold-percent, --max-lag, --substeps to `compare`.
void add_time_compare_options(CLI::App* compare, TimeCompareCliOptions& o);

// Reads the parameters named by o (file, then --set), then runs
// run_time_compare_with.
void run_time_compare(const TimeCompareCliOptions& o, const std::string& out_json, bool json);

// The entry point for any model source (e.g. a fitted model): predicts the
// logged run with `model` and reports fit, residual tests and failing windows.
void run_time_compare_with(const TimeCompareCliOptions& o, const PlatformParameters& model,
                           const std::string& out_json, bool json);

// One residual test of idlib/validate/time_fit.h as compare --log's JSON: channel
// (outputs[t.channel]), pass, worst_ratio, worst_lag, bound, bound_per_lag,
// lags_outside_per_lag_bound, and input (inputs[t.input]) for a cross test.
nlohmann::json correlation_test_json(const CorrelationTest& t, const std::vector<std::string>& outputs,
                                     const std::vector<std::string>& inputs);

// idlib/validate/nonlinearity.h's result as JSON: ran, segments, threshold, seen (any
// significant), sentence, and the significant tests (residual, feature, of, r, lag, t).
nlohmann::json nonlinearity_json(const NonlinearityResult& r, const std::vector<std::string>& outputs);

// A state-space or transfer-function model file (o.params) on any log: open loop from
// the logged input, or closed loop with o.controller from the logged excitation.
void run_model_time_compare(const TimeCompareCliOptions& o, const std::string& out_json, bool json);

}  // namespace lpvid::cli
