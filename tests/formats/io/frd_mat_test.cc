#include "formats/io/frd_mat.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <matio.h>

#include <cmath>
#include <numbers>
#include <random>

#include "formats/io/frd_csv.h"
#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace frd_mat_test {

using test::input_error;

class FrdMat : public test::TempDirTest {};

constexpr unsigned kSeed = 20261125;  // named seed for the random responses

// Random response on increasing omegas that are NOT 2*pi times a round number
// (the hardest case for the freq_hz conversion).
FrequencyResponse random_frd(Index nf, Index ny, Index nu, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  FrequencyResponse frd;
  frd.omega_rad_s.resize(nf);
  double w = 0.3;
  for (Index k = 0; k < nf; ++k) {
    frd.omega_rad_s[k] = w;
    w *= 1.01 + unit(rng);
    Eigen::MatrixXcd h(ny, nu);
    Eigen::MatrixXd c(ny, nu);
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j) {
        h(i, j) = Complex(normal(rng), normal(rng) * 1e-200);
        c(i, j) = unit(rng);
      }
    frd.response.push_back(h);
    frd.coherence.push_back(c);
    frd.flagged.push_back(unit(rng) < 0.3);
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

// A variable for a hand-made fixture: column-major data, im empty for real.
struct Var {
  std::string name;
  std::vector<size_t> dims;
  std::vector<double> re, im;
};

void write_vars(const std::string& path, const std::vector<Var>& vars, mat_ft version = MAT_FT_MAT5,
                matio_compression compression = MAT_COMPRESSION_NONE) {
  mat_t* mat = Mat_CreateVer(path.c_str(), nullptr, version);
  ASSERT_NE(mat, nullptr);
  for (const Var& v : vars) {
    std::vector<double> re = v.re, im = v.im;
    std::vector<size_t> dims = v.dims;
    mat_complex_split_t split{re.data(), im.data()};
    matvar_t* var = Mat_VarCreate(v.name.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(dims.size()),
                                  dims.data(), im.empty() ? static_cast<void*>(re.data()) : &split,
                                  im.empty() ? 0 : MAT_F_COMPLEX);
    ASSERT_NE(var, nullptr);
    ASSERT_EQ(Mat_VarWrite(mat, var, compression), 0);
    Mat_VarFree(var);
  }
  Mat_Close(mat);
}

TEST_F(FrdMat, WriteThenRead_GivesIdenticalDoublesInV5AndV73) {
  FrequencyResponse frd = random_frd(40, 2, 3, kSeed);
  frd.output_names = {"psi", "theta_b"};
  frd.input_names = {"u1", "u2", "u3"};
  for (const MatVersion version : {MatVersion::kV5, MatVersion::kV73}) {
    const std::string p = path(version == MatVersion::kV5 ? "v5.mat" : "v73.mat");
    write_frd_mat(p, frd, "S", version);
    const FrequencyResponse back = read_frd_mat(p);
    // omega -> freq_hz -> omega is exact when a preimage exists, else 1 ulp.
    for (Index k = 0; k < frd.num_frequencies(); ++k)
      EXPECT_LE(std::abs(back.omega_rad_s[k] - frd.omega_rad_s[k]),
                std::abs(std::nextafter(frd.omega_rad_s[k], 0.0) - frd.omega_rad_s[k]));
    FrequencyResponse expected = frd;
    expected.omega_rad_s = back.omega_rad_s;
    expect_identical(back, expected);
    expect_identical(read_frd_mat(p), back);  // and stable from then on
  }
  EXPECT_EQ(entries(), (std::vector<std::string>{"v5.mat", "v73.mat"}));  // no temporaries left
}

TEST_F(FrdMat, SameDataAsCsvAndMat_ReadsBackBitIdentical) {
  FrequencyResponse frd = random_frd(60, 3, 2, kSeed + 1);
  for (const auto& h : frd.response) frd.variance.push_back(h.cwiseAbs2() * 1e-4);
  frd.averages = 12;
  frd.input_names = {"v1", "v2"};  // outputs unnamed
  write_frd_csv(path("s.csv"), frd, "S");
  write_frd_mat(path("s.mat"), frd, "S");
  write_frd_mat(path("s73.mat"), frd, "S", MatVersion::kV73);
  const FrequencyResponse from_csv = read_frd_csv(path("s.csv"));
  expect_identical(read_frd_mat(path("s.mat")), from_csv);
  expect_identical(read_frd_mat(path("s73.mat")), from_csv);
}

TEST_F(FrdMat, TextFileRenamedMat_IsAOneLineInputError) {
  const std::string p = write("fake.mat", "freq_hz,S_1_1_re,S_1_1_im\n1,2,3\n");
  const std::string message = input_error([&] { read_frd_mat(p); });
  EXPECT_EQ(message, "'" + p + "' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB with "
                               "save(name, '-v7')");
  EXPECT_EQ(message.find('\n'), std::string::npos);
  const std::string empty = write("empty.mat", "");
  EXPECT_EQ(input_error([&] { read_frd_mat(empty); }),
            "'" + empty + "' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB with "
                          "save(name, '-v7')");
}

TEST_F(FrdMat, MissingFileAndDirectory_AreReported) {
  EXPECT_EQ(input_error([&] { read_frd_mat(path("none.mat")); }),
            "cannot open '" + path("none.mat") + "': No such file or directory; check the path");
  EXPECT_EQ(input_error([&] { read_frd_mat(dir_.string()); }),
            "cannot open '" + dir_.string() + "': Is a directory; give a file, not a directory");
}

TEST_F(FrdMat, RealSisoVectorInRadPerSecond_IsAccepted) {
  const std::string p = path("siso.mat");
  write_vars(p, {{"w", {1, 3}, {1, 2, 4}, {}}, {"G", {3, 1}, {0.5, 0.25, 0.125}, {}}, {"note", {1, 1}, {7}, {}}});
  const FrequencyResponse frd = read_frd_mat(p);
  EXPECT_EQ(frd.omega_rad_s, Eigen::Vector3d(1, 2, 4));
  ASSERT_EQ(frd.response.size(), 3u);
  EXPECT_EQ(frd.response[2](0, 0), Complex(0.125, 0));
  EXPECT_TRUE(frd.coherence.empty());
  EXPECT_TRUE(frd.flagged.empty());
}

TEST_F(FrdMat, MatrixForOneFrequency_IsAccepted) {
  const std::string p = path("one.mat");
  write_vars(p, {{"f", {1, 1}, {10}, {}}, {"P", {2, 2}, {1, 2, 3, 4}, {5, 6, 7, 8}}});
  const FrequencyResponse frd = read_frd_mat(p);
  EXPECT_EQ(frd.omega_rad_s[0], 10 * (2.0 * std::numbers::pi));
  EXPECT_EQ(frd.response[0](1, 0), Complex(2, 6));  // column-major: (2,1) is the second entry
  EXPECT_EQ(frd.response[0](0, 1), Complex(3, 7));
}

TEST_F(FrdMat, QuantityOption_PicksTheVariable) {
  const std::string p = path("two.mat");
  write_vars(p, {{"freq", {2, 1}, {1, 2}, {}}, {"S", {2, 1}, {1, 2}, {}}, {"P", {2, 1}, {3, 4}, {}}});
  EXPECT_EQ(input_error([&] { read_frd_mat(p); }),
            "'" + p + "': several response variables (S, P); choose one with the quantity option");
  FrdReadOptions t;
  t.quantity = "P";
  EXPECT_EQ(read_frd_mat(p, t).response[1](0, 0), Complex(4, 0));
}

struct BadMat {
  const char* name;
  std::vector<Var> vars;
  const char* quantity;
  const char* message;  // after "'path': "
};

class FrdMatErrors : public FrdMat, public ::testing::WithParamInterface<BadMat> {};

TEST_P(FrdMatErrors, MessageIsPinned) {
  const BadMat& bad = GetParam();
  const std::string p = path("bad.mat");
  write_vars(p, bad.vars);
  FrdReadOptions options;
  options.quantity = bad.quantity;
  EXPECT_EQ(input_error([&] { read_frd_mat(p, options); }), "'" + p + "': " + bad.message);
}

INSTANTIATE_TEST_SUITE_P(
    Rules, FrdMatErrors,
    ::testing::Values(
        BadMat{"NoFrequency", {{"S", {1, 1}, {1}, {}}, {"x", {1, 1}, {1}, {}}}, "",
               "no frequency variable; give one of freq_hz, f, freq (Hz) or w, omega (rad/s); the file holds: S, x"},
        BadMat{"TwoFrequencies", {{"f", {1, 1}, {1}, {}}, {"w", {1, 1}, {1}, {}}, {"S", {1, 1}, {1}, {}}}, "",
               "several frequency variables (f, w); keep one"},
        BadMat{"NoResponse", {{"f", {1, 1}, {1}, {}}, {"coh", {1, 1}, {1}, {}}}, "",
               "no response variable; give one of S, P, G, H, frd, or choose one with the quantity option; the file "
               "holds: f, coh"},
        BadMat{"QuantityMissing", {{"f", {1, 1}, {1}, {}}, {"S", {1, 1}, {1}, {}}}, "T",
               "no variable 'T' (the quantity asked for); choose one the file holds: f, S"},
        BadMat{"TwoResponses", {{"f", {1, 1}, {1}, {}}, {"S", {1, 1}, {1}, {}}, {"G", {1, 1}, {1}, {}}}, "",
               "several response variables (S, G); choose one with the quantity option"},
        BadMat{"WrongDims", {{"f", {4, 1}, {1, 2, 3, 4}, {}}, {"S", {2, 3, 5}, std::vector<double>(30, 1.0), {}}}, "",
               "response 'S' is 2×3×5 but there are 4 frequencies; give an outputs × inputs × frequencies array (or "
               "a vector of 4 entries for one output and one input)"},
        BadMat{"MatrixForSeveralFrequencies", {{"f", {2, 1}, {1, 2}, {}}, {"S", {2, 2}, {1, 2, 3, 4}, {}}}, "",
               "response 'S' is 2×2 but there are 2 frequencies; give an outputs × inputs × frequencies array (or a "
               "vector of 2 entries for one output and one input)"},
        BadMat{"NonIncreasingFrequency", {{"freq_hz", {3, 1}, {1, 3, 2}, {}}, {"S", {3, 1}, {1, 2, 3}, {}}}, "",
               "frequency 'freq_hz'(3) = 2 is not above 'freq_hz'(2) = 3; give strictly increasing frequencies"},
        BadMat{"NonPositiveFrequency", {{"w", {2, 1}, {0, 3}, {}}, {"S", {2, 1}, {1, 2}, {}}}, "",
               "frequency 'w'(1) = 0 is not a positive finite number; give frequencies > 0"},
        BadMat{"ComplexFrequency", {{"f", {1, 1}, {1}, {2}}, {"S", {1, 1}, {1}, {}}}, "",
               "variable 'f' is complex; save it as a real array"},
        BadMat{"NaNResponse", {{"f", {2, 1}, {1, 2}, {}}, {"S", {2, 1}, {1, NAN}, {}}}, "",
               "response 'S' is nan at output 1, input 1, frequency 2; NaN/Inf not allowed"},
        BadMat{"CoherenceOutOfRange",
               {{"f", {2, 1}, {1, 2}, {}}, {"S", {2, 1}, {1, 2}, {}}, {"coh", {2, 1}, {1, -0.5}, {}}}, "",
               "coherence 'coh' is -0.5 at output 1, input 1, frequency 2; coherence must be in [0, 1]"},
        BadMat{"CoherenceWrongShape",
               {{"f", {1, 1}, {1}, {}}, {"S", {1, 2}, {1, 2}, {}}, {"coh", {1, 1}, {1}, {}}}, "",
               "coherence 'coh' is 1×1 per frequency but response 'S' is 1×2; give coherence of the response's shape"},
        BadMat{"FlagNotBinary", {{"f", {1, 1}, {1}, {}}, {"S", {1, 1}, {1}, {}}, {"flag", {1, 1}, {3}, {}}}, "",
               "'flag'(1) is 3; write 0 or 1 (1 = untrusted frequency)"}),
    [](const ::testing::TestParamInfo<BadMat>& info) { return std::string(info.param.name); });

TEST_F(FrdMat, WriterErrors_LeaveNoFile) {
  const FrequencyResponse frd = random_frd(3, 1, 1, kSeed + 2);
  EXPECT_EQ(input_error([&] { write_frd_mat(path("x.mat"), frd, "flag"); }),
            "cannot write '" + path("x.mat") + "': quantity 'flag' is the name of another variable of the file; use "
                                               "S, P, G, ...");
  EXPECT_EQ(input_error([&] { write_frd_mat(path("no/x.mat"), frd, "S"); }),
            "cannot write '" + path("no/x.mat") + "': No such file or directory; check the directory exists and is "
                                                  "writable");
  EXPECT_EQ(input_error([&] { write_frd_mat("-", frd, "S"); }), "cannot write a .mat file to stdout; give a file path");
  EXPECT_TRUE(entries().empty());
}

// Issue 12, class 3: a truncated or damaged .mat file was accepted with values
// read from uninitialised memory.  The v5 reader checks every size against the
// bytes present: every prefix of a valid file is an error, or (cut between two
// variables, which the format cannot tell from a complete file) the same
// response without the optional variables that were cut off.
TEST_F(FrdMat, EveryTruncation_IsAnErrorOrTheSameData) {
  FrequencyResponse frd = random_frd(6, 2, 2, kSeed + 3);
  frd.output_names = {"psi", "theta"};
  const std::string p = path("whole.mat");
  write_frd_mat(p, frd, "S");
  const std::string bytes = read(p);
  const FrequencyResponse whole = read_frd_mat(p);
  int errors = 0;
  for (size_t n = 0; n < bytes.size(); ++n) {
    const std::string cut = write("cut.mat", bytes.substr(0, n));
    try {
      FrequencyResponse got = read_frd_mat(cut);
      // Optional variables after the response may be missing, never different.
      if (got.flagged.empty()) got.flagged = whole.flagged;
      if (got.coherence.empty()) got.coherence = whole.coherence;
      if (got.output_names.empty()) got.output_names = whole.output_names;
      expect_identical(got, whole);
    } catch (const InputError& e) {
      ++errors;
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
  }
  EXPECT_GE(errors, static_cast<int>(bytes.size()) - 40);  // a few cuts between variables go unnoticed
}

TEST_F(FrdMat, CompressedVariables_AreInflatedAndChecked) {
  const std::string p = path("z.mat");
  write_vars(p, {{"f", {3, 1}, {1, 2, 3}, {}}, {"S", {3, 1}, {0.5, 0.25, 0.125}, {1, 2, 3}}}, MAT_FT_MAT5,
             MAT_COMPRESSION_ZLIB);
  const FrequencyResponse frd = read_frd_mat(p);
  EXPECT_EQ(frd.response[2](0, 0), Complex(0.125, 3));
  // A damaged byte inside the zlib stream: an error, never a value from nowhere.
  std::string bytes = read(p);
  bytes[bytes.size() - 12] = static_cast<char>(bytes[bytes.size() - 12] ^ 0x5A);
  const std::string bad = write("zbad.mat", bytes);
  const std::string message = input_error([&] { read_frd_mat(bad); });
  EXPECT_NE(message, "<no error>");
}

TEST_F(FrdMat, RandomByteFlips_NeverCrashAndGiveFiniteResponses) {
  FrequencyResponse frd = random_frd(5, 2, 1, kSeed + 4);
  const std::string p = path("base.mat");
  write_frd_mat(p, frd, "S");
  const std::string base = read(p);
  std::mt19937_64 rng(kSeed + 5);  // named seed: the same 500 mutants every run
  std::uniform_int_distribution<size_t> at(0, base.size() - 1);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int k = 0; k < 500; ++k) {
    std::string bytes = base;
    for (int flips = 0; flips < 4; ++flips) bytes[at(rng)] = static_cast<char>(byte(rng));
    const std::string q = write("m.mat", bytes);
    try {
      const FrequencyResponse r = read_frd_mat(q);
      for (const auto& h : r.response) EXPECT_TRUE(h.allFinite());
    } catch (const InputError&) {
    }
  }
}

TEST_F(FrdMat, PipeInsteadOfAFile_IsRefused) {
  EXPECT_EQ(input_error([&] { read_frd_mat("/dev/null"); }),
            "cannot read '/dev/null': a .mat file must be a regular file (not a pipe or device); save it to a file "
            "first");
}

}  // namespace frd_mat_test
}  // namespace lpvid
