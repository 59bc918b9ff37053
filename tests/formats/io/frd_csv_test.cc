#include "formats/io/frd_csv.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace frd_csv_test {

using test::input_error;

class FrdCsv : public test::TempDirTest {};

constexpr unsigned kSeed = 20261124;  // named seed for the random responses

// A random ny x nu response on nf frequencies from 0.5 Hz up, omegas = 2*pi*f
// as a reader computes them.
FrequencyResponse random_frd(Index nf, Index ny, Index nu, unsigned seed, bool coherence, bool flags) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  FrequencyResponse frd;
  frd.omega_rad_s.resize(nf);
  double f = 0.5;
  for (Index k = 0; k < nf; ++k) {
    frd.omega_rad_s[k] = f * (2.0 * std::numbers::pi);
    f += 0.1 + unit(rng);
    Eigen::MatrixXcd h(ny, nu);
    Eigen::MatrixXd c(ny, nu);
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j) {
        h(i, j) = Complex(normal(rng), normal(rng));
        c(i, j) = unit(rng);
      }
    frd.response.push_back(h);
    if (coherence) frd.coherence.push_back(c);
    if (flags) frd.flagged.push_back(unit(rng) < 0.3);
  }
  return frd;
}

void expect_identical(const FrequencyResponse& a, const FrequencyResponse& b) {
  ASSERT_EQ(a.num_frequencies(), b.num_frequencies());
  EXPECT_TRUE((a.omega_rad_s.array() == b.omega_rad_s.array()).all());
  ASSERT_EQ(a.response.size(), b.response.size());
  for (size_t k = 0; k < a.response.size(); ++k) {
    ASSERT_EQ(a.response[k].rows(), b.response[k].rows());
    ASSERT_EQ(a.response[k].cols(), b.response[k].cols());
    EXPECT_TRUE((a.response[k].array() == b.response[k].array()).all()) << "frequency " << k;
  }
  ASSERT_EQ(a.coherence.size(), b.coherence.size());
  for (size_t k = 0; k < a.coherence.size(); ++k) EXPECT_TRUE((a.coherence[k].array() == b.coherence[k].array()).all());
  ASSERT_EQ(a.variance.size(), b.variance.size());
  for (size_t k = 0; k < a.variance.size(); ++k) EXPECT_TRUE((a.variance[k].array() == b.variance[k].array()).all());
  EXPECT_EQ(a.averages, b.averages);
  EXPECT_EQ(a.flagged, b.flagged);
  EXPECT_EQ(a.output_names, b.output_names);
  EXPECT_EQ(a.input_names, b.input_names);
}

TEST(FrdCsvOptions, BadQuantityAndToleranceAreRejected) {
  FrdReadOptions read;
  read.quantity = "S_1";
  EXPECT_EQ(input_error([&] { read.validate(); }),
            "quantity 'S_1' is not allowed; use letters and digits (not 'coh'), e.g. S");
  FrdMergeOptions merge;
  merge.frequency_tolerance = -1;
  EXPECT_EQ(input_error([&] { merge.validate(); }),
            "frequency tolerance -1 is not allowed; give a finite relative tolerance >= 0, e.g. 1e-9");
}

TEST_F(FrdCsv, WriteThenRead_GivesIdenticalDoubles) {
  FrequencyResponse frd = random_frd(50, 2, 3, kSeed, true, true);
  frd.output_names = {"psi", "theta"};
  frd.input_names = {"u1", "u2", "u3"};
  const std::string p = path("s.csv");
  write_frd_csv(p, frd, "S", {"SigLab export", "rig 2"});
  expect_identical(read_frd_csv(p), frd);
  EXPECT_EQ(read(p).rfind("# SigLab export\n# rig 2\n# outputs: psi,theta\n# inputs: u1,u2,u3\n"
                         "freq_hz,S_psi_u1_re,S_psi_u1_im,S_psi_u2_re,",
                         0),
            0u);
}

// The estimator's variance per entry and the averages behind the coherence travel
// with the response (issues 10, 11, 14: noise bands from the data, not a default).
TEST_F(FrdCsv, VarianceAndAverages_RoundTripExactly) {
  FrequencyResponse frd = random_frd(30, 3, 2, kSeed + 7, true, false);
  for (const auto& h : frd.response) frd.variance.push_back(h.cwiseAbs2() * 1e-4);
  frd.averages = 16;
  const std::string p = path("v.csv");
  write_frd_csv(p, frd, "S");
  expect_identical(read_frd_csv(p), frd);
  const std::string text = read(p);
  EXPECT_EQ(text.rfind("# averages: 16\nfreq_hz,", 0), 0u) << text.substr(0, 80);
  EXPECT_NE(text.find(",var_1_1,var_1_2,var_2_1,"), std::string::npos);
}

