// Logs in MATLAB .mat files (formats/io/mat_log.h): every layout, written here
// with libmatio directly (not with lpvid's writer), read back to the doubles the
// CSV reader gives for the same samples; every broken rule one InputError with
// "file:variable".
#include "formats/io/mat_log.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <matio.h>

#include <cmath>
#include <limits>
#include <random>

#include "formats/io/csv_log.h"
#include "tests/formats/io/test_util.h"
#include "tests/support/real_data.h"

namespace lpvid {
namespace mat_log_test {

using test::input_error;

class MatLog : public test::TempDirTest {};

constexpr unsigned kSeed = 20261124;  // named seed for the random samples

// N samples at 1 kHz with t = k * 1e-3 (rounded as a lab's logger writes it) and
// random channels of full double precision.
Eigen::MatrixXd samples(Index n, Index channels) {
  std::mt19937_64 rng(kSeed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd d(n, channels + 1);
  for (Index k = 0; k < n; ++k) {
    d(k, 0) = static_cast<double>(k) * 1e-3;
    for (Index j = 1; j <= channels; ++j) d(k, j) = normal(rng) * std::pow(10.0, static_cast<double>(j) - 3.0);
  }
  return d;
}

// ---- hand-made files through libmatio ---------------------------------------
matvar_t* num(const char* name, std::vector<size_t> dims, const double* data) {
  return Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(dims.size()), dims.data(),
                       const_cast<double*>(data), 0);
}
matvar_t* text(const char* name, const std::string& s) {
  size_t dims[2] = {1, s.size()};
  return Mat_VarCreate(name, MAT_C_CHAR, MAT_T_UTF8, 2, dims, const_cast<char*>(s.data()), 0);
}
matvar_t* cells(const char* name, const std::vector<std::string>& names) {
  std::vector<matvar_t*> c;
  for (const std::string& s : names) c.push_back(text(nullptr, s));
  size_t dims[2] = {1, names.size()};
  return Mat_VarCreate(name, MAT_C_CELL, MAT_T_CELL, 2, dims, c.data(), 0);
}

class File {
 public:
  File(const std::string& path, mat_ft version = MAT_FT_MAT5, matio_compression z = MAT_COMPRESSION_NONE)
      : z_(z) {
    mat_ = Mat_CreateVer(path.c_str(), nullptr, version);
    EXPECT_NE(mat_, nullptr);
  }
  ~File() { Mat_Close(mat_); }
  void add(matvar_t* var) {
    ASSERT_NE(var, nullptr);
    ASSERT_EQ(Mat_VarWrite(mat_, var, z_), 0);
    Mat_VarFree(var);
  }

