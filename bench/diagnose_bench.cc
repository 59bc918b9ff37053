// Benchmark of idlib/diagnose at the size: every candidate effect of the
// library refitted on 3 positions × 9 channels × 500 frequencies.
#include <benchmark/benchmark.h>

#include <random>

#include "idlib/diagnose/diagnose.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/models/platform.h"

namespace {

using namespace lpvid;

// Data: the default platform with a hidden 1 ms input delay, ZOH at 1 kHz,
// 1–2500 rad/s, 1 % complex noise at the diagonal scale with the matching H1
// coherence (as tests/idlib/diagnose/diagnose_test.cc).  Start: the bare
// platform (no effect), so all seven library effects are candidates; each is
// refitted with the global start (8 BOBYQA starts) and Levenberg–Marquardt, the
// candidates on the machine's cores.
void BM_Diagnose_AllCandidates_3x9x500(benchmark::State& state) {
  PhysicalModel truth = PhysicalModel::bare_platform();
  truth.add_effect("input_delay");
  truth.parameter("input_delay_s").value = 1e-3;
  DiagnoseOptions options;
  options.fit.sample_period_s = 1e-3;
  const Eigen::VectorXd w = log_frequency_grid(1.0, 2500.0, 500);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01;
  std::vector<FitDataset> data;
  for (double xb : kPaperBeamPositions_m) {
    FrequencyResponse r = target_response(truth, xb, w, options.fit);
    r.coherence.resize(r.response.size());
    for (std::size_t k = 0; k < r.response.size(); ++k) {
      const Eigen::MatrixXcd exact = r.response[k];
      Eigen::MatrixXd coh(3, 3);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double sigma = 0.01 * std::sqrt(std::abs(exact(i, i)) * std::abs(exact(j, j)));
          r.response[k](i, j) += std::complex<double>(sigma * n01(rng), sigma * n01(rng));
          const double a2 = std::norm(r.response[k](i, j));
          coh(i, j) = a2 / (a2 + 2.0 * 16.0 * sigma * sigma);
        }
      r.coherence[k] = coh;
    }
    data.push_back({xb, r, "x_b"});
  }
  const PhysicalModel start = PhysicalModel::bare_platform();
  bool named = false;
  std::size_t candidates = 0;
  for (auto _ : state) {
    const Diagnosis d = diagnose(start, data, options);
    named = d.explained && d.ranked.front().effect == "input_delay";
    candidates = d.ranked.size();
    benchmark::DoNotOptimize(d.baseline_error);
  }
  state.counters["candidates"] = static_cast<double>(candidates);
  state.counters["named_delay_first"] = named ? 1.0 : 0.0;
}
BENCHMARK(BM_Diagnose_AllCandidates_3x9x500)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