TEST_F(FrdCsv, MergedParts_KeepVarianceAndAverages) {
  FrequencyResponse full = random_frd(12, 2, 2, kSeed + 8, true, false);
  for (const auto& h : full.response) full.variance.push_back(h.cwiseAbs2() * 1e-3);
  full.averages = 8;
  std::vector<FrdPart> parts;
  for (Index j = 0; j < 2; ++j) {
    FrequencyResponse one = full;
    one.input_names = {"v" + std::to_string(j + 1)};
    for (size_t k = 0; k < one.response.size(); ++k) {
      one.response[k] = full.response[k].col(j);
      one.coherence[k] = full.coherence[k].col(j);
      one.variance[k] = full.variance[k].col(j);
    }
    const std::string p = path("part" + std::to_string(j) + ".csv");
    write_frd_csv(p, one, "S");
    parts.push_back(read_frd_part(p));
  }
  const FrequencyResponse merged = merge_frd_parts(parts);
  EXPECT_EQ(merged.averages, 8);
  ASSERT_EQ(merged.variance.size(), full.variance.size());
  for (size_t k = 0; k < full.variance.size(); ++k) EXPECT_TRUE((merged.variance[k].array() == full.variance[k].array()).all());
  // averages that differ between parts are refused
  FrequencyResponse other = full;
  other.averages = 4;
  for (size_t k = 0; k < other.response.size(); ++k) {
    other.response[k] = full.response[k].col(0);
    other.coherence[k] = full.coherence[k].col(0);
    other.variance[k] = full.variance[k].col(0);
  }
  other.input_names = {"v2"};
  write_frd_csv(path("odd.csv"), other, "S");
  const std::vector<FrdPart> mixed{parts[0], read_frd_part(path("odd.csv"))};
  EXPECT_NE(input_error([&] { merge_frd_parts(mixed); }).find("states 8 averages but"), std::string::npos);
}

TEST_F(FrdCsv, UnnamedChannels_AreWrittenAsIndicesAndReadBackUnnamed) {
  const FrequencyResponse frd = random_frd(5, 2, 2, kSeed + 1, false, false);
  const std::string p = path("p.csv");
  write_frd_csv(p, frd, "P");
  EXPECT_EQ(read(p).rfind("freq_hz,P_1_1_re,P_1_1_im,P_1_2_re,P_1_2_im,P_2_1_re,P_2_1_im,P_2_2_re,P_2_2_im\n0.5,", 0),
            0u);
  expect_identical(read_frd_csv(p), frd);
}

TEST_F(FrdCsv, AnyOmega_RoundTripsToTheNearestDoubleAndOmegasFromFilesExactly) {
  // Multiplying by 2*pi skips doubles, so an arbitrary omega may come back one
  // ulp off; an omega computed from a freq_hz (any file read) comes back exactly.
  std::mt19937_64 rng(kSeed + 2);
  std::uniform_real_distribution<double> log_f(-3, 6);
  FrequencyResponse arbitrary, from_hz;
  constexpr Index kCount = 2000;
  std::vector<double> w(kCount), f(kCount);
  for (Index k = 0; k < kCount; ++k) f[static_cast<size_t>(k)] = std::pow(10.0, log_f(rng));
  std::sort(f.begin(), f.end());
  arbitrary.omega_rad_s.resize(kCount);
  from_hz.omega_rad_s.resize(kCount);
  for (Index k = 0; k < kCount; ++k) {
    from_hz.omega_rad_s[k] = f[static_cast<size_t>(k)] * (2.0 * std::numbers::pi);
    arbitrary.omega_rad_s[k] = f[static_cast<size_t>(k)] * 7.0;
    arbitrary.response.push_back(Eigen::MatrixXcd::Ones(1, 1));
    from_hz.response.push_back(Eigen::MatrixXcd::Ones(1, 1));
  }
  write_frd_csv(path("a.csv"), arbitrary, "G");
  write_frd_csv(path("b.csv"), from_hz, "G");
  const FrequencyResponse a = read_frd_csv(path("a.csv")), b = read_frd_csv(path("b.csv"));
  EXPECT_TRUE((b.omega_rad_s.array() == from_hz.omega_rad_s.array()).all());
  for (Index k = 0; k < kCount; ++k)
    EXPECT_LE(std::abs(a.omega_rad_s[k] - arbitrary.omega_rad_s[k]), std::abs(std::nextafter(arbitrary.omega_rad_s[k], 0.0) - arbitrary.omega_rad_s[k]));
}

