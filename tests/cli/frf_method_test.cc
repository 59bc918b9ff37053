// frf --method periodic / lpm / lrm through the program: a first-order discrete system
// y[t] = a y[t−1] + b v[t] (its response b / (1 − a e^{−iωTs}) written here, not by
// lpvid) driven by a multisine (periodic) or white noise (lpm, lrm), and the bad-input paths
// of the new flags (one line on stderr, exit 2, no output).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "formats/io/frd_csv.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace frf_method_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::RunResult;
using lpvid::testing::TempDir;

constexpr double kTs = 1e-3, kA = 0.95, kB = 0.05;
constexpr int kL = 256, kPeriods = 4, kTransient = 2, kRealisations = 2;

Complex truth(double omega) { return kB / (1.0 - kA * std::exp(Complex(0, -omega * kTs))); }

// R realisations of a random-phase multisine on bins 1..40 (one block each), or white
// noise of the same length; y with white noise of rms 1e-3 and a cubic term `cubic` y³.
void write_log(const std::string& path, bool periodic, double cubic, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  std::ofstream out(path);
  out.precision(17);
  out << "t,v1,y1\n";
  double y = 0;
  int t = 0;
  for (int r = 0; r < kRealisations; ++r) {
    std::vector<double> period(kL, 0.0);
    for (int k = 1; k <= 40; ++k) {
      const double phi = phase(rng);
      for (int i = 0; i < kL; ++i) period[static_cast<size_t>(i)] += 0.2 * std::cos(2 * std::numbers::pi * k * i / kL + phi);
    }
    for (int i = 0; i < (kTransient + kPeriods) * kL; ++i, ++t) {
      const double v = periodic ? period[static_cast<size_t>(i % kL)] : n01(rng);
      y = kA * y + kB * v + cubic * y * y * y;
      out << t * kTs << "," << v << "," << y + 1e-3 * n01(rng) << "\n";
    }
  }
}

const std::string kPeriodicFlags = "--method periodic --period-samples 256 --periods 4 --transient-periods 2 "
                                   "--realisations 2 --excitation v1 --output y1 --quantity G ";

