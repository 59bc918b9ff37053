// lpvid on real measured data (../shared/real-data, see tests/support/real_data.h):
// skipped with a message when the data are absent.  Truth from outside the code under
// test where there is one; otherwise an independent estimator on the same file.
//
// F-16 ground vibration test (f16_gvt/README.md): periodic full-grid multisine, 9 periods
// of 8192 samples at 400 Hz, the generator voltage measured (the reference, with ADC
// noise), the shaker force measured (the plant input) and 3 accelerations.  The periodic
// FRF (period means, errors-in-variables variance) must accept the measured reference
// and agree with the Local Polynomial Method (lpm.h, transient-removing, one DFT of the
// whole record) at the excited lines: two different estimators on the same data.
//
// DaISy robot arm (daisy_robot_arm/README.md): 1024 samples, sample time unknown (t =
// sample index, Ts = 1): markov's default horizon must come from the data in samples.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "formats/io/frd_csv.h"
#include "formats/io/markov_csv.h"
#include "tests/support/real_data.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace real_data_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::TempDir;

const std::string kF16Channels = "--excitation voltage --input force --output acc1,acc2,acc3 --quantity P ";
const std::string kF16Layout = "--method periodic --period-samples 8192 --periods 8 --transient-periods 1 ";

double median(std::vector<double> x) {
  std::nth_element(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(x.size() / 2), x.end());
  return x[x.size() / 2];
}