TEST_F(FrdCsv, ReImAndDbDeg_GiveTheSameResponse) {
  const FrequencyResponse frd = random_frd(40, 2, 2, kSeed + 3, false, false);
  std::string polar = "freq_hz,S_1_1_db,S_1_1_deg,S_1_2_db,S_1_2_deg,S_2_1_db,S_2_1_deg,S_2_2_db,S_2_2_deg\n";
  for (Index k = 0; k < frd.num_frequencies(); ++k) {
    polar += fmt::format("{}", frd.omega_rad_s[k] / (2.0 * std::numbers::pi));
    for (Index i = 0; i < 2; ++i)
      for (Index j = 0; j < 2; ++j) {
        const Complex h = frd.response[static_cast<size_t>(k)](i, j);
        polar += fmt::format(",{},{}", 20.0 * std::log10(std::abs(h)), std::arg(h) * 180.0 / std::numbers::pi);
      }
    polar += '\n';
  }
  const FrequencyResponse read_back = read_frd_csv(write("polar.csv", polar));
  // db/deg -> complex costs a pow, a cos and a sin: a few ulps, far below 1e-12.
  constexpr double kPolarTolerance = 1e-12;
  for (Index k = 0; k < frd.num_frequencies(); ++k) {
    const auto& a = frd.response[static_cast<size_t>(k)];
    const auto& b = read_back.response[static_cast<size_t>(k)];
    for (Index i = 0; i < 2; ++i)
      for (Index j = 0; j < 2; ++j) EXPECT_LE(std::abs(a(i, j) - b(i, j)), kPolarTolerance * std::abs(a(i, j)));
  }
}

TEST_F(FrdCsv, MixedFormsPerPairAndColumnOrder_AreAccepted) {
  const std::string p = write("m.csv",
                              "# analyzer export\n"
                              "freq_hz,S_1_2_deg,S_1_1_re,flag,coh_1_1,S_1_1_im,S_1_2_db,coh_1_2\n"
                              "1,90,1.5,0,0.9,-2,20,1\n"
                              "2.5,-180,3,1,0,4,0,0.5\n");
  const FrequencyResponse frd = read_frd_csv(p);
  ASSERT_EQ(frd.num_frequencies(), 2);
  EXPECT_EQ(frd.omega_rad_s[1], 2.5 * (2.0 * std::numbers::pi));
  EXPECT_EQ(frd.num_outputs(), 1);
  EXPECT_EQ(frd.num_inputs(), 2);
  EXPECT_EQ(frd.response[0](0, 0), Complex(1.5, -2));
  EXPECT_NEAR(frd.response[0](0, 1).real(), 0.0, 1e-14);
  EXPECT_NEAR(frd.response[0](0, 1).imag(), 10.0, 1e-14);
  EXPECT_NEAR(frd.response[1](0, 1).real(), -1.0, 1e-15);
  EXPECT_EQ(frd.coherence[1](0, 1), 0.5);
  EXPECT_EQ(frd.flagged, (std::vector<bool>{false, true}));
  EXPECT_TRUE(frd.output_names.empty());
  EXPECT_TRUE(frd.input_names.empty());
}

TEST_F(FrdCsv, IndexAndNameColumns_GiveTheSameResponse) {
  const std::string by_index = write("i.csv", "freq_hz,S_1_1_re,S_1_1_im,S_2_1_re,S_2_1_im\n1,1,2,3,4\n");
  const std::string by_name = write("n.csv", "freq_hz,S_theta_v_re,S_theta_v_im,S_psi_v_re,S_psi_v_im\n1,3,4,1,2\n");
  const FrequencyResponse a = read_frd_csv(by_index), b = read_frd_csv(by_name);
  EXPECT_EQ(b.output_names, (std::vector<std::string>{"theta", "psi"}));  // header order
  EXPECT_EQ(b.input_names, (std::vector<std::string>{"v"}));
  EXPECT_EQ(a.response[0](0, 0), b.response[0](1, 0));
  EXPECT_EQ(a.response[0](1, 0), b.response[0](0, 0));
  // Names from metadata keep the metadata's order and may hold '_'.
  const std::string meta = write("meta.csv",
                                 "# outputs: psi,theta_b\n# inputs: u_1\n"
                                 "freq_hz,S_theta_b_u_1_re,S_theta_b_u_1_im,S_psi_u_1_re,S_psi_u_1_im\n1,3,4,1,2\n");
  const FrequencyResponse c = read_frd_csv(meta);
  EXPECT_EQ(c.output_names, (std::vector<std::string>{"psi", "theta_b"}));
  EXPECT_EQ(c.input_names, (std::vector<std::string>{"u_1"}));
  EXPECT_EQ(c.response[0](0, 0), Complex(1, 2));
  EXPECT_EQ(c.response[0](1, 0), Complex(3, 4));
}

