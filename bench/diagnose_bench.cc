// Benchmark of idlib/diagnose at the size: every candidate effect the
// model could add, refitted on 3 positions × 9 channels × 500 frequencies.
#include <benchmark/benchmark.h>

#include "idlib/diagnose/diagnose.h"
#include "tests/idlib/diagnose/independent_data.h"

namespace {

using namespace lpvid;

// Data: the INDEPENDENT platform (tests/support/independent_platform.h) of seed 201
// with a hidden fractional input delay, measured by the stepped-sine analyzer (S
// with coherence, 16 averages) at 500 frequencies from 0.15 to 400 Hz at each of
// three beam positions; start: `model init` with the user's design values
// (tests/idlib/diagnose/independent_data.h).  Every library effect the model lacks
// (8) is a candidate; each is refitted (global start over its own parameters +
// Levenberg–Marquardt), the candidates on the machine's cores.
void BM_Diagnose_AllCandidates_3x9x500(benchmark::State& state) {
  const testing::LoopCase c =
      testing::make_loop_case(201, indep::HiddenEffect::kDelay, testing::Route::kAnalyzer, 500);
  DiagnoseOptions options;
  options.fit = testing::loop_fit_options(c);
  bool named = false;
  std::size_t candidates = 0;
  for (auto _ : state) {
    const Diagnosis d = diagnose(c.start, c.data, options);
    named = d.explained && d.missing == "input_delay";
    candidates = d.ranked.size();
    benchmark::DoNotOptimize(d.baseline_error);
  }
  state.counters["candidates"] = static_cast<double>(candidates);
  state.counters["named_delay_first"] = named ? 1.0 : 0.0;
}
BENCHMARK(BM_Diagnose_AllCandidates_3x9x500)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

// Two effects hidden at once (issue 25): the same plant with the product of inertia
// and centre-of-mass offset (com_offset) and a coil lag; neither is significant
// alone, so diagnose also refits the pairs (the anchor with every other candidate,
// the best four by ΔBIC with each other) and names the pair.
void BM_Diagnose_TwoEffects_Pairs_3x9x500(benchmark::State& state) {
  const testing::LoopCase c = testing::make_loop_case(
      221, {indep::HiddenEffect::kComOffset, indep::HiddenEffect::kCoilLag}, testing::Route::kAnalyzer, 500);
  DiagnoseOptions options;
  options.fit = testing::loop_fit_options(c);
  bool named = false;
  std::size_t combinations = 0;
  for (auto _ : state) {
    const Diagnosis d = diagnose(c.start, c.data, options);
    named = d.explained && d.missing_effects.size() == 2;
    combinations = d.combinations.size();
    benchmark::DoNotOptimize(d.baseline_error);
  }
  state.counters["combinations"] = static_cast<double>(combinations);
  state.counters["named_the_pair"] = named ? 1.0 : 0.0;
}
BENCHMARK(BM_Diagnose_TwoEffects_Pairs_3x9x500)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(2);

}  // namespace
