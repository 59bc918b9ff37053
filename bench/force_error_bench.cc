// Benchmark of the force-error route (idlib/fit/force_error.h) at a real log's size:
// a positioning axis logged at 1 kHz for 1000 s (1e6 samples; the simulated axis of
// tests/support/friction_axis.h, closed loop, 1 µm encoder), preparing the log
// (smoothing, derivatives, noise estimates, standstill), one fit of the full model,
// one fit with a ripple's period searched, and one diagnosis (the baseline, the
// candidates the residual's signatures admit, their pairs).
#include <benchmark/benchmark.h>

#include "idlib/fit/force_error.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "tests/support/friction_axis.h"

namespace {

using namespace lpvid;

const friction_axis::Log& log_1e6() {
  static const friction_axis::Log log = [] {
    friction_axis::Experiment e;
    e.seconds = 1000.0;
    return friction_axis::simulate(friction_axis::Truth{}, e);
  }();
  return log;
}

PhysicalModel base_model() { return PhysicalModel::bare(make_mechanical_base(friction_axis::description())); }

void BM_ForceError_Prepare_1e6(benchmark::State& state) {
  const auto& log = log_1e6();
  const PhysicalModel m = base_model();
  for (auto _ : state) {
    const ForceErrorData d = prepare_force_error(m, log.i, log.x, 1e-3);
    benchmark::DoNotOptimize(d.q.data());
  }
  state.counters["samples"] = static_cast<double>(log.i.size());
}
BENCHMARK(BM_ForceError_Prepare_1e6)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_ForceError_Fit4_1e6(benchmark::State& state) {
  const auto& log = log_1e6();
  PhysicalModel m = base_model();
  m.add_effect("coulomb_friction");
  m.add_effect("force_offset");
  const ForceErrorData d = prepare_force_error(m, log.i, log.x, 1e-3);
  double error = 0.0;
  for (auto _ : state) {
    const ForceErrorFit f = fit_force_error(m, d);
    error = f.error;
    benchmark::DoNotOptimize(f.bic);
  }
  state.counters["error_percent"] = error;
}
BENCHMARK(BM_ForceError_Fit4_1e6)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

// The ripple's profile search on the same log: the periodogram over position of the
// residual without it (up to 2000 lines on 5·10⁴ rows), then golden section in its three
// highest peaks on every tenth row (the axis has no ripple: the search's cost, not its
// finding, is measured).
void BM_ForceError_FitRipple_1e6(benchmark::State& state) {
  const auto& log = log_1e6();
  PhysicalModel m = base_model();
  m.add_effect("coulomb_friction");
  m.add_effect("force_offset");
  m.add_effect("position_ripple");
  const ForceErrorData d = prepare_force_error(m, log.i, log.x, 1e-3);
  for (auto _ : state) {
    const ForceErrorFit f = fit_force_error(m, d);
    benchmark::DoNotOptimize(f.bic);
  }
}
BENCHMARK(BM_ForceError_FitRipple_1e6)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_ForceError_Diagnose_1e6(benchmark::State& state) {
  const auto& log = log_1e6();
  const PhysicalModel m = base_model();
  const ForceErrorData d = prepare_force_error(m, log.i, log.x, 1e-3);
  for (auto _ : state) {
    const ForceErrorDiagnosis r = diagnose_force_error(m, d);
    benchmark::DoNotOptimize(r.named);
  }
}
BENCHMARK(BM_ForceError_Diagnose_1e6)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
