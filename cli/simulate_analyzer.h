// lpvid simulate platform --analyzer: SigLab-style stepped-sine measurements of
// the input sensitivity S (v -> u), one FRD file per excited input, written next
// to the logs (idlib/sim/analyzer.h; docs/formats.md "Analyzer files").
// Called from cli/simulate.cc; kept apart so that the simulate command stays short.
#pragma once

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "idlib/core/types.h"

namespace lpvid::cli {

class OutputSet;

struct AnalyzerCliOptions {
  bool enabled = false;
  std::vector<double> band_hz = {0.15, 65.0};  // 0.94 .. 408 rad/s: the model's band
  Index points = 200;
  double integration_s = 1.0;
  Index averages = 4;
  bool mat = false;
};

// Adds --analyzer, --analyzer-band-hz, --analyzer-points, --analyzer-integration-s,
// --analyzer-averages, --analyzer-mat to the `simulate platform` command.
void add_analyzer_options(CLI::App& platform, AnalyzerCliOptions& options);

// Checks the options (InputError naming the flag) before anything is simulated,
// including that the sweep stays below the Nyquist frequency of every rate.
void check_analyzer_options(const AnalyzerCliOptions& options, const std::vector<double>& rates_hz);

// Registers the analyzer's files in out_dir/folder (when --analyzer is on).
void register_analyzer_files(OutputSet& outputs, const AnalyzerCliOptions& options, const std::string& out_dir,
                             const std::string& folder);

// Measures S of the loop (plant_d, controller) and stages dir/S_v1.csv,
// S_v2.csv, S_v3.csv (column j of S each; coherence), dir/truth_S.csv (the exact
// S on the same grid) and, with --analyzer-mat, dir/S.mat (the whole matrix).
// Returns the JSON summary entry; appends a line to text.
nlohmann::json write_analyzer_files(OutputSet& outputs, const AnalyzerCliOptions& options, const std::string& dir,
                                    const StateSpace& plant_d, const StateSpace& controller,
                                    const Eigen::Vector3d& sensor_noise_std, std::uint64_t seed,
                                    double beam_position_m, std::string& text);

}  // namespace lpvid::cli
