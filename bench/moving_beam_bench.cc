// Speed of the moving-beam simulation (idlib/sim/moving_beam.h) and of the
// time-domain fit (idlib/validate/time_fit.h): simulated seconds per wall second.
#include <benchmark/benchmark.h>

#include "idlib/plants/platform/platform.h"
#include "idlib/sim/moving_beam.h"
#include "idlib/validate/time_fit.h"

namespace {

using namespace lpvid;

// 60 s at 1 kHz of the built-in sweep: the beam moves 30 % of the time (0.6 s of
// every 2 s), so ~18 000 samples recompute the matrix exponential.
void BM_MovingBeamSweep_60s_1kHz(benchmark::State& state) {
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace controller = discrete_pi_controller(default_pi_gains(params), 1e-3);
  const BeamTrajectory traj = BeamTrajectory::sweep({}, 60.0);
  MovingBeamOptions o;
  for (auto _ : state) {
    SimulatedLog log = simulate_moving_beam(params, controller, traj, o);
    benchmark::DoNotOptimize(log.data.data());
  }
  state.counters["sim_s_per_s"] = benchmark::Counter(60.0, benchmark::Counter::kIsIterationInvariantRate);
}

// The same through the sampled trajectory, as compare --log sees it: the spline
// moves at every sample of the moves.
void BM_MovingBeamSplineTrajectory_60s_1kHz(benchmark::State& state) {
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace controller = discrete_pi_controller(default_pi_gains(params), 1e-3);
  MovingBeamOptions o;
  const SimulatedLog truth = simulate_moving_beam(params, controller, BeamTrajectory::sweep({}, 60.0), o);
  const BeamTrajectory traj = BeamTrajectory::from_samples(truth.data.col(0), truth.data.col(10));
  const Eigen::MatrixXd v = truth.data.middleCols(1, 3);
  for (auto _ : state) {
    MovingBeamPrediction p = predict_moving_beam(params, controller, traj, 0.0, v, o);
    benchmark::DoNotOptimize(p.q.data());
  }
  state.counters["sim_s_per_s"] = benchmark::Counter(60.0, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_TimeFit_3outputs_4inputs_60s_1kHz(benchmark::State& state) {
  const PlatformParameters params = PlatformParameters::defaults();
  const StateSpace controller = discrete_pi_controller(default_pi_gains(params), 1e-3);
  MovingBeamOptions o;
  o.excitation_std = Eigen::Vector3d(0.01, 0.01, 0.2);
  const SimulatedLog log = simulate_moving_beam(params, controller, BeamTrajectory::sweep({}, 60.0), o);
  const Eigen::MatrixXd q = log.data.middleCols(7, 3);
  const Eigen::MatrixXd qhat = q + 1e-6 * Eigen::MatrixXd::Ones(q.rows(), 3);
  Eigen::MatrixXd in(q.rows(), 4);
  in << log.data.middleCols(1, 3), log.data.col(10);
  for (auto _ : state) {
    TimeFitResult r = time_fit(q, qhat, in, 0.0, 1e-3, TimeFitOptions{});
    benchmark::DoNotOptimize(r.fit_percent.data());
  }
}

}  // namespace

BENCHMARK(BM_MovingBeamSweep_60s_1kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MovingBeamSplineTrajectory_60s_1kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TimeFit_3outputs_4inputs_60s_1kHz)->Unit(benchmark::kMillisecond)->UseRealTime();