TEST_F(FrdCsv, NamesWithUnderscores_RoundTripThroughMetadata) {
  FrequencyResponse frd = random_frd(3, 2, 1, kSeed + 4, true, false);
  frd.output_names = {"q_1", "q_2"};
  frd.input_names = {"v_a"};
  const std::string p = path("u.csv");
  write_frd_csv(p, frd, "G");
  expect_identical(read_frd_csv(p), frd);
}

TEST_F(FrdCsv, QuantityOption_SelectsOneOfSeveral) {
  const std::string p = write("st.csv", "freq_hz,S_1_1_re,S_1_1_im,T_1_1_re,T_1_1_im\n1,1,2,3,4\n");
  FrdReadOptions t;
  t.quantity = "T";
  EXPECT_EQ(read_frd_csv(p, t).response[0](0, 0), Complex(3, 4));
  EXPECT_EQ(input_error([&] { read_frd_csv(p); }),
            p + ":1:27: column 'T_1_1_re' holds quantity 'T' but column 'S_1_1_re' holds 'S'; a file holds one "
                "quantity, or choose one with the quantity option");
  FrdReadOptions g;
  g.quantity = "G";
  EXPECT_EQ(input_error([&] { read_frd_csv(p, g); }),
            p + ":1:1: no columns of quantity 'G'; the file holds S, T; choose one of them");
}

TEST_F(FrdCsv, AtomicWriterOverload_StagesTheFile) {
  const FrequencyResponse frd = random_frd(3, 1, 1, kSeed + 5, false, true);
  AtomicOutputSet out;
  write_frd_csv(out.stage(path("g.csv")), frd, "G");
  EXPECT_EQ(entries().size(), 1u);  // only the temporary
  EXPECT_FALSE(std::filesystem::exists(path("g.csv")));
  out.commit();
  expect_identical(read_frd_csv(path("g.csv")), frd);
}

// ---- reading errors, every message pinned ----------------------------------

struct BadFile {
  const char* name;
  const char* text;
  const char* message;  // after "path:"
};

class FrdCsvErrors : public FrdCsv, public ::testing::WithParamInterface<BadFile> {};

TEST_P(FrdCsvErrors, MessageIsPinned) {
  const BadFile& bad = GetParam();
  const std::string p = write("bad.csv", bad.text);
  EXPECT_EQ(input_error([&] { read_frd_csv(p); }), p + ":" + bad.message);
}

