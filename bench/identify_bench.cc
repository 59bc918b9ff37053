// identify end to end after parsing: Markov LS -> ERA -> unloop on simulated
// platform experiments (3 experiments, one input each), at the paper's two rates.
#include <benchmark/benchmark.h>

#include "idlib/identify/identify.h"
#include "idlib/lti/discretize.h"
#include "idlib/models/platform.h"
#include "idlib/sim/platform_sim.h"

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

void run(benchmark::State& state, double ts, double duration_s) {
  const Data d = make(ts, duration_s);
  std::vector<ExperimentView> views;
  for (std::size_t i = 0; i < d.v.size(); ++i) views.push_back({d.v[i], d.q[i]});
  for (auto _ : state) {
    IdentifyResult r = identify_closed_loop(views, ts, d.controller, IdentifyOptions{});
    benchmark::DoNotOptimize(r.plant.A.data());
    state.counters["closed_loop_order"] = static_cast<double>(r.closed_loop.order());
    state.counters["lags"] = static_cast<double>(r.num_lags);
  }
}

void BM_Identify_3x60s_1kHz(benchmark::State& state) { run(state, 1e-3, 60.0); }
void BM_Identify_3x100s_10kHz(benchmark::State& state) { run(state, 1e-4, 100.0); }

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

BENCHMARK(BM_Identify_3x60s_1kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Identify_3x100s_10kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SimulatePlatform_100s_10kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