TEST(RealData, F16PeriodicFrfAcceptsTheMeasuredReferenceAndAgreesWithLpm) {
  LPVID_REAL_DATA_OR_SKIP(log, "f16_gvt/f16_fullmsine_level1.csv");
  TempDir dir("f16");
  const std::string per = dir / "P_periodic.csv", lpm = dir / "P_lpm.csv";
  auto r = run_lpvid("frf " + kF16Layout + kF16Channels + "--json --out " + per + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto summary = nlohmann::json::parse(r.out);
  // The README's excited lines, found here from the measured voltage: bins 41..307.
  EXPECT_EQ(summary["lines"], 267);
  EXPECT_EQ(summary["measured_excitation"], true);
  // The voltage's period mean stands ~3e8 above its scatter (f16_gvt README: it repeats
  // to 2e-4 of its norm); 1e6 is far above the refusal threshold and far below that.
  EXPECT_GT(summary["excitation_periodicity"].get<double>(), 1e6);
  r = run_lpvid("frf --method lpm " + kF16Channels + "--out " + lpm + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;

  const FrequencyResponse p = read_frd_csv(per, {"P"}), l = read_frd_csv(lpm, {"P"});
  ASSERT_EQ(p.num_frequencies(), 267);
  EXPECT_NEAR(p.omega_rad_s(0) / (2 * std::numbers::pi), 41 * 400.0 / 8192, 1e-9);
  EXPECT_NEAR(p.omega_rad_s(266) / (2 * std::numbers::pi), 307 * 400.0 / 8192, 1e-9);
  // The LPM's grid is the whole record's DFT (73728 = 9 × 8192 points): line k of a
  // period is its bin 9k.
  std::vector<double> relative, sigmas, variance_ratio;
  for (Index k = 0; k < p.num_frequencies(); ++k) {
    Index best = 0;
    for (Index i = 1; i < l.num_frequencies(); ++i)
      if (std::abs(l.omega_rad_s(i) - p.omega_rad_s(k)) < std::abs(l.omega_rad_s(best) - p.omega_rad_s(k))) best = i;
    ASSERT_NEAR(l.omega_rad_s(best), p.omega_rad_s(k), 1e-9 * p.omega_rad_s(k));
    for (Index i = 0; i < 3; ++i) {
      const auto a = p.response[static_cast<size_t>(k)](i, 0), b = l.response[static_cast<size_t>(best)](i, 0);
      relative.push_back(std::abs(a - b) / std::abs(b));
      sigmas.push_back(std::abs(a - b) / std::sqrt(p.variance[static_cast<size_t>(k)](i, 0)));
      variance_ratio.push_back(p.variance[static_cast<size_t>(k)](i, 0) / l.variance[static_cast<size_t>(best)](i, 0));
    }
  }
  const double med = median(relative), vr = median(variance_ratio);
  double within1 = 0, within2 = 0;
  for (double s : sigmas) {
    within1 += s <= 1 ? 1.0 : 0.0;
    within2 += s <= 2 ? 1.0 : 0.0;
  }
  const double n = static_cast<double>(sigmas.size());
  std::printf("F-16 level 1, 267 lines x 3 outputs: median |periodic - lpm| / |lpm| = %.3g %%; within 1 / 2 sigma of "
              "the periodic estimate: %.3f / %.3f; median var_periodic / var_lpm %.3f\n",
              100 * med, within1 / n, within2 / n, vr);
  // Measured: 0.049 % (the issue: LPM agrees with the textbook periodic estimate to
  // 0.04 %); 0.1 % is twice that and still 3x below the periodic estimate's own median
  // relative sd (0.14 %).
  EXPECT_LT(med, 1e-3);
  // Measured 0.999 and 1.000 (the two estimators see the same noise, so they differ by
  // less than either's sd; the worst line is an anti-resonance at 5.66 Hz, |P| 4.5e-5
  // with a 50 % sd, off by 0.94 sd).
  EXPECT_GE(within1 / n, 0.9);
  EXPECT_GE(within2 / n, 0.98);
  // The sd is not inflated: two independent noise estimates — the period-to-period
  // scatter (periodic, 7 complex dof per line) and the LPM's local residuals (7 dof) —
  // agree: measured median ratio 0.92; the median over 801 entries of a ratio of two
  // 7-dof estimates is within ±10 % of its centre, so [0.7, 1.4] flags a 40 % error.
  EXPECT_GT(vr, 0.7);
  EXPECT_LT(vr, 1.4);
}

TEST(RealData, F16PeriodicFrfRefusesAWrongPeriodLength) {
  LPVID_REAL_DATA_OR_SKIP(log, "f16_gvt/f16_fullmsine_level1.csv");
  TempDir dir("f16bad");
  for (const char* L : {"8000", "8191"}) {
    const auto r = run_lpvid(std::string("frf --method periodic --period-samples ") + L +
                             " --periods 8 --transient-periods 1 " + kF16Channels + "--out " + (dir / "P.csv") + " " +
                             log);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr(std::string("with ") + L + " samples"));
    EXPECT_THAT(r.err, HasSubstr("check --period-samples"));
    EXPECT_FALSE(std::filesystem::exists(dir / "P.csv"));
  }
}

TEST(RealData, RobotArmMarkovDefaultHorizonComesFromTheDataInSamples) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("arm");
  const auto r = run_lpvid("markov --excitation u --output y --json --out " + (dir / "g.csv") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // 1024 samples, one input: min(1024 / 4, 1024 / 4) = 256 lags, whatever Ts is.
  EXPECT_EQ(nlohmann::json::parse(r.out)["lags"], 256);
  EXPECT_EQ(read_markov_csv(dir / "g.csv").g.size(), 257u);
  // A horizon in seconds on a log whose time is the sample index: refused, saying so
  // without contradicting itself (2 s is 2 lags at Ts = 1 s).
  const auto h = run_lpvid("markov --excitation u --output y --horizon-s 2 --out " + (dir / "h.csv") + " " + log);
  EXPECT_EQ(h.exit_code, 2);
  EXPECT_THAT(h.err, HasSubstr("the horizon of 2 s is only 2 lag(s) at the logs' sample time 1 s, fewer than 10; give "
                               "--lags, or a --horizon-s of at least 10 s"));
}

// markov's default on the robot arm: the arm's slowest mode (|z| 0.999) has not died out
// within the 256 lags a 1024-sample record supports, so least squares' last lags hold
// its tail (lag 256: 0.235 where the response is about −0.03); the default then compares
// least squares with the ARX estimate on data neither saw (each half predicting the
// other: 27.4 % and 3.07 % of the output energy missed, measured) and takes the ARX one.
// realize then gives order 6, stable, which simulates the record to 96.7 % with its
// initial state fitted (compare's default 'e') and 82.3 % from zero state; the least-
// squares route gave order 4 and 84.9 % / 84.6 %.  Reference: SLICOT n4sid (n = 4, s = 20)
// 89.3 % (the figure, its initial-state convention not stated).  Bounds: the
// choice made and said; stable; 'e' above n4sid's figure (95 % asserted); the ARX route
// through --method arx and its --arx-order; --arx-order without it refused.
TEST(RealData, RobotArmMarkovDefaultTakesTheArxEstimateWhenLeastSquaresIsTruncated) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("arm_arx");
  const auto r = run_lpvid("markov --excitation u --output y --json --out " + (dir / "g.csv") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto js = nlohmann::json::parse(r.out);
  EXPECT_EQ(js["method"], "arx");
  const std::string why = js["method_reason"].get<std::string>();
  std::printf("robot arm markov: %s\n", why.c_str());
  EXPECT_THAT(why, HasSubstr("has not died out within 256 lags"));
  EXPECT_THAT(why, HasSubstr("each half of the records predicted from the other"));
  const auto z = run_lpvid("realize --json " + (dir / "g.csv") + " --out " + (dir / "model.json"));
  ASSERT_EQ(z.exit_code, 0) << z.err;
  const auto c = run_lpvid("compare --json --log " + log + " --model " + (dir / "model.json"));
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto cs = nlohmann::json::parse(c.out);
  const double fe = cs["fit_percent"]["y"].get<double>(), fz = cs["fit_zero_state_percent"]["y"].get<double>();
  std::printf("robot arm markov + realize: order %d, fit %.2f %% with the initial state ('e'), %.2f %% from zero "
              "state (n4sid, n = 4: 89.3 %%)\n",
              nlohmann::json::parse(z.out)["order"].get<int>(), fe, fz);
  EXPECT_EQ(cs["stable"], true);
  EXPECT_GT(fe, 95.0);
  const auto given = run_lpvid("markov --method arx --arx-order 20 --excitation u --output y --json --out " +
                               (dir / "g20.csv") + " " + log);
  ASSERT_EQ(given.exit_code, 0) << given.err;
  EXPECT_EQ(nlohmann::json::parse(given.out)["arx_order"], 20);
  const auto bad = run_lpvid("markov --arx-order 20 --excitation u --output y --out " + (dir / "bad.csv") + " " + log);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_THAT(bad.err, HasSubstr("--arx-order 20 is for --method arx"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.csv"));
}

// The DaISy raw .mat as the lab saved it (one unnamed 1024 x 2 matrix, no rate): markov
// reads it with the names and rate given on the command line and writes the very Markov
// parameters it writes from the CSV export (the same doubles, made from it by numpy).
TEST(RealData, RobotArmRawMatWithNamesAndRateOnTheCommandLineGivesTheCsvsMarkovParameters) {
  LPVID_REAL_DATA_OR_SKIP(mat, "daisy_robot_arm/raw/robot_arm_dat.mat");
  LPVID_REAL_DATA_OR_SKIP(csv, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("armmat");
  const auto bare = run_lpvid("markov --excitation u --output y --out " + (dir / "bare.csv") + " " + mat);
  EXPECT_EQ(bare.exit_code, 2);
  EXPECT_THAT(bare.err, HasSubstr("the file holds: robot_arm_dat"));
  const auto a = run_lpvid("markov --log-columns u,y --log-rate 1 --excitation u --output y --out " + (dir / "a.csv") +
                           " " + mat);
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const auto b = run_lpvid("markov --excitation u --output y --out " + (dir / "b.csv") + " " + csv);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const MarkovSequence ga = read_markov_csv(dir / "a.csv").g, gb = read_markov_csv(dir / "b.csv").g;
  ASSERT_EQ(ga.size(), gb.size());
  double worst = 0, peak = 0;
  for (std::size_t k = 0; k < ga.size(); ++k) {
    worst = std::max(worst, (ga[k] - gb[k]).cwiseAbs().maxCoeff());
    peak = std::max(peak, gb[k].cwiseAbs().maxCoeff());
  }
  // The CSV holds the .mat's doubles written bit-exact (README): equal to rounding.
  EXPECT_LE(worst, 1e-12 * peak);
  // Names and rate for a file that has its own: refused, nothing written.
  const auto c = run_lpvid("markov --log-columns u,y --log-rate 1 --excitation u --output y --out " + (dir / "c.csv") +
                           " " + csv);
  EXPECT_EQ(c.exit_code, 2);
  EXPECT_THAT(c.err, HasSubstr("a CSV log names its channels and its time t in its header"));
  EXPECT_FALSE(std::filesystem::exists(dir / "c.csv"));
}

// The benchmark's nonlinearity (f16_gvt/README.md, Noël & Schoukens 2017): the wing
// torsion mode near 7.3 Hz softens and damps as the excitation level rises.  The periodic
// FRF of level 1 and of level 7 must show it beyond both estimates' own noise: the peak
// of |P| in 6.5-8 Hz moves down by at least one line (0.049 Hz) and its height falls by
// far more than the standard deviations there.  Measured: 7.324 -> 7.227 Hz on all
// three accelerations, |P| at the peak 0.270 -> 0.083 (acc2; sd 0.0003 / 0.0007).
// One full-grid realisation per level cannot separate the distortion from the linear
// part: this is the BLA at each level, and frf says so ("one realisation").
// markov + realize with the defaults on the F-16 (force -> three accelerations, level 1,
// 73 728 samples at 400 Hz, a multisine on 2–15 Hz only): least squares cannot be solved
// (no power above 15 Hz), so the regularised estimate; ERA at order 40 is unstable with
// |z| = 4.71, whose response overflows over the 2000 lags.  Its error against the Markov
// parameters was NaN, every comparison with it false, and realize wrote it unstable
// ("the stable model fits worse"): compare --log could not simulate it.  Now the stable
// refit is written.  Truth: the validation record (level 2), which no estimate saw.
// Measured: 52.7 / 38.7 / 35.7 % on level 1 and 55.5 / 42.9 / 39.9 % on level 2 (from zero
// state).  Bounds: stable, and each output better than its mean on the validation record
// by a margin (20 %) no diverging or empty model reaches.
TEST(RealData, F16MarkovRealizeWritesAStableModelThatPredictsTheValidationRecord) {
  LPVID_REAL_DATA_OR_SKIP(log, "f16_gvt/f16_fullmsine_level1.csv");
  LPVID_REAL_DATA_OR_SKIP(validation, "f16_gvt/f16_fullmsine_level2_validation.csv");
  TempDir dir("f16_era");
  const std::string io = " --excitation force --output acc1,acc2,acc3 ";
  const auto m = run_lpvid("markov --json --out " + (dir / "g.csv") + io + log);
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_EQ(nlohmann::json::parse(m.out)["method"], "regularized");
  const auto r = run_lpvid("realize --json " + (dir / "g.csv") + " --out " + (dir / "model.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto rs = nlohmann::json::parse(r.out);
  ASSERT_FALSE(rs["stabilized"].is_null()) << r.out;
  EXPECT_EQ(rs["stabilized"]["used"], true) << rs["stabilized"]["reason"];
  const auto c = run_lpvid("compare --json --log " + validation + " --model " + (dir / "model.json") +
                           " --input force --output acc1,acc2,acc3");
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto cs = nlohmann::json::parse(c.out);
  EXPECT_EQ(cs["stable"], true);
  for (const std::string y : {"acc1", "acc2", "acc3"}) {
    const double fit = cs["fit_zero_state_percent"][y].get<double>();
    std::printf("F-16 markov + realize (order %d), validation record, %s: %.2f %% from zero state\n",
                rs["order"].get<int>(), y.c_str(), fit);
    EXPECT_GT(fit, 20.0) << y;
  }
}

TEST(RealData, F16WingTorsionModeSoftensAndDampsFromLevel1ToLevel7) {
  LPVID_REAL_DATA_OR_SKIP(low, "f16_gvt/f16_fullmsine_level1.csv");
  LPVID_REAL_DATA_OR_SKIP(high, "f16_gvt/f16_fullmsine_level7.csv");
  TempDir dir("f16levels");
  struct Peak {
    double hz = 0, magnitude = 0, sd = 0;
  };
  auto peaks = [&](const std::string& log, const std::string& name) {
    const std::string out = dir / name;
    const auto r = run_lpvid("frf " + kF16Layout + kF16Channels + "--out " + out + " " + log);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_THAT(r.out, HasSubstr("one realisation"));
    const FrequencyResponse p = read_frd_csv(out, {"P"});
    std::vector<Peak> best(3);
    for (Index k = 0; k < p.num_frequencies(); ++k) {
      const double hz = p.omega_rad_s(k) / (2 * std::numbers::pi);
      if (hz < 6.5 || hz > 8.0) continue;
      for (Index i = 0; i < 3; ++i) {
        const double a = std::abs(p.response[static_cast<size_t>(k)](i, 0));
        if (a > best[static_cast<size_t>(i)].magnitude)
          best[static_cast<size_t>(i)] = {hz, a, std::sqrt(p.variance[static_cast<size_t>(k)](i, 0))};
      }
    }
    return best;
  };
  const auto one = peaks(low, "P1.csv"), seven = peaks(high, "P7.csv");
  for (std::size_t i = 0; i < 3; ++i) {
    std::printf("F-16 acc%zu: torsion peak %.4f Hz |P| %.4g (sd %.2g) at level 1, %.4f Hz |P| %.4g (sd %.2g) at level 7\n",
                i + 1, one[i].hz, one[i].magnitude, one[i].sd, seven[i].hz, seven[i].magnitude, seven[i].sd);
    EXPECT_LE(seven[i].hz, one[i].hz - 0.048);  // at least one line (400/8192 Hz) lower
    EXPECT_GT(one[i].magnitude - seven[i].magnitude, 20.0 * std::hypot(one[i].sd, seven[i].sd));
  }
}

// The model-error loop on the F-16 (issue 26): a mechanical base described by the user
// (samples/mechanical/f16_gvt.json: the driving point's mass line, accelerometers) fitted
// to the periodic FRF with its own variance; diagnose names one structural mode at a
// time.  Truth from outside the code: the benchmark's wing-torsion mode "around 7.3 Hz"
// (Noël & Schoukens 2017) and the FRF's own peak, 7.324 Hz at level 1 (f16_gvt/README.md,
// computed with numpy).  Measured: the first mode named is the torsion mode, 46.00 rad/s
// (7.32 Hz), zeta 0.0045-0.0056; the error 79.2 % -> 62.9 % -> 56.3 % with the second
// (57.6 rad/s, 9.17 Hz; the torsion mode then 46.01 ± 0.01 rad/s, zeta 0.0051 ± 0.0002).
// That model refitted to level 7 puts the torsion mode at 45.02 ± 0.13 rad/s (7.17 Hz)
// with zeta 0.026 ± 0.003: softened and damped, the benchmark's nonlinearity, far beyond
// both fits' standard errors.  Not reached (said in
// docs/real-data.md): the loop stops at the third mode, whose best fit is a broad patch
// over the close pair at 3.3/3.8 Hz; the floor (1.5 %) is not approached.
TEST(RealData, F16LoopNamesTheTorsionModeThenTheNextAndTheModeSoftensAtLevel7) {
  LPVID_REAL_DATA_OR_SKIP(low, "f16_gvt/f16_fullmsine_level1.csv");
  LPVID_REAL_DATA_OR_SKIP(high, "f16_gvt/f16_fullmsine_level7.csv");
  TempDir dir("f16loop");
  const std::string p1 = dir / "P1.csv", p7 = dir / "P7.csv";
  for (const auto& [log, out] : {std::pair{low, p1}, std::pair{high, p7}}) {
    const auto r = run_lpvid("frf " + kF16Layout + kF16Channels + "--out " + out + " " + log);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const std::string description = std::string(LPVID_SOURCE_DIR) + "/samples/mechanical/f16_gvt.json";
  auto r = run_lpvid("model init --base mechanical --from " + description + " --out " + (dir / "start.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // the force is measured at an impedance head, not a held command: the continuous response
  const std::string data = " --data " + p1 + " --measured-input";
  auto fit = [&](const std::string& model, const std::string& out, const std::string& d) {
    const auto f = run_lpvid("fit --model " + model + d + " --out " + out);
    EXPECT_EQ(f.exit_code, 0) << f.err;
    EXPECT_THAT(f.err, ::testing::Not(HasSubstr("ZOH")));
    return nlohmann::json::parse(std::ifstream(out))["fit"];
  };
  auto estimate = [](const nlohmann::json& f, const std::string& name) {
    for (const auto& [key, p] : f["parameters"].items())
      if (key == name) return std::pair<double, double>{p["estimate"].get<double>(), p["std_error"].get<double>()};
    ADD_FAILURE() << "no parameter " << name;
    return std::pair<double, double>{NAN, NAN};
  };
  const auto f0 = fit(dir / "start.json", dir / "fit0.json", data);
  r = run_lpvid("diagnose --model " + (dir / "fit0.json") + data + " --out " + (dir / "step1.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  EXPECT_THAT(r.out, HasSubstr("missing: structural_mode "));
  EXPECT_THAT(r.out, HasSubstr("one of several modes"));
  const auto f1 = fit(dir / "step1.json", dir / "fit1.json", data);
  const auto [w1, sw1] = estimate(f1, "mode_frequency_rad_s");
  const auto [z1, sz1] = estimate(f1, "mode_damping");
  std::printf("F-16 level 1: torsion mode %.4f ± %.4f rad/s (%.4f Hz), zeta %.4f ± %.4f; error %.2f %% -> %.2f %%\n",
              w1, sw1, w1 / (2 * std::numbers::pi), z1, sz1, 100 * f0["error"].get<double>(),
              100 * f1["error"].get<double>());
  // the benchmark's "around 7.3 Hz", within two lines (0.1 Hz) of the FRF's 7.324 Hz peak
  EXPECT_NEAR(w1 / (2 * std::numbers::pi), 7.324, 0.1);
  EXPECT_LT(z1, 0.02);  // lightly damped (the FRF's half-power width is ~0.08 Hz)
  EXPECT_LT(f1["error"].get<double>(), f0["error"].get<double>());
  r = run_lpvid("diagnose --model " + (dir / "fit1.json") + data + " --out " + (dir / "step2.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
  EXPECT_THAT(r.out, HasSubstr("missing: structural_mode_2 "));
  const auto f2 = fit(dir / "step2.json", dir / "fit2.json", data);
  const auto [w2, sw2] = estimate(f2, "mode_frequency_rad_s");
  const auto [z2, sz2] = estimate(f2, "mode_damping");
  std::printf("F-16 level 1: second mode %.4f rad/s; error %.2f %%; torsion mode %.4f ± %.4f rad/s, zeta %.4f ± %.4f\n",
              estimate(f2, "mode_2_frequency_rad_s").first, 100 * f2["error"].get<double>(), w2, sw2, z2, sz2);
  EXPECT_LT(f2["error"].get<double>(), f1["error"].get<double>());
  // level 7: the level-1 model of step 2 refitted (with one mode only, the torsion mode
  // also stands in for the 9.2 Hz one and comes out at zeta 0.068)
  const auto f7 = fit(dir / "fit2.json", dir / "fit7.json", " --data " + p7 + " --measured-input");
  const auto [w7, sw7] = estimate(f7, "mode_frequency_rad_s");
  const auto [z7, sz7] = estimate(f7, "mode_damping");
  std::printf("F-16 level 7: torsion mode %.4f ± %.4f rad/s (%.4f Hz), zeta %.4f ± %.4f\n", w7, sw7,
              w7 / (2 * std::numbers::pi), z7, sz7);
  EXPECT_LT(w7, w2 - 3 * std::hypot(sw2, sw7));  // softened beyond 3 standard errors
  EXPECT_GT(z7, z2 + 3 * std::hypot(sz2, sz7));  // and more damped
}

// The same loop with the model error in the weights (fit and diagnose --weighting auto;
// docs/math.md, "Weights when the model fails"), as docs/real-data.md runs it: weighted
// by the noise alone the third mode (3.47 Hz) raised the error figure from 56.3 % to
// 99 % and the loop stopped; with the model error in the weights every step names a
// further mode until the library's eight are in.  Truth from outside the code: the
// benchmark's wing-torsion mode "around 7.3 Hz" (Noël & Schoukens 2017), and the poles
// of a rational fit of the same FRF by vector fitting in numpy (common poles, complex
// residues, 24 pole pairs; not lpvid code): 1.86, 3.47, 3.96, 5.19, 6.62, 7.32, 9.17 Hz
// among them.  Measured (this machine): 79.2 % (mass line) -> 62.5 -> 54.8 -> 47.2 ->
// 39.8 -> 34.4 -> 25.5 -> 23.5 -> 6.77 % with the eighth mode, against a floor of
// 1.48 %; the modes at 1.878, 3.470, 3.971, 5.185, 6.614, 7.320, 9.166 and 20.8 Hz; about
// 100 s alone (five minutes before the fit kept its derivative arrays between calls).
// Bounds: every step names a mode and lowers the error; the end within
// 10 % (the measured 6.77 % with room for another machine's round-off in eight chained
// nonlinear fits); each of the seven in-band poles matched by a mode within 0.05 Hz
// (one FRF line, 400/8192 Hz).  Not reached, and said in docs/real-data.md: 1.5x the
// floor (a free rational fit needs about 40 pole pairs to come within 2x).
TEST(RealData, F16LoopWithTheModelErrorInTheWeightsAddsEveryModeTheLibraryOffers) {
  LPVID_REAL_DATA_OR_SKIP(low, "f16_gvt/f16_fullmsine_level1.csv");
  TempDir dir("f16weights");
  const std::string p1 = dir / "P1.csv";
  auto r = run_lpvid("frf " + kF16Layout + kF16Channels + "--out " + p1 + " " + low);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string description = std::string(LPVID_SOURCE_DIR) + "/samples/mechanical/f16_gvt.json";
  r = run_lpvid("model init --base mechanical --from " + description + " --out " + (dir / "fit-1.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string data = " --data " + p1 + " --measured-input --weighting auto";
  auto fit = [&](const std::string& model, const std::string& out) {
    const auto f = run_lpvid("fit --model " + model + data + " --out " + out);
    EXPECT_EQ(f.exit_code, 0) << f.err;
    return nlohmann::json::parse(std::ifstream(out))["fit"]["error"].get<double>();
  };
  double error = fit(dir / "fit-1.json", dir / "fit0.json");
  std::printf("F-16, model error in the weights: %.2f %%", 100 * error);
  for (int k = 1; k <= 8; ++k) {
    const std::string step = dir / fmt::format("step{}.json", k), next = dir / fmt::format("fit{}.json", k);
    r = run_lpvid("diagnose --model " + (dir / fmt::format("fit{}.json", k - 1)) + data + " --out " + step);
    ASSERT_EQ(r.exit_code, 0) << r.err << r.out;
    ASSERT_THAT(r.out, HasSubstr(k == 1 ? "missing: structural_mode " : fmt::format("missing: structural_mode_{} ", k)))
        << r.out;
    const double e = fit(step, next);
    std::printf(" -> %.2f %%", 100 * e);
    std::fflush(stdout);
    EXPECT_LT(e, error) << "step " << k;
    error = e;
  }
  std::printf("\n");
  EXPECT_LT(error, 0.10);
  const auto model = nlohmann::json::parse(std::ifstream(dir / "fit8.json"));
  std::vector<double> hz;
  for (int k = 1; k <= 8; ++k)
    hz.push_back(model["parameters"][k == 1 ? std::string("mode_frequency_rad_s")
                                             : fmt::format("mode_{}_frequency_rad_s", k)]["value"]
                     .get<double>() /
                 (2 * std::numbers::pi));
  std::sort(hz.begin(), hz.end());
  std::printf("modes (Hz):");
  for (double f : hz) std::printf(" %.3f", f);
  std::printf("\n");
  for (double pole : {1.86, 3.47, 3.96, 5.19, 6.62, 7.32, 9.17}) {
    double nearest = INFINITY;
    for (double f : hz) nearest = std::min(nearest, std::abs(f - pole));
    EXPECT_LT(nearest, 0.05) << "no mode within one line of the rational fit's pole at " << pole << " Hz";
  }
  // The eight modes refitted to level 7: the torsion mode (the one nearest 7.3 Hz)
  // softens and damps beyond both fits' standard errors, as the benchmark describes.
  // Measured: 45.995 ± 0.004 rad/s, zeta 0.00494 ± 0.00009 at level 1; 45.000 ± 0.020,
  // zeta 0.0204 ± 0.0005 at level 7 (error 14.8 % against a floor of 0.59 %).
  const std::string p7 = dir / "P7.csv";
  LPVID_REAL_DATA_OR_SKIP(high, "f16_gvt/f16_fullmsine_level7.csv");
  r = run_lpvid("frf " + kF16Layout + kF16Channels + "--out " + p7 + " " + high);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("fit --model " + (dir / "fit8.json") + " --data " + p7 + " --measured-input --weighting auto --out " +
                (dir / "fit8_level7.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto one = nlohmann::json::parse(std::ifstream(dir / "fit8.json"))["fit"]["parameters"];
  const auto seven = nlohmann::json::parse(std::ifstream(dir / "fit8_level7.json"))["fit"]["parameters"];
  std::string torsion;
  for (int k = 1; k <= 8; ++k) {
    const std::string name = k == 1 ? std::string("mode_") : fmt::format("mode_{}_", k);
    if (std::abs(one[name + "frequency_rad_s"]["estimate"].get<double>() / (2 * std::numbers::pi) - 7.32) < 0.05)
      torsion = name;
  }
  ASSERT_FALSE(torsion.empty());
  auto at = [&](const nlohmann::json& f, const std::string& what) {
    return std::pair<double, double>{f[torsion + what]["estimate"].get<double>(),
                                     f[torsion + what]["std_error"].get<double>()};
  };
  const auto [w1, sw1] = at(one, "frequency_rad_s");
  const auto [w7, sw7] = at(seven, "frequency_rad_s");
  const auto [z1, sz1] = at(one, "damping");
  const auto [z7, sz7] = at(seven, "damping");
  std::printf("torsion mode: level 1 %.4f ± %.4f rad/s, zeta %.5f ± %.5f; level 7 %.4f ± %.4f rad/s, zeta %.5f ± %.5f\n",
              w1, sw1, z1, sz1, w7, sw7, z7, sz7);
  EXPECT_LT(w7, w1 - 3 * std::hypot(sw1, sw7));
  EXPECT_GT(z7, z1 + 3 * std::hypot(sz1, sz7));
}

// The DaISy steel subframe (2 forces x 28 accelerometers, 8523 samples): the output-error
// refinement's full form would need a 7.3e7-entry Jacobian at order 6, so it runs in modal
// form with C and D eliminated.  Reference: SLICOT n4sid at n = 20 (s = 21) simulates the
// record with a median fit of 9.0 % over the 28 outputs (the figure).  Measured
// here at order 6 (73 s): stable, median 13.9 % from zero state (the structured fit alone
// is far below; the default, order 20, reaches 67.1 % in 11 min: docs/real-data.md).  The
// bound: above n4sid's figure at more than three times the order.
TEST(RealData, SteelSubframeRefinedInModalFormBeatsN4sidsFitAtASmallerOrder) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_flexible_structure/flexible_structure.csv");
  TempDir dir("subframe");
  const auto r = run_lpvid("identify --open-loop --plant-order 6 --excitation f1,f2 --output a1..a28 --json --out " +
                           (dir / "out") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["plant"]["stable"], true);
  const auto& rf = report["refinement"];
  EXPECT_EQ(rf["kept"], true);
  EXPECT_EQ(rf["form"], "modal");
  EXPECT_LT(rf["cost"].get<double>(), rf["start_cost"].get<double>());
  std::vector<double> fits = report["closed_loop"]["simulation_fit_percent"].get<std::vector<double>>();
  ASSERT_EQ(fits.size(), 28u);
  std::sort(fits.begin(), fits.end());
  const double median = 0.5 * (fits[13] + fits[14]);
  std::printf("steel subframe, order 6: median simulation fit %.2f %% from zero state (n4sid, n = 20: 9.0 %%); %s\n",
              median, rf["reason"].get<std::string>().c_str());
  EXPECT_GT(median, 9.0);
}

// markov + realize on the subframe with the defaults (the row: order 24,
// unstable, |z| = 1.006; with --order 20 still unstable), and at n4sid's order 20.
// realize now refits an unstable realisation with every pole inside the unit circle and keeps
// it unless it fits worse (fit_markov_stable).  Reference: SLICOT n4sid at n = 20 simulates
// the record with a median fit of 9.0 % over the 28 outputs.  markov's default takes the
// ARX estimate here (least squares' 1065 lags are truncated: the structure rings longer;
// held out, the halves miss 7.41 % of the output energy with least squares, 2.52 % with
// the ARX estimate).  Measured: defaults, order 24, stabilised: median 36.3 % from zero
// state; at order 20: 52.2 % (least squares' route gave 53.6 % at its order 25 and 45.2 %
// at order 20: realize's stabilising refit, from an ERA model with |z| ~ 1.01, decides
// these figures more than the Markov estimate does).  Bounds: stable both, and at order
// 20 above n4sid's 9.0 %.
TEST(RealData, SteelSubframeMarkovRealizeIsStableAndBeatsN4sidAtItsOrder) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_flexible_structure/flexible_structure.csv");
  TempDir dir("subframe_era");
  const std::string io = " --excitation f1,f2 --output a1..a28 ";
  const auto m = run_lpvid("markov --out " + (dir / "g.csv") + io + log);
  ASSERT_EQ(m.exit_code, 0) << m.err;
  for (const std::string order : {"", " --order 20"}) {
    const auto r = run_lpvid("realize --json " + (dir / "g.csv") + order + " --out " + (dir / "model.json"));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto rs = nlohmann::json::parse(r.out);
    const auto c = run_lpvid("compare --json --log " + log + " --model " + (dir / "model.json") +
                             " --input f1,f2 --output a1..a28");
    ASSERT_EQ(c.exit_code, 0) << c.err;
    const auto cs = nlohmann::json::parse(c.out);
    EXPECT_EQ(cs["stable"], true) << order;
    std::vector<double> fits;
    for (const auto& [name, fit] : cs["fit_zero_state_percent"].items()) fits.push_back(fit.get<double>());
    ASSERT_EQ(fits.size(), 28u);
    std::sort(fits.begin(), fits.end());
    const double median = 0.5 * (fits[13] + fits[14]);
    std::printf("steel subframe, markov + realize%s: order %d, median fit %.2f %% from zero state (n4sid, n = 20: "
                "9.0 %%); %s\n",
                order.c_str(), rs["order"].get<int>(), median,
                rs["stabilized"].is_null() ? "not stabilised" : rs["stabilized"]["reason"].get<std::string>().c_str());
    if (!order.empty()) {
      EXPECT_GT(median, 9.0);
    }
  }
}

// identify --open-loop on the robot arm with the defaults: a stable plant of order <= 6
// and MATLAB compare's simulation fit on the record, from zero state (compare's 'z') and
// with the record's initial state fitted (compare's default 'e').  Reference: SLICOT
// n4sid (s = 20, n = 4) reaches 89.3 % on this file (the figure, Octave; its
// initial-state convention is not stated); markov + realize reached 79.9 % (order 4, 200
// lags).  Measured: the structured fit alone (--no-refine, order 4) 87.3 % / 89.1 %; with
// the output-error refinement (the record does not start from rest: fitting its initial
// state lowers the simulation error 7.5x, so Akaike keeps it) at the ladder's order 4
// 88.9 % / 96.6 %, and with the default order check on held-out halves, which takes order
// 6, 88.8 % / 97.2 %; refined from rest only (x(0) = 0, order 4) it is 90.7 % from zero
// state.  The bounds: the refinement must beat the structured fit in compare's default
// figure, and stay above n4sid's 89.3 % there (97.2 % measured, 95 % asserted); from zero
// state above 88 %.
TEST(RealData, RobotArmOpenLoopIdentifyGivesAStablePlantThatSimulatesTheRecord) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("arm_identify");
  const auto r = run_lpvid("identify --open-loop --excitation u --output y --json --out " + (dir / "out") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["plant"]["stable"], true);
  EXPECT_LE(report["plant"]["order"].get<int>(), 6);
  const double fit = report["closed_loop"]["simulation_fit_percent"][0].get<double>();
  const double fit_e = report["closed_loop"]["simulation_fit_initial_state_percent"][0].get<double>();
  const auto s = run_lpvid("identify --open-loop --no-refine --excitation u --output y --json --out " + (dir / "plain") +
                           " " + log);
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const auto plain = nlohmann::json::parse(s.out);
  const double plain_e = plain["closed_loop"]["simulation_fit_initial_state_percent"][0].get<double>();
  std::printf("robot arm: order %d, simulation fit %.1f %% from zero state, %.1f %% with its initial state (structured "
              "alone %.1f %%); %s\n",
              report["plant"]["order"].get<int>(), fit, fit_e, plain_e,
              report["fit"]["refinement_reason"].get<std::string>().c_str());
  EXPECT_GE(fit, 88.0);
  EXPECT_GE(fit_e, 95.0);
  EXPECT_GT(fit_e, plain_e + 3.0);
  EXPECT_THAT(report["fit"]["excitation_reason"].get<std::string>(), HasSubstr("coloured"));
  EXPECT_THAT(report["fit"]["bands_reason"].get<std::string>(), HasSubstr("output-error refinement"));
  // compare --log judges the written model on the record as identify did (its columns from
  // the model's names): the same two figures from the written file.
  const auto c = run_lpvid("compare --json --log " + log + " --model " + (dir / "out/plant.json"));
  ASSERT_EQ(c.exit_code, 0) << c.err;
  const auto cmp = nlohmann::json::parse(c.out);
  EXPECT_NEAR(cmp["fit_percent"]["y"].get<double>(), fit_e, 1e-9);
  EXPECT_NEAR(cmp["fit_zero_state_percent"]["y"].get<double>(), fit, 1e-9);
  EXPECT_EQ(cmp["stable"], true);
}

// The same with --initial-state zero (MATLAB ssest's InitialState 'zero'): the refinement
// holds the initial state at zero, so it fits the model that simulates the record best
// from rest — the figure the issue compares with n4sid (issue 24: "robot arm >= 90 % at
// order <= 6").  Measured: order 6 (the held-out check again), 90.9 % from zero state
// (the default's 88.8 %; n4sid's 89.3 %), 94.4 % with the initial state fitted (the
// default's 97.2 %: the record does not start from rest, and this model was not fitted
// to its start).  Bounds: from zero state at least 90 % (the figure, 0.9 points
// below the measured); the summary says the states were held; a misspelt value, or the
// option beside --no-refine (nothing to hold), refused.
TEST(RealData, RobotArmFromRestOnlyBeatsN4sidFromZeroState) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("arm_identify_zero");
  const auto r = run_lpvid("identify --open-loop --initial-state zero --excitation u --output y --json --out " +
                           (dir / "out") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["plant"]["stable"], true);
  EXPECT_LE(report["plant"]["order"].get<int>(), 6);
  const double fit = report["closed_loop"]["simulation_fit_percent"][0].get<double>();
  std::printf("robot arm, --initial-state zero: order %d, simulation fit %.1f %% from zero state (n4sid 89.3 %%)\n",
              report["plant"]["order"].get<int>(), fit);
  EXPECT_GE(fit, 90.0);
  EXPECT_THAT(report["fit"]["refinement_reason"].get<std::string>(), HasSubstr("held at zero, as asked"));
  const auto bad = run_lpvid("identify --open-loop --initial-state rest --excitation u --output y --out " +
                             (dir / "bad") + " " + log);
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_THAT(bad.err, HasSubstr("--initial-state rest: use 'auto'"));
  EXPECT_EQ(std::count(bad.err.begin(), bad.err.end(), '\n'), 1) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
  // with no refinement to hold: refused, not ignored
  const auto unused = run_lpvid("identify --open-loop --no-refine --initial-state zero --excitation u --output y --out " +
                                (dir / "unused") + " " + log);
  EXPECT_NE(unused.exit_code, 0);
  EXPECT_THAT(unused.err, HasSubstr("--no-refine runs none; drop one of the two"));
  EXPECT_FALSE(std::filesystem::exists(dir / "unused"));
}

// The order check on held-out halves (identify's `held_out_order`) reproduced by hand as a
// user would do it: write each half of the record to its own file, identify the first at
// the chosen order with the horizon the check uses (a quarter of the half, 128 lags),
// judge it on the second with compare --log (compare's 'e' figure), and the reverse; the
// two figures combined over both halves are the check's held-out fit for that order.
// Also: the check ran, the written plant has its chosen order, and that order predicts
// the held-out halves at least as well as the ladder's.
TEST(RealData, RobotArmHeldOutOrderCheckIsWhatTwoSeparateRunsGive) {
  LPVID_REAL_DATA_OR_SKIP(log, "daisy_robot_arm/robot_arm.csv");
  TempDir dir("arm_held_out");
  const auto r = run_lpvid("identify --open-loop --excitation u --output y --json --out " + (dir / "out") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto report = nlohmann::json::parse(r.out);
  const auto& h = report["held_out_order"];
  ASSERT_TRUE(h.is_object());
  ASSERT_EQ(h["ran"], true) << h.dump();
  const int chosen = h["chosen_order"].get<int>(), ladder = h["ladder_order"].get<int>();
  EXPECT_EQ(report["plant"]["order"].get<int>(), chosen);
  double chosen_fit = NAN, ladder_fit = NAN;
  for (const auto& row : h["orders"]) {
    if (row["order"].get<int>() == chosen) chosen_fit = row["fit_percent"].get<double>();
    if (row["order"].get<int>() == ladder && row.contains("fit_percent")) ladder_fit = row["fit_percent"].get<double>();
  }
  ASSERT_TRUE(std::isfinite(chosen_fit)) << h.dump();
  if (std::isfinite(ladder_fit)) {
    EXPECT_GE(chosen_fit, ladder_fit);
  }
  std::printf("robot arm held out: %s\n", h["reason"].get<std::string>().c_str());

  // The halves as files (t kept: the second starts at 512).
  std::ifstream in(log);
  std::vector<std::string> head, rows;
  for (std::string line; std::getline(in, line);) (rows.empty() && (line.empty() || line[0] == '#' || line[0] == 't') ? head : rows).push_back(line);
  ASSERT_EQ(rows.size(), 1024u);
  const std::string half[2] = {dir / "first.csv", dir / "second.csv"};
  double ref2[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    std::ofstream out(half[k]);
    for (const auto& line : head) out << line << "\n";
    std::vector<double> y;
    for (std::size_t t = 512 * static_cast<std::size_t>(k); t < 512 * static_cast<std::size_t>(k + 1); ++t) {
      out << rows[t] << "\n";
      y.push_back(std::stod(rows[t].substr(rows[t].rfind(',') + 1)));
    }
    double mean = 0;
    for (double v : y) mean += v / static_cast<double>(y.size());
    for (double v : y) ref2[k] += (v - mean) * (v - mean);
  }
  double err2 = 0;
  for (int k = 0; k < 2; ++k) {
    const std::string model = dir / ("half" + std::to_string(k));
    const auto f = run_lpvid(fmt::format("identify --open-loop --excitation u --output y --plant-order {} --lags 128 --out {} {}",
                                         chosen, model, half[k]));
    ASSERT_EQ(f.exit_code, 0) << f.err;
    const auto c = run_lpvid("compare --json --log " + half[1 - k] + " --model " + model + "/plant.json");
    ASSERT_EQ(c.exit_code, 0) << c.err;
    const double fit = nlohmann::json::parse(c.out)["fit_percent"]["y"].get<double>();
    err2 += std::pow(1.0 - fit / 100.0, 2) * ref2[1 - k];
  }
  const double by_hand = 100.0 * (1.0 - std::sqrt(err2 / (ref2[0] + ref2[1])));
  std::printf("robot arm held out, order %d: %.6f %% in identify's check, %.6f %% by two separate runs\n", chosen,
              chosen_fit, by_hand);
  // The same arithmetic on the same numbers but for the CSV's printed digits (9 significant).
  EXPECT_NEAR(by_hand, chosen_fit, 1e-4);
}

}  // namespace real_data_test
}  // namespace lpvid
