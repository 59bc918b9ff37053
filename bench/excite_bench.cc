// Benchmarks of lpvid excite: a 3-input multisine of 10^6 samples per input
// (3 x 10^6 values; zipper, L = 10 000, 1 transient + 99 periods, 1..400 Hz at
// 1 kHz), generated alone, with crest-factor minimisation (200 iterations per
// input), and generated then written as the CSV log `lpvid excite` writes.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "formats/io/csv_log.h"
#include "idlib/signal/excitation.h"

namespace {

lpvid::ExcitationSpec bench_spec() {
  lpvid::ExcitationSpec s;
  s.kind = lpvid::ExcitationKind::kMultisine;
  s.sample_rate_hz = 1000;
  s.channels = 3;
  s.mimo = lpvid::MimoDesign::kZipper;
  s.period_samples = 10'000;
  s.transient_periods = 1;
  s.periods = 99;  // (1 + 99) x 10 000 = 10^6 samples per input
  s.band_lo_hz = 1;
  s.band_hi_hz = 400;
  s.rms = {0.05, 0.05, 1.0};
  s.seed = 1;  // named seed of the benchmark signal
  return s;
}

void BM_ExciteMultisine_3x1M(benchmark::State& state) {
  const lpvid::ExcitationSpec s = bench_spec();
  for (auto _ : state) {
    lpvid::ExcitationSignal x = lpvid::generate_excitation(s);
    benchmark::DoNotOptimize(x.samples.data());
  }
  state.counters["samples"] = 3e6;
}
BENCHMARK(BM_ExciteMultisine_3x1M)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ExciteMultisineMinimisedCrest_3x1M(benchmark::State& state) {
  lpvid::ExcitationSpec s = bench_spec();
  s.minimise_crest = true;
  s.crest_iterations = 200;
  for (auto _ : state) {
    lpvid::ExcitationSignal x = lpvid::generate_excitation(s);
    benchmark::DoNotOptimize(x.samples.data());
  }
}
BENCHMARK(BM_ExciteMultisineMinimisedCrest_3x1M)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same with a relative amplitude spectrum (excite --amplitude): 10x at 1 Hz falling
// log-log to 1 at 20 Hz, flat to 400 Hz; one log/pow per line on top of the flat case.
void BM_ExciteMultisineShaped_3x1M(benchmark::State& state) {
  lpvid::ExcitationSpec s = bench_spec();
  s.shape_f_hz = {1, 20, 400};
  s.shape_amplitude = {10, 1, 1};
  for (auto _ : state) {
    lpvid::ExcitationSignal x = lpvid::generate_excitation(s);
    benchmark::DoNotOptimize(x.samples.data());
  }
}
BENCHMARK(BM_ExciteMultisineShaped_3x1M)->Unit(benchmark::kMillisecond)->UseRealTime();

// What `lpvid excite --out x.csv` does after parsing: generate, add t, write the log.
void BM_ExciteMultisineToCsv_3x1M(benchmark::State& state) {
  const lpvid::ExcitationSpec s = bench_spec();
  const auto dir = std::filesystem::temp_directory_path() / ("lpvid_excite_bench_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "ms.csv").string();
  for (auto _ : state) {
    const lpvid::ExcitationSignal x = lpvid::generate_excitation(s);
    Eigen::MatrixXd data(x.samples.rows(), 4);
    for (lpvid::Index k = 0; k < data.rows(); ++k) data(k, 0) = static_cast<double>(k) / s.sample_rate_hz;
    data.rightCols(3) = x.samples;
    // The design line (~20 kB of bins here) matters little next to 3 x 10^6 numbers: left out.
    lpvid::write_log(path, {"t", "v1", "v2", "v3"}, data);
  }
  state.counters["MB"] = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_ExciteMultisineToCsv_3x1M)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
