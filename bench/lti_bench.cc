// Benchmarks of idlib/lti and idlib/closedloop on the 3-DOF stage sizes.
#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <random>

#include "idlib/closedloop/unloop.h"
#include "idlib/lti/discretize.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"

namespace {

using namespace lpvid;

constexpr std::uint32_t kSeedBench = 7;

StateSpace stage_plant(double Ts) {
  const Eigen::Vector3d mass(0.1, 0.1, 7.0);
  Eigen::Matrix3d K;
  K << 4.0, 0.3, 0.5, 0.3, 2.5, 0.2, 0.5, 0.2, 700.0;
  const Eigen::Matrix3d Minv = mass.cwiseInverse().asDiagonal();
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(6, 6);
  s.A.topRightCorner(3, 3).setIdentity();
  s.A.bottomLeftCorner(3, 3) = -Minv * K;
  s.A.bottomRightCorner(3, 3) = -Minv * Eigen::Vector3d(1.5, 0.3, 350.0).asDiagonal();
  s.B = Eigen::MatrixXd::Zero(6, 3);
  s.B.bottomRows(3) = Minv;
  s.C = Eigen::MatrixXd::Zero(3, 6);
  s.C.leftCols(3).setIdentity();
  s.D = Eigen::MatrixXd::Zero(3, 3);
  return discretize_zoh(s, Ts);
}

StateSpace pi(double Ts) {
  const Eigen::Vector3d kp(40.0, 40.0, 2800.0), ki(200.0, 50.0, 5000.0);
  return StateSpace{Eigen::MatrixXd::Identity(3, 3), Ts * Eigen::MatrixXd::Identity(3, 3), Eigen::MatrixXd(ki.asDiagonal()),
                    Eigen::MatrixXd((kp + ki * Ts).asDiagonal()), Ts, {}, {}};
}

void BM_EvaluateResponse12States3x3At10kFrequencies(benchmark::State& state) {
  std::mt19937 rng(kSeedBench);
  std::normal_distribution<double> N;
  StateSpace s;
  s.A = Eigen::MatrixXd::NullaryExpr(12, 12, [&]() { return 0.2 * N(rng); });
  s.B = Eigen::MatrixXd::NullaryExpr(12, 3, [&]() { return N(rng); });
  s.C = Eigen::MatrixXd::NullaryExpr(3, 12, [&]() { return N(rng); });
  s.D = Eigen::MatrixXd::Zero(3, 3);
  s.sample_period_s = 1e-3;
  const Eigen::VectorXd w = log_frequency_grid(0.1, 3000.0, 10000);
  for (auto _ : state) benchmark::DoNotOptimize(evaluate_response(s, w));
  state.SetItemsProcessed(state.iterations() * 10000);
}
BENCHMARK(BM_EvaluateResponse12States3x3At10kFrequencies)->Unit(benchmark::kMillisecond);

void BM_PlantFromClosedLoop9States(benchmark::State& state) {
  const double Ts = 1e-3;
  const StateSpace C = pi(Ts);
  const StateSpace G = closed_loop_output(stage_plant(Ts), C);
  for (auto _ : state) benchmark::DoNotOptimize(plant_from_closed_loop(G, C, UnloopOptions{}));
}
BENCHMARK(BM_PlantFromClosedLoop9States)->Unit(benchmark::kMillisecond);

}  // namespace
