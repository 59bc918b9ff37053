// identify --open-loop: logs where the excitation is the plant's input (no controller).
// The truth is a discrete plant written here (two lightly damped modes and a real pole,
// as a flexible mechanism's; built from its poles, not from lpvid), simulated here by
// its own recursion; lpvid sees only the CSV log and compares with the truth file.
// The excitation is white, or coloured (white noise through a first-order low-pass at
// 80 rad/s, so the input power falls by 30 dB across the band): the structured route
// estimates the noise spectrum from the logs and must not assume a white input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "formats/io/frd_csv.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace open_loop_identify_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

constexpr double kTs = 1e-3;
// 20 s at 1 kHz white; 60 s coloured (its horizon is 4 s, and the bands' replicates
// need at least 8 segments of a horizon each).
int samples(bool coloured) { return coloured ? 60000 : 20000; }
constexpr unsigned kSeed = 20261128;

// The true plant: x[k+1] = A x[k] + B u[k], y[k] = C x[k] (order 5), from its poles:
// modes at 40 and 260 rad/s (damping 0.03, 0.02) and a real pole at 15 rad/s.
struct Truth {
  double A[5][5] = {};
  double B[5] = {}, C[5] = {};
};

Truth make_truth() {
  Truth t;
  const auto mode = [&](int i, double w, double zeta, double b, double c) {
    const double r = std::exp(-zeta * w * kTs), th = w * std::sqrt(1 - zeta * zeta) * kTs;
    t.A[i][i] = r * std::cos(th);
    t.A[i][i + 1] = -r * std::sin(th);
    t.A[i + 1][i] = r * std::sin(th);
    t.A[i + 1][i + 1] = r * std::cos(th);
    t.B[i] = b;
    t.C[i + 1] = c;
  };
  mode(0, 40.0, 0.03, 0.05, 1.0);
  mode(2, 260.0, 0.02, 0.2, 1.0);
  t.A[4][4] = std::exp(-15.0 * kTs);
  t.B[4] = 0.015;
  t.C[4] = 1.0;
  return t;
}

void write_truth(const Truth& t, const std::string& path) {
  nlohmann::json A = nlohmann::json::array(), B = nlohmann::json::array(), C = nlohmann::json::array();
  nlohmann::json crow = nlohmann::json::array();
  for (int i = 0; i < 5; ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int j = 0; j < 5; ++j) row.push_back(t.A[i][j]);
    A.push_back(row);
    B.push_back({t.B[i]});
    crow.push_back(t.C[i]);
  }
  C.push_back(crow);
  const nlohmann::json j = {{"type", "state_space"}, {"ts", kTs}, {"A", A}, {"B", B}, {"C", C},
                            {"D", {{0.0}}},           {"inputs", {"u"}}, {"outputs", {"y"}}};
  std::ofstream(path) << j.dump();
}

// The log: u white (or low-passed), y the truth's response plus white sensor noise of
// 1 % of y's RMS.
void write_log(const Truth& t, bool coloured, const std::string& path) {
  std::mt19937_64 rng(kSeed + (coloured ? 1 : 0));
  std::normal_distribution<double> normal(0.0, 1.0);
  const int kN = samples(coloured);
  std::vector<double> u(kN), y(kN);
  double x[5] = {}, lp = 0.0;
  const double a = std::exp(-80.0 * kTs);
  for (int k = 0; k < kN; ++k) {
    const double w = normal(rng);
    lp = a * lp + (1 - a) * w * 8.0;
    u[k] = coloured ? lp : w;
    double yk = 0.0;
    for (int i = 0; i < 5; ++i) yk += t.C[i] * x[i];
    y[k] = yk;
    double nx[5];
    for (int i = 0; i < 5; ++i) {
      nx[i] = t.B[i] * u[k];
      for (int j = 0; j < 5; ++j) nx[i] += t.A[i][j] * x[j];
    }
    std::copy(nx, nx + 5, x);
  }
  double ms = 0.0;
  for (double v : y) ms += v * v;
  const double sigma = 0.01 * std::sqrt(ms / kN);
  std::ofstream f(path);
  f << "t,u,y\n";
  f.precision(17);
  for (int k = 0; k < kN; ++k) f << k * kTs << ',' << u[k] << ',' << y[k] + sigma * normal(rng) << '\n';
}

// The truth's response at ω (rad/s): C (e^{jωTs} I − A)⁻¹ B, by Eigen's LU here.
std::complex<double> truth_response(const Truth& t, double omega) {
  Eigen::Matrix<std::complex<double>, 5, 5> Z;
  Eigen::Matrix<std::complex<double>, 5, 1> b;
  Eigen::Matrix<std::complex<double>, 1, 5> c;
  const std::complex<double> z = std::polar(1.0, omega * kTs);
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 5; ++j) Z(i, j) = (i == j ? z : 0.0) - t.A[i][j];
    b(i) = t.B[i];
    c(i) = t.C[i];
  }
  return (c * Z.partialPivLu().solve(b))(0);
}

class OpenLoopIdentify : public ::testing::TestWithParam<bool> {};

