#include "cli/fit_inputs.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/dataset_manifest.h"
#include "formats/io/history.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {

void add_fit_input_options(CLI::App& app, FitInputOptions& o) {
  app.add_option("--model", o.model, "start model file (lpvid model init)")->required();
  app.add_option("--data", o.data,
                 "FILE@X_B: FRD (.csv/.mat; A.csv,B.csv,C.csv@X_B merges one file per excited input) or "
                 "state-space .json, x_b in m (repeat); a base without a scheduling variable (mechanical) takes FILE "
                 "alone; or give --datasets once");
  app.add_option("--datasets", o.datasets,
                 "dataset manifest (JSON): the files and x_b of every data set, and optionally target, "
                 "controller, rate_hz, averages, noise_level, band_rad_s (docs/formats.md)");
  app.add_option("--target", o.target, "what the data are: plant (default), G (v -> q) or S (v -> u)");
  app.add_option("--controller", o.controller, "controller C (e = -q -> u_c), state-space or transfer-function JSON, or its measured response "
                 "(FRD .csv/.mat on exactly the data's frequency lines); for G and S");
  app.add_option("--rate-hz", o.rate_hz, "sample rate of the data's experiment: fit the sampled (ZOH) response")
      ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz (omit it to use the data's or controller's)"));
  app.add_flag("--measured-input", o.measured_input,
               "the data's input was measured (a force at an impedance head, a current), not a held command: fit "
               "the continuous response (no ZOH); excludes --rate-hz");
  app.add_option("--averages", o.averages,
                 "independent averages behind the data's coherence, when the files do not state it ('# averages: K')")
      ->check(number_in(1, 1e9, "the number of averages"));
  app.add_option("--noise-level", o.noise_level,
                 "relative rms error of the measurement (e.g. 0.01), for data with neither variance nor coherence")
      ->check(number_in(0, 1, "the relative noise level (0.01 for 1 %)", true, true));
  app.add_option("--band-min", o.band_min, "use only frequencies >= this (rad/s)")
      ->check(positive_up_to(kMaxFrequency, "the lowest frequency in rad/s"));
  app.add_option("--band-max", o.band_max, "use only frequencies <= this (rad/s)")
      ->check(positive_up_to(kMaxFrequency, "the highest frequency in rad/s"));
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
  app.add_option("--weighting", o.weighting,
                 "noise (default: each line weighed by its measured noise, maximum likelihood when the model can be "
                 "exact) or auto (when the model fails beyond 1.5x the noise floor, its error joins the noise in the "
                 "weights: fit refits so, diagnose reports every model's figure so, Delta BIC stays the noise-weighted "
                 "fits'; docs/math.md, 'Weights when the model fails')")
      ->check(CLI::IsMember({"noise", "auto"}));
}

std::vector<std::string> frequency_options_given(const CLI::App& app) {
  static const char* const kNames[] = {"--target",    "--controller", "--rate-hz",  "--averages",
                                       "--noise-level", "--band-min",  "--band-max", "--starts",
                                       "--no-global", "--seed",       "--max-iterations", "--grid-lo",
                                       "--grid-hi",   "--grid-count", "--weighting"};
  std::vector<std::string> out;
  for (const char* name : kNames)
    if (app.count(name) > 0) out.emplace_back(name);
  return out;
}

void refuse_frequency_options(const std::vector<std::string>& given, const std::string& command) {
  if (given.empty()) return;
  std::string list = given.front();
  for (std::size_t k = 1; k < given.size(); ++k) list += (k + 1 == given.size() ? " and " : ", ") + given[k];
  throw InputError(fmt::format("{} --log: {} {} of the frequency route (a measured response: {} --data); a log is "
                               "fitted without {}: drop {}",
                               command, list, given.size() > 1 ? "are options" : "is an option", command,
                               given.size() > 1 ? "them" : "it", given.size() > 1 ? "them" : "it"));
}

FitDataSpec parse_data_spec(const std::string& spec) {
  const size_t at = spec.rfind('@');
  if (at == std::string::npos && !spec.empty()) {
    // No tag: for a base without a scheduling variable (mechanical) none is needed;
    // a scheduled base refuses the NaN when the model is known (check_schedule).
    FitDataSpec d;
    d.label = spec;
    d.beam_position_m = std::numeric_limits<double>::quiet_NaN();
    d.files = spec.find(',') != std::string::npos ? split_names(spec, "--data") : std::vector<std::string>{spec};
    return d;
  }
  if (at == std::string::npos || at == 0)
    throw InputError(fmt::format("--data '{}': missing @x_b tag; write FILE@X_B with the beam position in metres, "
                                 "e.g. P_left.csv@-0.1, or give the data sets once with --datasets",
                                 spec));
  FitDataSpec d;
  d.label = spec;
  const std::string path = spec.substr(0, at);
  const std::string xb = spec.substr(at + 1);
  if (!parse_decimal(xb, d.beam_position_m))
    throw InputError(fmt::format("--data '{}': the x_b tag '{}' is not a number; write FILE@X_B with x_b in metres, "
                                 "e.g. P_left.csv@-0.1",
                                 spec, xb));
  d.files = path.find(',') != std::string::npos ? split_names(path, "--data") : std::vector<std::string>{path};
  return d;
}

