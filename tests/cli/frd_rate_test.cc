// The sample rate an FRD estimated from a log records ('# sample_rate_hz: X', .mat
// variable sample_rate_hz) and what fit/diagnose/compare --model do with it: warn
// (one line) when no rate is given, refuse a different one, say nothing otherwise.
//
// The data: lpvid's platform simulator (truth = the physical model `model init` writes,
// given to `simulate platform --truth-model`) in its sampled loop at 1 kHz, a short
// periodic multisine (1 s periods, 1 transient + 3 measured, one input at a time), and
// the plant P estimated by `frf --method periodic` at the three paper positions.  The
// rate the files must record is the one `excite --rate-hz 1000` put into the log, not
// anything lpvid's FRF code computes.
//
// Measured (this data, `fit --no-global` from the truth model, then `model export
// --xb 0 --rate-hz 1000` of each fit compared with the simulator's
// middle_1000hz/truth_plant.json by `lpvid compare`, 6-900 rad/s, weights 0.1,0.1,1):
//   without --rate-hz: fit error figure 10.27 % (noise floor 3.55 %), fitted plant vs
//                      truth 1.397 % mean, 1.729 % max weighted matrix error;
//   with --rate-hz 1000: fit error figure 3.98 %, fitted plant vs truth 0.008 % mean,
//                      0.010 % max.
// The test asserts the second is below a tenth of the first (measured ratio ~170).
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <matio.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>

#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "formats/io/model_json.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace frd_rate_test {

using ::testing::HasSubstr;
using ::testing::Not;
using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

int lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

class FrdRate : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<TempDir>("frd_rate");
    const TempDir& d = *dir_;
    auto ok = [](const std::string& args) {
      const auto r = run_lpvid(args);
      ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.err;
    };
    ok(fmt::format("excite --kind multisine --rate-hz 1000 --period-samples 1000 --periods 3 --transient-periods 1 "
                   "--realisations 1 --band-hz 1,150 --grid log --lines-per-decade 20 --channels 3 --mimo "
                   "one-at-a-time --rms 0.05,0.05,1 --seed 7 --out {}",
                   d / "ms.csv"));
    ok(fmt::format("model init --out {}", d / "truth.json"));
    ok(fmt::format("simulate platform --truth-model {} --excitation {} --positions left,middle,right --out {}",
                   d / "truth.json", d / "ms.csv", d / "rig"));
    for (const char* p : {"left", "middle", "right"})
      ok(fmt::format("frf --method periodic --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 --quantity P "
                     "--out {} {}",
                     d / fmt::format("P_{}.csv", p), d / fmt::format("rig/{}_1000hz/exp_excitation.csv", p)));
  }
  static void TearDownTestSuite() { dir_.reset(); }

  static std::string data(const std::string& prefix = "P_") {
    const TempDir& d = *dir_;
    return fmt::format("--data {}@-0.1 --data {}@0 --data {}@0.1", d / (prefix + "left.csv"),
                       d / (prefix + "middle.csv"), d / (prefix + "right.csv"));
  }
  // A copy of P_<p>.csv with its sample_rate_hz line replaced by `line` ("" = removed).
  static void rewrite(const std::string& to_prefix, const std::string& line) {
    for (const char* p : {"left", "middle", "right"}) {
      std::istringstream in(slurp(*dir_ / fmt::format("P_{}.csv", p)));
      std::ofstream out(*dir_ / fmt::format("{}{}.csv", to_prefix, p));
      for (std::string l; std::getline(in, l);) {
        if (l.rfind("# sample_rate_hz:", 0) == 0) {
          if (!line.empty()) out << line << "\n";
        } else {
          out << l << "\n";
        }
      }
    }
  }

  static inline std::unique_ptr<TempDir> dir_;
};

