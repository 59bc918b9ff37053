// The 6-DOF maglev stage (seed 001): closed-loop simulation speed (simulated
// seconds per wall-clock second) and the grey-box fit time.
#include <benchmark/benchmark.h>

#include "idlib/diagnose/diagnose.h"
#include "idlib/signal/frf.h"
#include "idlib/sim/stage6_sim.h"
#include "idlib/stage6/stage6_fit.h"
#include "idlib/stage6/stage6_output_error.h"

namespace {

using namespace lpvid::stage6;

// The paper's regulation run, 8 s, RK4 at 10 kHz, control at 1 kHz.
void BM_Stage6Regulation_8s(benchmark::State& state, bool lag) {
  SimulationOptions sim;
  sim.duration_s = 8.0;
  StageEffects effects;
  effects.electrical_lag = lag;  // (α(z) is not used here: 0.3 rad tilts move a motor's gap by ~20 mm)
  for (auto _ : state) {
    const StageRun run = simulate_regulation(StageParameters{}, effects, paper_initial_configuration(),
                                             paper_reference_configuration(), {}, sim);
    benchmark::DoNotOptimize(run.q.data());
  }
  state.counters["sim_s_per_wall_s"] =
      benchmark::Counter(sim.duration_s * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK_CAPTURE(BM_Stage6Regulation_8s, rigid, false)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Stage6Regulation_8s, dq_currents, true)->Unit(benchmark::kMillisecond)->UseRealTime();

StageRun experiment(double duration_s, bool lag, bool noisy = false) {
  SimulationOptions sim;
  if (noisy) sim.sensor_noise_std << 1e-9, 1e-9, 1e-8, 1e-7, 1e-7, 1e-7;  // simulate stage6 --experiment
  sim.duration_s = duration_s;
  sim.excitation_std << 2, 2, 2, 0.1, 0.1, 0.1;
  sim.seed = 42;  // fixed seed: same work every run
  StageEffects effects;
  effects.electrical_lag = lag;
  Vector6d q0 = Vector6d::Zero();
  q0(2) = 250e-6;
  return simulate_regulation(StageParameters{}, effects, q0, paper_reference_configuration(), {}, sim);
}

// The full fit (H, κ, com offset) on a 2 s / 10 s log at 1 kHz.
void BM_Stage6Fit(benchmark::State& state) {
  const StageRun run = experiment(static_cast<double>(state.range(0)), false);
  for (auto _ : state) {
    const StageFitResult r = fit_stage(StageParameters{}, run.wrench, run.q_measured, 1e-3);
    benchmark::DoNotOptimize(r.rms_residual);
  }
}
BENCHMARK(BM_Stage6Fit)->Arg(2)->Arg(10)->Unit(benchmark::kMillisecond);

// The output-error fit (H, κ; 0.3 s windows, two passes, standard errors) on a
// 2 s / 10 s log with the default sensor noise, started from the equation-error
// fit (computed outside the timed loop).
void BM_Stage6FitOutputError(benchmark::State& state) {
  const StageRun run = experiment(static_cast<double>(state.range(0)), false, true);
  StageFitModel model;
  model.com_offset = false;
  const StageFitResult start = fit_stage(StageParameters{}, run.wrench, run.q_measured, 1e-3, model);
  for (auto _ : state) {
    const StageOutputErrorResult r =
        fit_stage_output_error(StageParameters{}, run.wrench, run.q_measured, 1e-3, model, {}, &start);
    benchmark::DoNotOptimize(r.sigma2);
  }
}
BENCHMARK(BM_Stage6FitOutputError)->Arg(2)->Arg(10)->Unit(benchmark::kMillisecond);

// The diagnosis (base + three candidates, the lag by golden section) on 2 s.
void BM_Stage6Diagnose_2s(benchmark::State& state) {
  const StageRun run = experiment(2.0, true);
  for (auto _ : state) {
    const StageDiagnosis d = diagnose_stage(StageParameters{}, run.wrench, run.q_measured, 1e-3);
    benchmark::DoNotOptimize(d.base.rms_residual);
  }
}
BENCHMARK(BM_Stage6Diagnose_2s)->Unit(benchmark::kMillisecond);

// The model-error loop's diagnose on the stage (base stage6, the same framework as
// the platform's): the plant from a 60 s closed-loop log (frf --input, 256 lines,
// 6 × 6 channels) with a hidden gap dependence, every library candidate the base
// lacks (9), candidates on 2 threads.  The log and its FRF are made once.
void BM_Stage6DiagnoseAllCandidates_60s_256lines(benchmark::State& state) {
  SimulationOptions sim;
  sim.duration_s = 60.0;
  sim.sensor_noise_std << 1e-9, 1e-9, 1e-8, 1e-7, 1e-7, 1e-7;
  sim.excitation_std << 2, 2, 2, 0.1, 0.1, 0.1;
  sim.seed = 3;
  StageEffects effects;
  effects.gap_dependence = true;
  StageParameters truth;
  truth.inertia_kgm2.diagonal() << 0.034, 0.025, 0.061;
  const StageRun run =
      simulate_regulation(truth, effects, paper_reference_configuration(), paper_reference_configuration(), {}, sim);
  const int order[6] = {0, 1, 2, 5, 4, 3};  // the base's input order (stage6_base.h)
  Eigen::MatrixXd v(run.t_s.size(), 6), z(run.t_s.size(), 12);
  for (int c = 0; c < 6; ++c) {
    v.col(c) = run.excitation.col(order[c]);
    z.col(c) = run.q_measured.col(c);
    z.col(6 + c) = run.wrench.col(order[c]);
  }
  lpvid::FrfOptions fo;
  fo.sample_period_s = 1e-3;
  fo.segment_length = 512;
  const std::vector<lpvid::FitDataset> data = {{0.0, lpvid::estimate_plant_frf({{v, z}}, fo), "stage"}};
  lpvid::DiagnoseOptions o;
  o.fit.sample_period_s = 1e-3;
  std::string named;
  for (auto _ : state) {
    const lpvid::Diagnosis d = lpvid::diagnose(lpvid::PhysicalModel::initial("stage6"), data, o);
    named = d.missing;
    benchmark::DoNotOptimize(d.baseline_error);
  }
  state.SetLabel("named " + named);
}
BENCHMARK(BM_Stage6DiagnoseAllCandidates_60s_256lines)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