 private:
  mat_t* mat_;
  matio_compression z_;
};

// Layout (d): data + names (+ excitation_design, as `lpvid excite` writes).
void write_matrix(const std::string& path, const std::vector<std::string>& names, const Eigen::MatrixXd& d,
                  mat_ft version, matio_compression z) {
  File f(path, version, z);
  f.add(num("data", {static_cast<size_t>(d.rows()), static_cast<size_t>(d.cols())}, d.data()));
  f.add(cells("names", names));
  f.add(text("excitation_design", "{\"kind\": \"multisine\"}"));
}

void expect_identical(const Log& a, const Log& b) {
  EXPECT_EQ(a.names, b.names);
  ASSERT_EQ(a.data.rows(), b.data.rows());
  ASSERT_EQ(a.data.cols(), b.data.cols());
  EXPECT_TRUE((a.data.array() == b.data.array()).all());
  EXPECT_EQ(a.sample_period_s, b.sample_period_s);  // bit for bit: the same formula on the same doubles
}

TEST_F(MatLog, MatrixAndNames_ReadsTheDoublesOfTheCsvLogInV5CompressedV5AndV73) {
  const Eigen::MatrixXd d = samples(500, 3);
  const std::vector<std::string> names = {"t", "v1", "u1", "q1"};
  write_log(path("run.csv"), names, d);  // shortest round-trip text: reads back the identical doubles
  const Log csv = read_log(path("run.csv"));
  struct Case {
    const char* file;
    mat_ft version;
    matio_compression z;
  };
  for (const Case c : {Case{"v5.mat", MAT_FT_MAT5, MAT_COMPRESSION_NONE}, Case{"v5z.mat", MAT_FT_MAT5, MAT_COMPRESSION_ZLIB},
                       Case{"v73.mat", MAT_FT_MAT73, MAT_COMPRESSION_NONE}}) {
    SCOPED_TRACE(c.file);
    write_matrix(path(c.file), names, d, c.version, c.z);
    expect_identical(read_log(path(c.file)), csv);
  }
}

TEST_F(MatLog, LpvidsOwnWriter_AndAFileWithoutTheExtension_ReadAsMat) {
  const Eigen::MatrixXd d = samples(50, 2);
  const std::vector<std::string> names = {"t", "v1", "q1"};
  write_log_mat(path("a.mat"), names, d, false, {{"excitation_design", "x"}});
  write_log_mat(path("b.mat"), names, d, true);
  write_log(path("c.csv"), names, d);
  const Log csv = read_log(path("c.csv"));
  expect_identical(read_log(path("a.mat")), csv);
  expect_identical(read_log(path("b.mat")), csv);
  std::filesystem::rename(path("a.mat"), path("renamed.log"));  // found by its MAT-file header
  expect_identical(read_log(path("renamed.log")), csv);
}

// write_log_mat refuses what write_log refuses, with the same words (one check,
// detail::check_log_columns; the texts are pinned in csv_log_test.cc), and creates
// nothing.
TEST_F(MatLog, LpvidsOwnWriter_RefusesBadColumnsAsTheCsvWriterDoes) {
  const std::string p = path("bad");
  const Eigen::MatrixXd d = Eigen::MatrixXd::Zero(2, 2);
  const std::vector<std::vector<std::string>> cases = {{"t", "a,b"}, {"time", "a"}, {"t"}, {"t", "t"}};
  for (const auto& names : cases) {
    const std::string csv = input_error([&] { write_log(p, names, d); });
    EXPECT_NE(csv.find("cannot write '" + p + "': "), std::string::npos) << csv;
    EXPECT_EQ(input_error([&] { write_log_mat(p, names, d); }), csv);
    EXPECT_EQ(input_error([&] { write_log_mat(p, names, d, true); }), csv);
    EXPECT_FALSE(std::filesystem::exists(p));
  }
  EXPECT_EQ(input_error([&] { write_log_mat(p, {"time", "a"}, d); }),
            "cannot write '" + p + "': no column 't'; a log needs a time column 't' in seconds");
}

TEST_F(MatLog, OneVariablePerSignal_TakesEveryNumericVectorAndIgnoresScalarsAndText) {
  const Eigen::MatrixXd d = samples(40, 2);
  {
    File f(path("a.mat"));
    f.add(num("t", {40, 1}, d.col(0).data()));
    f.add(num("v1", {1, 40}, d.col(1).data()));  // a row vector is a signal too
    const double ts = 1e-3;
    f.add(num("Ts", {1, 1}, &ts));  // a scalar: not a signal
    f.add(text("note", "rig 2"));
    f.add(num("q1", {40, 1}, d.col(2).data()));
  }
  const Log log = read_log(path("a.mat"));
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v1", "q1"}));
  EXPECT_TRUE((log.data.array() == d.array()).all());
}

TEST_F(MatLog, OneStruct_ItsFieldsAreTheSignals) {
  const Eigen::MatrixXd d = samples(30, 2);
  {
    File f(path("s.mat"), MAT_FT_MAT5, MAT_COMPRESSION_ZLIB);
    const char* fields[] = {"t", "u1", "y1"};
    size_t dims[2] = {1, 1};
    matvar_t* s = Mat_VarCreateStruct("run", 2, dims, fields, 3);
    Mat_VarSetStructFieldByName(s, "t", 0, num(nullptr, {30, 1}, d.col(0).data()));
    Mat_VarSetStructFieldByName(s, "u1", 0, num(nullptr, {30, 1}, d.col(1).data()));
    Mat_VarSetStructFieldByName(s, "y1", 0, num(nullptr, {30, 1}, d.col(2).data()));
    f.add(s);
  }
  const Log log = read_log(path("s.mat"));
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "u1", "y1"}));
  EXPECT_TRUE((log.data.array() == d.array()).all());
}

