// indep_sim: writes datasets from the independent platform simulator
// (tests/support/independent_platform.h) in lpvid's file formats, for trying lpvid
// as a new user would on a plant it was not written against.  A test tool, not
// part of lpvid.
//
//   indep_sim --out DIR [--seed N] [--hidden none|mode|delay|coil_lag|com_offset|rod_twist|sensor_resonance|gain[,...]]
//             [--rate-hz 1000] [--duration-s 60] [--noise-scale X] [--no-logs] [--no-analyzer]
//             [--averages 16] [--no-averages-line] [--integration-s 4] [--points 300] [--f-max-hz 400]
//             [--ratio-min 0.3] [--ratio-max 3] [--cl-damping-min 0.02] [--noise-min 0.1] [--noise-max 10]
//             [--no-zero-noise]   (the draw's ranges, DrawOptions)
//             [--levitated]       (no rods: zero spring stiffness, tilts open-loop unstable)
//             [--bandwidth-scale X] (every drawn closed-loop bandwidth times X)
//
// Writes DIR/{left,middle,right}/ (x_b = -0.1, 0, +0.1 m): controller.json,
// exp_v1.csv exp_v2.csv exp_v3.csv (white noise on one input each), S_v1..3.csv
// (stepped-sine analyzer of S with coherence), truth_plant.json (the sampled plant),
// truth_S.csv is not written (the truth stays with the test); DIR/truth.txt lists
// every drawn value.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>
#include <algorithm>

#include "tests/support/independent_draw.h"

