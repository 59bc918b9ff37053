// Benchmarks of idlib/signal at the size of a long lab log: 3 excitation channels,
// 3 outputs, 1e6 samples, 2000 lags.
#include <benchmark/benchmark.h>

#include <cmath>
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

// One estimate of `method` on the 3 x 3 x 1e6 FIR log at 2000 lags, per iteration; the
// counter is what the method reports (PCG's iterations, the ARX order).
void markov_on_fir_log(benchmark::State& state, lpvid::MarkovOptions::Method method, const char* counter) {
  std::mt19937_64 rng(kBenchSeed);
  const Eigen::MatrixXd v = white(kSamples, kChannels, rng);
  const Eigen::MatrixXd q = fir_output(v, rng);
  lpvid::MarkovOptions options;
  options.num_lags = kLags;
  options.method = method;
  const std::vector<lpvid::ExperimentView> experiments{{v, q}};
  Index reported = 0;
  for (auto _ : state) {
    lpvid::MarkovResult r = lpvid::estimate_markov(experiments, options);
    reported = method == lpvid::MarkovOptions::Method::kArx ? r.arx_order : r.iterations;
    benchmark::DoNotOptimize(r.g.data());
  }
  state.counters[counter] = static_cast<double>(reported);
}

void BM_MarkovLS_3x3_1M_2000lags(benchmark::State& state) {
  markov_on_fir_log(state, lpvid::MarkovOptions::Method::kLeastSquares, "pcg_iterations");
}
BENCHMARK(BM_MarkovLS_3x3_1M_2000lags)->Unit(benchmark::kMillisecond);

// The regularised estimate (TC kernel) at markov's default horizon for a long 2-input log
// (min(N / 4, N / (4 m), 2000) = 2000 lags: 4002 unknowns per output, solved dense), inputs
// through a fourth-order low-pass at a tenth of the Nyquist frequency: hyperparameter
// tuning on 300 lags, the dense normal matrix, four Choleskys per output.
void BM_MarkovRegularized_2x2_1M_coloured(benchmark::State& state) {
  const Index lags = state.range(0);
  std::mt19937_64 rng(kBenchSeed);
  Eigen::MatrixXd v = white(kSamples, 2, rng);
  // Two cascaded one-pole low-passes twice over (a fourth-order roll-off).
  for (Index c = 0; c < 2; ++c)
    for (int pass = 0; pass < 4; ++pass) {
      double y = 0.0;
      for (Index t = 0; t < kSamples; ++t) v(t, c) = y = 0.85 * y + 0.15 * v(t, c);
    }
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd q = 0.01 * white(kSamples, 2, rng);
  for (Index k = 0; k < 40; ++k) {
    Eigen::MatrixXd g(2, 2);
    for (Index i = 0; i < g.size(); ++i) g(i) = d(rng) * std::pow(0.9, static_cast<double>(k));
    q.bottomRows(kSamples - k) += v.topRows(kSamples - k) * g.transpose();
  }
  lpvid::MarkovOptions options;
  options.num_lags = lags;
  options.method = lpvid::MarkovOptions::Method::kRegularized;
  const std::vector<lpvid::ExperimentView> experiments{{v, q}};
  for (auto _ : state) {
    lpvid::MarkovResult r = lpvid::estimate_markov(experiments, options);
    benchmark::DoNotOptimize(r.g.data());
  }
}
BENCHMARK(BM_MarkovRegularized_2x2_1M_coloured)->Arg(600)->Arg(2000)->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace

// The ARX estimate (markov_arx.h) on the same 3 x 3 x 1e6 log, 2000 lags: per output the
// Gram matrix of [q_i, v] at lags 0..60 by blocked FFT, then orders 1..60 (one Cholesky
// of up to 300 regressors per output and order), the recursion to 2000 lags, and
// estimate_markov's FIR residual for noise_std.
void BM_MarkovArx_3x3_1M_2000lags(benchmark::State& state) {
  markov_on_fir_log(state, lpvid::MarkovOptions::Method::kArx, "arx_order");
}
BENCHMARK(BM_MarkovArx_3x3_1M_2000lags)->Iterations(1)->Unit(benchmark::kMillisecond);
