// lpvid simulate platform --trajectory FILE | --profile NAME — the platform in
// closed loop while the beam moves along x_b(t) (seed 000, Fig. 14).
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/output_set.h"
#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/model_json.h"
#include "formats/io/platform_json.h"
#include "idlib/core/error.h"
#include "idlib/sim/moving_beam.h"

namespace lpvid::cli {

void add_trajectory_options(CLI::App* platform, TrajectoryCliOptions& o) {
  platform->add_option("--trajectory", o.trajectory,
                       "move the beam along x_b(t) from a CSV with columns t (s) and x_b (m); writes one run per rate "
                       "(run.csv with columns t,v1..v3,u1..u3,q1..q3,x_b)");
  platform->add_option("--profile", o.profile,
                       "move the beam along a built-in profile: sweep (min-jerk moves left -> right -> left, "
                       "0.6 s moves, 1.4 s rests; --duration-s long)");
  platform->add_option("--excite", o.excite,
                       "with --trajectory/--profile: white excitation on none, all, T_psi, T_theta or F_z (default none)");
  platform->add_option("--substeps", o.substeps, "with --trajectory/--profile: integration pieces per sample (1..1000)")
      ->check(integer_in(1, 1000, "the integration pieces per sample"));
}

void run_simulate_trajectory(const TrajectoryCliOptions& o, const PlatformParameters& params,
                             const SimulateShared& shared) {
  if (!o.trajectory.empty() && !o.profile.empty())
    throw InputError("give either --trajectory FILE or --profile NAME, not both");
  if (!o.profile.empty() && o.profile != "sweep")
    throw InputError(fmt::format("--profile '{}': unknown profile; use sweep", o.profile));
  MovingBeamOptions base;
  base.substeps = o.substeps;
  base.sensor_noise_std *= shared.noise_scale;
  const ExcitationOptions ex_defaults;
  const std::vector<std::string> inputs = {"T_psi", "T_theta", "F_z"};
  if (o.excite == "all") {
    base.excitation_std = ex_defaults.excitation_std;
  } else if (o.excite != "none") {
    const auto it = std::find(inputs.begin(), inputs.end(), o.excite);
    if (it == inputs.end())
      throw InputError(fmt::format("--excite '{}': expected none, all, T_psi, T_theta or F_z", o.excite));
    const auto i = it - inputs.begin();
    base.excitation_std(i) = ex_defaults.excitation_std(i);
  }
  base.validate();
  if (o.profile == "sweep") check_simulated_samples(shared.duration_s, shared.rates_hz);

  // Every output, checked before the trajectory is read; folders are created
  // when the files are published, after the last simulation.
  const std::string name = o.trajectory.empty() ? o.profile : std::filesystem::path(o.trajectory).stem().string();
  OutputSet outputs;
  outputs.input(o.trajectory);
  outputs.directory("--out", shared.out_dir);
  std::vector<std::string> dirs;
  for (const double rate : shared.rates_hz) {
    const std::string folder = fmt::format("{}_{}hz", name, std::llround(rate));
    const std::string dir = join_path(shared.out_dir, folder);
    if (std::find(dirs.begin(), dirs.end(), dir) != dirs.end())
      throw InputError(fmt::format("--rate-hz {} gives the folder '{}' twice; give each rate once",
                                   fmt::join(shared.rates_hz, ","), dir));
    dirs.push_back(dir);
    for (const char* file : {"run.csv", "controller.json", "truth_parameters.json"})
      outputs.file_in(shared.out_dir, join_path(folder, file));
  }
  outputs.check();

  // The trajectory: read (and checked against the stroke) before any simulation.
  BeamTrajectory traj = BeamTrajectory::constant(0.0, 0.0, 1.0);
  if (!o.trajectory.empty()) {
    const BeamSamples s = read_beam_samples(o.trajectory, params.beam_stroke_m);
    traj = BeamTrajectory::from_samples(s.t_s, s.x_b_m);
    check_simulated_samples(traj.end_s() - traj.start_s(), shared.rates_hz);
  } else {
    traj = BeamTrajectory::sweep({}, shared.duration_s);
  }
  const auto gains = default_pi_gains(params);
  nlohmann::json summary = nlohmann::json::array();
  std::string text;
  for (std::size_t ir = 0; ir < shared.rates_hz.size(); ++ir) {
    const double ts = 1.0 / shared.rates_hz[ir];
    MovingBeamOptions mo = base;
    mo.sample_period_s = ts;
    mo.seed = shared.seed * 1000003ULL + ir * 101ULL;
    const StateSpace controller = discrete_pi_controller(gains, ts);
    const SimulatedLog log = simulate_moving_beam(params, controller, traj, mo);
    const std::string& dir = dirs[ir];
    const nlohmann::json provenance = {{"command", "lpvid simulate platform"},
                                       {"trajectory", o.trajectory.empty() ? o.profile : o.trajectory},
                                       {"seed", mo.seed}};
    OutputSet& out = outputs;
    write_log(out.stage(join_path(dir, "run.csv")), log.names, log.data,
              {fmt::format("lpvid simulate platform: moving beam ({}) sample_period_s={} excite={} seed={}", name, ts,
                           o.excite, mo.seed)});
    out.stage(join_path(dir, "controller.json"), state_space_to_json(controller, {{"provenance", provenance}}));
    out.stage(join_path(dir, "truth_parameters.json"),
              platform_parameters_to_json(params, {{"provenance", provenance}}));
    const double duration = traj.end_s() - traj.start_s();
    summary.push_back({{"dir", dir}, {"rate_hz", shared.rates_hz[ir]}, {"duration_s", duration}, {"samples", log.data.rows()}});
    text += fmt::format("wrote {} (moving beam: {}, {} Hz, {} s)\n", dir, name, shared.rates_hz[ir], duration);
  }
  outputs.commit();
  print_summary(shared.json, summary, text);
}

}  // namespace lpvid::cli
