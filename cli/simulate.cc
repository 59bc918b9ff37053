// lpvid simulate platform — closed-loop white-noise experiments on the 3-DOF
// LPV platform (seed 000, eqs 1–9) under three discrete PI controllers, with the
// exact models written beside the logs so that tests and users know the truth.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "cli/simulate_analyzer.h"
#include "cli/simulate_stage6.h"
#include "formats/io/csv_log.h"
#include "formats/io/excitation_file.h"
#include "formats/io/model_json.h"
#include "formats/io/physical_model_json.h"
#include "formats/io/platform_json.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/interconnect.h"
#include "idlib/physical/evaluate.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"

namespace lpvid::cli {
namespace {

constexpr const char* kSimulateExample = R"(
Example:
  lpvid simulate platform --out data --positions left,middle,right --rate-hz 1000 --duration-s 60
writes data/middle_1000hz/{exp_T_psi.csv, exp_T_theta.csv, exp_F_z.csv} (one experiment
per excited input: columns t, v1..v3, u1..u3, q1..q3), controller.json, and the truth:
truth_plant.json (ZOH-sampled), truth_plant_continuous.json, truth_closed_loop.json.
Beam positions: left, middle, right (see docs/assumptions.md) or a number in metres.
  lpvid simulate platform --out other --set coil_damping_Ns_per_m=40 --set J_psi_kgm2=0.07
simulates a platform with other physical values (the PI gains are redesigned for them).
  lpvid simulate platform --out data --profile sweep --duration-s 12
moves the beam (min-jerk sweeps left -> right -> left) and writes data/sweep_1000hz/{run.csv
(columns t, v1..v3, u1..u3, q1..q3, x_b), controller.json, truth_parameters.json};
--trajectory FILE (columns t, x_b) moves it along your reference instead.
  lpvid simulate platform --out data --analyzer --analyzer-band-hz 0.15,65 --analyzer-integration-s 1
also measures S (v -> u) as a stepped-sine analyzer: S_v1.csv, S_v2.csv, S_v3.csv (column j
of S with coherence, input j excited) and truth_S.csv; then
  lpvid unloop --sensitivity data/middle_1000hz/S_v*.csv --controller data/middle_1000hz/controller.json --out P.csv)";

struct SimulateOptions {
  std::string out_dir;
  std::vector<std::string> positions = {"left", "middle", "right"};
  std::vector<double> rates_hz = {1000.0};
  double duration_s = 60.0;
  std::uint64_t seed = 1;
  double noise_scale = 1.0;
  bool simultaneous = false;
  bool json = false;
  std::vector<std::string> overrides;  // NAME=VALUE
  std::string truth_model;             // physical model file (lpvid model): the truth, effects included
  AnalyzerCliOptions analyzer;         // --analyzer* (cli/simulate_analyzer.h)
  std::string excitation;              // --excitation FILE (lpvid excite): replaces the white noise
  bool duration_given = false;
};

// The documented platform with `--set NAME=VALUE` overrides (formats/io/platform_json.h).
PlatformParameters parameters_with(const std::vector<std::string>& overrides) {
  PlatformParameters params = PlatformParameters::defaults();
  apply_parameter_overrides(params, overrides);
  return params;
}

double parse_position(const std::string& text) {
  if (text == "left") return kBeamLeft_m;
  if (text == "middle") return kBeamMiddle_m;
  if (text == "right") return kBeamRight_m;
  double v = 0;
  if (parse_decimal(text, v)) return v;
  throw InputError(fmt::format("--positions: '{}' is not left, middle, right or a number in metres; give e.g. "
                               "left,middle,0.05",
                               text.size() <= 40 ? text : text.substr(0, 40) + "..."));
}

std::string position_label(const std::string& text) {
  std::string label = text;
  for (char& c : label)
    if (c == '.' || c == '-') c = c == '.' ? 'p' : 'm';
  return label;
}

void run(const SimulateOptions& o) {
  check_simulated_samples(o.duration_s, o.rates_hz);
  check_analyzer_options(o.analyzer, o.rates_hz);
  std::vector<double> positions_m;
  for (const auto& p : o.positions) positions_m.push_back(parse_position(p));
  if (!o.truth_model.empty() && !o.overrides.empty())
    throw InputError("--set and --truth-model both given: put the values in the model file (lpvid model) or use --set alone");
  const bool designed = !o.excitation.empty();
  if (designed && o.simultaneous)
    throw InputError("--simultaneous does not apply with --excitation (the file says which inputs are excited when); "
                     "leave it out");
  if (designed && o.duration_given)
    throw InputError("--duration-s does not apply with --excitation (the file sets the length); leave it out");
  if (designed && o.rates_hz.size() != 1)
    throw InputError("--excitation is sampled at one rate: give one --rate-hz, the file's");

  // Every file of every folder, checked before anything is read or simulated;
  // the folders are created when the files are published, after the last simulation.
  static const char* const kInputs[] = {"T_psi", "T_theta", "F_z"};
  OutputSet outputs;
  outputs.input(o.truth_model);
  outputs.input(o.excitation);
  outputs.directory("--out", o.out_dir);
  std::vector<std::string> dirs;
  for (std::size_t ip = 0; ip < positions_m.size(); ++ip)
    for (std::size_t ir = 0; ir < o.rates_hz.size(); ++ir) {
      const std::string dir =
          join_path(o.out_dir, fmt::format("{}_{}hz", position_label(o.positions[ip]), std::llround(o.rates_hz[ir])));
      if (std::find(dirs.begin(), dirs.end(), dir) != dirs.end())
        throw InputError(fmt::format("--positions {} and --rate-hz {} give the folder '{}' twice; give each position "
                                     "and rate once",
                                     fmt::join(o.positions, ","), fmt::join(o.rates_hz, ","), dir));
      dirs.push_back(dir);
      const std::string folder = fmt::format("{}_{}hz", position_label(o.positions[ip]), std::llround(o.rates_hz[ir]));
      for (const char* name : {"controller.json", "truth_plant.json", "truth_plant_continuous.json", "truth_closed_loop.json"})
        outputs.file_in(o.out_dir, join_path(folder, name));
      if (designed) {
        outputs.file_in(o.out_dir, join_path(folder, "exp_excitation.csv"));
      } else if (o.simultaneous) {
        outputs.file_in(o.out_dir, join_path(folder, "exp_all.csv"));
      } else {
        for (const char* input : kInputs) outputs.file_in(o.out_dir, join_path(folder, fmt::format("exp_{}.csv", input)));
      }
      register_analyzer_files(outputs, o.analyzer, o.out_dir, folder);
    }
  outputs.check();

  // A designed excitation (lpvid excite): its v1..v3 replace the white noise sample
  // for sample, at the file's rate; the log copies its design line for frf.
  std::optional<ExcitationFile> excitation;
  if (designed) {
    excitation = read_excitation_file(o.excitation);
    const ExcitationDesign& d = excitation->design;
    if (d.channels != 3)
      throw InputError(fmt::format("--excitation {}: {} channel{} but the platform has 3 inputs (v1..v3); write it with "
                                   "lpvid excite --channels 3",
                                   o.excitation, d.channels, d.channels == 1 ? "" : "s"));
    // 1e-6 relative: the same rate written with different rounding.
    if (!(std::abs(d.sample_rate_hz - o.rates_hz[0]) <= 1e-6 * o.rates_hz[0]))
      throw InputError(fmt::format("--excitation {} is sampled at {} Hz but --rate-hz is {}; give --rate-hz {} or "
                                   "write the signal at {} Hz (lpvid excite --rate-hz)",
                                   o.excitation, d.sample_rate_hz, o.rates_hz[0], d.sample_rate_hz, o.rates_hz[0]));
  }

  // The truth: the documented platform with --set overrides, or a physical model
  // file with its effects (a hidden effect for the model-error loop; the PI gains
  // are designed on its rigid-body terms, as for --set).
  std::optional<PhysicalModel> truth;
  if (!o.truth_model.empty()) truth = read_physical_model(o.truth_model);
  const PlatformParameters params = truth ? platform_parameters(*truth) : parameters_with(o.overrides);
  for (std::size_t ip = 0; ip < positions_m.size(); ++ip)
    if (!(std::abs(positions_m[ip]) <= params.beam_stroke_m))
      throw InputError(fmt::format("--positions {}: x_b = {} m is outside the stroke |x_b| <= {} m (beam_stroke_m); "
                                   "give a position within the stroke, or left, middle, right",
                                   o.positions[ip], positions_m[ip], params.beam_stroke_m));
  const auto gains = default_pi_gains(params);
  nlohmann::json summary = nlohmann::json::array();
  std::string text;
  for (std::size_t ip = 0; ip < positions_m.size(); ++ip) {
    for (std::size_t ir = 0; ir < o.rates_hz.size(); ++ir) {
      const double ts = 1.0 / o.rates_hz[ir];
      const std::string dir = dirs[ip * o.rates_hz.size() + ir];
      // With a truth model the discrete plant carries its effects (an input delay as
      // whole-sample shift states); the continuous file holds the delay-free part.
      const StateSpace plant_c =
          truth ? physical_state_space(*truth, positions_m[ip]).system : platform_model(params, positions_m[ip]);
      const StateSpace plant_d =
          truth ? physical_state_space(*truth, positions_m[ip], ts).system : discretize_zoh(plant_c, ts);
      const StateSpace controller = discrete_pi_controller(gains, ts);
      const StateSpace closed_loop = closed_loop_output(plant_d, controller);
      const nlohmann::json provenance = {
          {"command", "lpvid simulate platform"}, {"beam_position_m", positions_m[ip]}, {"seed", o.seed},
          {"truth_model", o.truth_model}};
      outputs.stage(join_path(dir, "controller.json"), state_space_to_json(controller, {{"provenance", provenance}}));
      outputs.stage(join_path(dir, "truth_plant.json"), state_space_to_json(plant_d, {{"provenance", provenance}}));
      outputs.stage(join_path(dir, "truth_plant_continuous.json"),
                    state_space_to_json(plant_c, {{"provenance", provenance}}));
      outputs.stage(join_path(dir, "truth_closed_loop.json"), state_space_to_json(closed_loop, {{"provenance", provenance}}));

      ExcitationOptions ex;
      ex.duration_s = o.duration_s;
      ex.sample_period_s = ts;
      ex.sensor_noise_std *= o.noise_scale;
      if (excitation) {
        ex.excitation_samples = excitation->log.data.rightCols(3);
        ex.seed = o.seed * 1000003ULL + ip * 1009ULL + ir * 101ULL;
        const SimulatedLog log = simulate_excitation(plant_d, controller, ex);
        write_log(outputs.stage(join_path(dir, "exp_excitation.csv")), log.names, log.data,
                  {fmt::format("lpvid simulate platform: beam_position_m={} sample_period_s={} excited=designed "
                               "excitation={} seed={}",
                               positions_m[ip], ts, o.excitation, ex.seed),
                   excitation_design_comment(excitation->design)});
      }
      const int runs = excitation ? 0 : o.simultaneous ? 1 : 3;
      for (int input = 0; input < runs; ++input) {
        ex.excited_input = o.simultaneous ? -1 : input;
        // Distinct, reproducible streams per (seed, position, rate, input).
        ex.seed = o.seed * 1000003ULL + ip * 1009ULL + ir * 101ULL + static_cast<std::uint64_t>(input);
        const SimulatedLog log = simulate_excitation(plant_d, controller, ex);
        const std::string name = o.simultaneous ? "exp_all.csv" : fmt::format("exp_{}.csv", plant_c.input_names[input]);
        write_log(outputs.stage(join_path(dir, name)), log.names, log.data,
                  {fmt::format("lpvid simulate platform: beam_position_m={} sample_period_s={} excited={} seed={}",
                               positions_m[ip], ts, o.simultaneous ? "all" : plant_c.input_names[input], ex.seed)});
      }
      summary.push_back({{"dir", dir}, {"beam_position_m", positions_m[ip]}, {"rate_hz", o.rates_hz[ir]}});
      text += fmt::format("wrote {} (x_b = {} m, {} Hz, {} s{})\n", dir, positions_m[ip], o.rates_hz[ir],
                          excitation ? static_cast<double>(excitation->log.num_samples()) * ts : o.duration_s,
                          excitation ? ", excitation " + o.excitation : std::string());
      if (o.analyzer.enabled)
        summary.back()["analyzer"] =
            write_analyzer_files(outputs, o.analyzer, dir, plant_d, controller, ex.sensor_noise_std,
                                 o.seed * 1000003ULL + ip * 1009ULL + ir * 101ULL + 7ULL, positions_m[ip], text);
    }
  }
  outputs.commit();
  print_summary(o.json, summary, text);
}

}  // namespace