INSTANTIATE_TEST_SUITE_P(
    Rules, FrdCsvErrors,
    ::testing::Values(
        BadFile{"EmptyFile", "",
                "1:1: the file is empty; give a file that starts with a header row naming the columns, e.g. 't,v1,q1'"},
        BadFile{"NoFrequencyColumn", "f,S_1_1_re,S_1_1_im\n1,2,3\n",
                "1:1: no column 'freq_hz' in the header; the header must name 'freq_hz' (Hz) and the response columns, "
                "e.g. 'freq_hz,S_1_1_re,S_1_1_im' (see docs/formats.md)"},
        BadFile{"MissingImaginaryPart", "freq_hz,S_1_1_re,S_1_1_im,S_2_1_re\n1,2,3,4\n",
                "1:27: no column 'S_2_1_im' for the imaginary part of output 2, input 1 (its real part is column "
                "'S_2_1_re'); give both 'S_2_1_re' and 'S_2_1_im', or 'S_2_1_db' and 'S_2_1_deg'"},
        BadFile{"MissingMagnitude", "freq_hz,S_1_1_deg\n1,2\n",
                "1:9: no column 'S_1_1_db' for the magnitude in dB of output 1, input 1 (its phase in degrees is "
                "column 'S_1_1_deg'); give both 'S_1_1_re' and 'S_1_1_im', or 'S_1_1_db' and 'S_1_1_deg'"},
        BadFile{"MissingPair", "freq_hz,S_1_1_re,S_1_1_im,S_2_2_re,S_2_2_im\n1,2,3,4,5\n",
                "1:1: no columns for output 1, input 2; every output/input pair needs a response: give both "
                "'S_1_2_re' and 'S_1_2_im', or 'S_1_2_db' and 'S_1_2_deg'"},
        BadFile{"MissingNamedPair", "# inputs: u1,u2\nfreq_hz,S_psi_u1_re,S_psi_u1_im\n1,2,3\n",
                "2:1: no columns for output 'psi', input 'u2'; every output/input pair needs a response: give both "
                "'S_psi_u2_re' and 'S_psi_u2_im', or 'S_psi_u2_db' and 'S_psi_u2_deg'"},
        BadFile{"MixedReImAndDbDeg", "freq_hz,S_1_1_re,S_1_1_deg\n1,2,3\n",
                "1:18: columns 'S_1_1_re' and 'S_1_1_deg' mix re/im with db/deg for output 1, input 1; give both "
                "'S_1_1_re' and 'S_1_1_im', or 'S_1_1_db' and 'S_1_1_deg'"},
        BadFile{"NegativeVariance", "freq_hz,S_1_1_re,S_1_1_im,var_1_1\n1,2,3,-4\n",
                "2:7: variance -4 in column 'var_1_1' is negative; write a variance >= 0"},
        BadFile{"VarianceOfAMissingPair", "freq_hz,S_1_1_re,S_1_1_im,var_1_2\n1,2,3,4\n",
                "1:27: column 'var_1_2' is the variance of output 1, input 2, which have no response columns; give "
                "variance only for pairs with a response"},
        BadFile{"VarianceForSomePairsOnly", "freq_hz,S_1_1_re,S_1_1_im,S_2_1_re,S_2_1_im,var_1_1\n1,2,3,4,5,6\n",
                "1:45: no column 'var_2_1' for the variance of output 2, input 1; give variance for every pair or for "
                "none"},
        BadFile{"AveragesNotANumber", "# averages: many\nfreq_hz,S_1_1_re,S_1_1_im\n1,2,3\n",
                "1:3: 'averages: many' is not a number of averages; give the independent averages behind the "
                "coherence as a number >= 1, e.g. '# averages: 16'"},
        BadFile{"AveragesTwice", "# averages: 4\n# averages: 4\nfreq_hz,S_1_1_re,S_1_1_im\n1,2,3\n",
                "2:3: 'averages' is given twice (also on line 1); give it once"},
        BadFile{"DuplicateColumn", "freq_hz,S_1_1_re,S_1_1_im,S_1_1_re\n1,2,3,4\n",
                "1:27: duplicate column name 'S_1_1_re' (also column 2); give every column its own name"},
        BadFile{"DuplicateColumnByIndex", "freq_hz,S_1_1_re,S_1_1_im,S_01_1_im\n1,2,3,4\n",
                "1:27: column 'S_01_1_im' repeats column 3 'S_1_1_im' (imaginary part of output 1, input 1); give "
                "each column once"},
        BadFile{"NonIncreasingFrequency", "freq_hz,S_1_1_re,S_1_1_im\n1,2,3\n# c\n1,2,3\n",
                "4:1: frequency 1 Hz is not above the previous row's 1 Hz; freq_hz must increase strictly from row "
                "to row"},
        BadFile{"NonPositiveFrequency", "S_1_1_re,S_1_1_im,freq_hz\n1,2,0\n",
                "2:5: frequency 0 Hz is not positive; give freq_hz > 0 in Hz"},
        BadFile{"NaN", "freq_hz,S_1_1_re,S_1_1_im\n1,nan,3\n",
                "2:3: 'nan' in column 'S_1_1_re' is not a finite number; write a finite number there (NaN/Inf not allowed)"},
        BadFile{"Inf", "freq_hz,S_1_1_re,S_1_1_im\n1,2,-inf\n",
                "2:5: '-inf' in column 'S_1_1_im' is not a finite number; write a finite number there (NaN/Inf not allowed)"},
        BadFile{"CoherenceAboveOne", "freq_hz,S_1_1_re,S_1_1_im,coh_1_1\n1,2,3,0.5\n2,2,3,  1.25\n",
                "3:9: coherence 1.25 in column 'coh_1_1' is outside [0, 1]; write a coherence between 0 and 1"},
        BadFile{"CoherenceForSomePairs", "freq_hz,S_1_1_re,S_1_1_im,S_1_2_re,S_1_2_im,coh_1_2\n1,2,3,4,5,1\n",
                "1:45: no column 'coh_1_1' for the coherence of output 1, input 1; give coherence for every pair or "
                "for none"},
        BadFile{"CoherenceWithoutResponse", "freq_hz,S_1_1_re,S_1_1_im,coh_2_1\n1,2,3,1\n",
                "1:27: column 'coh_2_1' is the coherence of output 2, input 1, which have no response columns; "
                "give coherence only for pairs with a response"},
        BadFile{"FlagNotBinary", "freq_hz,S_1_1_re,S_1_1_im,flag\n1,2,3,2\n",
                "2:7: flag 2 is not 0 or 1; write 1 for an untrusted frequency, else 0"},
        BadFile{"UnknownColumn", "freq_hz,S_1_1_re,S_1_1_im,temp\n1,2,3,4\n",
                "1:27: column 'temp' is not an FRD column; the columns are freq_hz, <Q>_<output>_<input>_re and _im "
                "(or _db and _deg), coh_<output>_<input>, var_<output>_<input>, dvar_<output>_<input> and flag, with <Q> letters and digits (S, P, "
                "G, ...): rename or remove the column"},
        BadFile{"UnderscoreNameWithoutMetadata", "freq_hz,S_q_1_v_re,S_q_1_v_im\n1,2,3\n",
                "1:9: cannot split 'q_1_v' of column 'S_q_1_v_re' into an output and an input; without '# outputs:' "
                "and '# inputs:' metadata a channel is an index or a name without '_', so write <output>_<input> "
                "with one '_' or list the names in '# outputs: ...' and '# inputs: ...' lines before the header"},
        BadFile{"NameNotInMetadata", "# outputs: psi\nfreq_hz,S_phi_u_re,S_phi_u_im\n1,2,3\n",
                "2:9: cannot split 'phi_u' of column 'S_phi_u_re' into a listed output and input (outputs psi; "
                "inputs <names without '_' or indices>); check the names against the '# outputs:' and '# inputs:' "
                "lines"},
        BadFile{"AmbiguousSplit", "# outputs: a,a_b\n# inputs: b_c,c\nfreq_hz,S_a_b_c_re,S_a_b_c_im\n1,2,3\n",
                "3:9: column 'S_a_b_c_re' splits two ways (output 'a', input 'b_c' or output 'a_b', input 'c'); "
                "rename the channels so that <output>_<input> splits one way"},
        BadFile{"IndexMixedWithName", "freq_hz,S_1_1_re,S_1_1_im,S_psi_1_re,S_psi_1_im\n1,2,3,4,5\n",
                "1:27: column 'S_psi_1_re' names output 'psi' but column 'S_1_1_re' names output index '1'; name "
                "all outputs by index or all by name"},
        BadFile{"IndexZero", "freq_hz,S_1_0_re,S_1_0_im\n1,2,3\n",
                "1:9: input index '0' in column 'S_1_0_re' is not allowed; give an index from 1 to 256"},
        BadFile{"MetadataTwice", "# outputs: a\n# outputs: b\nfreq_hz,S_a_1_re,S_a_1_im\n1,2,3\n",
                "2:3: 'outputs' is given twice (also on line 1); give it once"},
        BadFile{"MetadataNameTwice", "# inputs: u, v,u\nfreq_hz,S_1_u_re,S_1_u_im\n1,2,3\n",
                "1:16: name 'u' appears twice in 'inputs'; give every channel its own name"},
        BadFile{"NoResponseColumns", "freq_hz,flag\n1,0\n",
                "1:1: no response columns; add <Q>_<output>_<input>_re and _im (or _db and _deg) columns, e.g. "
                "'S_1_1_re,S_1_1_im'"},
        BadFile{"NoRows", "freq_hz,S_1_1_re,S_1_1_im\n# nothing measured\n",
                "3:1: no rows after the header; give one row per frequency"}),
    [](const ::testing::TestParamInfo<BadFile>& info) { return std::string(info.param.name); });

