#include "cli/fit_inputs.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli/common.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid::cli {

void add_fit_input_options(CLI::App& app, FitInputOptions& o) {
  app.add_option("--model", o.model, "start model file (lpvid model init)")->required();
  app.add_option("--data", o.data,
                 "FILE@X_B: FRD (.csv/.mat; A.csv,B.csv,C.csv@X_B merges one file per excited input) or "
                 "state-space .json, x_b in m (repeat); or give --datasets once");
  app.add_option("--datasets", o.datasets,
                 "dataset manifest (JSON): the files and x_b of every data set, and optionally target, "
                 "controller, rate_hz, averages, noise_level, band_rad_s (docs/formats.md)");
  app.add_option("--target", o.target, "what the data are: plant (default), G (v -> q) or S (v -> u)");
  app.add_option("--controller", o.controller, "controller C (e = -q -> u_c), state-space JSON; for G and S");
  app.add_option("--rate-hz", o.rate_hz, "sample rate of the data's experiment: fit the sampled (ZOH) response");
  app.add_option("--averages", o.averages,
                 "independent averages behind the data's coherence, when the files do not state it ('# averages: K')");
  app.add_option("--noise-level", o.noise_level,
                 "relative rms error of the measurement (e.g. 0.01), for data with neither variance nor coherence");
  app.add_option("--band-min", o.band_min, "use only frequencies >= this (rad/s)");
  app.add_option("--band-max", o.band_max, "use only frequencies <= this (rad/s)");
  app.add_option("--starts", o.starts, "global start: number of BOBYQA starts (default 8)");
  app.add_flag("--no-global", o.no_global, "skip the global start (Levenberg-Marquardt from the start only)");
  app.add_option("--seed", o.seed, "seed of the global start's random points (default 1)");
  app.add_option("--max-iterations", o.max_iterations, "Levenberg-Marquardt iterations (default 200)");
  app.add_option("--grid-lo", o.grid_lo, "model data: lowest frequency in rad/s (default 1)");
  app.add_option("--grid-hi", o.grid_hi, "model data: highest frequency in rad/s (default 600)");
  app.add_option("--grid-count", o.grid_count, "model data: number of frequencies (default 200)");
}

FitDataSpec parse_data_spec(const std::string& spec) {
  const size_t at = spec.rfind('@');
  if (at == std::string::npos || at == 0)
    throw InputError(fmt::format("--data '{}': missing @x_b tag; write FILE@X_B with the beam position in metres, "
                                 "e.g. P_left.csv@-0.1, or give the data sets once with --datasets",
                                 spec));
  FitDataSpec d;
  d.label = spec;
  const std::string path = spec.substr(0, at);
  const std::string xb = spec.substr(at + 1);
  size_t used = 0;
  try {
    d.beam_position_m = std::stod(xb, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (xb.empty() || used != xb.size() || !std::isfinite(d.beam_position_m))
    throw InputError(fmt::format("--data '{}': the x_b tag '{}' is not a number; write FILE@X_B with x_b in metres, "
                                 "e.g. P_left.csv@-0.1",
                                 spec, xb));
  d.files = path.find(',') != std::string::npos ? split_names(path, "--data") : std::vector<std::string>{path};
  return d;
}

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The manifest's values (NaN / empty where it does not say).
struct Manifest {
  std::string target, controller;
  double rate_hz = kUnset, averages = kUnset, noise_level = kUnset, band_min = kUnset, band_max = kUnset;
  std::vector<FitDataSpec> specs;
};

Manifest read_manifest(const std::string& path) {
  using nlohmann::json;
  const std::string text = slurp(path);
  auto fail = [&](const std::string& key, const std::string& what) {
    const size_t at = key.empty() ? 0 : detail::find_top_level_key(text, key);
    const detail::CellPosition pos = detail::text_position(text, at);
    detail::fail_at(path, pos.line, pos.column, what);
  };
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    const detail::CellPosition pos = detail::text_position(text, e.byte == 0 ? 0 : e.byte - 1);
    detail::fail_at(path, pos.line, pos.column, "invalid JSON; fix the JSON syntax");
  }
  if (!root.is_object())
    fail("", "a dataset manifest is a JSON object {\"format\": \"lpvid-datasets\", \"datasets\": [...]} "
             "(docs/formats.md)");
  if (!root.contains("format") || root["format"] != "lpvid-datasets")
    fail("format", "key 'format' must be \"lpvid-datasets\"; is this a dataset manifest? (docs/formats.md)");
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  auto resolve = [&](const std::string& p) {
    const std::filesystem::path q(p);
    return (q.is_absolute() || dir.empty() ? q : dir / q).lexically_normal().string();
  };
  Manifest m;
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string& key = it.key();
    const json& v = it.value();
    auto number = [&](double& out) {
      if (!v.is_number()) fail(key, fmt::format("key '{}' must be a number", key));
      out = v.get<double>();
    };
    if (key == "format") {
      continue;
    } else if (key == "target" || key == "controller") {
      if (!v.is_string()) fail(key, fmt::format("key '{}' must be a string", key));
      (key == "target" ? m.target : m.controller) = key == "controller" ? resolve(v.get<std::string>()) : v.get<std::string>();
    } else if (key == "rate_hz") {
      number(m.rate_hz);
    } else if (key == "averages") {
      number(m.averages);
    } else if (key == "noise_level") {
      number(m.noise_level);
    } else if (key == "band_rad_s") {
      if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
        fail(key, "key 'band_rad_s' must be [low, high] in rad/s, e.g. [1, 600]");
      m.band_min = v[0].get<double>();
      m.band_max = v[1].get<double>();
    } else if (key == "datasets") {
      if (!v.is_array() || v.empty())
        fail(key, "key 'datasets' must be a non-empty array of {\"beam_position_m\": X, \"files\": [...]}");
      for (const json& d : v) {
        if (!d.is_object() || !d.contains("beam_position_m") || !d["beam_position_m"].is_number() ||
            !d.contains("files") || !d["files"].is_array() || d["files"].empty())
          fail(key, "each data set is {\"beam_position_m\": X (m), \"files\": [\"a.csv\", ...]} (one file, or one "
                    "per excited input)");
        for (auto f = d.begin(); f != d.end(); ++f)
          if (f.key() != "beam_position_m" && f.key() != "files" && f.key() != "label")
            fail(key, fmt::format("a data set has unknown key '{}'; give beam_position_m, files and optionally label",
                                  f.key()));
        FitDataSpec s;
        s.beam_position_m = d["beam_position_m"].get<double>();
        for (const json& f : d["files"]) {
          if (!f.is_string()) fail(key, fmt::format("files: {} is not a path", f.dump()));
          s.files.push_back(resolve(f.get<std::string>()));
        }
        s.label = d.contains("label") && d["label"].is_string() ? d["label"].get<std::string>()
                                                                : fmt::format("x_b = {:g} m", s.beam_position_m);
        m.specs.push_back(std::move(s));
      }
    } else {
      fail(key, fmt::format("unknown key '{}'; a manifest has format, datasets and optionally target, controller, "
                            "rate_hz, averages, noise_level, band_rad_s",
                            key));
    }
  }
  if (m.specs.empty()) fail("", "the manifest has no 'datasets'; list the files and x_b of every data set");
  return m;
}