std::string measured_controller_rate_warning(const std::string& controller_path) {
  return fmt::format("lpvid: warning: --controller {} is a measured response with no sample rate and no --rate-hz "
                     "was given, so the model's continuous response is used; if the loop ran on a sampled "
                     "controller, S and G come out systematically wrong (no ZOH, worst towards Nyquist): give "
                     "--rate-hz with the controller's sample rate (or rate_hz in the manifest)",
                     controller_path);
}

std::string recorded_rate_warning(const std::string& path, double rate_hz, std::size_t more) {
  return fmt::format("lpvid: warning: {} was estimated from a log sampled at {} Hz (its sample_rate_hz{}) and no "
                     "--rate-hz was given, so the model's continuous response is fitted to data that map held (ZOH) "
                     "command samples to output samples: it lacks the ZOH's half-sample delay, which shows up as a "
                     "missing input_delay of about Ts/2 = {:.6g} s; give --rate-hz {} (or rate_hz in the manifest)",
                     path, rate_hz,
                     more > 0 ? fmt::format("; {} more file{} record{} a rate", more, more > 1 ? "s" : "",
                                            more > 1 ? "" : "s")
                              : std::string(),
                     0.5 / rate_hz, rate_hz);
}

namespace {

double pick(double flag, double manifest) { return std::isnan(flag) ? manifest : flag; }

// The recorded rate and the fit's rate are one rate: as frf joins logs of one sample
// period (cli/logs.cc), 1e-6 relative, which timestamps rounded to microseconds meet
// on logs of a second or more; the ZOH phase a 1e-6 difference moves is < 2e-6 rad.
constexpr double kSameRateTolerance = 1e-6;

// The data sets' specs: from --data or from the manifest (returned; empty without one).
DatasetManifest read_fit_specs(const FitInputOptions& o, FitInputs& in) {
  if (o.data.empty() == o.datasets.empty())
    throw InputError(o.data.empty() ? "give the data: --data FILE@X_B (repeat) or --datasets MANIFEST.json"
                                    : "give the data once: --data FILE@X_B or --datasets MANIFEST.json, not both");
  DatasetManifest m;
  if (!o.datasets.empty()) {
    m = read_dataset_manifest(o.datasets);
    for (const ManifestDataset& d : m.datasets) in.specs.push_back({d.files, d.beam_position_m, d.label});
  } else {
    for (const auto& s : o.data) in.specs.push_back(parse_data_spec(s));
  }
  return m;
}

// The fit's options from the flags, else the manifest, each checked; returns the
// sample rate given (NaN: none).
double fit_options_from_flags(const FitInputOptions& o, const DatasetManifest& m, FitInputs& in) {
  FitOptions& options = in.options;
  const std::string target = !o.target.empty() ? o.target : !m.target.empty() ? m.target : "plant";
  options.target = parse_target(target);
  options.global_start = !o.no_global;
  options.global_starts = o.starts;
  options.max_iterations = o.max_iterations;
  options.seed = o.seed;
  const double rate = pick(o.rate_hz, m.rate_hz);
  if (o.measured_input && !std::isnan(rate))
    throw InputError(fmt::format("--measured-input and {} {}: a measured input is fitted with the continuous response, "
                                 "a held command with the sampled one at its rate; give one of them",
                                 std::isnan(o.rate_hz) ? o.datasets + ": rate_hz" : "--rate-hz", rate));
  if (!std::isnan(rate) && !(rate > 0 && rate <= kMaxRateHz))
    throw InputError(fmt::format("{} {}: give the sample rate in Hz (> 0, at most {:g}), or omit it",
                                 std::isnan(o.rate_hz) ? o.datasets + ": rate_hz" : "--rate-hz", rate, kMaxRateHz));
  const double averages = pick(o.averages, m.averages);
  if (!std::isnan(averages)) {
    if (!(averages >= 1 && averages <= 1e9))
      throw InputError(fmt::format("--averages {}: give the independent averages behind the coherence, a number >= 1",
                                   averages));
    options.noise.averages = averages;
  }
  const double level = pick(o.noise_level, m.noise_level);
  if (!std::isnan(level)) {
    if (!std::isfinite(level) || level <= 0 || level >= 1)
      throw InputError(fmt::format("--noise-level {}: give the relative rms error of the measurement, in (0, 1), e.g. "
                                   "0.01 for 1 %",
                                   level));
    options.noise.noise_level = level;
  }
  const double lo = pick(o.band_min, m.band_min), hi = pick(o.band_max, m.band_max);
  for (const double b : {lo, hi})
    if (!std::isnan(b) && !(b > 0))
      throw InputError(fmt::format("{}: the band [{}, {}] rad/s has a bound <= 0; give frequencies > 0 in rad/s",
                                   o.datasets.empty() ? "--band-min/--band-max" : o.datasets, lo, hi));
  if (!std::isnan(lo)) options.band_min_rad_s = lo;
  if (!std::isnan(hi)) options.band_max_rad_s = hi;
  if (!(o.grid_hi > o.grid_lo))
    throw InputError(fmt::format("--grid-lo {} is not below --grid-hi {} (rad/s); give --grid-lo below --grid-hi",
                                 o.grid_lo, o.grid_hi));
  if (!std::isnan(lo) && !std::isnan(hi) && !(lo < hi))
    throw InputError(fmt::format("--band-min {} is not below --band-max {} (rad/s); give a band with low < high",
                                 lo, hi));
  in.controller_path = !o.controller.empty() ? o.controller : m.controller;
  if (options.target != FitTarget::kPlant && in.controller_path.empty())
    throw InputError(fmt::format("--target {} needs --controller C.json (the known controller, e = -q -> u_c; or its "
                                 "measured response C.csv)",
                                 target));
  return rate;
}

std::vector<LoadedResponse> load_fit_responses(const FitInputs& in) {
  std::vector<LoadedResponse> loaded;
  for (const auto& s : in.specs) {
    if (s.files.size() > 1) {
      LoadedResponse merged;
      merged.path = s.label;
      merged.frd = load_frd_merged(s.files);
      loaded.push_back(std::move(merged));
    } else {
      loaded.push_back(load_response(s.files.front()));
    }
  }
  return loaded;
}

// Sample period: flag (or manifest), else a discrete data model's, else the controller's.
double fit_sample_period(const FitInputOptions& o, const DatasetManifest& m, double rate,
                         const std::vector<LoadedResponse>& loaded, FitInputs& in) {
  const FitOptions& options = in.options;
  double ts = !std::isnan(rate) ? 1.0 / rate : 0.0;
  in.sample_period_source = !std::isnan(o.rate_hz) ? "--rate-hz" : !std::isnan(m.rate_hz) ? o.datasets : "";
  for (const auto& l : loaded)
    if (ts == 0.0 && l.model && l.model->is_discrete()) {
      ts = l.model->sample_period_s;
      in.sample_period_source = l.path;
    }
  if (ts == 0.0 && options.controller && options.controller->is_discrete()) {
    ts = options.controller->sample_period_s;
    in.sample_period_source = in.controller_path;
  }
  return ts;
}

void fit_datasets_from(const FitInputOptions& o, const std::vector<LoadedResponse>& loaded, FitInputs& in) {
  const FitOptions& options = in.options;
  for (std::size_t i = 0; i < in.specs.size(); ++i) {
    FitDataset d;
    d.beam_position_m = in.specs[i].beam_position_m;
    d.label = in.specs[i].label;
    if (loaded[i].model) {
      double top = o.grid_hi;
      const double period = loaded[i].model->sample_period_s;
      // Below 0.9 of the data model's Nyquist frequency.
      if (period > 0) top = std::min(top, 0.9 * M_PI / period);
      d.response = frequency_response(*loaded[i].model, log_frequency_grid(o.grid_lo, top, o.grid_count));
    } else {
      d.response = *loaded[i].frd;
    }
    // A measured controller is known only at its lines: they must be every data set's.
    if (options.measured_controller && options.target != FitTarget::kPlant)
      check_controller_lines(*options.measured_controller, d.response.omega_rad_s, in.controller_path,
                             loaded[i].model ? d.label + fmt::format(" (a model, evaluated on the --grid-lo/-hi/-count "
                                                                     "grid)")
                                             : d.label);
    in.data.push_back(std::move(d));
  }
}

// FRD data (and a measured controller) that lpvid frf estimated from a log record
// the log's rate: the response of held samples at that rate.  The fit's rate must be
// that one; without any, the continuous model misses the ZOH (said below).
void check_recorded_rates(const FitInputOptions& o, const std::vector<LoadedResponse>& loaded, const FitInputs& in) {
  const FitOptions& options = in.options;
  const double ts = options.sample_period_s;
  struct Recorded {
    std::string path;
    double rate_hz;
  };
  std::vector<Recorded> recorded;
  for (const auto& l : loaded)
    if (l.frd && l.frd->sample_rate_hz > 0) recorded.push_back({l.path, l.frd->sample_rate_hz});
  const bool controller_used = options.measured_controller && options.target != FitTarget::kPlant;
  if (controller_used && options.measured_controller->sample_rate_hz > 0)
    recorded.push_back({in.controller_path, options.measured_controller->sample_rate_hz});
  if (ts > 0.0)
    for (const Recorded& r : recorded)
      if (std::abs(r.rate_hz * ts - 1.0) > kSameRateTolerance) {
        const std::string source =
            in.sample_period_source == "--rate-hz" ? fmt::format("--rate-hz {}", 1.0 / ts)
            : in.sample_period_source == o.datasets ? fmt::format("{}: rate_hz {}", o.datasets, 1.0 / ts)
            : fmt::format("{} (discrete, ts = {} s, {} Hz)", in.sample_period_source, ts, 1.0 / ts);
        throw InputError(fmt::format(
            "{} was estimated from a log sampled at {} Hz (its sample_rate_hz) but the fit's rate is {}; the ZOH "
            "response is fitted at one rate, the rate of the log: give --rate-hz {} (or re-estimate the FRD from a "
            "log at the loop's rate)",
            r.path, r.rate_hz, source, r.rate_hz));
      }
  // Without a rate the continuous model stands in for data of a sampled loop.  Said
  // once, after every input check (a bad input stays a one-line error): the recorded
  // rate when some file has one, else the measured controller's missing rate.
  if (ts == 0.0 && !recorded.empty() && !o.measured_input)
    std::fprintf(stderr, "%s\n",
                 recorded_rate_warning(recorded.front().path, recorded.front().rate_hz, recorded.size() - 1).c_str());
  else if (controller_used && ts == 0.0)
    std::fprintf(stderr, "%s\n", measured_controller_rate_warning(in.controller_path).c_str());
}

}  // namespace

