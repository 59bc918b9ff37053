// indep_stage_sim: writes a closed-loop log from the independent 6-DOF stage
// simulator (tests/support/independent_stage.h) in the layout of
// `lpvid simulate stage6 --experiment`, for trying lpvid's stage loop as a new user
// would on a stage it was not written against.  A test tool, not part of lpvid.
//
//   indep_stage_sim --out DIR [--seed N] [--hidden none|gap|lag|com|delay]
//                   [--duration-s 60] [--noise-scale X (default: drawn 0.5-2)]
//                   [--lpvid-conventions]  (the law's velocity exact: lpvid's own simulator's
//                                           choice, tests/cli/indep_stage_crosscheck_test.cc)
//
// Writes DIR/exp_stage6.csv (t, v1..v6, u1..u6, q1..q6: excitation, body wrench sent
// to the allocation F_x F_y F_z tau_x tau_y tau_z, measured x y z psi theta phi) and
// DIR/truth.txt (every drawn value, `name = value  # note`).  A draw that does not
// hover (the loop diverges, or over the second half the height is > 3 mm off the
// reference or a tilt > 20 mrad) is redrawn with another seed (at most 10 times; the
// count is in truth.txt).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "tests/support/independent_stage.h"

int main(int argc, char** argv) {
  std::string out, hidden = "none";
  std::uint64_t seed = 1;
  double duration = 60, noise_scale = -1;
  bool lpvid_conventions = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "indep_stage_sim: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--out") out = next();
    else if (a == "--seed") seed = std::stoull(next());
    else if (a == "--hidden") hidden = next();
    else if (a == "--duration-s") duration = std::stod(next());
    else if (a == "--noise-scale") noise_scale = std::stod(next());
    else if (a == "--lpvid-conventions") lpvid_conventions = true;
    else {
      std::fprintf(stderr, "indep_stage_sim: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  indep_stage::Hidden h;
  if (out.empty() || !indep_stage::parse_hidden(hidden, &h)) {
    std::fprintf(stderr, "indep_stage_sim: --out DIR is required; --hidden is one of none, gap, lag, com, delay\n");
    return 2;
  }
  indep_stage::HoveringRun hr;
  std::string notes;
  const bool hovered = indep_stage::run_hovering(
      seed, h, noise_scale,
      [&](indep_stage::Draw& d) {
        d.experiment.duration_s = duration;
        if (lpvid_conventions) {
          d.controller.true_velocity = true;
          d.description += "conventions = lpvid  # exact velocity in the law\n";
        }
      },
      &hr, &notes);
  if (!notes.empty()) std::fprintf(stderr, "%s", notes.c_str());
  if (hovered) {
    const Eigen::VectorXd mean = hr.mean_q_second_half;
    const double q_ref_z = hr.draw.experiment.q_ref(2);
    std::filesystem::create_directories(out);
    indep_stage::write_log_csv(out + "/exp_stage6.csv", hr.log);
    FILE* f = std::fopen((out + "/truth.txt").c_str(), "w");
    std::fprintf(f, "seed = %llu\nredraws = %d\n%shover_height_above_ref_m = %.6g\nhover_yaw_rad = %.6g\n"
                 "hover_pitch_rad = %.6g\nhover_roll_rad = %.6g\n",
                 static_cast<unsigned long long>(seed), hr.redraws, hr.draw.description.c_str(), mean(2) - q_ref_z,
                 mean(3), mean(4), mean(5));
    std::fclose(f);
    std::printf("indep_stage_sim: wrote %s/exp_stage6.csv (%ld rows; hidden %s, seed %llu; hovering %.3f mm above the "
                "reference, tilts %.3f %.3f %.3f mrad)\n",
                out.c_str(), static_cast<long>(hr.log.t.size()), hidden.c_str(), static_cast<unsigned long long>(seed),
                1e3 * (mean(2) - q_ref_z), 1e3 * mean(3), 1e3 * mean(4), 1e3 * mean(5));
    return 0;
  }
  std::fprintf(stderr, "indep_stage_sim: no draw of seed %llu hovered; use another seed\n",
               static_cast<unsigned long long>(seed));
  return 1;
}