Command make_simulate_command() {
  return {"simulate", "simulate closed-loop experiments with known truth", [](CLI::App& parent) {
            auto* sim = parent.add_subcommand("simulate", "Simulate closed-loop experiments with known truth");
            sim->require_subcommand(1);
            auto opts = std::make_shared<SimulateOptions>();
            auto* platform = sim->add_subcommand(
                "platform", "3-DOF LPV platform (seed 000) under three discrete PI controllers" + std::string(kSimulateExample));
            platform->add_option("--out", opts->out_dir, "output directory (one folder per position and rate)")
                ->required();
            auto* positions = platform->add_option("--positions", opts->positions, "beam positions: left, middle, right or metres")
                ->delimiter(',');
            platform->add_option("--rate-hz", opts->rates_hz, "sampling rates in Hz (e.g. 1000,10000)")
                ->delimiter(',')
                ->check(positive_up_to(kMaxRateHz, "each sample rate in Hz"));
            auto* duration = platform->add_option("--duration-s", opts->duration_s, "length of each experiment in seconds")
                ->check(positive_up_to(kMaxDurationS, "the length of each experiment in s"));
            platform->add_option("--excitation", opts->excitation,
                                 "drive the inputs with this signal (lpvid excite: CSV or .mat, v1..v3 at --rate-hz) "
                                 "instead of white noise; writes exp_excitation.csv with the design line");
            platform->add_option("--seed", opts->seed, "random seed (same seed, same logs)")->check(seed_value());
            platform->add_option("--noise-scale", opts->noise_scale, "multiplies the default sensor noise (0 = none)")
                ->check(number_in(0, kMaxScale, "the noise scale"));
            platform->add_flag("--simultaneous", opts->simultaneous,
                               "excite all three inputs at once in one experiment (default: one input per experiment)");
            platform->add_option("--truth-model", opts->truth_model,
                                 "simulate this physical model file (lpvid model; effects included) instead of the "
                                 "documented platform");
            platform->add_option("--set", opts->overrides,
                                 "override a physical parameter, NAME=VALUE in the units of its name "
                                 "(repeatable; see docs/assumptions.md); the PI gains follow the parameters");
            platform->add_flag("--json", opts->json, "print the summary as JSON");
            add_analyzer_options(*platform, opts->analyzer);
            auto beam = std::make_shared<TrajectoryCliOptions>();
            add_trajectory_options(platform, *beam);
            platform->callback([opts, beam, positions, duration] {
              opts->duration_given = duration->count() > 0;
              if (!beam->active()) return run(*opts);
              // Flags of the fixed-position experiments do not apply to a moving beam.
              const char* ignored = positions->count() > 0       ? "--positions"
                                    : opts->analyzer.enabled     ? "--analyzer"
                                    : !opts->truth_model.empty() ? "--truth-model"
                                    : opts->simultaneous         ? "--simultaneous"
                                    : !opts->excitation.empty()  ? "--excitation"
                                                                 : nullptr;
              if (ignored != nullptr)
                throw InputError(fmt::format("{} does not apply to a moving beam (--profile/--trajectory); leave it "
                                             "out, or drop --profile/--trajectory",
                                             ignored));
              run_simulate_trajectory(*beam, parameters_with(opts->overrides),
                                      {opts->out_dir, opts->rates_hz, opts->duration_s, opts->seed, opts->noise_scale,
                                       opts->json});
            });
            install_simulate_stage6(*sim);
          }};
}

}  // namespace lpvid::cli