FitInputs load_fit_inputs(const FitInputOptions& o, OutputSet& outputs) {
  FitInputs in;
  const DatasetManifest m = read_fit_specs(o, in);
  const double rate = fit_options_from_flags(o, m, in);
  // A data file without an @ tag: only a base without a scheduling variable
  // (mechanical) takes one; the model says which (read again below, after the checks).
  for (const auto& s : in.specs)
    if (std::isnan(s.beam_position_m) && !read_physical_model(o.model).base_info().schedule_name.empty())
      throw InputError(fmt::format("--data '{}': missing @x_b tag; write FILE@X_B with the beam position in metres, "
                                   "e.g. P_left.csv@-0.1, or give the data sets once with --datasets",
                                   s.label));
  in.inputs = {o.model};
  if (!o.datasets.empty()) in.inputs.push_back(o.datasets);
  for (const auto& s : in.specs)
    for (const auto& f : s.files) in.inputs.push_back(f);
  if (!in.controller_path.empty()) in.inputs.push_back(in.controller_path);
  outputs.inputs(in.inputs);
  outputs.check();

  FitOptions& options = in.options;
  in.start = read_physical_model(o.model);
  if (!in.controller_path.empty()) {
    if (is_measured_controller(in.controller_path))
      options.measured_controller = read_measured_controller(in.controller_path);
    else
      options.controller = read_controller(in.controller_path);
  }
  const std::vector<LoadedResponse> loaded = load_fit_responses(in);
  options.sample_period_s = fit_sample_period(o, m, rate, loaded, in);
  options.validate();
  fit_datasets_from(o, loaded, in);
  check_recorded_rates(o, loaded, in);
  return in;
}

