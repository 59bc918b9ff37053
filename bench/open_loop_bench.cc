// Issue 24's benchmarks: the open-loop route (identify_open_loop, structured fit and
// output-error refinement) and the refinement alone on 10⁶ samples; the direct route on
// a point-to-point axis with and without friction; compare --log's
// numerics for any model on 10⁶ samples; the periodic FRF on the F-16 ground vibration
// test (real data, read from ../shared/real-data when present, else skipped with the
// reason in the table).
#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "formats/io/csv_log.h"
#include "idlib/identify/direct.h"
#include "idlib/identify/identify.h"
#include "idlib/identify/output_error.h"
#include "idlib/lti/analysis.h"
#include "idlib/signal/periodic_frf.h"
#include "idlib/validate/nonlinearity.h"
#include "idlib/validate/time_fit.h"
#include "tests/support/friction_axis.h"
#include "tests/support/real_data.h"

namespace {

using namespace lpvid;

constexpr Index kSamples = 1'000'000;
constexpr double kTs = 1e-3;

// A lightly damped mechanism at 1 kHz (a resonance at 60 rad/s, ζ = 0.05, and a real pole
// at 300 rad/s), torque -> position: order 3, stable.  The poles are sampled exactly
// (z = e^{sTs}); B and C are chosen, not derived (the cost depends on sizes only).
StateSpace mechanism() {
  const double w = 60.0, zeta = 0.05, wd = w * std::sqrt(1 - zeta * zeta);
  const double r = std::exp(-zeta * w * kTs), th = wd * kTs;
  StateSpace s;
  s.A.resize(3, 3);
  s.A << r * std::cos(th), -r * std::sin(th), 0, r * std::sin(th), r * std::cos(th), 0, 0, 0, std::exp(-300.0 * kTs);
  s.B.resize(3, 1);
  s.B << 0.01, 0.0, 0.02;
  s.C.resize(1, 3);
  s.C << 1.0, 0.5, 1.0;
  s.D = Eigen::MatrixXd::Zero(1, 1);
  s.sample_period_s = kTs;
  return s;
}

struct Record {
  Eigen::MatrixXd u, y;
};

// White input, output with white noise at 2 % of its rms (fixed seed: the same work every run).
Record record(const StateSpace& plant, Index samples) {
  std::mt19937_64 rng(20261129);
  std::normal_distribution<double> d(0.0, 1.0);
  Record r;
  r.u.resize(samples, 1);
  for (Index t = 0; t < samples; ++t) r.u(t, 0) = d(rng);
  r.y = simulate_discrete(plant, r.u);
  const double rms = std::sqrt(r.y.squaredNorm() / static_cast<double>(samples));
  for (Index t = 0; t < samples; ++t) r.y(t, 0) += 0.02 * rms * d(rng);
  return r;
}

void BM_IdentifyOpenLoop_SISO_1M(benchmark::State& state) {
  const Record rec = record(mechanism(), kSamples);
  const std::vector<ExperimentView> views = {{rec.u, rec.y}};
  for (auto _ : state) {
    const IdentifyResult r = identify_open_loop(views, kTs, IdentifyOptions{});
    benchmark::DoNotOptimize(r.plant.A.data());
    state.counters["order"] = static_cast<double>(r.plant.order());
    state.counters["lags"] = static_cast<double>(r.num_lags);
    state.counters["refined"] = r.choices.refinement.kept ? 1.0 : 0.0;
  }
}
BENCHMARK(BM_IdentifyOpenLoop_SISO_1M)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// The refinement alone from a start whose poles are 2 % off (radius and angle), x(0) and
// an offset fitted: 3 states, 9 + 3 + 3 + 3 + 1 = 19 parameters, 10⁶ residuals
// (1.9·10⁷ Jacobian entries, just under kMaxOutputErrorJacobianEntries).
void BM_RefineOutputError_SISO_1M(benchmark::State& state) {
  const StateSpace truth = mechanism();
  const Record rec = record(truth, kSamples);
  StateSpace start = truth;
  start.A.topLeftCorner(2, 2) *= 0.999;
  start.A(2, 2) = std::exp(-306.0 * kTs);
  const std::vector<ExperimentView> views = {{rec.u, rec.y}};
  for (auto _ : state) {
    const OutputErrorResult r = refine_output_error(views, start);
    benchmark::DoNotOptimize(r.model.A.data());
    state.counters["iterations"] = r.iterations;
    state.counters["accepted"] = r.accepted ? 1.0 : 0.0;
  }
}
BENCHMARK(BM_RefineOutputError_SISO_1M)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// compare --log with a state-space model: both simulations (x(0) = 0 and fitted, with
// offsets) and the time-domain tests (fit, whiteness and cross over 25 lags, windows),
// and the nonlinearity tests (idlib/validate/nonlinearity.h).
void BM_CompareModelLog_SISO_1M(benchmark::State& state) {
  const StateSpace truth = mechanism();
  const Record rec = record(truth, kSamples);
  TimeFitOptions fo;
  fo.window_s = 50.0;
  for (auto _ : state) {
    const SimulatedOutput e = simulate_with_fitted_start(truth, rec.u, rec.y, true);
    const SimulatedOutput z = simulate_with_fitted_start(truth, rec.u, rec.y, false);
    const TimeFitResult r = time_fit(rec.y, e.predicted, rec.u, 0.0, kTs, fo);
    const NonlinearityResult nl = nonlinearity_tests(rec.y - e.predicted, e.predicted);
    benchmark::DoNotOptimize(z.predicted.data());
    state.counters["nonlinear_seen"] = static_cast<double>(nl.significant.size());
    state.counters["fit_percent"] = r.fit_percent(0);
  }
}
BENCHMARK(BM_CompareModelLog_SISO_1M)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// frf --method periodic on the F-16 level-1 file as the CLI runs it: the measured voltage
// as the reference, force and three accelerations measured, 8192-sample periods, 1
// transient + 8 periods (73 728 samples), the plant force -> acc from (PS) S⁻¹ with the
// errors-in-variables variance; after parsing (the CSV read is outside the loop).
void BM_PeriodicFrf_F16_Level1(benchmark::State& state) {
  const std::string path = testing::real_data_file("f16_gvt/f16_fullmsine_level1.csv");
  if (path.empty()) {
    state.SkipWithError("../shared/real-data/f16_gvt not found (set LPVID_REAL_DATA)");
    return;
  }
  const Log log = read_log(path);
  const Eigen::MatrixXd v = log.columns({"voltage"});
  const Eigen::MatrixXd z = log.columns({"acc1", "acc2", "acc3", "force"});
  PeriodicFrfOptions o;
  o.layout = {8192, 8, 1, 1, 1};
  o.sample_period_s = log.sample_period_s;
  for (auto _ : state) {
    const PeriodicFrfResult r = estimate_periodic_frf(v, z, 1, o);
    benchmark::DoNotOptimize(r.frd.response.data());
    state.counters["lines"] = static_cast<double>(r.frd.num_frequencies());
  }
  state.counters["samples"] = static_cast<double>(v.rows());
}
BENCHMARK(BM_PeriodicFrf_F16_Level1)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// identify's direct route (direct.h) on point-to-point moves, after parsing: the friction
// axis of tests/support/friction_axis.h, 30 s at 1 kHz, under its PD; /0 the axis with no
// friction (the linear ladder, orders 1..4), /1 with Coulomb friction and an offset (the
// ladder with friction beside the plant, orders 1..2, as identify runs it after the
// linear one).  The route is for such short, low-order logs; 10⁶ samples of it would be
// the output-error refinement's cost, measured above.
void BM_IdentifyDirect_FrictionAxis_30s(benchmark::State& state) {
  const bool friction = state.range(0) != 0;
  friction_axis::Truth t;
  if (!friction) t.coulomb_N = t.offset_N = 0.0;
  friction_axis::Experiment e;
  e.point_to_point = true;
  const friction_axis::Log log = friction_axis::simulate(t, e);
  // The simulator's PD on e = r − enc, as tests/cli/reference_identify_test.cc writes it.
  const double wc = 2 * M_PI * 30.0, kp = t.m_kg * wc * wc, kd = 2 * 0.7 * t.m_kg * wc;
  const double a = std::exp(-2 * M_PI * 300.0 * kTs), c = (1 - a) / kTs, kf = t.k_f_N_per_A;
  StateSpace C;
  C.A.resize(2, 2);
  C.A << a, -c, 0.0, 0.0;
  C.B.resize(2, 1);
  C.B << c, 1.0;
  C.C.resize(1, 2);
  C.C << kd * a / kf, -kd * c / kf;
  C.D = Eigen::MatrixXd::Constant(1, 1, (kp + kd * c) / kf);
  C.sample_period_s = kTs;
  const Eigen::MatrixXd r = log.r, q = log.x;
  const Eigen::MatrixXd u = applied_plant_input(C, Eigen::MatrixXd(0, 0), r, q);
  const Eigen::MatrixXd v = simulate_discrete(C, (r.array() - r(0, 0)).matrix());
  const std::vector<ExperimentView> loop = {{v, q}}, applied = {{u, q}};
  for (auto _ : state) {
    IdentifyResult base;
    const DirectLadder ladder = identify_direct_in_loop(loop, applied, kTs, C, friction ? 2 : kDirectMaxOrder, base,
                                                        friction);
    benchmark::DoNotOptimize(base.plant.A.data());
    state.counters["order"] = static_cast<double>(ladder.order);
    state.counters["coulomb"] = ladder.friction ? ladder.friction->coulomb(0, 0) : 0.0;
  }
}
BENCHMARK(BM_IdentifyDirect_FrictionAxis_30s)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