TEST_P(OpenLoopIdentify, RecoversTheTruePlantWithItsOrderAndBands) {
  const bool coloured = GetParam();
  TempDir dir(coloured ? "open_coloured" : "open_white");
  const Truth t = make_truth();
  write_truth(t, dir / "truth.json");
  write_log(t, coloured, dir / "log.csv");
  const double top = coloured ? 500.0 : 1000.0;
  const auto r = run_lpvid("identify --open-loop --excitation u --output y --json --band-min 5 --band-max " +
                           std::to_string(top) + " --truth " +
                           (dir / "truth.json") + " --out " + (dir / "out") + " " + (dir / "log.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["route"], "open loop: the excitation is the plant's input (C = 0, G = P)");
  EXPECT_TRUE(report["controller"].is_null());
  EXPECT_EQ(report["plant"]["order"], 5) << report["fit"]["order_reason"];
  EXPECT_EQ(report["plant"]["stable"], true);
  // `fit` is the structured fit; the written plant is the refinement's when it was kept,
  // and the report says which (formats.md, identify's report).
  ASSERT_TRUE(report["refinement"].is_object());
  EXPECT_EQ(report["plant"]["source"], report["refinement"]["kept"].get<bool>()
                                           ? "output-error refinement (report.refinement)"
                                           : "structured fit (report.fit)");
  if (report["refinement"]["kept"].get<bool>()) {
    EXPECT_LT(report["refinement"]["cost"].get<double>(), report["refinement"]["start_cost"].get<double>());
  }
  // 1 % output noise on 20 s.  White input: measured 0.030 % mean (max 0.14 %); the
  // bound 0.1 % is 3x that.  Coloured: the input's spectral density falls by a factor
  // ~280 from DC to Nyquist while the low-frequency modes, excited 8x harder, set the
  // output noise (1 % of y's RMS): at 1000 rad/s the data hold little; measured 5.3 %
  // mean, 49 % at 1000 rad/s, which the bands must cover (below).  Before the fit
  // weighed bins by the excitation's spectrum it was order 3 at 66 % mean error.
  const double mean = report["truth"]["weighted_error_mean"].get<double>();
  std::printf("%s input: order %d, mean error %.4f %%, max %.4f %% at %.4g rad/s; %s\n", coloured ? "coloured" : "white",
              report["plant"]["order"].get<int>(), 100 * mean, 100 * report["truth"]["weighted_error_max"].get<double>(),
              report["truth"]["omega_at_max_rad_s"].get<double>(), (report["fit"]["excitation_reason"].dump() + " " + report["fit"]["band_reason"].dump() + " " + report["markov"]["horizon_reason"].dump()).c_str());
  EXPECT_LE(mean, coloured ? 0.10 : 0.001) << "mean error " << mean;
  // The 95 % bands (|P^ - P| <= 2 sigma, identify.h kBandRadiusPerSigma) cover the truth
  // at >= 85 % of the plant_frd.csv frequencies in 5..1000 rad/s (the band's nominal
  // coverage is 95-98 %; neighbouring frequencies are correlated, so one record's
  // coverage scatters).
  const FrequencyResponse frd = read_frd_csv(dir / "out/plant_frd.csv");
  int inside = 0, total = 0;
  for (Index k = 0; k < frd.num_frequencies(); ++k) {
    const double w = frd.omega_rad_s(k);
    if (w < 5.0 || w > top) continue;
    ++total;
    const double err = std::abs(frd.response[static_cast<std::size_t>(k)](0, 0) - truth_response(t, w));
    inside += err <= 2.0 * std::sqrt(frd.variance[static_cast<std::size_t>(k)](0, 0)) ? 1 : 0;
  }
  ASSERT_GT(total, 100);
  std::printf("bands cover the truth at %d of %d frequencies; markov %s; warnings %s\n", inside, total, report["markov"]["termination"].dump().c_str(), report["warnings"].dump().c_str());
  EXPECT_GE(inside, 0.85 * total);
  // No closed_loop.json in open loop; the plant and its bands are written.
  EXPECT_FALSE(std::filesystem::exists(dir / "out/closed_loop.json"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out/plant.json"));
  EXPECT_THAT(slurp(dir / "out/plant_frd.csv"), HasSubstr("var_y_u"));
}

INSTANTIATE_TEST_SUITE_P(WhiteAndColouredInput, OpenLoopIdentify, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& i) { return i.param ? "Coloured" : "White"; });

TEST(OpenLoopIdentifyUsage, NeitherOrBothOfControllerAndOpenLoopIsRefusedInOneLine) {
  TempDir dir("open_usage");
  const Truth t = make_truth();
  write_log(t, false, dir / "log.csv");
  auto r = run_lpvid("identify --excitation u --output y --out " + (dir / "out") + " " + (dir / "log.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("no controller: give --controller C.json (the controller that ran, for closed-loop "
                               "logs) or --open-loop (the excitation is the plant's input)"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  std::ofstream(dir / "c.json")
      << R"({"type":"state_space","ts":0.001,"A":[],"B":[],"C":[],"D":[[1]],"inputs":["e"],"outputs":["u"]})";
  r = run_lpvid("identify --open-loop --controller " + (dir / "c.json") + " --excitation u --output y --out " +
                (dir / "out") + " " + (dir / "log.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--open-loop and --controller both given"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

}  // namespace open_loop_identify_test
}  // namespace lpvid
