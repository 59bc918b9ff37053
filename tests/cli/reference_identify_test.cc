// identify --excitation-at reference (issue 24): a positioning axis — a motor driving a
// ball screw, force → position with a pure integrator — under a PD-type controller with
// a filtered derivative, excited through its setpoint r (e = r − q) about an operating
// point, the experiment a user of such an axis runs.  The truth is the axis written here
// (exact ZOH sampling of K / (s (τ s + 1)), derived by hand), simulated here by its own
// recursion with the controller in the loop on the MEASURED position; lpvid sees only the
// CSV log and the controller file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <utility>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "formats/io/frd_csv.h"
#include "idlib/identify/identify.h"
#include "tests/support/friction_axis.h"
#include "tests/support/positioning_axis.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace reference_identify_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

using namespace lpvid::testing::positioning_axis;

// How many of plant_frd.csv's frequencies in 1–1000 rad/s have the axis's true response
// inside the 95 % band |P̂ − P| <= 2 σ, and how many there are.
std::pair<int, int> bands_covering_the_axis(const std::string& frd_path) {
  const FrequencyResponse frd = read_frd_csv(frd_path);
  const Axis ax;
  int inside = 0, total = 0;
  for (Index k = 0; k < frd.num_frequencies(); ++k) {
    const double w = frd.omega_rad_s(k);
    if (w < 1.0 || w > 1000.0) continue;
    ++total;
    inside += std::abs(frd.response[static_cast<std::size_t>(k)](0, 0) - ax.response(w)) <=
              2.0 * std::sqrt(frd.variance[static_cast<std::size_t>(k)](0, 0));
  }
  return {inside, total};
}

