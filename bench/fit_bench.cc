// Benchmark of idlib/fit: the physical-model fit of the size.
#include <benchmark/benchmark.h>

#include <algorithm>

#include "idlib/fit/fit.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"

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

}  // namespace
