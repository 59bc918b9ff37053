// Realization: partial SVD of a large block Hankel matrix against a full SVD,
// and the whole ERA on a 3x3 sequence of 2000 lags.
#include <benchmark/benchmark.h>
#include "idlib/core/eigen_decompositions.h"

#include <Eigen/SVD>
#include <cmath>
#include <random>

#include "idlib/realization/era.h"
#include "idlib/realization/hankel.h"

namespace {

constexpr std::uint64_t kBenchSeed = 1500;

// 3x3 Markov parameters of a damped order-10 system plus white noise of 1e-3.
lpvid::MarkovSequence bench_sequence(lpvid::Index lags) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> normal(0.0, 1.0);
  lpvid::MarkovSequence g(static_cast<std::size_t>(lags));
  for (lpvid::Index k = 0; k < lags; ++k) {
    Eigen::MatrixXd gk = Eigen::MatrixXd::Zero(3, 3);
    for (int mode = 0; mode < 5; ++mode) {
      const double decay = std::exp(-0.002 * (mode + 1) * static_cast<double>(k));
      const double phase = 0.01 * (mode + 1) * static_cast<double>(k);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) gk(i, j) += decay * std::cos(phase + i + 2 * j + mode);
    }
    for (int i = 0; i < 9; ++i) gk.data()[i] += 1e-3 * normal(rng);
    g[static_cast<std::size_t>(k)] = gk;
  }
  return g;
}

void BM_HankelLeadingSvd1500k31(benchmark::State& state) {
  const lpvid::MarkovSequence g = bench_sequence(1002);
  for (auto _ : state) {
    const Eigen::MatrixXd H = lpvid::block_hankel(g, 500, 500, 1, 1);
    benchmark::DoNotOptimize(lpvid::leading_svd(H, 31).singular_values.data());
  }
}
BENCHMARK(BM_HankelLeadingSvd1500k31)->Unit(benchmark::kMillisecond);

void BM_HankelFullBdcsvd1500(benchmark::State& state) {
  const lpvid::MarkovSequence g = bench_sequence(1002);
  for (auto _ : state) {
    const Eigen::MatrixXd H = lpvid::block_hankel(g, 500, 500, 1, 1);
    Eigen::BDCSVD<Eigen::MatrixXd> svd(H, Eigen::ComputeThinU | Eigen::ComputeThinV);
    benchmark::DoNotOptimize(svd.singularValues().data());
  }
}
BENCHMARK(BM_HankelFullBdcsvd1500)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_RealizeEra3x3Lags2000(benchmark::State& state) {
  const lpvid::MarkovSequence g = bench_sequence(2001);
  lpvid::EraOptions options;
  options.sample_period_s = 1e-3;
  options.markov_noise_std = Eigen::MatrixXd::Constant(3, 3, 1e-3);
  for (auto _ : state) benchmark::DoNotOptimize(lpvid::realize_era(g, options).model.A.data());
}
BENCHMARK(BM_RealizeEra3x3Lags2000)->Unit(benchmark::kMillisecond);

}  // namespace
