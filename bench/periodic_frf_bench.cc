// Benchmarks of the periodic FRF (per-period averaging, closed-loop ratio) and of the
// Local Polynomial Method at the size of long lab logs.  The cost depends on sizes
// only, so the "system" is a short random FIR (as frf_bench.cc).
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <cmath>
#include <numbers>
#include <random>

#include "idlib/signal/lpm.h"
#include "idlib/signal/lrm.h"
#include "idlib/signal/periodic_frf.h"

namespace {

using lpvid::Index;

constexpr std::uint64_t kBenchSeed = 616161;

// z = FIR(v) (4 taps, random gains, `outputs` channels) + small noise.
Eigen::MatrixXd fir_of(const Eigen::MatrixXd& v, Index outputs, std::mt19937_64& rng) {
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd z(v.rows(), outputs);
  for (Index t = 0; t < z.rows(); ++t)
    for (Index c = 0; c < outputs; ++c) z(t, c) = 0.01 * d(rng);
  for (Index k = 0; k < 4; ++k) {
    Eigen::MatrixXd g(outputs, v.cols());
    for (Index i = 0; i < g.size(); ++i) g(i) = d(rng);
    z.bottomRows(v.rows() - k) += v.topRows(v.rows() - k) * g.transpose();
  }
  return z;
}

// 3 inputs, 3 experiments (experiment e excites input e with a 1000-line multisine of
// period L = 8192), T = 2 + P = 38 periods each: 3 × 40 × 8192 = 983,040 samples of
// 3 references and 6 measured channels ([y u]); the plant P = (PS) S⁻¹ per line.
void BM_PeriodicPlantFrf_3x3_1M(benchmark::State& state) {
  constexpr Index kL = 8192, kP = 38, kT = 2, kE = 3;
  std::mt19937_64 rng(kBenchSeed);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  const Index block = (kT + kP) * kL;
  Eigen::MatrixXd v = Eigen::MatrixXd::Zero(kE * block, 3);
  for (Index e = 0; e < kE; ++e) {
    Eigen::VectorXd period = Eigen::VectorXd::Zero(kL);
    for (Index k = 1; k <= 1000; ++k) {
      const double phi = phase(rng);
      for (Index t = 0; t < kL; ++t) period(t) += std::cos(2 * std::numbers::pi * k * t / kL + phi);
    }
    for (Index p = 0; p < kT + kP; ++p) v.block(e * block + p * kL, e, kL, 1) = period;
  }
  const Eigen::MatrixXd z = fir_of(v, 6, rng);
  lpvid::PeriodicFrfOptions o;
  o.layout = {kL, kP, kT, 1, kE};
  o.sample_period_s = 1e-3;
  Index lines = 0;
  for (auto _ : state) {
    const lpvid::PeriodicFrfResult r = lpvid::estimate_periodic_frf(v, z, 3, o);
    lines = r.frd.num_frequencies();
    benchmark::DoNotOptimize(r.frd.response.data());
  }
  state.counters["lines"] = static_cast<double>(lines);
  state.counters["samples"] = static_cast<double>(v.rows());
}
BENCHMARK(BM_PeriodicPlantFrf_3x3_1M)->Unit(benchmark::kMillisecond);

// LPM on one record of 10⁶ samples: SISO (1 input, 1 output), every bin (499,999).
void BM_Lpm_SISO_1M(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd u(1'000'000, 1);
  for (Index t = 0; t < u.rows(); ++t) u(t, 0) = d(rng);
  const Eigen::MatrixXd y = fir_of(u, 1, rng);
  lpvid::LpmOptions o;
  o.sample_period_s = 1e-3;
  Index bins = 0;
  for (auto _ : state) {
    const lpvid::LpmResult r = lpvid::estimate_lpm_frf({{u, y}}, 0, o);
    bins = r.frd.num_frequencies();
    benchmark::DoNotOptimize(r.frd.response.data());
  }
  state.counters["bins"] = static_cast<double>(bins);
}
BENCHMARK(BM_Lpm_SISO_1M)->Unit(benchmark::kMillisecond);

// LRM (numerator and denominator degree 2, 15-bin windows, 2 reweighting steps) on
// the LPM's record above: SISO, 10⁶ samples, every bin (499,999).
void BM_Lrm_SISO_1M(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd u(1'000'000, 1);
  for (Index t = 0; t < u.rows(); ++t) u(t, 0) = d(rng);
  const Eigen::MatrixXd y = fir_of(u, 1, rng);
  lpvid::LrmOptions o;
  o.sample_period_s = 1e-3;
  Index bins = 0;
  for (auto _ : state) {
    const lpvid::LrmResult r = lpvid::estimate_lrm_frf({{u, y}}, 0, o);
    bins = r.frd.num_frequencies();
    benchmark::DoNotOptimize(r.frd.response.data());
  }
  state.counters["bins"] = static_cast<double>(bins);
}
BENCHMARK(BM_Lrm_SISO_1M)->Unit(benchmark::kMillisecond);

// LPM closed loop on one record of 10⁶ samples: 3 references, [y u] 6 channels, every
// 8th bin (62,500), the plant (PS) S⁻¹ per bin.
void BM_LpmPlant_3x3_1M_Stride8(benchmark::State& state) {
  std::mt19937_64 rng(kBenchSeed);
  std::normal_distribution<double> d(0.0, 1.0);
  Eigen::MatrixXd v(1'000'000, 3);
  for (Index i = 0; i < v.size(); ++i) v(i) = d(rng);
  const Eigen::MatrixXd z = fir_of(v, 6, rng);
  lpvid::LpmOptions o;
  o.sample_period_s = 1e-3;
  o.stride = 8;
  for (auto _ : state) {
    const lpvid::LpmResult r = lpvid::estimate_lpm_frf({{v, z}}, 3, o);
    benchmark::DoNotOptimize(r.frd.response.data());
  }
}
BENCHMARK(BM_LpmPlant_3x3_1M_Stride8)->Unit(benchmark::kMillisecond);

}  // namespace