TEST_F(FrdCsv, MissingFile_IsReportedWithoutPosition) {
  EXPECT_EQ(input_error([&] { read_frd_csv(path("none.csv")); }),
            "cannot open '" + path("none.csv") + "': No such file or directory; check the path");
}

// ---- writing errors --------------------------------------------------------

TEST_F(FrdCsv, WriterRejectsBadInput_AndLeavesNoFile) {
  FrequencyResponse frd = random_frd(3, 1, 2, kSeed + 6, false, false);
  const std::string p = path("w.csv");
  EXPECT_EQ(input_error([&] { write_frd_csv(p, frd, "coh"); }),
            "cannot write '" + p + "': quantity 'coh' is not allowed; use letters and digits (not 'coh'), e.g. S");
  EXPECT_EQ(input_error([&] { write_frd_csv(p, frd, "S", {"outputs: a"}); }),
            "cannot write '" + p + "': comment 'outputs: a' would be read as '# outputs:' metadata; reword it");
  FrequencyResponse names = frd;
  names.input_names = {"a b", "c"};
  EXPECT_EQ(input_error([&] { write_frd_csv(p, names, "S"); }),
            "cannot write '" + p + "': input name 'a b' is not allowed; use names without commas, quotes, blanks or "
                                   "line breaks");
  FrequencyResponse ambiguous = frd;
  ambiguous.output_names = {"a_b"};
  ambiguous.input_names = {"c", "b_c"};
  ambiguous.output_names = {"a"};
  ambiguous.response.assign(3, Eigen::MatrixXcd::Ones(2, 2));
  ambiguous.output_names = {"a", "a_b"};
  EXPECT_EQ(input_error([&] { write_frd_csv(p, ambiguous, "S"); }),
            "cannot write '" + p + "': output 'a' and input 'b_c' give 'a_b_c', which does not split one way into an "
                                   "output and an input; rename the channels");
  FrequencyResponse nan = frd;
  nan.response[1](0, 1) = Complex(0, NAN);
  EXPECT_EQ(input_error([&] { write_frd_csv(p, nan, "S"); }),
            "cannot write '" + p + "': response 2 (1, 2) is (0,nan); only finite values can be written");
  FrequencyResponse decreasing = frd;
  decreasing.omega_rad_s[2] = decreasing.omega_rad_s[1];
  EXPECT_EQ(input_error([&] { write_frd_csv(p, decreasing, "S"); }),
            fmt::format("cannot write '{}': frequency 3 is {} rad/s; frequencies must be finite, positive and strictly "
                        "increasing",
                        p, frd.omega_rad_s[1]));
  FrequencyResponse coherence = frd;
  coherence.coherence.assign(3, Eigen::MatrixXd::Constant(1, 2, 1.5));
  EXPECT_EQ(input_error([&] { write_frd_csv(p, coherence, "S"); }),
            "cannot write '" + p + "': coherence 1 (1, 1) is 1.5; coherence must be in [0, 1]");
  FrequencyResponse flags = frd;
  flags.flagged = {true};
  EXPECT_EQ(input_error([&] { write_frd_csv(p, flags, "S"); }),
            "cannot write '" + p + "': 1 flags for 3 frequencies; give one per frequency or none");
  EXPECT_TRUE(entries().empty());
}