TEST(ReferenceIdentify, APositioningAxisWithAnIntegratorExcitedThroughItsSetpointIsRecovered) {
  TempDir dir("reference_axis");
  write_files(dir.path());
  const auto r = run_lpvid("identify --controller " + (dir / "controller.json") +
                           " --excitation r --excitation-at reference --output q --json --band-min 1 --band-max 1000"
                           " --truth " + (dir / "truth.json") + " --out " + (dir / "out") + " " + (dir / "axis.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["excitation_at"], "reference");
  // The Markov parameters are of v = C r -> q: markov.csv names its input so (after
  // the controller's output u), not after the reference column r.
  ASSERT_EQ(report["loop_inputs"], nlohmann::json::array({"C*r->u"}));
  {
    std::ifstream in(dir / "out/markov.csv");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\n# inputs: C*r->u\n"), std::string::npos) << text.substr(0, 200);
  }
  EXPECT_EQ(report["plant"]["order"], 2) << report["fit"]["order_reason"];
  const double mean = report["truth"]["weighted_error_mean"].get<double>();
  std::printf("axis: order %d, mean error %.4f %%, max %.4f %% at %.4g rad/s; refinement: %s\n",
              report["plant"]["order"].get<int>(), 100 * mean, 100 * report["truth"]["weighted_error_max"].get<double>(),
              report["truth"]["omega_at_max_rad_s"].get<double>(),
              report["fit"]["refinement_reason"].get<std::string>().c_str());
  // Sensor noise 0.2 % of the excursion: measured 0.0166 % mean (max 0.085 % at 1 rad/s, where the
  // loop gain is highest); the bound is 3x that.
  EXPECT_LE(mean, 0.0005);
  // Every frequency of the error band is pinned down by the data (a reference excites
  // the whole loop; identify.h band_support).
  EXPECT_EQ(report["plant"]["support"]["supported"], report["plant"]["support"]["points"]);
  // The integrator is identified as one: a pole at z = 1 within the bands' resolution.
  const auto [inside, total] = bands_covering_the_axis(dir / "out/plant_frd.csv");
  ASSERT_GT(total, 50);
  std::printf("bands cover the truth at %d of %d frequencies\n", inside, total);
  EXPECT_GE(inside, 0.85 * total);
}

// The same axis on a short log (the first 8192 samples, 8 s): the loop's start transient
// (the references' mean is not the operating point the loop stood at) is a larger share of
// the record, and the structured fit, which cannot model it, lands further from the axis.
// The closed-loop output-error refinement fits the loop's initial state with the plant,
// and is kept because on held-out halves it predicts better, significantly and by more
// than 10 % in error norm.  Measured: mean error 0.0997 % structured (--no-refine),
// 0.0254 % refined (held-out error norm x0.195, 3.72 standard errors), the bands covering
// the truth at 343 of 343 frequencies.  The bounds: the refinement at least halves the
// error (4x measured) and its bands cover >= 85 %, as above.  On the full 30 s log (the
// test above) the refinement runs and is not kept: held-out fits equal to 0.01 points.
TEST(ReferenceIdentify, OnAShortLogTheClosedLoopRefinementIsKeptAndLandsNearerTheAxis) {
  TempDir dir("reference_axis_short");
  write_files(dir.path());
  {
    std::ifstream in(dir / "axis.csv");
    std::ofstream out(dir / "short.csv");
    std::string line;
    for (int k = 0; k <= 8192 && std::getline(in, line); ++k) out << line << "\n";
  }
  const std::string args = "identify --controller " + (dir / "controller.json") +
                           " --excitation r --excitation-at reference --output q --json --band-min 1 --band-max 1000"
                           " --truth " + (dir / "truth.json") + " " + (dir / "short.csv");
  const auto r = run_lpvid(args + " --out " + (dir / "out"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto s = run_lpvid(args + " --no-refine --out " + (dir / "plain"));
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto report = nlohmann::json::parse(r.out), plain = nlohmann::json::parse(s.out);
  const double mean = report["truth"]["weighted_error_mean"].get<double>();
  const double plain_mean = plain["truth"]["weighted_error_mean"].get<double>();
  std::printf("axis, 8 s: mean error %.4f %% refined, %.4f %% structured; %s\n", 100 * mean, 100 * plain_mean,
              report["fit"]["refinement_reason"].get<std::string>().c_str());
  ASSERT_TRUE(report["refinement"].is_object());
  EXPECT_EQ(report["refinement"]["kept"], true);
  EXPECT_EQ(report["plant"]["source"], "output-error refinement (report.refinement)");
  EXPECT_LE(mean, 0.5 * plain_mean);
  const auto [inside, total] = bands_covering_the_axis(dir / "out/plant_frd.csv");
  ASSERT_GT(total, 50);
  EXPECT_GE(inside, 0.85 * total);
}

// The references enter as deviations from the setpoint the loop stood at: a log that
// holds its first setpoint for the first 10 samples (kReferenceAtRestSamples) and starts
// away from its references' mean adds no step to v; one that moves from its first sample
// is taken about its mean.  Truth by hand: a PD u = k_p e + k_d (e_k − e_{k−1}); filtering
// r − r̄ from rest on the first log would put (k_p + k_d)(0.3 − r̄) into v(0), the
// derivative's kick the loop never applied.
TEST(ReferenceIdentify, TheReferencesEnterAsDeviationsFromTheSetpointTheLoopStoodAt) {
  const double kp = 3.0, kd = 40.0;
  StateSpace pd;  // x = e_{k−1}: u = (k_p + k_d) e_k − k_d x
  pd.A = Eigen::MatrixXd::Zero(1, 1);
  pd.B = Eigen::MatrixXd::Ones(1, 1);
  pd.C = Eigen::MatrixXd::Constant(1, 1, -kd);
  pd.D = Eigen::MatrixXd::Constant(1, 1, kp + kd);
  pd.sample_period_s = 0.001;
  const auto pd_of = [&](const Eigen::VectorXd& r, double r0) {
    Eigen::VectorXd out(r.size());
    double prev = 0.0;
    for (Index k = 0; k < r.size(); ++k) {
      const double e = r(k) - r0;
      out(k) = kp * e + kd * (e - prev);
      prev = e;
    }
    return out;
  };
  Eigen::VectorXd at_rest = Eigen::VectorXd::Constant(40, 0.3);
  for (Index k = 12; k < 40; ++k) at_rest(k) = 0.3 - 0.02 * static_cast<double>(k - 11);
  const Eigen::MatrixXd v = reference_as_input_excitation(pd, at_rest);
  EXPECT_LE((v.col(0) - pd_of(at_rest, 0.3)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(v(0, 0), 0.0);
  Eigen::VectorXd moving(40);
  for (Index k = 0; k < 40; ++k) moving(k) = 0.3 * std::sin(0.2 * static_cast<double>(k) + 1.0);
  const Eigen::MatrixXd w = reference_as_input_excitation(pd, moving);
  EXPECT_LE((w.col(0) - pd_of(moving, moving.mean())).cwiseAbs().maxCoeff(), 1e-12);
}

// The friction axis of tests/support/friction_axis.h with its friction and offset zero
// is K / (s (τ s + 1)), K = k_f / c, τ = m / c; its exact ZOH sampling (the current is
// held between samples), derived by hand: w' = (K i − w) / τ, x' = w.
std::complex<double> linear_friction_axis(const friction_axis::Truth& t, double ts, double omega) {
  const double K = t.k_f_N_per_A / t.c_Ns_per_m, tau = t.m_kg / t.c_Ns_per_m, a = std::exp(-ts / tau);
  Eigen::Matrix2d A;
  A << 1.0, tau * (1 - a), 0.0, a;
  const Eigen::Vector2d B(K * (ts - tau * (1 - a)), K * (1 - a));
  const std::complex<double> z = std::polar(1.0, omega * ts);
  const Eigen::Matrix2cd M = z * Eigen::Matrix2cd::Identity() - A.cast<std::complex<double>>();
  return (M.inverse() * B.cast<std::complex<double>>())(0);
}

// The same axis as the simulator integrates it (friction_axis::linear_sample_map: its
// semi-implicit substeps, one linear map per sample): the truth for the simulator's logs.
std::complex<double> simulated_friction_axis(const friction_axis::Truth& t, double ts, double omega) {
  const friction_axis::SampleMap m = friction_axis::linear_sample_map(t, 1.0 / ts);
  const std::complex<double> z = std::polar(1.0, omega * ts);
  const Eigen::Matrix2cd M = z * Eigen::Matrix2cd::Identity() - m.A.cast<std::complex<double>>();
  return (M.inverse() * m.B.cast<std::complex<double>>())(0);
}

// Over plant_frd.csv's frequencies in [lo, hi] rad/s: the mean of |P^/P − 1| against
// the linear friction axis as the simulator integrates it, and the share whose 95 % band
// |P^ − P| <= 2 σ holds it.  (The simulator's integration and the exact ZOH, two
// derivations of the same axis, must agree to its integration error, 1e-4 relative at
// c h / m = 8e-5: checked here at every frequency, so neither is mistyped.)
std::pair<double, double> against_linear_friction_axis(const std::string& frd_path, const friction_axis::Truth& t,
                                                       double lo, double hi) {
  const FrequencyResponse frd = read_frd_csv(frd_path);
  double sum = 0.0;
  int inside = 0, total = 0;
  for (Index k = 0; k < frd.num_frequencies(); ++k) {
    const double w = frd.omega_rad_s(k);
    if (w < lo || w > hi) continue;
    const std::complex<double> p = simulated_friction_axis(t, 1e-3, w);
    EXPECT_LT(std::abs(linear_friction_axis(t, 1e-3, w) / p - 1.0), 2e-4) << w << " rad/s";
    const std::complex<double> e = frd.response[static_cast<std::size_t>(k)](0, 0);
    sum += std::abs(e / p - 1.0);
    inside += std::abs(e - p) <= 2.0 * std::sqrt(frd.variance[static_cast<std::size_t>(k)](0, 0));
    ++total;
  }
  EXPECT_GT(total, 50) << frd_path;
  return {sum / std::max(total, 1), static_cast<double>(inside) / std::max(total, 1)};
}

// The simulator's PD on e = r − enc (30 Hz, ζ 0.7, derivative filtered at 300 Hz) as a
// state space from e to the current, state [d_{k−1}, e_{k−1}].
void write_friction_axis_pd(const friction_axis::Truth& t, const std::string& path) {
  const double ts = 1e-3, wc = 2 * M_PI * 30.0, kp = t.m_kg * wc * wc, kd = 2 * 0.7 * t.m_kg * wc;
  const double a = std::exp(-2 * M_PI * 300.0 * ts), c = (1 - a) / ts, kf = t.k_f_N_per_A;
  std::ofstream(path) << nlohmann::json{{"type", "state_space"}, {"ts", ts},
                                        {"A", {{a, -c}, {0.0, 0.0}}}, {"B", {{c}, {1.0}}},
                                        {"C", {{kd * a / kf, -kd * c / kf}}}, {"D", {{(kp + kd * c) / kf}}}};
}

// dir/p2p.csv (t, r, i, enc): the friction axis with its friction and offset zero (a
// linear axis), point-to-point moves, PD on the encoder; dir/C.json that PD.  Returns
// the axis.
friction_axis::Truth write_linear_point_to_point(const std::filesystem::path& dir) {
  friction_axis::Truth t;
  t.coulomb_N = 0.0;
  t.offset_N = 0.0;
  friction_axis::Experiment e;
  e.point_to_point = true;
  friction_axis::write_csv(friction_axis::simulate(t, e), dir / "p2p.csv");
  write_friction_axis_pd(t, dir / "C.json");
  return t;
}

// The linear axis under a broadband reference (5 mm rms low-passed at 20 Hz about a 0.3 Hz
// sine), its position read with white noise of a 1 um quantiser's variance (0.289 um rms),
// seed 6 of ten drawn: the route through the loop's response takes order 4 with a pole
// at +15.6 rad/s, 48.6 % off the axis over 1-400 rad/s, and its output-error refinement
// brings the loop's simulation error from 109 to 0.0117 (from rest).  The refinement is
// kept only when it predicts held-out halves better; here the structured fit on a half
// failed (its tail rounds ran into a loop whose response overflows, then its bands into
// non-finite bins), and until stop 55 that failure kept the structured fit.  Now the
// tail rounds stop before an overflowing correction, and a half whose structured fit
// fails is compared with the whole logs' structured fit, which has seen it (a comparison
// that favours it).  Measured: kept (held-out error norm x0.00058), 0.0010 % mean error
// over 1-400 rad/s, the bands covering the axis at every frequency there.  (The other
// nine seeds: refinement kept, 0.0001-0.0016 %.)  Bound: 0.01 %, 10x the measured, 4800x
// below the failure.
TEST(ReferenceIdentify, ABroadbandReferenceWhoseHalfFitFailsStillKeepsTheRefinementThatFitsTheLogs) {
  TempDir dir("reference_broadband");
  friction_axis::Truth t;
  t.coulomb_N = 0.0;
  t.offset_N = 0.0;
  friction_axis::Experiment e;
  e.random_reference = true;
  e.seed = 6;
  e.white_position_noise_m = 1e-6 / std::sqrt(12.0);
  friction_axis::write_csv(friction_axis::simulate(t, e), dir / "log.csv");
  write_friction_axis_pd(t, dir / "C.json");
  const auto r = run_lpvid("identify --controller " + (dir / "C.json") +
                           " --excitation r --excitation-at reference --output enc --json --out " + (dir / "out") + " " +
                           (dir / "log.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  const std::string why = report["refinement"]["reason"].get<std::string>();
  EXPECT_TRUE(report["refinement"]["kept"].get<bool>()) << why;
  const auto [mean, covered] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 400.0);
  std::printf("broadband reference, seed 6: order %d, mean error %.4f %% over 1-400 rad/s, bands covering %.2f; %s\n",
              report["plant"]["order"].get<int>(), 100 * mean, covered, why.substr(why.rfind(';') + 1).c_str());
  EXPECT_LE(mean, 1e-4);
  EXPECT_GE(covered, 0.9);
}

// Point-to-point moves (minimum-jerk, with rests: how an industrial axis is exercised,
// and issue 24's held-out axis) excite a handful of frequencies: the loop's response over
// the horizon is not determined by them, even noise-free (measured on this log: least
// squares' 512 lags 54 % off the true closed loop, the regularised estimate 19 %), and
// the route through it finds no plant.  The plant itself is low order and the moves do
// determine it: the direct route (idlib/identify/direct.h) fits strictly proper ARX
// starts to the input the loop applied, u = C(r − q), and refines each by output error
// in its loop, simulated from the references (so the encoder noise the feedback returns
// to u does not bias it).  Measured: order 2 (the truth's), mean error against the axis as
// the simulator integrates it (friction_axis::linear_sample_map; the exact ZOH differs
// from it by 4e-5, which this fit resolves: against the ZOH the bands held only 6 %)
// 0.0005 % over 1–10 rad/s, 0.0070 % over 10–60, 0.048 % over 60–400, the loop's
// simulation fit 100.0 %.  The bound, 0.2 % over 1–400 rad/s, is 10× the measured mean
// and 25× below the Welch-leakage errors the structured route's failure came from.  The
// band's coverage is not asserted: the residual is the encoder's quantisation, and the
// sandwich's segments understate the error from one quantisation to the next (not
// through the 12.2 s cycle's repetition: the residual's autocorrelation beyond a segment
// stays below 0.3 on the worst-covered logs; why is open).  Measured over ten encoder
// steps 0.8–1.25 µm: 61 % of the frequencies covered (36 % with the sandwich's former
// fixed 8 segments; here 65 segments, the residual's correlation time allowing the
// shortest), all-or-nothing per log.  With white noise of the quantiser's variance
// instead: 93 %, but the mean squared error 2.0-2.1x the predicted variance above 10
// rad/s over ten draws (0.32x below): the bands are too narrow on these moves even
// for white noise (subcommands.md, identify).
// With --no-direct the route's refusal stands: one line, the excitation named as why,
// nothing written.  The log: tests/support/friction_axis.h, its friction and offset
// zero (a linear axis), PD on the encoder.
TEST(ReferenceIdentify, PointToPointMovesAreIdentifiedByTheDirectRouteInTheLoop) {
  TempDir dir("reference_p2p");
  const friction_axis::Truth t = write_linear_point_to_point(dir.path());
  const std::string args = "identify --controller " + (dir / "C.json") +
                           " --excitation r --excitation-at reference --output enc --json " + (dir / "p2p.csv");
  const auto refused = run_lpvid(args + " --no-direct --out " + (dir / "refused"));
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_THAT(refused.err, HasSubstr("the excitation does not determine the loop's response"));
  EXPECT_THAT(refused.err, HasSubstr("add broadband excitation"));
  EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "refused")) << "a failed identify left its output directory";

  const auto r = run_lpvid(args + " --out " + (dir / "out"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  ASSERT_TRUE(report["direct"].is_object()) << r.out.substr(0, 400);
  EXPECT_EQ(report["direct"]["reading"], "applied");
  EXPECT_THAT(report["route"].get<std::string>(), HasSubstr("direct"));
  EXPECT_THAT(report["direct"]["why"].get<std::string>(), HasSubstr("the excitation does not determine"));
  EXPECT_EQ(report["plant"]["order"], 2) << report["fit"]["order_reason"];
  EXPECT_TRUE(std::filesystem::exists(dir / "out/closed_loop.json"));
  const auto [mean, covered] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 400.0);
  std::printf("point-to-point, direct route: order %d, mean error %.4f %% over 1-400 rad/s, band covering %.2f\n",
              report["plant"]["order"].get<int>(), 100 * mean, covered);
  EXPECT_LE(mean, 0.002);
}

// The same point-to-point moves on the axis WITH its Coulomb friction (6.5 N) and force
// offset (2.8 N), as a real positioning axis has them (issue 24's held-out axis; issue
// 26's published axis models reach their figures with viscous + Coulomb friction and an
// offset).  Fitted linearly, the direct route gives the loop's best linear approximation,
// 40–61 % off the linear part, and the residual follows the sign of the velocity (the
// summary's nonlinearity test).  identify then fits the plant again with friction beside
// it (direct.h): inputs sign(velocity) and a constant next to u, the rests — where the
// stuck axis's friction holds whatever balances it — and the loop's settling after each
// left out of the criterion.  Measured: order 2, the linear part 0.0074 % mean off the
// exact ZOH axis over 1–400 rad/s (0.0037 % over 1–10), bands covering it at 95 % of the
// frequencies; the friction as a force at the input 0.6500 A against the motion — the
// simulator's 6.5 N / k_f 10 N/A.  (Seed 11 with 3 N and −1 N: 0.020 %, 0.300 A.)
// Bounds: the linear part within 0.1 % mean (13× the measured; the linear fit is 40 % off),
// the band covering >= 0.8; the Coulomb force within 2 % of the truth's (the estimate is
// the loop's steady response to the sign input, set by every move's standing error).
// No force offset is reported: a constant force moves the loop's output by a constant,
// which each log's free output offset takes too (the constant column fitted beside the
// plant came out 0.0236 for this axis's 2.8 N and 0.0229 for none): the summary says so.
TEST(ReferenceIdentify, AFrictionAxisIsIdentifiedWithItsFrictionBesideThePlant) {
  TempDir dir("reference_friction");
  const friction_axis::Truth t;  // Coulomb 6.5 N, offset 2.8 N
  friction_axis::Experiment e;
  e.point_to_point = true;
  friction_axis::write_csv(friction_axis::simulate(t, e), dir / "p2p.csv");
  write_friction_axis_pd(t, dir / "C.json");
  const auto r = run_lpvid("identify --controller " + (dir / "C.json") +
                           " --excitation r --excitation-at reference --output enc --out " + (dir / "out") + " " +
                           (dir / "p2p.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("friction: the linear plant's residual followed the sign of the velocity"));
  EXPECT_THAT(r.out, HasSubstr("the friction fitted beside it is what they miss"));
  EXPECT_THAT(r.out, HasSubstr("the constant force is not given: the logs cannot tell it from the encoder's offset"));
  const auto report = nlohmann::json::parse(std::ifstream(dir / "out/report.json"));
  ASSERT_TRUE(report["direct"]["friction"].is_object()) << report["direct"].dump();
  EXPECT_FALSE(report["direct"]["friction"].contains("offset")) << report["direct"]["friction"].dump();
  EXPECT_EQ(report["plant"]["order"], 2) << report["fit"]["order_reason"];
  const double coulomb = report["direct"]["friction"]["coulomb"][0][0].get<double>();
  EXPECT_NEAR(coulomb, -t.coulomb_N / t.k_f_N_per_A, 0.02 * t.coulomb_N / t.k_f_N_per_A);
  const auto [mean, covered] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 400.0);
  std::printf("friction axis, direct route with friction: mean error %.4f %% over 1-400 rad/s, band covering %.2f, "
              "Coulomb %.4f A\n", 100 * mean, covered, coulomb);
  EXPECT_LE(mean, 0.001);
  EXPECT_GE(covered, 0.8);
}

// A reference of two sines (issue 24: "few-sine references"), as an axis is often
// exercised: the friction axis (Coulomb 6.5 N, offset 2.8 N) tracking 0.1 sin(2π 0.4 t)
// + 0.03 sin(2π 1.3 t + 1) m under its PD, 30 s.  Two lines do not determine the loop's
// 512-lag response, so the route through it finds no plant; the direct route does, with
// the friction beside it.  Measured: order 2, the linear part 0.0007 % mean off the axis
// as the simulator integrates it over 1–400 rad/s, the bands covering it at every
// frequency, the Coulomb force 0.64999 A for the simulator's 0.65 (the linear axis on the
// same reference: 0.0006 %, bands covering 81 %).  Bounds: 0.01 % mean (14× the
// measured), the Coulomb force to 1 % (65× the measured), coverage >= 0.8.
TEST(ReferenceIdentify, AReferenceOfTwoSinesIsIdentifiedByTheDirectRouteWithTheFriction) {
  TempDir dir("reference_sines");
  const friction_axis::Truth t;  // Coulomb 6.5 N, offset 2.8 N
  friction_axis::Experiment e;  // both_ways: the two sines
  friction_axis::write_csv(friction_axis::simulate(t, e), dir / "sines.csv");
  write_friction_axis_pd(t, dir / "C.json");
  const auto r = run_lpvid("identify --controller " + (dir / "C.json") +
                           " --excitation r --excitation-at reference --output enc --json --out " + (dir / "out") +
                           " " + (dir / "sines.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  ASSERT_TRUE(report["direct"].is_object()) << r.out.substr(0, 400);
  EXPECT_EQ(report["plant"]["order"], 2) << report["fit"]["order_reason"];
  ASSERT_TRUE(report["direct"]["friction"].is_object()) << report["direct"].dump();
  const double coulomb = report["direct"]["friction"]["coulomb"][0][0].get<double>();
  const auto [mean, covered] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 400.0);
  std::printf("two sines, direct route with friction: mean error %.4f %% over 1-400 rad/s, band covering %.2f, "
              "Coulomb %.5f A\n", 100 * mean, covered, coulomb);
  EXPECT_LE(mean, 1e-4);
  EXPECT_GE(covered, 0.8);
  EXPECT_NEAR(coulomb, -t.coulomb_N / t.k_f_N_per_A, 0.01 * t.coulomb_N / t.k_f_N_per_A);
}

// A drive's logged command given as the "excitation" (issue 24's held-out axis was run
// as `identify --controller C.json --excitation v --output q`, v the drive's command):
// the loop as declared (v added to the controller's output) fits no plant, so the route
// through the loop's response fails.  The direct route then reads the column as the
// plant's own input: strictly proper ARX starts refined as open-loop data.  (It does not
// fit the declared loop, u = v + C(−q): on the same axis with Coulomb friction that
// reading closed a stable loop with a plant 100 % off — here its starts closed none.)  Measured on the linear friction axis's logged current (with its
// sensor's noise, 5 mA): order 2, mean error 0.067 % over 1–10 rad/s and 0.88 % over
// 10–60 (the moves carry little power there), the band covering the truth at every
// frequency of 1–400 rad/s, simulation fit 99.9 %.  Bounds: 2 % over 1–60 rad/s (the
// mean there measured 0.5 %), coverage >= 0.9.
TEST(ReferenceIdentify, ADrivesLoggedCommandGivenAsTheExcitationIsReadAsThePlantsInput) {
  TempDir dir("reference_command");
  const friction_axis::Truth t = write_linear_point_to_point(dir.path());
  const auto r = run_lpvid("identify --controller " + (dir / "C.json") + " --excitation i --output enc --json --out " +
                           (dir / "out") + " " + (dir / "p2p.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  ASSERT_TRUE(report["direct"].is_object()) << r.out.substr(0, 400);
  EXPECT_EQ(report["direct"]["reading"], "excitation is the input");
  ASSERT_EQ(report["direct"]["readings"].size(), 1u);  // the declared input-side loop is not read (cli/identify.cc)
  EXPECT_EQ(report["plant"]["order"], 2) << report["fit"]["order_reason"];
  const auto [mean, covered_low] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 60.0);
  const auto [mean_all, covered] = against_linear_friction_axis(dir / "out/plant_frd.csv", t, 1.0, 400.0);
  std::printf("drive command as excitation: mean error %.4f %% over 1-60 rad/s (%.4f %% to 400), bands covering "
              "%.2f\n", 100 * mean, 100 * mean_all, covered);
  EXPECT_LE(mean, 0.02);
  EXPECT_GE(covered, 0.9);
  EXPECT_GE(covered_low, 0.9);
}

TEST(ReferenceIdentifyUsage, ReferencesThatDoNotFitTheLoopAreRefusedInOneLine) {
  TempDir dir("reference_usage");
  write_files(dir.path());
  const std::string tail = " --out " + (dir / "out") + " " + (dir / "axis.csv");
  auto r = run_lpvid("identify --controller " + (dir / "controller.json") +
                     " --excitation r,u --excitation-at reference --output q" + tail);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--excitation-at reference: 2 reference column(s) for 1 output(s); give one reference "
                               "per --output"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1);
  r = run_lpvid("identify --controller " + (dir / "controller.json") + " --excitation r --excitation-at setpoint --output q" +
                tail);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--excitation-at setpoint: use 'input'"));
  r = run_lpvid("identify --open-loop --excitation r --excitation-at reference --output q" + tail);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--excitation-at reference needs the loop's controller"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

}  // namespace reference_identify_test
}  // namespace lpvid