// Every frf method records the log's rate; the value is excite's --rate-hz (the log's
// Ts = (t_last - t_first) / (N - 1) from shortest-form timestamps: 1e-12 covers it).
TEST_F(FrdRate, FrfRecordsTheLogRateWithEveryMethod) {
  const TempDir& d = *dir_;
  const std::string log = d / "rig/middle_1000hz/exp_excitation.csv";
  for (const std::string method : {"welch", "lpm", "lrm"}) {
    const std::string out = d / fmt::format("S_{}.csv", method);
    const auto r = run_lpvid(fmt::format("frf --method {} --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out {} {}",
                                         method, out, log));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NEAR(read_frd_csv(out).sample_rate_hz, 1000.0, 1e-9) << method;
    EXPECT_THAT(slurp(out), HasSubstr("\n# sample_rate_hz: ")) << method;
  }
  EXPECT_NEAR(read_frd_csv(d / "P_middle.csv").sample_rate_hz, 1000.0, 1e-9);

  // Timestamps rounded to microseconds (a real logger's): 10 s at 1024 Hz records a rate
  // 4.4e-8 off the nominal (measured) -- why fit takes 1e-6 relative as the same rate.
  {
    std::ofstream log(d / "rounded.csv");
    log << "t,v1,y1\n";
    double y = 0;
    for (int k = 0; k < 10240; ++k) {
      const double v = std::sin(0.37 * k * k);  // broadband, deterministic
      y = 0.9 * y + v;
      log << fmt::format("{:.6f},{},{}\n", k / 1024.0, v, y);
    }
  }
  const auto r = run_lpvid(fmt::format("frf --excitation v1 --output y1 --quantity G --out {} {}", d / "rounded_G.csv",
                                       d / "rounded.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double off = std::abs(read_frd_csv(d / "rounded_G.csv").sample_rate_hz / 1024.0 - 1.0);
  EXPECT_GT(off, 1e-9);
  EXPECT_LT(off, 1e-6);
}

// The line and the .mat variable round-trip bit-exactly; a file without them reads 0
// and otherwise identical data (old files and analyzer exports are unchanged).
TEST_F(FrdRate, RateRoundTripsThroughCsvAndMatAndOldFilesReadUnchanged) {
  const TempDir& d = *dir_;
  FrequencyResponse f = read_frd_csv(d / "P_middle.csv");
  f.sample_rate_hz = 1.0 / 3e-4;  // not a short decimal: the writer must keep every bit
  write_frd_csv(d / "rt.csv", f, "P");
  EXPECT_EQ(read_frd_csv(d / "rt.csv").sample_rate_hz, f.sample_rate_hz);
  for (const MatVersion v : {MatVersion::kV5, MatVersion::kV73}) {
    const std::string path = d / (v == MatVersion::kV5 ? "rt5.mat" : "rt73.mat");
    write_frd_mat(path, f, "P", v);
    const FrequencyResponse back = read_frd_mat(path);
    EXPECT_EQ(back.sample_rate_hz, f.sample_rate_hz);
    EXPECT_EQ(back.omega_rad_s, f.omega_rad_s);
  }
  rewrite("old_", "");
  const FrequencyResponse with = read_frd_csv(d / "P_middle.csv"), without = read_frd_csv(d / "old_middle.csv");
  EXPECT_EQ(without.sample_rate_hz, 0.0);
  EXPECT_EQ(without.omega_rad_s, with.omega_rad_s);
  ASSERT_EQ(without.response.size(), with.response.size());
  for (size_t k = 0; k < with.response.size(); ++k) {
    EXPECT_EQ(without.response[k], with.response[k]);
    EXPECT_EQ(without.variance[k], with.variance[k]);
  }
  f.sample_rate_hz = 0;
  write_frd_mat(d / "norate.mat", f, "P");
  EXPECT_EQ(read_frd_mat(d / "norate.mat").sample_rate_hz, 0.0);
  EXPECT_THAT(slurp(d / "rt.csv"), HasSubstr("# sample_rate_hz: "));
  write_frd_csv(d / "norate.csv", f, "P");
  EXPECT_THAT(slurp(d / "norate.csv"), Not(HasSubstr("sample_rate_hz")));
  // Parts of one merge must agree on the rate.
  FrdPart a = read_frd_part(d / "P_middle.csv"), b = read_frd_part(d / "old_middle.csv");
  EXPECT_THROW(merge_frd_parts({a, b}), InputError);
}

// The warning: data from frf without --rate-hz (one line, what/why/what to do); none
// with --rate-hz or with the line removed (an analyzer's or an older file); the
// error figure with the line removed is exactly the one with it (the rate is never
// used silently).  And the effect on the fit, against the simulator's truth_plant.json.
TEST_F(FrdRate, WarnsExactlyWhenDataRecordARateAndNoneIsGiven) {
  const TempDir& d = *dir_;
  rewrite("old_", "");
  auto compare = [&](const std::string& data_args, const std::string& extra) {
    const auto r = run_lpvid(fmt::format("compare --model {} {} --json {}", d / "truth.json", data_args, extra));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return std::make_pair(r.err, r.exit_code == 0 ? nlohmann::json::parse(r.out).at("error").get<double>() : -1.0);
  };
  const auto [bare_err, bare] = compare(data(), "");
  EXPECT_EQ(lines(bare_err), 1) << bare_err;
  EXPECT_THAT(bare_err, HasSubstr("lpvid: warning: " + d / "P_left.csv"));
  EXPECT_THAT(bare_err, HasSubstr("sampled at 1000 Hz"));
  EXPECT_THAT(bare_err, HasSubstr("half-sample delay"));
  EXPECT_THAT(bare_err, HasSubstr("input_delay of about Ts/2 = 0.0005 s"));
  EXPECT_THAT(bare_err, HasSubstr("give --rate-hz 1000"));
  const auto [rated_err, rated] = compare(data(), "--rate-hz 1000");
  EXPECT_EQ(rated_err, "");
  const auto [old_err, old] = compare(data("old_"), "");
  EXPECT_EQ(old_err, "");
  EXPECT_EQ(old, bare);
  // Within 1e-6 relative (rounded timestamps) it is the same rate: no error, no warning.
  EXPECT_EQ(compare(data(), "--rate-hz 1000.0005").first, "");

  // The fits (LM from the truth, cheap): exported at x_b = 0 and compared with the
  // simulator's sampled plant there.  Measured 1.397 % vs 0.008 % mean (header).
  auto fit_vs_truth = [&](const std::string& name, const std::string& extra) {
    const auto f = run_lpvid(fmt::format("fit --model {} {} --no-global {} --out {}", d / "truth.json", data(), extra,
                                         d / (name + ".json")));
    EXPECT_EQ(f.exit_code, 0) << f.err;
    EXPECT_EQ(lines(f.err), extra.empty() ? 1 : 0) << f.err;  // the warning, once, only without the rate
    const auto e = run_lpvid(fmt::format("model export --model {} --xb 0 --rate-hz 1000 --out {}", d / (name + ".json"),
                                         d / (name + "_mid.json")));
    EXPECT_EQ(e.exit_code, 0) << e.err;
    const auto c = run_lpvid(fmt::format("compare {} {} --band-min 6 --band-max 900 --weights 0.1,0.1,1 --json",
                                         d / (name + "_mid.json"), d / "rig/middle_1000hz/truth_plant.json"));
    EXPECT_EQ(c.exit_code, 0) << c.err;
    return c.exit_code == 0 ? nlohmann::json::parse(c.out) : nlohmann::json();
  };
  const nlohmann::json continuous = fit_vs_truth("fit_continuous", "");
  const nlohmann::json sampled = fit_vs_truth("fit_sampled", "--rate-hz 1000");
  ASSERT_TRUE(continuous.contains("weighted_error_mean") && sampled.contains("weighted_error_mean")) << continuous.dump();
  std::fprintf(stderr, "[rate] fitted plant vs truth_plant.json, mean weighted error: without --rate-hz %.4g, with %.4g\n",
               continuous.at("weighted_error_mean").get<double>(), sampled.at("weighted_error_mean").get<double>());
  EXPECT_LT(sampled.at("weighted_error_mean").get<double>(), 0.1 * continuous.at("weighted_error_mean").get<double>());
}

// A measured controller (FRD) without a rate and S data from frf: one warning line,
// the recorded rate's (not both).
TEST_F(FrdRate, OneWarningLineWithAMeasuredControllerToo) {
  const TempDir& d = *dir_;
  const std::string s = d / "S_mid.csv";
  ASSERT_EQ(run_lpvid(fmt::format("frf --method periodic --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out {} "
                                  "{}",
                                  s, d / "rig/middle_1000hz/exp_excitation.csv"))
                .exit_code,
            0);
  const FrequencyResponse sd = read_frd_csv(s);
  FrequencyResponse c = frequency_response(read_state_space(d / "rig/middle_1000hz/controller.json"), sd.omega_rad_s);
  write_frd_csv(d / "C.csv", c, "C");
  const auto r = run_lpvid(fmt::format("compare --model {} --target S --controller {} --data {}@0 --json",
                                       d / "truth.json", d / "C.csv", s));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr("sampled at 1000 Hz"));
  EXPECT_THAT(r.err, Not(HasSubstr("measured response with no sample rate")));
  // The discrete controller model gives the rate (the lab sample's S route): silent.
  const auto m = run_lpvid(fmt::format("compare --model {} --target S --controller {} --data {}@0 --json",
                                       d / "truth.json", d / "rig/middle_1000hz/controller.json", s));
  EXPECT_EQ(m.exit_code, 0) << m.err;
  EXPECT_EQ(m.err, "");
}

// A rate other than the recorded one: exit 2, one line naming the file and both
// rates, nothing written.  A malformed or repeated line: file:line:column, exit 2.
TEST_F(FrdRate, MismatchAndMalformedLinesAreExit2) {
  const TempDir& d = *dir_;
  const auto r = run_lpvid(fmt::format("fit --model {} {} --no-global --rate-hz 2000 --out {}", d / "truth.json",
                                       data(), d / "mismatch.json"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(lines(r.err), 1) << r.err;
  EXPECT_THAT(r.err, HasSubstr(d / "P_left.csv"));
  EXPECT_THAT(r.err, HasSubstr("1000 Hz"));
  EXPECT_THAT(r.err, HasSubstr("--rate-hz 2000"));
  EXPECT_FALSE(std::filesystem::exists(d / "mismatch.json"));
  const auto diag = run_lpvid(fmt::format("diagnose --model {} {} --rate-hz 2000", d / "truth.json", data()));
  EXPECT_EQ(diag.exit_code, 2);
  EXPECT_EQ(lines(diag.err), 1) << diag.err;

  // The line's position: line 2 of the file frf wrote (after its one comment line).
  const std::string bad = "# sample_rate_hz: 1kHz";
  rewrite("bad_", bad);
  const auto m = run_lpvid(fmt::format("compare --model {} {}", d / "truth.json", data("bad_")));
  EXPECT_EQ(m.exit_code, 2);
  EXPECT_EQ(lines(m.err), 1) << m.err;
  EXPECT_THAT(m.err, HasSubstr(fmt::format("{}:2:{}: 'sample_rate_hz: 1kHz' is not a sample rate", d / "bad_left.csv",
                                           bad.find("1kHz") + 1)));
  for (const std::string value : {"0", "-1000", "nan", "1e400", ""}) {
    rewrite("bad_", "# sample_rate_hz: " + value);
    EXPECT_THROW(read_frd_csv(d / "bad_left.csv"), InputError) << value;
  }
  rewrite("bad_", "# sample_rate_hz: 1000\n# sample_rate_hz: 1000");
  try {
    read_frd_csv(d / "bad_left.csv");
    ADD_FAILURE() << "a repeated line was read";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("bad_left.csv:3:3: 'sample_rate_hz' is given twice (also on line 2)"));
  }

  // .mat: a sample_rate_hz that is not one positive number.
  const std::string mat = d / "bad.mat";
  {
    mat_t* f = Mat_CreateVer(mat.c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(f, nullptr);
    double hz[2] = {1.0, 2.0}, p[2] = {1.0, 0.5}, rate[1] = {-1000.0};
    size_t d2[2] = {2, 1}, d1[2] = {1, 1};
    for (auto [name, dims, values] : {std::tuple{"freq_hz", d2, hz}, std::tuple{"P", d2, p},
                                      std::tuple{"sample_rate_hz", d1, rate}}) {
      matvar_t* v = Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, values, 0);
      ASSERT_EQ(Mat_VarWrite(f, v, MAT_COMPRESSION_NONE), 0);
      Mat_VarFree(v);
    }
    Mat_Close(f);
  }
  const auto bm = run_lpvid(fmt::format("compare --model {} --data {}@0 --noise-level 0.01", d / "truth.json", mat));
  EXPECT_EQ(bm.exit_code, 2);
  EXPECT_EQ(lines(bm.err), 1) << bm.err;
  EXPECT_THAT(bm.err, HasSubstr(fmt::format("'{}': 'sample_rate_hz' must be one number > 0", mat)));
}

}  // namespace frd_rate_test
}  // namespace lpvid
