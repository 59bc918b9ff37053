// identify end to end after parsing on simulated platform experiments (3 experiments,
// one input each), at the paper's two rates: the default structured fit and the paper's
// recipe (Markov LS -> ERA -> unloop); and the structured fit on the independent
// simulator's seed-1 plant.
#include <benchmark/benchmark.h>

#include "idlib/identify/identify.h"
#include "idlib/lti/discretize.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/sim/platform_sim.h"
#include "tests/idlib/identify/independent_case.h"
#include "tests/support/independent_draw.h"

namespace {

using namespace lpvid;

struct Data {
  StateSpace controller;
  std::vector<Eigen::MatrixXd> v, q;
};

Data make(double ts, double duration_s) {
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace plant = discretize_zoh(platform_model(params, kBeamMiddle_m), ts);
  Data d;
  d.controller = discrete_pi_controller(default_pi_gains(params), ts);
  for (int input = 0; input < 3; ++input) {
    ExcitationOptions ex;
    ex.duration_s = duration_s;
    ex.sample_period_s = ts;
    ex.excited_input = input;
    ex.seed = 42 + static_cast<std::uint64_t>(input);  // fixed seed: same work every run
    const SimulatedLog log = simulate_excitation(plant, d.controller, ex);
    d.v.push_back(log.data.middleCols(1, 3));
    d.q.push_back(log.data.middleCols(7, 3));
  }
  return d;
}

void run(benchmark::State& state, double ts, double duration_s, IdentifyMethod method = IdentifyMethod::kStructured) {
  const Data d = make(ts, duration_s);
  std::vector<ExperimentView> views;
  for (std::size_t i = 0; i < d.v.size(); ++i) views.push_back({d.v[i], d.q[i]});
  for (auto _ : state) {
    IdentifyOptions options;
    options.method = method;
    IdentifyResult r = identify_closed_loop(views, ts, d.controller, options);
    benchmark::DoNotOptimize(r.plant.A.data());
    state.counters["plant_order"] = static_cast<double>(r.plant.order());
    state.counters["closed_loop_order"] = static_cast<double>(r.closed_loop.order());
    state.counters["lags"] = static_cast<double>(r.num_lags);
  }
}

void BM_Identify_3x60s_1kHz(benchmark::State& state) { run(state, 1e-3, 60.0); }

// The same on logs of the INDEPENDENT simulator (tests/support, as
// independent_identify_test.cc): seed 1, 3 × 60 s at 1 kHz, beam at x_b = −0.1, 0, 0.1 m
// (state.range(0) = 0, 1, 2), sensor noise × state.range(1) (0 = noise-free).
void run_independent_case(benchmark::State& state, const testing::IndependentCase& c) {
  testing::IndependentCase logs_only = c;
  logs_only.identify = false;
  const testing::IndependentOutcome o = testing::run_independent(logs_only);
  std::vector<ExperimentView> views;
  for (std::size_t i = 0; i < o.v.size(); ++i) views.push_back({o.v[i], o.q[i]});
  for (auto _ : state) {
    IdentifyResult r = identify_closed_loop(views, c.sample_period_s, o.controller, IdentifyOptions{});
    benchmark::DoNotOptimize(r.plant.A.data());
    state.counters["plant_order"] = static_cast<double>(r.plant.order());
    state.counters["lags"] = static_cast<double>(r.num_lags);
  }
}
void BM_Identify_Independent_Seed1_3x60s_1kHz(benchmark::State& state) {
  run_independent_case(state, {1, static_cast<int>(state.range(0)), static_cast<double>(state.range(1))});
}
void BM_Identify_3x100s_10kHz(benchmark::State& state) { run(state, 1e-4, 100.0); }
// 10 kHz on the independent simulator: the robustness suite's two draws (seed 3 beam left,
// noise-free; seed 4 middle, noise x0.53 as drawn), 3 x 100 s (state.range(0) = seed).
void BM_Identify_Independent_3x100s_10kHz(benchmark::State& state) {
  const auto seed = static_cast<std::uint64_t>(state.range(0));
  run_independent_case(state, {seed, seed == 3 ? 0 : 1, -1.0, 1e-4, 100.0});
}
// The paper's recipe (--method era), the default before issue 11.
void BM_IdentifyEra_3x60s_1kHz(benchmark::State& state) { run(state, 1e-3, 60.0, IdentifyMethod::kEra); }
void BM_IdentifyEra_3x100s_10kHz(benchmark::State& state) { run(state, 1e-4, 100.0, IdentifyMethod::kEra); }

// Simulated seconds per wall second of the closed-loop platform simulator.
void BM_SimulatePlatform_100s_10kHz(benchmark::State& state) {
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace plant = discretize_zoh(platform_model(params, kBeamMiddle_m), 1e-4);
  const StateSpace controller = discrete_pi_controller(default_pi_gains(params), 1e-4);
  ExcitationOptions ex;
  ex.duration_s = 100.0;
  ex.sample_period_s = 1e-4;
  for (auto _ : state) {
    SimulatedLog log = simulate_excitation(plant, controller, ex);
    benchmark::DoNotOptimize(log.data.data());
  }
  state.counters["sim_s_per_s"] = benchmark::Counter(100.0, benchmark::Counter::kIsIterationInvariantRate);
}

}  // namespace

// CPU time is the whole process's (identify runs independent work on the pool of
// idlib/core/parallel.h), so it can exceed the wall-clock time.
BENCHMARK(BM_Identify_3x60s_1kHz)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_Identify_3x100s_10kHz)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_IdentifyEra_3x60s_1kHz)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_IdentifyEra_3x100s_10kHz)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();
BENCHMARK(BM_Identify_Independent_Seed1_3x60s_1kHz)
    ->ArgsProduct({{0, 1, 2}, {1, 0}})
    ->ArgNames({"position", "noise"})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime()
    ->Iterations(1);
BENCHMARK(BM_Identify_Independent_3x100s_10kHz)
    ->Arg(3)
    ->Arg(4)
    ->ArgName("seed")
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()
    ->UseRealTime()
    ->Iterations(1);
BENCHMARK(BM_SimulatePlatform_100s_10kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
