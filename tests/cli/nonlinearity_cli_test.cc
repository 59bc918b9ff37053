// identify and compare --log say when a record holds a nonlinearity that no linear model
// can follow (idlib/validate/nonlinearity.h).  The truth is the independent friction-axis
// simulator (tests/support/friction_axis.h: a carriage on a ball screw with viscous and
// Coulomb friction, sticking at rest, integrated in 100 substeps, under a discrete PD on
// the quantised encoder), excited through a broadband reference, once with Coulomb
// friction and once without (everything else, the seed included, the same): the
// controller file is the simulator's PD written as a state-space model here.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "tests/support/friction_axis.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace nonlinearity_cli_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

// The simulator's PD, current = (kp err + kd d + 2 N) / k_f with d = α d + (1 − α)(err −
// err_prev)/Ts, as x⁺ = A x + B err, i = C x + D err over x = [d_prev; err_prev] (the
// 2 N feedforward is a constant: the log's means absorb it).
void write_controller(const friction_axis::Truth& p, double ts, const std::string& path) {
  const double wc = 2.0 * M_PI * 30.0, kp = p.m_kg * wc * wc, kd = 2.0 * 0.7 * p.m_kg * wc;
  const double a = std::exp(-2.0 * M_PI * 300.0 * ts), c = (1.0 - a) / ts, kf = p.k_f_N_per_A;
  std::ofstream(path) << nlohmann::json{{"type", "state_space"},
                                        {"ts", ts},
                                        {"A", {{a, -c}, {0.0, 0.0}}},
                                        {"B", {{c}, {1.0}}},
                                        {"C", {{kd * a / kf, -kd * c / kf}}},
                                        {"D", {{(kp + kd * c) / kf}}},
                                        {"inputs", {"e"}},
                                        {"outputs", {"i"}}}
                             .dump();
}

nlohmann::json identify_axis(double coulomb_N, const TempDir& dir, const std::string& tag) {
  friction_axis::Truth p;
  p.coulomb_N = coulomb_N;
  p.offset_N = 0.0;
  friction_axis::Experiment e;
  e.random_reference = true;
  e.seconds = 30.0;
  const friction_axis::Log log = friction_axis::simulate(p, e);
  const std::string csv = dir / (tag + ".csv"), ctl = dir / (tag + "_controller.json");
  friction_axis::write_csv(log, csv);
  write_controller(p, 1.0 / e.rate_hz, ctl);
  const auto r = run_lpvid(fmt::format("identify --controller {} --excitation r --excitation-at reference --output enc "
                                       "--json --out {} {}",
                                       ctl, dir / tag, csv));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return nullptr;
  const auto report = nlohmann::json::parse(r.out);
  std::printf("axis, Coulomb %.1f N: simulation fit %.2f %%; nonlinearity: %s\n", coulomb_N,
              report["closed_loop"]["simulation_fit_initial_state_percent"][0].get<double>(),
              report["closed_loop"]["nonlinearity"]["sentence"].get<std::string>().c_str());
  return report;
}

// With Coulomb friction (6.5 N against a PD holding a 4.2 kg carriage) the best linear
// approximation leaves a residual that follows the sign of the position's rate: said,
// friction-like.  Without it (the same axis, reference and noise) nothing is seen — the
// family-wise level is 99 %, and the encoder's 1 µm quantisation is the only nonlinearity
// left.
TEST(NonlinearityCli, IdentifySaysAFrictionAxisHoldsANonlinearityAndTheFrictionlessOneDoesNot) {
  TempDir dir("nonlinear_axis");
  const auto linear = identify_axis(0.0, dir, "linear");
  const auto friction = identify_axis(6.5, dir, "friction");
  ASSERT_FALSE(linear.is_null());
  ASSERT_FALSE(friction.is_null());
  const auto& nl0 = linear["closed_loop"]["nonlinearity"];
  const auto& nl1 = friction["closed_loop"]["nonlinearity"];
  ASSERT_EQ(nl0["ran"], true);
  ASSERT_EQ(nl1["ran"], true);
  EXPECT_EQ(nl0["seen"], false) << nl0.dump();
  ASSERT_EQ(nl1["seen"], true) << nl1.dump();
  EXPECT_EQ(nl1["significant"][0]["feature"], "sign of the rate") << nl1.dump();
  EXPECT_THAT(nl1["sentence"].get<std::string>(), ::testing::HasSubstr("friction-like"));

  // compare --log of the friction axis's identified plant in its loop says the same.
  const auto c = run_lpvid(fmt::format("compare --json --log {} --model {} --controller {} --excitation r "
                                       "--excitation-at reference --output enc",
                                       dir / "friction.csv", dir / "friction/plant.json",
                                       dir / "friction_controller.json"));
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto cmp = nlohmann::json::parse(c.out);
  EXPECT_EQ(cmp["nonlinearity"]["seen"], true) << cmp["nonlinearity"].dump();
}

}  // namespace nonlinearity_cli_test
}  // namespace lpvid
