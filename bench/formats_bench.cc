// Benchmarks of formats/io: reading and writing time-domain logs.
// BM_ReadLog parses a ~146 MB, 10-column CSV (the size of BUILD-NOTES.md's CSV
// measurement) generated once in a temporary directory; BM_WriteLog writes the
// same data.  Both report bytes/s of CSV text.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>

#include "formats/io/csv_log.h"
#include "formats/io/mat_log.h"

namespace {

constexpr lpvid::Index kRows = 1'600'000;  // 10 columns of ~9 bytes: ~146 MB
constexpr lpvid::Index kColumns = 10;
constexpr unsigned kSeed = 1;  // named seed of the benchmark data

struct BenchLog {
  std::filesystem::path dir;
  std::string path;
  std::vector<std::string> names;
  Eigen::MatrixXd data;
  size_t bytes = 0;

  BenchLog() {
    dir = std::filesystem::temp_directory_path() / ("lpvid_formats_bench_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    path = (dir / "log.csv").string();
    names.push_back("t");
    for (lpvid::Index j = 1; j < kColumns; ++j) names.push_back("c" + std::to_string(j));
    std::mt19937_64 rng(kSeed);
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    data.resize(kRows, kColumns);
    for (lpvid::Index k = 0; k < kRows; ++k) {
      data(k, 0) = static_cast<double>(k) * 1e-4;
      // Values with 6 significant digits, like a logger's output.
      for (lpvid::Index j = 1; j < kColumns; ++j) data(k, j) = std::round(uniform(rng) * 1e6) / 1e6;
    }
    lpvid::write_log(path, names, data);
    bytes = std::filesystem::file_size(path);
  }
  ~BenchLog() { std::filesystem::remove_all(dir); }
};

BenchLog& bench_log() {
  static BenchLog log;
  return log;
}

void BM_ReadLog(benchmark::State& state) {
  BenchLog& log = bench_log();
  for (auto _ : state) {
    lpvid::Log read = lpvid::read_log(log.path);
    benchmark::DoNotOptimize(read.data.data());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(log.bytes));
  state.counters["MB"] = static_cast<double>(log.bytes) / 1e6;
}
BENCHMARK(BM_ReadLog)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_WriteLog(benchmark::State& state) {
  BenchLog& log = bench_log();
  const std::string out = (log.dir / "out.csv").string();
  for (auto _ : state) lpvid::write_log(out, log.names, log.data);
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(log.bytes));
  std::filesystem::remove(out);
}
BENCHMARK(BM_WriteLog)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same samples as a .mat log (data + names, uncompressed): arg 0 = v5 (lpvid's
// parser), 1 = v7.3 (libmatio/HDF5).  Bytes/s of the .mat file.
void BM_ReadLogMat(benchmark::State& state) {
  BenchLog& log = bench_log();
  const bool v73 = state.range(0) == 1;
  const std::string path = (log.dir / (v73 ? "log73.mat" : "log5.mat")).string();
  if (!std::filesystem::exists(path)) lpvid::write_log_mat(path, log.names, log.data, v73);
  const size_t bytes = std::filesystem::file_size(path);
  for (auto _ : state) {
    lpvid::Log read = lpvid::read_log(path);
    benchmark::DoNotOptimize(read.data.data());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(bytes));
  state.counters["MB"] = static_cast<double>(bytes) / 1e6;
}
BENCHMARK(BM_ReadLogMat)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