// Simulink "Structure With Time": x.time, x.signals(i).values (N x width), .label.
matvar_t* simulink(const char* name, const Eigen::VectorXd& t, const std::vector<std::pair<std::string, Eigen::MatrixXd>>& sig) {
  const char* top[] = {"time", "signals", "blockName"};
  size_t one[2] = {1, 1};
  matvar_t* x = Mat_VarCreateStruct(name, 2, one, top, 3);
  Mat_VarSetStructFieldByName(x, "time", 0, num(nullptr, {static_cast<size_t>(t.size()), 1}, t.data()));
  const char* fields[] = {"values", "dimensions", "label"};
  size_t dims[2] = {1, sig.size()};
  matvar_t* s = Mat_VarCreateStruct(nullptr, 2, dims, fields, 3);
  for (size_t i = 0; i < sig.size(); ++i) {
    const Eigen::MatrixXd& v = sig[i].second;
    Mat_VarSetStructFieldByName(s, "values", i, num(nullptr, {static_cast<size_t>(v.rows()), static_cast<size_t>(v.cols())}, v.data()));
    const double width = static_cast<double>(v.cols());
    Mat_VarSetStructFieldByName(s, "dimensions", i, num(nullptr, {1, 1}, &width));
    Mat_VarSetStructFieldByName(s, "label", i, text(nullptr, sig[i].first));
  }
  Mat_VarSetStructFieldByName(x, "signals", 0, s);
  Mat_VarSetStructFieldByName(x, "blockName", 0, text(nullptr, "model/To Workspace"));
  return x;
}

TEST_F(MatLog, SimulinkStructureWithTime_NamesChannelsByLabelWidthAndVariable) {
  const Eigen::MatrixXd d = samples(25, 4);  // t and 4 channels
  for (const mat_ft version : {MAT_FT_MAT5, MAT_FT_MAT73}) {
    const std::string p = path(version == MAT_FT_MAT5 ? "sim5.mat" : "sim73.mat");
    {
      File f(p, version);
      f.add(simulink("u", d.col(0), {{"v", d.middleCols(1, 2)}}));                       // width 2: v1, v2
      f.add(simulink("y", d.col(0), {{"q1", d.col(3)}, {"", d.col(4)}}));                 // labelled, unlabelled
    }
    const Log log = read_log(p);
    EXPECT_EQ(log.names, (std::vector<std::string>{"t", "v1", "v2", "q1", "y_2"}));
    EXPECT_TRUE((log.data.array() == d.array()).all());
  }
}