TEST(FrfMethod, PeriodicWritesTheExcitedLinesWithNoiseAndDistortionVariance) {
  TempDir dir("frfper");
  write_log(dir / "log.csv", true, 0.0, 1);
  const RunResult r = run_lpvid("frf " + kPeriodicFlags + "--out " + (dir / "G.csv") + " " + (dir / "log.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("frf (periodic): 40 excited lines"));
  EXPECT_THAT(r.out, HasSubstr("noise rms per sample: y1 "));
  EXPECT_THAT(r.out, HasSubstr("not above the noise"));
  const FrequencyResponse g = read_frd_csv(dir / "G.csv");
  ASSERT_EQ(g.num_frequencies(), 40);
  ASSERT_EQ(g.distortion_variance.size(), 40u);
  for (Index k = 0; k < 40; ++k) {
    const double w = 2 * std::numbers::pi * static_cast<double>(k + 1) / (kL * kTs);
    EXPECT_NEAR(g.omega_rad_s(k), w, 1e-9 * w);
    // Noise 1e-3 against |Y| ≈ 0.2·|G| per line, averaged over 2 × 4 periods: the
    // error is ~1e-3 of |G|; 2e-2 is far outside it and far below any wrong estimate.
    EXPECT_LT(std::abs(g.response[static_cast<size_t>(k)](0, 0) - truth(w)), 2e-2 * std::abs(truth(w))) << k;
    EXPECT_GT(g.variance[static_cast<size_t>(k)](0, 0), 0.0);
  }
}

// --excited-bins takes numbers and ranges first:last: 1:20,21,22:40 names the 40 lines the
// excitation carries, so the FRD is byte-identical to the one with the lines found from
// the data; a reversed range and a non-number are refused in one line.
TEST(FrfMethod, ExcitedBinsTakeRanges) {
  TempDir dir("frfbins");
  write_log(dir / "log.csv", true, 0.0, 1);
  const std::string log = " " + (dir / "log.csv");
  RunResult r = run_lpvid("frf " + kPeriodicFlags + "--out " + (dir / "a.csv") + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("frf " + kPeriodicFlags + "--excited-bins 1:20,21,22:40 --out " + (dir / "b.csv") + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(lpvid::testing::slurp(dir / "a.csv"), lpvid::testing::slurp(dir / "b.csv"));
  for (const auto& [bins, what] : std::vector<std::pair<std::string, std::string>>{
           {"40:1", "--excited-bins '40:1': the range '40:1' ends before it starts"},
           {"1:x", "--excited-bins '1:x': '1:x' is not a bin number or a range first:last"}}) {
    r = run_lpvid("frf " + kPeriodicFlags + "--excited-bins " + bins + " --out " + (dir / "c.csv") + log);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr(what));
    EXPECT_FALSE(std::filesystem::exists(dir / "c.csv"));
  }
}

TEST(FrfMethod, PeriodicShowsACubicNonlinearityAsDistortionBands) {
  TempDir dir("frfcubic");
  write_log(dir / "log.csv", true, -0.05, 2);
  const RunResult r = run_lpvid("frf " + kPeriodicFlags + "--out " + (dir / "G.csv") + " " + (dir / "log.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("nonlinear distortion above the noise"));
}

// frf with `flags` (a local method, every 8th bin) on white noise through the system:
// each bin against its own written variance.  |Ĝ − G|² <= 6.51 var is the 99 % band of
// F(2, 14) (both default windows leave q = 7 degrees of freedom for SISO); at least 90 %
// of the bins must lie inside it (expected 99 %), and none may be off by half of |G|.
RunResult local_method_on_white_noise(const std::string& flags, const std::string& tag) {
  TempDir dir(tag);
  write_log(dir / "log.csv", false, 0.0, 3);
  const RunResult r = run_lpvid("frf " + flags + " --excitation v1 --output y1 --quantity G --out " + (dir / "G.csv") +
                                " " + (dir / "log.csv"));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return r;
  const FrequencyResponse g = read_frd_csv(dir / "G.csv");
  EXPECT_GT(g.num_frequencies(), 50);
  EXPECT_EQ(g.variance.size(), static_cast<size_t>(g.num_frequencies()));
  if (g.variance.size() != static_cast<size_t>(g.num_frequencies())) return r;
  int inside = 0;
  for (Index k = 0; k < g.num_frequencies(); ++k) {
    const double w = g.omega_rad_s(k);
    const double e = std::abs(g.response[static_cast<size_t>(k)](0, 0) - truth(w));
    inside += e * e <= 6.51 * g.variance[static_cast<size_t>(k)](0, 0) ? 1 : 0;
    EXPECT_LT(e, 0.5 * std::abs(truth(w))) << w;
  }
  std::printf("frf %s: %d of %d bins inside the 99 %% band\n", flags.c_str(), inside,
              static_cast<int>(g.num_frequencies()));
  EXPECT_GE(inside, 0.9 * static_cast<double>(g.num_frequencies()));
  return r;
}

TEST(FrfMethod, LpmOnWhiteNoiseGivesTheResponse) {
  local_method_on_white_noise("--method lpm --lpm-stride 8", "frflpm");
}

TEST(FrfMethod, LrmOnWhiteNoiseGivesTheResponse) {
  const RunResult r = local_method_on_white_noise("--method lrm --lrm-stride 8", "frflrm");
  EXPECT_THAT(r.out, HasSubstr("frf (lrm): "));
  EXPECT_THAT(r.out, HasSubstr("15 bins per window, 7 dof"));
}

TEST(FrfMethod, RefusesLayoutFlagsWithoutPeriodicALongLayoutAndAWrongPeriod) {
  TempDir dir("frfbadper");
  write_log(dir / "log.csv", true, 0.0, 4);
  const std::string out = dir / "G.csv";
  auto rejected = [&](const std::string& args, const std::string& what) {
    const RunResult r = run_lpvid("frf " + args + " --out " + out + " " + (dir / "log.csv"));
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr(what));
    EXPECT_FALSE(std::filesystem::exists(out));
  };
  rejected("--periods 4 --excitation v1 --output y1", "--periods describes periodic data: use it with --method periodic");
  // (the layout comes either whole from flags or whole from the log's design line)
  rejected("--method periodic --periods 4 --excitation v1 --output y1",
           "--periods without --period-samples: give the whole layout by flags, or none of it");
  rejected("--method periodic --excitation v1 --output y1", "--method periodic needs the layout");
  rejected("--method fourier --excitation v1 --output y1", "--method 'fourier': use welch, lpm, lrm or periodic");
  rejected("--method lpm --lrm-stride 4 --excitation v1 --output y1",
           "--lrm-stride is an option of the Local Rational Method: use it with --method lrm");
  rejected("--method lrm --lpm-order 3 --excitation v1 --output y1",
           "--lpm-order is an option of the Local Polynomial Method: use it with --method lpm");
  rejected("--method lrm --window rect --excitation v1 --output y1", "--window is a Welch option: --method lrm");
  rejected("--method lrm --lrm-denominator-degree 0 --excitation v1 --output y1", "--lrm-denominator-degree");
  rejected("--method lrm --lrm-half-width 3 --excitation v1 --output y1",
           "log.csv: LRM half width 3 leaves -1 degrees of freedom for 8 parameters per output; give a larger half "
           "width");
  rejected("--method lpm --segment 256 --excitation v1 --output y1", "--segment is a Welch option");
  rejected("--method periodic --period-samples 256 --periods 8 --transient-periods 2 --realisations 2 --excitation v1 "
           "--output y1",
           "but the layout needs");
  rejected("--method periodic --period-samples 200 --periods 4 --transient-periods 2 --excitation v1 --output y1",
           "repeat with 200 samples: at no bin does its period mean stand 100× above the noise of its "
           "period-to-period scatter");
}

// The layout from the design line: excite records it, simulate --excitation copies
// it into the log, and frf --method periodic without layout flags reads it; the
// FRD is byte-identical to the one from the same layout given by flags.
TEST(FrfMethod, PeriodicTakesTheLayoutFromTheLogsDesignLine) {
  TempDir dir("frfdesign");
  auto r = run_lpvid("excite --kind multisine --rate-hz 1000 --period-samples 500 --periods 2 --transient-periods 1 "
                     "--band-hz 2,100 --channels 3 --mimo one-at-a-time --rms 0.05,0.05,1 --out " + (dir / "ms.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("simulate platform --excitation " + (dir / "ms.csv") + " --positions middle --out " + (dir / "rig"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string log = dir / "rig/middle_1000hz/exp_excitation.csv";
  const std::string common = "frf --method periodic --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 ";
  r = run_lpvid(common + "--out " + (dir / "a.csv") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid(common + "--period-samples 500 --periods 2 --transient-periods 1 --experiments 3 --out " +
                (dir / "b.csv") + " " + log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream a(dir / "a.csv"), b(dir / "b.csv");
  const std::string ta((std::istreambuf_iterator<char>(a)), {}), tb((std::istreambuf_iterator<char>(b)), {});
  EXPECT_FALSE(ta.empty());
  EXPECT_EQ(ta, tb);
}

}  // namespace frf_method_test
}  // namespace lpvid