double pick(double flag, double manifest) { return std::isnan(flag) ? manifest : flag; }

}  // namespace

FitInputs load_fit_inputs(const FitInputOptions& o, const std::vector<std::string>& outputs) {
  FitInputs in;
  if (o.data.empty() == o.datasets.empty())
    throw InputError(o.data.empty() ? "give the data: --data FILE@X_B (repeat) or --datasets MANIFEST.json"
                                    : "give the data once: --data FILE@X_B or --datasets MANIFEST.json, not both");
  Manifest m;
  if (!o.datasets.empty()) {
    for (const auto& out : outputs)
      if (!out.empty()) check_not_overwriting({o.datasets}, out);
    m = read_manifest(o.datasets);
    in.specs = m.specs;
  } else {
    for (const auto& s : o.data) in.specs.push_back(parse_data_spec(s));
  }
  FitOptions& options = in.options;
  const std::string target = !o.target.empty() ? o.target : !m.target.empty() ? m.target : "plant";
  options.target = parse_target(target);
  options.global_start = !o.no_global;
  options.global_starts = o.starts;
  options.max_iterations = o.max_iterations;
  options.seed = o.seed;
  const double rate = pick(o.rate_hz, m.rate_hz);
  if (!std::isnan(rate) && (!std::isfinite(rate) || rate <= 0))
    throw InputError(fmt::format("--rate-hz {}: give the sample rate in Hz (> 0), or omit it", rate));
  const double averages = pick(o.averages, m.averages);
  if (!std::isnan(averages)) {
    if (!std::isfinite(averages) || averages < 1)
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
  if (!std::isnan(lo)) options.band_min_rad_s = lo;
  if (!std::isnan(hi)) options.band_max_rad_s = hi;
  if (!(o.grid_lo > 0) || !(o.grid_hi > o.grid_lo) || o.grid_count < 2)
    throw InputError("--grid-lo/--grid-hi/--grid-count: need 0 < lo < hi and count >= 2");
  in.controller_path = !o.controller.empty() ? o.controller : m.controller;
  if (options.target != FitTarget::kPlant && in.controller_path.empty())
    throw InputError(fmt::format("--target {} needs --controller C.json (the known controller, e = -q -> u_c)",
                                 target));
  in.inputs = {o.model};
  if (!o.datasets.empty()) in.inputs.push_back(o.datasets);
  for (const auto& s : in.specs)
    for (const auto& f : s.files) in.inputs.push_back(f);
  if (!in.controller_path.empty()) in.inputs.push_back(in.controller_path);
  for (const auto& out : outputs)
    if (!out.empty()) check_not_overwriting(in.inputs, out);

  in.start = read_physical_model(o.model);
  if (!in.controller_path.empty()) options.controller = read_state_space(in.controller_path);
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
  // Sample period: flag (or manifest), else a discrete data model's, else the controller's.
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
  options.sample_period_s = ts;
  options.validate();

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
    in.data.push_back(std::move(d));
  }
  return in;
}

}  // namespace lpvid::cli