// ---- every broken rule: one InputError naming file and variable -------------
// Layout (e): a lab's own file (the F-16 benchmark's raw files: row vectors Force and
// Voltage, a 3 × N Acceleration, a scalar Fs, no time vector).
TEST_F(MatLog, LabFileWithASampleRate_RowAndColumnVectorsAndChannelMatricesEitherWay) {
  const Index n = 50;
  const Eigen::MatrixXd d = samples(n, 6);
  const Eigen::MatrixXd acc = d.middleCols(3, 3).transpose();  // 3 x N: channels along rows
  {
    File f(path("f16.mat"), MAT_FT_MAT5, MAT_COMPRESSION_ZLIB);
    f.add(num("Force", {1, static_cast<size_t>(n)}, d.col(1).data()));
    f.add(num("Voltage", {static_cast<size_t>(n), 1}, d.col(2).data()));
    f.add(num("Acceleration", {3, static_cast<size_t>(n)}, acc.data()));
    const Eigen::MatrixXd strain = d.middleCols(6, 1);  // N x 1 as a matrix: a column vector
    f.add(num("Strain", {static_cast<size_t>(n), 1}, strain.data()));
    const double fs = 400.0, level = 7.0;
    f.add(num("Fs", {1, 1}, &fs));
    f.add(num("Level", {1, 1}, &level));  // another scalar: metadata, not a signal
    f.add(text("note", "shaker at the wing tip"));
  }
  const Log log = read_log(path("f16.mat"));
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "Force", "Voltage", "Acceleration1", "Acceleration2",
                                                 "Acceleration3", "Strain"}));
  ASSERT_EQ(log.data.rows(), n);
  for (Index k = 0; k < n; ++k) EXPECT_NEAR(log.data(k, 0), static_cast<double>(k) / 400.0, 1e-15);  // t = k Ts
  EXPECT_TRUE((log.data.middleCols(1, 2).array() == d.middleCols(1, 2).array()).all());
  EXPECT_TRUE((log.data.middleCols(3, 3).array() == d.middleCols(3, 3).array()).all());  // row c of Acceleration
  EXPECT_TRUE((log.data.col(6).array() == d.col(6).array()).all());
  EXPECT_NEAR(log.sample_period_s, 1.0 / 400.0, 1e-15);
  {
    // N x channels with a sample period Ts in seconds.
    File f(path("ts.mat"));
    const Eigen::MatrixXd y = d.middleCols(1, 2);
    f.add(num("y", {static_cast<size_t>(n), 2}, y.data()));
    const double ts = 0.01;
    f.add(num("Ts", {1, 1}, &ts));
  }
  const Log byts = read_log(path("ts.mat"));
  EXPECT_EQ(byts.names, (std::vector<std::string>{"t", "y1", "y2"}));
  EXPECT_TRUE((byts.data.rightCols(2).array() == d.middleCols(1, 2).array()).all());
  EXPECT_NEAR(byts.sample_period_s, 0.01, 1e-15);
  // Broken rules: one line naming the file and the variable.
  const double zero = 0.0, fs = 1000.0, ts = 1e-3;
  {
    File f(path("rate0.mat"));
    f.add(num("u", {static_cast<size_t>(n), 1}, d.col(1).data()));
    f.add(num("fs", {1, 1}, &zero));
  }
  EXPECT_EQ(input_error([&] { read_log(path("rate0.mat")); }),
            path("rate0.mat") + ":fs: is 0; give the sample rate in Hz as a positive number");
  {
    File f(path("both.mat"));
    f.add(num("u", {static_cast<size_t>(n), 1}, d.col(1).data()));
    f.add(num("Fs", {1, 1}, &fs));
    f.add(num("Ts", {1, 1}, &ts));
  }
  EXPECT_EQ(input_error([&] { read_log(path("both.mat")); }),
            path("both.mat") + ":Ts: gives the sample rate and so does Fs; keep one of them");
  {
    File f(path("short.mat"));
    f.add(num("u", {static_cast<size_t>(n), 1}, d.col(1).data()));
    f.add(num("y", {static_cast<size_t>(n - 1), 1}, d.col(2).data()));
    f.add(num("Fs", {1, 1}, &fs));
  }
  EXPECT_EQ(input_error([&] { read_log(path("short.mat")); }),
            path("short.mat") + ":y: has 49 samples but the longest signal has 50; every signal needs one sample per "
                                "time");
  {
    File f(path("square.mat"));
    const Eigen::MatrixXd sq = d.topRows(7).leftCols(7);
    f.add(num("X", {7, 7}, sq.data()));
    f.add(num("Fs", {1, 1}, &fs));
  }
  EXPECT_EQ(input_error([&] { read_log(path("square.mat")); }).rfind(path("square.mat") + ":X: is 7 × 7: time could run along either dimension", 0), 0u);
  {
    Eigen::MatrixXd bad = acc;
    bad(1, 20) = std::numeric_limits<double>::infinity();
    File f(path("inf.mat"));
    f.add(num("Acceleration", {3, static_cast<size_t>(n)}, bad.data()));
    f.add(num("Fs", {1, 1}, &fs));
  }
  EXPECT_EQ(input_error([&] { read_log(path("inf.mat")); }),
            path("inf.mat") + ":Acceleration: row 2 ('Acceleration2') holds Inf at sample 21; a log holds finite "
                              "numbers only: remove or interpolate the bad samples");
}

