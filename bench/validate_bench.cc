// Benchmarks of the model-error model (idlib/validate/model_error.h) and the
// compare figure (formats/plot/compare_plot.h) at the size of one lpvid frf
// estimate of the 3-DOF platform: 3 x 3 channels, 1024 frequencies.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "formats/plot/compare_plot.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/plants/platform/platform.h"
#include "idlib/validate/model_error.h"

namespace {

using namespace lpvid;

constexpr std::uint32_t kSeedBench = 7;
constexpr Index kFrequencies = 1024;

// The platform at x_b = +0.1 m as data (5 % noise, coherence 0.95) against the
// platform at x_b = 0 as the model: failures on several channels.
struct Case {
  Eigen::VectorXd omega = log_frequency_grid(3, 3000, kFrequencies);
  std::vector<Eigen::MatrixXcd> model = evaluate_response(platform_model(PlatformParameters::defaults(), 0.0), omega);
  FrequencyResponse data;
  std::vector<Eigen::MatrixXd> sigma;  // H1: |Ĥ| sqrt((1 − γ²)/(2 n_d γ²)), 16 averages
  Case() {
    std::mt19937 rng(kSeedBench);
    std::normal_distribution<double> n01;
    data.omega_rad_s = omega;
    for (const auto& r : evaluate_response(platform_model(PlatformParameters::defaults(), kBeamRight_m), omega)) {
      Eigen::MatrixXcd x = r;
      for (Index i = 0; i < 3; ++i)
        for (Index j = 0; j < 3; ++j) x(i, j) += 0.05 * std::abs(r(i, j)) * Complex(n01(rng), n01(rng));
      data.response.push_back(x);
      data.coherence.push_back(Eigen::MatrixXd::Constant(3, 3, 0.95));
      sigma.push_back(x.cwiseAbs() * std::sqrt(0.05 / (2 * 16 * 0.95)));
    }
  }
};

void BM_ModelErrorAndFailingBands_3x3_1024(benchmark::State& state) {
  const Case c;
  const ModelErrorOptions o;
  for (auto _ : state) {
    const auto bands = failing_bands(model_error(c.data, c.model, c.sigma, o), o);
    benchmark::DoNotOptimize(bands.data());
  }
}
BENCHMARK(BM_ModelErrorAndFailingBands_3x3_1024)->Unit(benchmark::kMillisecond);

void BM_ComparePng_3x3_1024(benchmark::State& state) {
  const Case c;
  const ModelErrorOptions o;
  const ModelErrorModel mem = model_error(c.data, c.model, c.sigma, o);
  std::vector<CompareBandMark> marks;
  for (const auto& b : failing_bands(mem, o)) marks.push_back({b.output, b.input, b.lo_rad_s, b.hi_rad_s});
  const std::vector<CompareSeries> series = {{"", mem.omega_rad_s, mem.data, mem.model, mem.radius, mem.scale, mem.skipped}};
  for (auto _ : state) {
    const auto png = compare_png(series, marks, {});
    benchmark::DoNotOptimize(png.data());
  }
}
BENCHMARK(BM_ComparePng_3x3_1024)->Unit(benchmark::kMillisecond);

}  // namespace