// ---- merging ---------------------------------------------------------------

TEST_F(FrdCsv, MergeOfThreeOneInputFiles_EqualsTheFullFile) {
  // The analyzer excites one input at a time: file k holds input k only.
  FrequencyResponse full = random_frd(30, 2, 3, kSeed + 7, true, false);
  const std::string full_path = path("full.csv");
  write_frd_csv(full_path, full, "S");
  std::vector<FrdPart> parts;
  for (Index j = 0; j < 3; ++j) {
    std::string text = fmt::format("freq_hz,S_1_{0}_re,S_1_{0}_im,S_2_{0}_re,S_2_{0}_im,coh_1_{0},coh_2_{0},flag\n", j + 1);
    for (Index k = 0; k < full.num_frequencies(); ++k) {
      const auto& h = full.response[static_cast<size_t>(k)];
      const auto& c = full.coherence[static_cast<size_t>(k)];
      text += fmt::format("{},{},{},{},{},{},{},{}\n", full.omega_rad_s[k] / (2.0 * std::numbers::pi), h(0, j).real(),
                          h(0, j).imag(), h(1, j).real(), h(1, j).imag(), c(0, j), c(1, j), j == 1 && k == 4 ? 1 : 0);
    }
    parts.push_back(read_frd_part(write(fmt::format("u{}.csv", j + 1), text)));
    EXPECT_EQ(parts.back().pairs, (std::vector<std::pair<Index, Index>>{{0, j}, {1, j}}));
  }
  const FrequencyResponse merged = merge_frd_parts({parts[2], parts[0], parts[1]});
  FrequencyResponse expected = read_frd_csv(full_path);
  expected.flagged.assign(30, false);
  expected.flagged[4] = true;
  expect_identical(merged, expected);
}