// The F-16 benchmark's raw file as the lab saved it (../shared/real-data/f16_gvt/raw,
// read when present): the same samples as the CSV export made from it independently
// (numpy, f16_gvt/README.md), which prints 10 significant digits.
TEST_F(MatLog, RealF16RawFile_ReadsAsTheCsvExport) {
  LPVID_REAL_DATA_OR_SKIP(mat, "f16_gvt/raw/F16Data_FullMSine_Level1.mat");
  LPVID_REAL_DATA_OR_SKIP(csv, "f16_gvt/f16_fullmsine_level1.csv");
  const Log raw = read_log(mat), exported = read_log(csv);
  ASSERT_EQ(raw.data.rows(), exported.data.rows());
  EXPECT_NEAR(raw.sample_period_s, exported.sample_period_s, 1e-12);
  const auto col = [](const Log& log, const std::string& name) { return log.data.col(log.column(name)); };
  for (const auto& [mine, theirs] : std::vector<std::pair<std::string, std::string>>{
           {"Voltage", "voltage"}, {"Force", "force"}, {"Acceleration1", "acc1"}, {"Acceleration2", "acc2"},
           {"Acceleration3", "acc3"}}) {
    const Eigen::VectorXd a = col(raw, mine), b = col(exported, theirs);
    // 10 significant digits in the CSV: within 1e-9 of each sample's magnitude (plus a
    // floor of 1e-9 of the channel's peak for samples near zero).
    const double peak = b.cwiseAbs().maxCoeff();
    EXPECT_LE(((a - b).array().abs() - 1e-9 * (b.array().abs() + peak)).maxCoeff(), 0.0) << mine;
  }
}

TEST_F(MatLog, OneUnnamedMatrix_TakesItsNamesAndRateFromTheCommandLineAndNothingElse) {
  // A DaISy file: one N x k matrix, no t, no rate.  Without names and rate it is refused
  // saying what it holds; with them (LogReadOptions, the CLI's --log-columns/--log-rate)
  // its columns are the channels, t = k / rate.
  const Index n = 40;
  const Eigen::MatrixXd d = samples(n, 3);
  const Eigen::MatrixXd m = d.rightCols(3);
  {
    File f(path("daisy.mat"));
    f.add(num("robot_arm_dat", {static_cast<size_t>(n), 3}, m.data()));
  }
  EXPECT_NE(input_error([&] { read_log(path("daisy.mat")); }).find("the file holds: robot_arm_dat"), std::string::npos);
  LogReadOptions o;
  o.sample_rate_hz = 1024;
  o.channel_names = {"u", "y1", "y2"};
  const Log log = read_log(path("daisy.mat"), o);
  EXPECT_EQ(log.names, (std::vector<std::string>{"t", "u", "y1", "y2"}));
  ASSERT_EQ(log.data.rows(), n);
  EXPECT_TRUE((log.data.rightCols(3).array() == m.array()).all());
  for (Index k = 0; k < n; ++k) EXPECT_EQ(log.data(k, 0), static_cast<double>(k) / 1024.0);
  EXPECT_EQ(log.sample_period_s, 1.0 / 1024.0);
  // A bad sample is named by the given name.
  {
    Eigen::MatrixXd bad = m;
    bad(5, 1) = std::numeric_limits<double>::quiet_NaN();
    File f(path("nan.mat"));
    f.add(num("x", {static_cast<size_t>(n), 3}, bad.data()));
  }
  EXPECT_EQ(input_error([&] { read_log(path("nan.mat"), o); }),
            path("nan.mat") + ":x: column 2 ('y1') holds a NaN at row 6; a log holds finite numbers only: remove or "
                              "interpolate the bad samples");
  // Never two sources for one thing, never a silent default.
  LogReadOptions names_only = o;
  names_only.sample_rate_hz = 0;
  EXPECT_EQ(input_error([&] { read_log(path("daisy.mat"), names_only); }),
            path("daisy.mat") + ": --log-columns names the channels but the file has no time t and no rate (Fs, Ts); "
                                "give --log-rate HZ too; the file holds: robot_arm_dat");
  LogReadOptions two = o;
  two.channel_names = {"u", "y"};
  EXPECT_EQ(input_error([&] { read_log(path("daisy.mat"), two); }),
            path("daisy.mat") + ": --log-columns gives 2 name(s) but the file holds 3 channel(s) (robot_arm_dat1, "
                                "robot_arm_dat2, robot_arm_dat3); give one name per channel, in the file's order");
  {
    File f(path("withfs.mat"));
    f.add(num("x", {static_cast<size_t>(n), 3}, m.data()));
    const double fs = 400.0;
    f.add(num("Fs", {1, 1}, &fs));
  }
  EXPECT_EQ(input_error([&] { read_log(path("withfs.mat"), o); }),
            path("withfs.mat") + ":Fs: gives the sample rate and so does --log-rate 1024; drop --log-rate");
  write_matrix(path("named.mat"), {"t", "u", "y1", "y2"}, d, MAT_FT_MAT5, MAT_COMPRESSION_NONE);
  EXPECT_EQ(input_error([&] { read_log(path("named.mat"), o); }),
            path("named.mat") + ": the file gives its own time and channel names (data and names); --log-columns and "
                                "--log-rate are for a file without them (drop them)");
  write_log(path("log.csv"), {"t", "u", "y1", "y2"}, d);
  EXPECT_EQ(input_error([&] { read_log(path("log.csv"), o); }),
            path("log.csv") + ": a CSV log names its channels and its time t in its header; --log-columns and "
                              "--log-rate are for a .mat file without them (drop them)");
  LogReadOptions dup = o;
  dup.channel_names = {"u", "y", "y"};
  EXPECT_NE(input_error([&] { read_log(path("daisy.mat"), dup); }).find("'y' is given twice"), std::string::npos);
}

