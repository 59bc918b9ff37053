// lpvid excite and the simulators driven by its signal: files as a user gets
// them, errors as a user sees them (exit 2, one line, nothing written).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <fstream>
#include <numbers>

#include "formats/io/csv_log.h"
#include "formats/io/excitation_design.h"
#include "formats/io/excitation_file.h"
#include "formats/io/model_json.h"
#include "idlib/lti/frequency_response.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace excite_test {

using ::testing::HasSubstr;
using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

TEST(Excite, WritesAPeriodicMultisineWithItsDesignLine) {
  TempDir dir("excite");
  const auto r = run_lpvid("excite --rate-hz 1000 --period-samples 200 --periods 3 --transient-periods 1 "
                           "--band-hz 5,100 --channels 2 --mimo hadamard --rms 0.1,2 --out " + (dir / "ms.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("resolution fs/L = 5 Hz"));
  const ExcitationFile f = read_excitation_file(dir / "ms.csv");
  const ExcitationDesign& d = f.design;
  EXPECT_EQ(d.kind, "multisine");
  EXPECT_EQ(d.mimo, "hadamard");
  EXPECT_EQ(d.experiments, 2);
  EXPECT_EQ(d.period_samples, 200);
  // Bins k with 5 <= 5k <= 100: 1..20 on both inputs.
  std::vector<Index> bins;
  for (Index k = 1; k <= 20; ++k) bins.push_back(k);
  EXPECT_EQ(d.excited_bins, (std::vector<std::vector<Index>>{bins, bins}));
  ASSERT_EQ(f.log.num_samples(), 2 * 4 * 200);
  // t = k / fs from 0.
  EXPECT_EQ(f.log.data(0, 0), 0.0);
  EXPECT_DOUBLE_EQ(f.log.data(799, 0), 0.799);
  // Each block repeats its period to the last bit; experiment 2 has input 2 negated (H = [1 1; 1 -1]).
  for (Index j = 1; j <= 2; ++j)
    for (Index p = 1; p < 4; ++p)
      EXPECT_TRUE(f.log.data.col(j).segment(p * 200, 200) == f.log.data.col(j).segment(0, 200));
  EXPECT_TRUE(f.log.data.col(1).segment(800, 200) == f.log.data.col(1).segment(0, 200));
  EXPECT_TRUE(f.log.data.col(2).segment(800, 200) == -f.log.data.col(2).segment(0, 200));
  // The RMS of one period is the one asked for (printed with 17 digits: 1e-12).
  for (Index j = 1; j <= 2; ++j) {
    const double rms = std::sqrt(f.log.data.col(j).segment(200, 200).squaredNorm() / 200);
    EXPECT_NEAR(rms, j == 1 ? 0.1 : 2.0, 1e-12 * rms);
    EXPECT_NEAR(d.rms[static_cast<std::size_t>(j - 1)], rms, 1e-12 * rms);
  }
}

// excite --amplitude FILE: the points (10 Hz, 1), (100 Hz, 0.01), (200 Hz, 0.04) are
// a(f) = (f/10)^-2 on [10, 100], 0.01 (f/100)^2 on [100, 200] (straight lines in
// log-log), 1 below 10 Hz and 0.04 above 200 Hz (constant beyond the ends): the
// closed form below, not lpvid's interpolator, is the truth.
double three_point_shape(double f) {
  if (f <= 10) return 1.0;
  if (f <= 100) return std::pow(f / 10, -2.0);
  if (f <= 200) return 0.01 * std::pow(f / 100, 2.0);
  return 0.04;
}

// The DFT of one period of the written v1, summed directly at every bin, has
// amplitude c a(f_k) on the excited lines (c from the RMS asked for, by Parseval) and
// nothing elsewhere; the design line records the same amplitudes.
TEST(Excite, AmplitudeFileShapesTheLinesAndTheDesignRecordsThem) {
  TempDir dir("excite_amp");
  std::ofstream(dir / "amp.csv") << "# relative amplitude\nf_hz,amplitude\n10,1\n100,0.01\n200,0.04\n";
  const auto r = run_lpvid("excite --rate-hz 1000 --period-samples 250 --periods 1 --transient-periods 1 "
                           "--band-hz 4,300 --rms 0.5 --minimise-crest --crest-iterations 30 --amplitude " +
                           (dir / "amp.csv") + " --out " + (dir / "ms.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("amplitude spectrum"));
  const ExcitationFile f = read_excitation_file(dir / "ms.csv");
  const std::vector<Index>& bins = f.design.excited_bins.at(0);
  ASSERT_EQ(bins.size(), 75u);  // 4 Hz lines, 4..300 Hz
  ASSERT_EQ(f.design.amplitudes.size(), 1u);
  ASSERT_EQ(f.design.amplitudes[0].size(), bins.size());
  double sum = 0;
  for (Index k : bins) sum += 0.5 * std::pow(three_point_shape(4.0 * static_cast<double>(k)), 2);
  const double c = 0.5 / std::sqrt(sum);
  const Eigen::VectorXd period = f.log.data.col(1).segment(250, 250);  // after the transient period
  // Samples written with 17 significant digits (1e-16 relative) and a 250-term DFT
  // in double: ~1e-14 of the largest line of round-off; the smallest line is 1/100
  // of the largest, so 1e-10 of each line bounds the round-off by ~1e4x, and a line
  // with the wrong slope or a leaked line would be off by percent.
  constexpr double kRelTolerance = 1e-10;
  std::size_t i = 0;
  for (Index k = 0; k <= 125; ++k) {
    std::complex<double> x(0, 0);
    for (Index t = 0; t < 250; ++t) x += period(t) * std::polar(1.0, -2 * std::numbers::pi * static_cast<double>((k * t) % 250) / 250.0);
    const double amplitude = 2 * std::abs(x) / 250.0;
    if (i < bins.size() && bins[i] == k) {
      const double want = c * three_point_shape(4.0 * static_cast<double>(k));
      EXPECT_NEAR(amplitude, want, kRelTolerance * want) << "bin " << k;
      EXPECT_NEAR(f.design.amplitudes[0][i], want, kRelTolerance * want) << "bin " << k;
      ++i;
    } else {
      EXPECT_LE(amplitude, kRelTolerance * c * 0.01) << "bin " << k;
    }
  }
  EXPECT_EQ(i, bins.size());
}

TEST(Excite, BadAmplitudeFilesAreRefusedAtTheCellWithNothingWritten) {
  TempDir dir("excite_ampbad");
  auto refused = [&](const std::string& text, const std::string& where, const std::string& what,
                     const std::string& extra = "") {
    std::ofstream(dir / "amp.csv") << text;
    const auto r = run_lpvid("excite --period-samples 250 --band-hz 4,300 --rms 0.5 --amplitude " + (dir / "amp.csv") +
                             extra + " --out " + (dir / "ms.csv"));
    EXPECT_EQ(r.exit_code, 2) << text;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr((dir / "amp.csv") + where)) << r.err;
    EXPECT_THAT(r.err, HasSubstr(what)) << r.err;
    EXPECT_EQ(count_files(dir.path()), 1);  // amp.csv only
  };
  refused("f_hz,amplitude\n10,1\n20, -2\n", ":3:5:", "amplitude -2 is not positive");
  refused("f_hz,amplitude\n10,1\n10,2\n", ":3:1:", "is not above the previous row's 10 Hz");
  refused("f_hz,amplitude\n0,1\n10,2\n", ":2:1:", "frequency 0 Hz is not positive");
  refused("f_hz,amplitude\n10,1\n", ":3:1:", "an amplitude spectrum needs at least 2 points");
  refused("f_hz,amp\n10,1\n20,2\n", ":1:1:", "no column 'amplitude'");
  refused("f_hz,amplitude\n10,1\n20,x\n", ":3:4:", "");
  // --amplitude shapes multisine lines only.
  std::ofstream(dir / "amp.csv") << "f_hz,amplitude\n10,1\n20,2\n";
  const auto r = run_lpvid("excite --kind noise --duration-s 1 --rms 0.5 --amplitude " + (dir / "amp.csv") + " --out " +
                           (dir / "n.csv"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("--amplitude does not apply to a noise (multisine only)"));
  EXPECT_EQ(count_files(dir.path()), 1);
}

TEST(Excite, SameSeedGivesTheSameBytes) {
  TempDir dir("seed");
  const std::string args = "excite --period-samples 500 --band-hz 1,300 --phase random --minimise-crest "
                           "--crest-iterations 20 --peak 1 --seed 42 --out ";
  ASSERT_EQ(run_lpvid(args + (dir / "a.csv")).exit_code, 0);
  ASSERT_EQ(run_lpvid(args + (dir / "b.csv")).exit_code, 0);
  EXPECT_EQ(slurp(dir / "a.csv"), slurp(dir / "b.csv"));
  ASSERT_EQ(run_lpvid("excite --period-samples 500 --band-hz 1,300 --peak 1 --seed 43 --out " + (dir / "c.csv")).exit_code, 0);
  EXPECT_NE(slurp(dir / "a.csv"), slurp(dir / "c.csv"));
}

TEST(Excite, MatOutputHoldsTheSameSignalAsTheCsv) {
  TempDir dir("mat");
  const std::string args = "excite --kind prbs --period-samples 127 --periods 2 --rms 0.5 --out ";
  ASSERT_EQ(run_lpvid(args + (dir / "p.csv")).exit_code, 0);
  const auto r = run_lpvid(args + (dir / "p.mat") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("\"prbs_order\": 7"));
  const ExcitationFile csv = read_excitation_file(dir / "p.csv");
  const ExcitationFile mat = read_excitation_file(dir / "p.mat");
  EXPECT_TRUE(csv.log.data == mat.log.data);
  EXPECT_EQ(excitation_design_json(csv.design), excitation_design_json(mat.design));
  EXPECT_EQ(csv.design.prbs_order, 7);
}

TEST(Excite, DesignsThatCannotWorkAreRefusedWithExit2AndNothingWritten) {
  TempDir dir("bad");
  const std::string out = " --out " + (dir / "x.csv");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"excite --period-samples 100 --band-hz 1,600 --rms 1", "0 < low <= high < fs/2 = 500 Hz"},
      {"excite --period-samples 100 --band-hz 1,5 --rms 1", "holds no DFT line"},
      {"excite --period-samples 100 --rms 1 --kind chirp", "--kind: 'chirp' is not one of"},
      {"excite --period-samples 100", "give the amplitude"},
      {"excite --kind noise --duration-s 1 --band-hz 1,5 --rms 1", "--band-hz does not apply to a noise"},
      {"excite --kind noise --rms 1", "needs its length: give --duration-s"},
      {"excite --kind prbs --period-samples 1000 --rms 1", "give 511 (m = 9) or 1023 (m = 10)"},
      {"excite --period-s 0.0015 --rms 1", "not a whole number"},
      {"excite --period-samples 100 --rms 1 --channels 2 --phase schroeder --mimo single", "same signal"},
      {"excite --period-samples 100 --rms 1,2", "2 values for 1 inputs"},
      {"excite --rms 1", "needs its period"},
      {"excite --period-samples 100 --rms 1 --crest-iterations 5", "without --minimise-crest"},
  };
  for (const auto& [args, text] : cases) {
    const auto r = run_lpvid(args + out);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_THAT(r.err, HasSubstr(text)) << args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(count_files(dir.path()), 0) << args;
  }
}

TEST(SimulateWithExcitation, PlatformLogCarriesTheFileSamplesAndItsDesignLine) {
  TempDir dir("simx");
  ASSERT_EQ(run_lpvid("excite --period-samples 100 --periods 2 --band-hz 2,200 --channels 3 --rms 0.05,0.05,1 "
                      "--out " + (dir / "ms.csv")).exit_code, 0);
  const auto r = run_lpvid("simulate platform --positions middle --excitation " + (dir / "ms.csv") + " --out " +
                           (dir / "data"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ExcitationFile ms = read_excitation_file(dir / "ms.csv");
  const std::string log_path = dir / "data/middle_1000hz/exp_excitation.csv";
  const Log log = read_log(log_path);
  ASSERT_EQ(log.num_samples(), ms.log.num_samples());
  // v1..v3 of the log are the file's samples, bit for bit; the loop responded.
  EXPECT_TRUE(log.columns({"v1", "v2", "v3"}) == ms.log.columns({"v1", "v2", "v3"}));
  EXPECT_GT(log.columns({"q1"}).norm(), 0);
  const auto design = read_excitation_design(log_path);
  ASSERT_TRUE(design.has_value());
  EXPECT_EQ(excitation_design_json(*design), excitation_design_json(ms.design));
  EXPECT_FALSE(std::filesystem::exists(dir / "data/middle_1000hz/exp_T_psi.csv"));
}

// DFT of x[0..L) at bin k, summed directly.
Complex dft_at(const Eigen::VectorXd& x, Index start, Index L, Index k) {
  Complex sum(0, 0);
  for (Index t = 0; t < L; ++t) sum += x(start + t) * std::polar(1.0, -2 * std::numbers::pi * static_cast<double>((k * t) % L) / L);
  return sum;
}

// The designed signal is usable for identification: with no sensor noise, the
// steady period of each one-at-a-time experiment gives the closed loop v -> q at
// the excited lines as Q(k) / V_j(k), equal to the exact truth_closed_loop.json.
TEST(SimulateWithExcitation, PlatformSteadyPeriodsGiveTheTrueClosedLoopAtTheExcitedLines) {
  TempDir dir("simg");
  ASSERT_EQ(run_lpvid("excite --period-samples 1000 --periods 1 --transient-periods 3 --band-hz 1,200 --every 7 "
                      "--channels 3 --rms 0.05,0.05,1 --out " + (dir / "ms.csv")).exit_code, 0);
  const auto r = run_lpvid("simulate platform --positions middle --noise-scale 0 --excitation " + (dir / "ms.csv") +
                           " --out " + (dir / "data"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ExcitationFile ms = read_excitation_file(dir / "ms.csv");
  const Log log = read_log(dir / "data/middle_1000hz/exp_excitation.csv");
  const StateSpace truth = read_state_space(dir / "data/middle_1000hz/truth_closed_loop.json");
  const Index L = 1000, block = 4 * L;
  double worst = 0;
  for (Index e = 0; e < 3; ++e) {
    const Index start = e * block + 3 * L;  // the period after the 3 transient ones
    const Eigen::VectorXd v = log.columns({"v" + std::to_string(e + 1)});
    const auto& bins = ms.design.excited_bins[static_cast<std::size_t>(e)];
    Eigen::VectorXd omega(static_cast<Index>(bins.size()));
    for (std::size_t i = 0; i < bins.size(); ++i) omega(static_cast<Index>(i)) = 2 * std::numbers::pi * bins[i];  // fs / L = 1 Hz
    const auto G = evaluate_response(truth, omega);
    for (std::size_t i = 0; i < bins.size(); ++i) {
      const Complex V = dft_at(v, start, L, bins[i]);
      Eigen::VectorXcd estimate(3);
      for (Index out = 0; out < 3; ++out)
        estimate(out) = dft_at(log.columns({"q" + std::to_string(out + 1)}), start, L, bins[i]) / V;
      const Eigen::VectorXcd exact = G[i].col(e);
      worst = std::max(worst, (estimate - exact).norm() / exact.norm());
    }
  }
  // What remains is the loop's transient after 3 periods of 1 s plus round-off:
  // measured 2.6e-10.  An excitation shifted by one sample would be off by
  // |1 - e^{-i 2 pi k / L}| >= 0.04 at the lowest line, a wrong scale by O(1).
  EXPECT_LT(worst, 1e-7);
}

TEST(SimulateWithExcitation, Stage6ExperimentUsesTheFileSamples) {
  TempDir dir("s6x");
  ASSERT_EQ(run_lpvid("excite --period-samples 60 --periods 1 --band-hz 20,400 --channels 6 --mimo zipper "
                      "--rms 1,1,1,0.05,0.05,0.05 --out " + (dir / "ms.mat")).exit_code, 0);
  const auto r = run_lpvid("simulate stage6 --experiment --excitation " + (dir / "ms.mat") + " --out " + (dir / "exp"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ExcitationFile ms = read_excitation_file(dir / "ms.mat");
  const Log log = read_log(dir / "exp/exp_stage6.csv");
  ASSERT_EQ(log.num_samples(), ms.log.num_samples());
  const std::vector<std::string> v = {"v1", "v2", "v3", "v4", "v5", "v6"};
  EXPECT_TRUE(log.columns(v) == ms.log.columns(v));
  ASSERT_TRUE(read_excitation_design(dir / "exp/exp_stage6.csv").has_value());
}

TEST(SimulateWithExcitation, RateOrChannelMismatchIsRefusedWithNothingWritten) {
  TempDir dir("simbad");
  ASSERT_EQ(run_lpvid("excite --period-samples 100 --channels 3 --rms 1 --out " + (dir / "three.csv")).exit_code, 0);
  ASSERT_EQ(run_lpvid("excite --period-samples 100 --rms 1 --out " + (dir / "one.csv")).exit_code, 0);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"simulate platform --positions middle --rate-hz 2000 --excitation " + (dir / "three.csv"),
       "is sampled at 1000 Hz but --rate-hz is 2000"},
      {"simulate platform --positions middle --excitation " + (dir / "one.csv"), "1 channel but the platform has 3"},
      {"simulate platform --positions middle --duration-s 3 --excitation " + (dir / "three.csv"),
       "--duration-s does not apply with --excitation"},
      {"simulate stage6 --experiment --excitation " + (dir / "three.csv"), "3 channels but the stage has 6"},
      {"simulate stage6 --excitation " + (dir / "three.csv"), "add --experiment"},
  };
  for (const auto& [args, text] : cases) {
    const auto r = run_lpvid(args + " --out " + (dir / "out"));
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_THAT(r.err, HasSubstr(text)) << args;
    EXPECT_FALSE(std::filesystem::exists(dir / "out")) << args;
  }
}

}  // namespace excite_test
}  // namespace lpvid
