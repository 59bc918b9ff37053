// Benchmark of idlib/fit: the physical-model fit of the size.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include <fmt/format.h>

#include "idlib/fit/fit.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"
#include "tests/support/described_base.h"

namespace {

using namespace lpvid;

// 3 positions × 9 channels × 500 frequencies (ZOH plant at 1 kHz), default
// free set (the base's 14 and com_offset's 5 + rod_twist's 2: 21 parameters),
// start 2x off on every free parameter, global start
// (8 BOBYQA starts on 30 frequencies per position) then Levenberg–Marquardt.
void BM_FitPlatform_3x9x500_GlobalStart(benchmark::State& state) {
  PhysicalModel truth = platform_defaults_model();
  truth.parameter("com_x_m").value = 0.006;
  truth.parameter("com_y_m").value = -0.004;
  FitOptions options;
  options.sample_period_s = 1e-3;
  const Eigen::VectorXd w = log_frequency_grid(1.0, 1000.0, 500);
  std::vector<FitDataset> data;
  for (double xb : kPaperBeamPositions_m) data.push_back({xb, target_response(truth, xb, w, options), "x_b"});
  PhysicalModel start = truth;
  int k = 0;
  for (auto& p : start.parameters)
    if (p.free) p.value = std::clamp(k++ % 2 == 0 ? 2.0 * p.value : 0.5 * p.value, p.lower, p.upper);
  double worst = 0.0;
  for (auto _ : state) {
    const FitResult r = fit_physical_model(start, data, options);
    for (const auto& e : r.parameters)
      worst = std::max(worst, std::abs(e.estimate - truth.parameter(e.name).value) /
                                  std::max(std::abs(truth.parameter(e.name).value), 1e-3));
    benchmark::DoNotOptimize(r.cost_final);
  }
  state.counters["worst_rel_error"] = worst;
}
BENCHMARK(BM_FitPlatform_3x9x500_GlobalStart)->Unit(benchmark::kMillisecond);

// The F-16 loop's last fit at its size (docs/real-data.md): a described structure of
// three DOFs at accelerometers, the shaker force on the first, the driving point's mass
// line and eight structural modes (1.9-20.8 Hz, the modes the loop found): 41 free
// parameters, 267 lines in 2-15 Hz, 3 outputs x 1 input, continuous (a measured input).
// Exact data from the model itself, the start 1 % off in every mode frequency and 20 %
// in every damping and shape; a local fit (no global start), as diagnose's refits are.
// Each Jacobian holds 267 x 41 response derivatives: the case whose per-call allocation
// of them was half of a diagnosis's time (docs/dev/CI.md, thirty-third session).
void BM_FitMechanical_EightModes_3x1x267(benchmark::State& state) {
  const auto par = described_base::parameter;
  const auto ex = described_base::entry;
  MechanicalDescription d;
  d.name = "structure";
  d.dofs = {{"q_drive", "a.u."}, {"q_wing", "a.u."}, {"q_payload", "a.u."}};
  d.inputs = {{"force", "N"}};
  d.outputs = {{"acc1", "a.u./s2", 2}, {"acc2", "a.u./s2", 2}, {"acc3", "a.u./s2", 2}};
  d.parameters = {par("m_drive", "N s2/a.u.", 80.0, 1.0, 1e4, true)};
  d.mass = {{ex("m_drive"), ex("0"), ex("0")}, {ex("0"), ex("m_drive"), ex("0")}, {ex("0"), ex("0"), ex("m_drive")}};
  d.damping = d.stiffness = {{ex("0"), ex("0"), ex("0")}, {ex("0"), ex("0"), ex("0")}, {ex("0"), ex("0"), ex("0")}};
  d.input_map = {{ex("1")}, {ex("0")}, {ex("0")}};
  d.output_map = {{ex("1"), ex("0"), ex("0")}, {ex("0"), ex("1"), ex("0")}, {ex("0"), ex("0"), ex("1")}};
  PhysicalModel truth = PhysicalModel::bare(make_mechanical_base(d));
  const double hz[] = {1.878, 3.470, 3.971, 5.185, 6.614, 7.320, 9.166, 20.8};
  for (int k = 1; k <= 8; ++k) {
    const std::string prefix = k == 1 ? "mode_" : fmt::format("mode_{}_", k);
    truth.add_effect(k == 1 ? std::string("structural_mode") : fmt::format("structural_mode_{}", k));
    truth.parameter(prefix + "frequency_rad_s").value = 2.0 * std::numbers::pi * hz[k - 1];
    truth.parameter(prefix + "damping").value = 0.005 + 0.003 * k;
    int j = 0;
    for (const char* dof : {"q_drive", "q_wing", "q_payload"})
      truth.parameter(prefix + "shape_" + dof).value = 0.02 * (1.0 + 0.3 * ((k + j++) % 3)) * (k % 2 == 0 ? -1 : 1);
  }
  FitOptions options;
  options.global_start = false;
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(267, 2.0 * std::numbers::pi * 2.0, 2.0 * std::numbers::pi * 15.0);
  const std::vector<FitDataset> data{{0.0, target_response(truth, 0.0, w, options), "structure"}};
  PhysicalModel start = truth;
  int free = 0;
  for (auto& p : start.parameters) {
    if (!p.free) continue;
    ++free;
    const double off = p.name.find("frequency") != std::string::npos ? 1.01 : 1.2;
    p.value = std::clamp(p.value * off, p.lower, p.upper);
  }
  double error = 0.0;
  for (auto _ : state) {
    const FitResult r = fit_physical_model(start, data, options);
    error = r.error;
    benchmark::DoNotOptimize(r.cost_final);
  }
  state.counters["free"] = free;
  state.counters["error_percent"] = 100.0 * error;  // ~1e-13: the truth reached
}
BENCHMARK(BM_FitMechanical_EightModes_3x1x267)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
