// Benchmarks of idlib/signal at the size of a long lab log: 3 excitation channels,
// 3 outputs, 1e6 samples, 2000 lags.
#include <benchmark/benchmark.h>

#include <random>

#include "idlib/signal/correlation.h"
#include "idlib/signal/markov.h"

namespace {

using lpvid::Index;

constexpr std::uint64_t kBenchSeed = 424242;
constexpr Index kSamples = 1'000'000;
constexpr Index kChannels = 3;
constexpr Index kLags = 2000;

Eigen::MatrixXd white(Index n, Index channels, std::mt19937_64& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd v(n, channels);
  for (Index c = 0; c < channels; ++c)
    for (Index t = 0; t < n; ++t) v(t, c) = d(rng);
  return v;
}

// q = FIR(v) with a short, decaying random MIMO impulse response plus white noise.
Eigen::MatrixXd fir_output(const Eigen::MatrixXd& v, std::mt19937_64& rng) {
  constexpr Index kTaps = 8;
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd q = 0.01 * white(v.rows(), kChannels, rng);
  for (Index k = 0; k < kTaps; ++k) {
    Eigen::MatrixXd g(kChannels, kChannels);
    for (Index i = 0; i < g.size(); ++i) g(i) = d(rng) * std::pow(0.5, static_cast<double>(k));
    q.bottomRows(v.rows() - k) += v.topRows(v.rows() - k) * g.transpose();
  }
  return q;
}

void BM_CrossCorrelation_3x3_1M_2000lags(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  const Eigen::MatrixXd x = white(kSamples, kChannels, rng);
  const Eigen::MatrixXd y = white(kSamples, kChannels, rng);
  for (auto _ : state) {
    auto r = lpvid::cross_correlation(x, y, kLags);
    benchmark::DoNotOptimize(r.data());
  }
}
BENCHMARK(BM_CrossCorrelation_3x3_1M_2000lags)->Unit(benchmark::kMillisecond);

void BM_MarkovLS_3x3_1M_2000lags(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  const Eigen::MatrixXd v = white(kSamples, kChannels, rng);
  const Eigen::MatrixXd q = fir_output(v, rng);
  lpvid::MarkovOptions options;
  options.num_lags = kLags;
  const std::vector<lpvid::ExperimentView> experiments{{v, q}};
  Index iterations = 0;
  for (auto _ : state) {
    lpvid::MarkovResult r = lpvid::estimate_markov(experiments, options);
    iterations = r.iterations;
    benchmark::DoNotOptimize(r.g.data());
  }
  state.counters["pcg_iterations"] = static_cast<double>(iterations);
}
BENCHMARK(BM_MarkovLS_3x3_1M_2000lags)->Unit(benchmark::kMillisecond);

}  // namespace
