// Benchmarks of the frequency-domain route: the H1/Welch FRF estimate at the size
// of a long lab log, and the plant from the input sensitivity on a dense grid.
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <random>

#include "idlib/closedloop/sensitivity.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/signal/frf.h"

namespace {

using lpvid::Index;

constexpr std::uint64_t kBenchSeed = 515151;
constexpr Index kChannels = 3;

// y = FIR(v) (4 taps, random 3x3 gains) + small noise: the FRF cost does not depend
// on the system, only on sizes.
Eigen::MatrixXd output_of(const Eigen::MatrixXd& v, std::mt19937_64& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(v.rows(), kChannels);
  for (Index t = 0; t < y.rows(); ++t)
    for (Index c = 0; c < kChannels; ++c) y(t, c) = 0.01 * d(rng);
  for (Index k = 0; k < 4; ++k) {
    Eigen::MatrixXd g(kChannels, kChannels);
    for (Index i = 0; i < g.size(); ++i) g(i) = d(rng);
    y.bottomRows(v.rows() - k) += v.topRows(v.rows() - k) * g.transpose();
  }
  return y;
}

// Times one Welch estimator at 1 kHz with its default options; counts the bins.
template <typename Estimator>
void time_estimator(benchmark::State& state, const std::vector<lpvid::ExperimentView>& experiments,
                    Estimator estimate) {
  lpvid::FrfOptions options;
  options.sample_period_s = 1e-3;
  Index bins = 0;
  for (auto _ : state) {
    const lpvid::FrequencyResponse h = estimate(experiments, options);
    bins = h.num_frequencies();
    benchmark::DoNotOptimize(h.response.data());
  }
  state.counters["bins"] = static_cast<double>(bins);
}

// One experiment per input (that input white, the others zero), each of
// samples_per_experiment samples; automatic segment length, 50 % overlap, Hann.
void run_frf(benchmark::State& state, Index samples_per_experiment) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> d(0.0, 1.0);
  std::vector<Eigen::MatrixXd> vs, ys;
  for (Index j = 0; j < kChannels; ++j) {
    Eigen::MatrixXd v = Eigen::MatrixXd::Zero(samples_per_experiment, kChannels);
    for (Index t = 0; t < samples_per_experiment; ++t) v(t, j) = d(rng);
    ys.push_back(output_of(v, rng));
    vs.push_back(std::move(v));
  }
  std::vector<lpvid::ExperimentView> experiments;
  for (Index j = 0; j < kChannels; ++j) experiments.push_back({vs[static_cast<size_t>(j)], ys[static_cast<size_t>(j)]});
  time_estimator(state, experiments, lpvid::estimate_frf);
}

// 3 experiments x 333,334 samples = 1,000,002 samples of 3 inputs + 3 outputs
// (auto segment 16384, 39 segments per experiment).
void BM_Frf_3x3_1M(benchmark::State& state) { run_frf(state, 333'334); }
BENCHMARK(BM_Frf_3x3_1M)->Unit(benchmark::kMillisecond);

// 3 experiments x 1,000,000 samples (auto segment 32768, 60 segments per experiment).
void BM_Frf_3x3_3x1M(benchmark::State& state) { run_frf(state, 1'000'000); }
BENCHMARK(BM_Frf_3x3_3x1M)->Unit(benchmark::kMillisecond);

// The plant route P = S_yv S_uv⁻¹ (estimate_plant_frf) on one experiment of 10⁶
// samples with all three excitations at once: y as above, u = v + small noise (the
// cost depends only on sizes).  Two Welch passes (the second, with segments twice
// as long, for the Richardson leakage term).
void BM_PlantFrf_3x3_1M(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> d(0.0, 1.0);
  const Index n = 1'000'000;
  Eigen::MatrixXd v(n, kChannels);
  for (Index i = 0; i < v.size(); ++i) v(i) = d(rng);
  Eigen::MatrixXd z(n, 2 * kChannels);
  z.leftCols(kChannels) = output_of(v, rng);
  for (Index t = 0; t < n; ++t)
    for (Index c = 0; c < kChannels; ++c) z(t, kChannels + c) = v(t, c) + 0.01 * d(rng);
  const std::vector<lpvid::ExperimentView> experiments{{v, z}};
  time_estimator(state, experiments, lpvid::estimate_plant_frf);
}
BENCHMARK(BM_PlantFrf_3x3_1M)->Unit(benchmark::kMillisecond);

// A 3x3 discrete 6-state plant under a diagonal PI (1 kHz), S evaluated on 10,000
// log-spaced frequencies from 0.1 rad/s to 0.99 Nyquist.
void BM_PlantFromSensitivity_10k(benchmark::State& state) {
  constexpr double kTs = 1e-3;
  lpvid::StateSpace plant;
  plant.A = Eigen::MatrixXd::Identity(6, 6) * 0.99;
  plant.A.topRightCorner(3, 3) = Eigen::MatrixXd::Identity(3, 3) * kTs;
  plant.B = Eigen::MatrixXd::Zero(6, 3);
  plant.B.bottomRows(3) = Eigen::MatrixXd::Identity(3, 3) * kTs;
  plant.C = Eigen::MatrixXd::Zero(3, 6);
  plant.C.leftCols(3).setIdentity();
  plant.D = Eigen::MatrixXd::Zero(3, 3);
  plant.sample_period_s = kTs;
  lpvid::StateSpace pi;
  pi.A = Eigen::MatrixXd::Identity(3, 3);
  pi.B = kTs * Eigen::MatrixXd::Identity(3, 3);
  pi.C = 5.0 * Eigen::MatrixXd::Identity(3, 3);
  pi.D = 2.0 * Eigen::MatrixXd::Identity(3, 3);
  pi.sample_period_s = kTs;
  const Eigen::VectorXd w = lpvid::log_frequency_grid(0.1, 0.99 * 3.141592653589793 / kTs, 10'000);
  const lpvid::FrequencyResponse S =
      lpvid::frequency_response(lpvid::closed_loop_input_sensitivity(plant, pi), w);
  for (auto _ : state) {
    const lpvid::SensitivityUnloopResult r = lpvid::plant_from_sensitivity(S, pi, {});
    benchmark::DoNotOptimize(r.plant.response.data());
  }
}
BENCHMARK(BM_PlantFromSensitivity_10k)->Unit(benchmark::kMillisecond);

}  // namespace