int main(int argc, char** argv) {
  std::string out, hidden = "none";
  std::uint64_t seed = 1;
  double rate = 1000, duration = 60, noise_override = -1, integration_s = 4;
  double bandwidth_scale = 1;  // --bandwidth-scale: every drawn closed-loop bandwidth times this
  bool levitated = false;  // --levitated: no rods (zero spring stiffness), the beam's gravity left
  unsigned long long noise_seed = 0;  // --noise-seed: another noise (and excitation) realisation of the same plant
  bool logs = true, analyzer = true, averages_line = true;
  int averages = 16, points = 300;
  indep::DrawOptions dopt;  // the draw's ranges (tests/support/independent_draw.h)
  double f_max_hz = 400.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "indep_sim: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--out") out = next();
    else if (a == "--seed") seed = std::stoull(next());
    else if (a == "--hidden") hidden = next();
    else if (a == "--rate-hz") rate = std::stod(next());
    else if (a == "--duration-s") duration = std::stod(next());
    else if (a == "--noise-scale") noise_override = std::stod(next());
    else if (a == "--noise-seed") noise_seed = std::stoull(next());
    else if (a == "--no-logs") logs = false;
    else if (a == "--no-analyzer") analyzer = false;
    else if (a == "--averages") averages = std::stoi(next());
    else if (a == "--no-averages-line") averages_line = false;
    else if (a == "--integration-s") integration_s = std::stod(next());
    else if (a == "--points") points = std::stoi(next());
    else if (a == "--f-max-hz") f_max_hz = std::stod(next());
    else if (a == "--ratio-min") dopt.min_ratio = std::stod(next());
    else if (a == "--ratio-max") dopt.max_ratio = std::stod(next());
    else if (a == "--cl-damping-min") dopt.min_cl_damping = std::stod(next());
    else if (a == "--noise-min") dopt.min_noise_scale = std::stod(next());
    else if (a == "--noise-max") dopt.max_noise_scale = std::stod(next());
    else if (a == "--no-zero-noise") dopt.allow_zero_noise = false;
    else if (a == "--levitated") levitated = true;
    else if (a == "--bandwidth-scale") bandwidth_scale = std::stod(next());
    else {
      std::fprintf(stderr, "indep_sim: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (out.empty()) {
    std::fprintf(stderr, "indep_sim: --out DIR is required\n");
    return 2;
  }
  using indep::HiddenEffect;
  // one effect, or several separated by commas (drawn together: independent_draw.h)
  std::vector<HiddenEffect> effects;
  for (std::size_t at = 0; at <= hidden.size();) {
    const std::size_t comma = std::min(hidden.find(',', at), hidden.size());
    const std::string name = hidden.substr(at, comma - at);
    bool found = false;
    for (HiddenEffect e : {HiddenEffect::kNone, HiddenEffect::kMode, HiddenEffect::kDelay, HiddenEffect::kCoilLag,
                           HiddenEffect::kComOffset, HiddenEffect::kRodTwist, HiddenEffect::kSensorResonance,
                           HiddenEffect::kGain})
      if (name == indep::hidden_name(e)) effects.push_back(e), found = true;
    if (!found) {
      std::fprintf(stderr, "indep_sim: unknown hidden effect %s\n", name.c_str());
      return 2;
    }
    at = comma + 1;
  }
  const double Ts = 1.0 / rate;
  const double xb[3] = {-0.1, 0.0, 0.1};
  int redraws = 0;
  indep::Draw d;
  try {
    d = indep::draw_stable(seed, effects, dopt, Ts, {xb[0], xb[1], xb[2]}, &redraws);
  } catch (const std::runtime_error&) {
    std::fprintf(stderr, "indep_sim: the drawn PID loop of seed %llu is unstable (no experiment exists); use another seed\n",
                 static_cast<unsigned long long>(seed));
    return 1;
  }
  if (redraws > 0) d.description += "hidden_effect_redraws = " + std::to_string(redraws) + "  # earlier draws destabilised the loop\n";
  if (noise_override >= 0) d.noise_scale = noise_override;
  if (bandwidth_scale != 1) {
    for (double& w : d.pid.bandwidth_rad_s) w *= bandwidth_scale;
    d.description += "bandwidth_scale = " + std::to_string(bandwidth_scale) + "\n";
    const indep::Discrete Cb = indep::pid_controller(d.plant, d.pid, Ts);
    for (double x : xb)
      if (!levitated && indep::closed_loop_spectral_radius(indep::sampled_plant(d.plant, x, Ts), Cb) >= 1) {
        std::fprintf(stderr, "indep_sim: with --bandwidth-scale %g the loop of seed %llu is unstable; use another\n",
                     bandwidth_scale, static_cast<unsigned long long>(seed));
        return 1;
      }
  }
  if (levitated && !indep::levitate(d, Ts, {xb[0], xb[1], xb[2]})) {
    std::fprintf(stderr, "indep_sim: the levitated loop of seed %llu is unstable; use another seed\n",
                 static_cast<unsigned long long>(seed));
    return 1;
  }

  indep::Noise noise;
  noise.sensor_std_m = 0.3e-6 * d.noise_scale;
  std::filesystem::create_directories(out);
  {
    FILE* f = std::fopen((out + "/truth.txt").c_str(), "w");
    std::fprintf(f, "seed = %llu\nhidden = %s\n%s", static_cast<unsigned long long>(seed), hidden.c_str(),
                 d.description.c_str());
    std::fclose(f);
  }
  const indep::Discrete C = indep::pid_controller(d.plant, d.pid, Ts);
  const char* names[3] = {"left", "middle", "right"};
  for (int pos = 0; pos < 3; ++pos) {
    const std::string dir = out + "/" + names[pos];
    std::filesystem::create_directories(dir);
    const indep::Discrete P = indep::sampled_plant(d.plant, xb[pos], Ts);
    indep::write_controller_json(dir + "/controller.json", C);
    indep::write_state_space_json(dir + "/truth_plant.json", P, {"T_psi", "T_theta", "F_z"}, {"psi", "theta", "z"});
    if (logs) {
      const double ex[3] = {0.05, 0.05, 1.0};
      for (int j = 0; j < 3; ++j) {
        const auto N = static_cast<Eigen::Index>(std::llround(duration * rate));
        const Eigen::MatrixXd log = indep::simulate_log(P, C, d.plant, noise, ex, j, N, seed * 1000 + 10 * pos + j + noise_seed * 7919);
        indep::write_log_csv(dir + "/exp_v" + std::to_string(j + 1) + ".csv", log);
      }
    }
    if (analyzer) {
      Eigen::VectorXd w(points);
      for (int k = 0; k < points; ++k) w(k) = 2 * M_PI * 0.15 * std::pow(f_max_hz / 0.15, k / (points - 1.0));
      const double amp[3] = {0.05, 0.05, 1.0};
      const auto Nb = static_cast<Eigen::Index>(std::llround(integration_s * rate / averages));
      const indep::AnalyzerData a =
          indep::analyzer_S(P, C, d.plant, noise, w, amp, averages, Nb, seed * 1000 + 500 + pos);
      indep::write_analyzer_csv(dir, a, averages_line);
    }
  }
  std::printf("indep_sim: wrote %s (hidden %s, seed %llu, noise scale %.3g)\n", out.c_str(), hidden.c_str(),
              static_cast<unsigned long long>(seed), d.noise_scale);
  return 0;
}