TEST_F(FrdCsv, MergeOfNamedParts_MatchesByName) {
  const FrdPart a = read_frd_part(write("a.csv", "# inputs: u1,u2\nfreq_hz,S_psi_u2_re,S_psi_u2_im\n1,3,4\n"));
  const FrdPart b = read_frd_part(write("b.csv", "freq_hz,S_psi_u1_re,S_psi_u1_im\n1,1,2\n"));
  const FrequencyResponse merged = merge_frd_parts({a, b});
  EXPECT_EQ(merged.input_names, (std::vector<std::string>{"u1", "u2"}));
  EXPECT_EQ(merged.output_names, (std::vector<std::string>{"psi"}));
  EXPECT_EQ(merged.response[0](0, 0), Complex(1, 2));
  EXPECT_EQ(merged.response[0](0, 1), Complex(3, 4));
}

TEST_F(FrdCsv, MergeErrors_NameThePartsAndThePair) {
  const std::string a = write("a.csv", "freq_hz,S_1_1_re,S_1_1_im\n1,1,2\n2,1,2\n");
  const std::string b = write("b.csv", "freq_hz,S_1_1_re,S_1_1_im,S_1_2_re,S_1_2_im\n1,1,2,3,4\n2,1,2,3,4\n");
  const std::string c = write("c.csv", "freq_hz,S_1_3_re,S_1_3_im\n1,1,2\n2,1,2\n");
  const std::string d = write("d.csv", "freq_hz,S_1_2_re,S_1_2_im\n1,1,2\n2.001,1,2\n");
  const std::string e = write("e.csv", "freq_hz,S_1_2_re,S_1_2_im\n1,1,2\n");
  const std::string f = write("f.csv", "freq_hz,P_1_2_re,P_1_2_im\n1,1,2\n2,1,2\n");
  const std::string g = write("g.csv", "freq_hz,S_1_2_re,S_1_2_im,coh_1_2\n1,1,2,1\n2,1,2,1\n");
  const std::string h = write("h.csv", "freq_hz,S_1_u2_re,S_1_u2_im\n1,1,2\n2,1,2\n");
  auto merge = [](std::vector<std::string> paths) {
    std::vector<FrdPart> parts;
    for (const std::string& p : paths) parts.push_back(read_frd_part(p));
    return merge_frd_parts(parts);
  };
  EXPECT_EQ(input_error([&] { merge({a, b}); }),
            "cannot merge FRD parts: output 1, input 1 is in both '" + a + "' and '" + b +
                "'; give every pair in exactly one file");
  EXPECT_EQ(input_error([&] { merge({a, c}); }),
            "cannot merge FRD parts: output 1, input 2 is in none of the files '" + a + "', '" + c +
                "'; give every pair in exactly one file");
  EXPECT_EQ(input_error([&] { merge({a, d}); }),
            "cannot merge FRD parts: frequency 2 is 2 Hz in '" + a + "' but 2.001 Hz in '" + d +
                "' (relative difference 0.0005, above the tolerance 1e-09); give files measured on the same "
                "frequency grid");
  EXPECT_EQ(input_error([&] { merge({a, e}); }),
            "cannot merge FRD parts: '" + a + "' has 2 frequencies but '" + e +
                "' has 1; give files measured on the same frequency grid");
  EXPECT_EQ(input_error([&] { merge({a, f}); }),
            "cannot merge FRD parts: '" + a + "' holds quantity 'S' but '" + f +
                "' holds 'P'; give files of one quantity");
  EXPECT_EQ(input_error([&] { merge({a, g}); }),
            "cannot merge FRD parts: '" + g + "' has coherence columns but '" + a +
                "' has none; give coherence in every file or in none");
  EXPECT_EQ(input_error([&] { merge({a, h}); }),
            "cannot merge FRD parts: '" + a + "' indexes its inputs but '" + h +
                "' names them; name the inputs in every file or in none");
  EXPECT_EQ(input_error([&] { merge_frd_parts({}); }), "cannot merge FRD parts: no parts; give at least one file");
}

TEST_F(FrdCsv, MergeWithinTolerance_TakesTheFirstGrid) {
  const FrdPart a = read_frd_part(write("a.csv", "freq_hz,S_1_1_re,S_1_1_im\n1,1,2\n"));
  const FrdPart b = read_frd_part(write("b.csv", "freq_hz,S_1_2_re,S_1_2_im\n1.0000000001,3,4\n"));
  const FrequencyResponse merged = merge_frd_parts({a, b});
  EXPECT_EQ(merged.omega_rad_s[0], a.frd.omega_rad_s[0]);
  EXPECT_EQ(merged.response[0](0, 1), Complex(3, 4));
}

}  // namespace frd_csv_test
}  // namespace lpvid