// The DaISy robot arm's raw .mat (one unnamed 1024 x 2 matrix, ../shared/real-data) read
// with the names and rate its README gives: the same samples as the CSV export made
// from it independently.
TEST_F(MatLog, RealDaisyRawFile_WithNamesAndRateReadsAsTheCsvExport) {
  LPVID_REAL_DATA_OR_SKIP(mat, "daisy_robot_arm/raw/robot_arm_dat.mat");
  LPVID_REAL_DATA_OR_SKIP(csv, "daisy_robot_arm/robot_arm.csv");
  const Log exported = read_log(csv);
  LogReadOptions o;
  o.sample_rate_hz = 1.0 / exported.sample_period_s;
  o.channel_names = {"u", "y"};
  const Log raw = read_log(mat, o);
  ASSERT_EQ(raw.data.rows(), exported.data.rows());
  for (const char* name : {"u", "y"}) {
    const Eigen::VectorXd a = raw.data.col(raw.column(name)), b = exported.data.col(exported.column(name));
    EXPECT_LE((a - b).cwiseAbs().maxCoeff(), 1e-12 * b.cwiseAbs().maxCoeff()) << name;
  }
}

TEST_F(MatLog, BadInput_IsAnInputErrorNamingFileAndVariable) {
  Eigen::MatrixXd d = samples(2000, 3);
  const std::vector<std::string> names = {"t", "v1", "u1", "q1"};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  {
    Eigen::MatrixXd bad = d;
    bad(1206, 2) = nan;
    write_matrix(path("run.mat"), names, bad, MAT_FT_MAT5, MAT_COMPRESSION_NONE);
    EXPECT_EQ(input_error([&] { read_log(path("run.mat")); }),
              path("run.mat") + ":data: column 3 ('u1') holds a NaN at row 1207; a log holds finite numbers only: "
                                "remove or interpolate the bad samples");
  }
  {
    Eigen::MatrixXd bad = d;
    bad(700, 0) = bad(699, 0);
    write_matrix(path("t.mat"), names, bad, MAT_FT_MAT73, MAT_COMPRESSION_NONE);
    EXPECT_EQ(input_error([&] { read_log(path("t.mat")); }),
              path("t.mat") + fmt::format(":data: column 1 ('t') time t = {} s at row 701 is not after the previous row's t "
                                          "= {} s; t must increase strictly from row to row (one file = one experiment)",
                                          bad(699, 0), bad(699, 0)));
  }
  {
    // A dropped sample: row 1001 (t = 1.000 s) missing.
    Eigen::MatrixXd bad(d.rows() - 1, d.cols());
    bad << d.topRows(1000), d.bottomRows(d.rows() - 1001);
    write_matrix(path("gap.mat"), names, bad, MAT_FT_MAT5, MAT_COMPRESSION_ZLIB);
    const std::string e = input_error([&] { read_log(path("gap.mat")); });
    EXPECT_EQ(e.rfind(path("gap.mat") + fmt::format(":data: column 1 ('t') time step {} s (from t = {} s, row 1000) differs",
                                                    bad(1000, 0) - bad(999, 0), bad(999, 0)),
                      0),
              0u)
        << e;
  }
  {
    // A variable name is bytes from the file: a line break in it (fuzz finding,
    // log_mat) is escaped like the rest of the message, which stays one line.
    Eigen::VectorXd t = d.col(0);
    t(5) += 0.4e-3;
    File f(path("nl.mat"));
    const char* fields[] = {"t"};
    size_t dims[2] = {1, 1};
    matvar_t* s = Mat_VarCreateStruct("r\nu", 2, dims, fields, 1);
    Mat_VarSetStructFieldByName(s, "t", 0, num(nullptr, {static_cast<size_t>(t.size()), 1}, t.data()));
    f.add(s);
  }
  {
    const std::string e = input_error([&] { read_log(path("nl.mat")); });
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    EXPECT_EQ(e.rfind(path("nl.mat") + ":r\\x0Au.t: time step ", 0), 0u) << e;
  }
  write_matrix(path("names.mat"), {"t", "v1", "v1", "q1"}, d, MAT_FT_MAT5, MAT_COMPRESSION_NONE);
  EXPECT_EQ(input_error([&] { read_log(path("names.mat")); }),
            path("names.mat") + ":names{3}: channel name 'v1' appears twice (also at names{2}); give every channel its own name");
  write_matrix(path("not.mat"), {"time", "v1", "u1", "q1"}, d, MAT_FT_MAT5, MAT_COMPRESSION_NONE);
  EXPECT_EQ(input_error([&] { read_log(path("not.mat")); }),
            path("not.mat") + ":data: no channel named 't'; add a time channel 't' in seconds (docs/formats.md)");
  write_matrix(path("three.mat"), {"t", "v1", "q1"}, d, MAT_FT_MAT5, MAT_COMPRESSION_NONE);
  EXPECT_EQ(input_error([&] { read_log(path("three.mat")); }).rfind(path("three.mat") + ":names: must be a cell array of 4 names", 0), 0u);
  {
    File f(path("short.mat"));
    f.add(num("t", {2000, 1}, d.col(0).data()));
    f.add(num("q1", {1999, 1}, d.col(1).data()));
  }
  EXPECT_EQ(input_error([&] { read_log(path("short.mat")); }),
            path("short.mat") + ":q1: has 1999 samples but t has 2000; every signal needs one sample per time");
  {
    File f(path("none.mat"));
    f.add(num("x", {2000, 1}, d.col(1).data()));
  }
  EXPECT_EQ(input_error([&] { read_log(path("none.mat")); }).rfind(path("none.mat") + ": no log in the file; ", 0), 0u);
  write("text.mat", "t,v1\n0,1\n0.001,2\n");
  EXPECT_EQ(input_error([&] { read_log(path("text.mat")); }),
            "'" + path("text.mat") + "' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB "
                                     "with save(name, '-v7')");
  EXPECT_EQ(input_error([&] { read_log(path("missing.mat")); }),
            "cannot open '" + path("missing.mat") + "': No such file or directory; check the path");
}

}  // namespace mat_log_test
}  // namespace lpvid
