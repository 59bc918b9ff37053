#include "cli/simulate_analyzer.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "cli/common.h"
#include "cli/output_set.h"
#include "formats/io/atomic_file.h"
#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/sim/analyzer.h"

namespace lpvid::cli {

void add_analyzer_options(CLI::App& platform, AnalyzerCliOptions& o) {
  platform.add_flag("--analyzer", o.enabled,
                    "also measure S (v -> u) as a stepped-sine analyzer would: S_v1.csv, S_v2.csv, S_v3.csv "
                    "(one excited input each), truth_S.csv");
  platform.add_option("--analyzer-band-hz", o.band_hz, "analyzer sweep: lowest,highest frequency in Hz")
      ->delimiter(',')
      ->expected(2)
      ->check(positive_up_to(kMaxFrequency, "each end of the sweep in Hz"));
  platform.add_option("--analyzer-points", o.points, "analyzer sweep: number of log-spaced frequencies")
      ->check(integer_in(1, kMaxFrequencyPoints, "the number of frequencies"));
  platform.add_option("--analyzer-integration-s", o.integration_s,
                      "analyzer: measurement time per frequency and input in s (noise falls as 1/sqrt)")
      ->check(positive_up_to(kMaxDurationS, "the measurement time per frequency in s"));
  platform.add_option("--analyzer-averages", o.averages, "analyzer: blocks averaged per frequency (>= 2)")
      ->check(integer_in(2, 1'000'000, "the number of averages"));
  platform.add_flag("--analyzer-mat", o.mat, "analyzer: also write the whole S as S.mat (MATLAB v5)");
}

void check_analyzer_options(const AnalyzerCliOptions& o, const std::vector<double>& rates_hz) {
  if (!o.enabled) return;
  if (o.band_hz.size() != 2 || !(o.band_hz[0] > 0) || !(o.band_hz[1] > o.band_hz[0]) || !std::isfinite(o.band_hz[1]))
    throw InputError(fmt::format("--analyzer-band-hz {}: give two frequencies in Hz, 0 < lowest < highest",
                                 fmt::join(o.band_hz, ",")));
  for (double r : rates_hz)
    if (!(o.band_hz[1] < r / 2))
      throw InputError(fmt::format("--analyzer-band-hz {}: the highest frequency must be below the Nyquist frequency "
                                   "{} Hz of --rate-hz {}; lower the band or raise --rate-hz",
                                   fmt::join(o.band_hz, ","), r / 2, r));
}

void register_analyzer_files(OutputSet& outputs, const AnalyzerCliOptions& o, const std::string& out_dir,
                             const std::string& folder) {
  if (!o.enabled) return;
  for (const char* name : {"S_v1.csv", "S_v2.csv", "S_v3.csv", "truth_S.csv"})
    outputs.file_in(out_dir, join_path(folder, name));
  if (o.mat) outputs.file_in(out_dir, join_path(folder, "S.mat"));
}

nlohmann::json write_analyzer_files(OutputSet& files, const AnalyzerCliOptions& o, const std::string& dir, const StateSpace& plant_d,
                                    const StateSpace& controller, const Eigen::Vector3d& sensor_noise_std,
                                    std::uint64_t seed, double beam_position_m, std::string& text) {
  AnalyzerOptions a;
  const double lo = 2 * std::numbers::pi * o.band_hz[0], hi = 2 * std::numbers::pi * o.band_hz[1];
  a.omega_rad_s = o.points == 1 ? Eigen::VectorXd::Constant(1, lo) : log_frequency_grid(lo, hi, o.points);
  a.integration_s = o.integration_s;
  a.averages = o.averages;
  a.sensor_noise_std = sensor_noise_std;
  a.sample_period_s = plant_d.sample_period_s;
  a.seed = seed;
  const AnalyzerMeasurement m = measure_sensitivity(plant_d, controller, a);

  const std::string about =
      fmt::format("lpvid simulate platform --analyzer: stepped sine, beam_position_m={} sample_period_s={} "
                  "integration_s={} averages={} seed={}",
                  beam_position_m, a.sample_period_s, a.integration_s, a.averages, seed);
  nlohmann::json written = nlohmann::json::array();
  for (Index j = 0; j < 3; ++j) {
    // Column j of S: what the analyzer records while input j is excited.
    FrequencyResponse part = m.sensitivity;
    part.flagged.clear();  // the analyzer flags nothing: no flag column
    part.averages = a.averages;  // the blocks behind its coherence ('# averages: K')
    part.input_names = {m.sensitivity.input_names[static_cast<std::size_t>(j)]};
    for (std::size_t k = 0; k < part.response.size(); ++k) {
      part.response[k] = m.sensitivity.response[k].col(j);
      part.coherence[k] = m.sensitivity.coherence[k].col(j);
    }
    const std::string path = join_path(dir, fmt::format("S_{}.csv", part.input_names[0]));
    write_frd_csv(files.stage(path), part, "S",
                  {about, fmt::format("excited input: {} (amplitude {})", part.input_names[0], a.excitation_amplitude(j))});
    written.push_back(path);
  }
  const std::string truth = join_path(dir, "truth_S.csv");
  write_frd_csv(files.stage(truth), m.exact_sensitivity, "S", {"lpvid simulate platform --analyzer: exact S (truth)"});
  written.push_back(truth);
  if (o.mat) {
    const std::string mat = join_path(dir, "S.mat");
    FrequencyResponse whole = m.sensitivity;
    whole.flagged.clear();
    whole.averages = a.averages;
    write_frd_mat(files.stage(mat), whole, "S");
    written.push_back(mat);
  }
  text += fmt::format("  analyzer: S at {} frequencies, noise on S {:.3g} % (mean relative), in {}\n",
                      a.omega_rad_s.size(), 100 * m.mean_relative_noise, dir);
  return {{"files", written},
          {"frequencies", a.omega_rad_s.size()},
          {"noise_on_S_mean_relative", m.mean_relative_noise},
          {"noise_on_S_max_relative", m.relative_noise.maxCoeff()}};
}

}  // namespace lpvid::cli