std::string fit_history_text(const std::string& start_model, const std::string& out, const FitResult& r,
                             const std::vector<std::string>& outs, const std::vector<std::string>& ins,
                             const std::string& note) {
  std::vector<HistoryRecord> records;
  if (std::filesystem::exists(history_path_for(start_model))) records = read_history(history_path_for(start_model));
  HistoryRecord rec;
  rec.timestamp = utc_timestamp_now();
  rec.model = out;
  rec.effects = r.model.effects;
  rec.free_parameters = static_cast<Index>(r.parameters.size());
  rec.cost = r.cost_final;
  rec.error_mean = 0.0;
  rec.error_max = 0.0;
  for (const auto& c : r.channels) {
    rec.error_mean += c.relative_rms_error / static_cast<double>(r.channels.size());
    rec.error_max = std::max(rec.error_max, c.relative_rms_error);
    rec.channels.push_back({outs[static_cast<std::size_t>(c.output)], ins[static_cast<std::size_t>(c.input)],
                            c.relative_rms_error, c.relative_rms_error});
  }
  rec.error = r.error;
  rec.noise_floor = r.noise_floor;
  rec.aic = r.aic;
  rec.bic = r.bic;
  rec.note = note;
  std::string text;
  for (const auto& old : records) text += history_line(old) + "\n";
  text += history_line(rec) + "\n";
  return text;
}

}  // namespace lpvid::cli
