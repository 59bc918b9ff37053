// Logs in .mat files through the program (issue 14): the same experiment saved as
// CSV and as .mat (v5, compressed v5, v7.3) gives byte-identical outputs from frf
// and identify; a bad .mat log is one line on stderr, exit 2, nothing written.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <matio.h>

#include <filesystem>
#include <fstream>
#include <memory>

#include "formats/io/csv_log.h"
#include "formats/io/excitation_design.h"
#include "formats/io/mat_log.h"
#include "tests/support/run_lpvid.h"

namespace lpvid {
namespace mat_log_cli_test {

using lpvid::testing::count_files;
using lpvid::testing::run_lpvid;
using lpvid::testing::RunResult;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;
namespace fs = std::filesystem;

constexpr const char* kLogs[] = {"exp_T_psi", "exp_T_theta", "exp_F_z"};

// One simulated experiment set (middle position, 1 kHz, 4 s) copied into
// csv/, v5/, v5z/ and v73/ under identical file names (exp_T_psi ..., no extension:
// the .mat files are found by their MAT-file header), so that the provenance the
// commands write (which names the paths) is the same text in every directory.
class MatLogCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<TempDir>("matlogcli");
    const RunResult r = run_lpvid("simulate platform --out " + (*dir_ / "sim") +
                                  " --positions middle --rate-hz 1000 --duration-s 4 --seed 7");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const char* d : {"csv", "v5", "v5z", "v73"}) fs::create_directories(dir_->path() / d);
    for (const char* name : kLogs) {
      const std::string csv = *dir_ / (std::string("sim/middle_1000hz/") + name + ".csv");
      fs::copy_file(csv, dir_->path() / "csv" / name);
      const Log log = read_log(csv);
      write_log_mat(*dir_ / (std::string("v5/") + name), log.names, log.data, false);
      write_log_mat(*dir_ / (std::string("v73/") + name), log.names, log.data, true);
      // Compressed v5, as MATLAB's default save writes it (libmatio, not lpvid's writer).
      mat_t* mat = Mat_CreateVer((*dir_ / (std::string("v5z/") + name)).c_str(), nullptr, MAT_FT_MAT5);
      ASSERT_NE(mat, nullptr);
      size_t dims[2] = {static_cast<size_t>(log.data.rows()), static_cast<size_t>(log.data.cols())};
      matvar_t* data = Mat_VarCreate("data", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, const_cast<double*>(log.data.data()), 0);
      ASSERT_EQ(Mat_VarWrite(mat, data, MAT_COMPRESSION_ZLIB), 0);
      Mat_VarFree(data);
      std::vector<matvar_t*> cells;
      for (const std::string& n : log.names) {
        size_t cd[2] = {1, n.size()};
        cells.push_back(Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UTF8, 2, cd, const_cast<char*>(n.data()), 0));
      }
      size_t nd[2] = {1, cells.size()};
      matvar_t* names = Mat_VarCreate("names", MAT_C_CELL, MAT_T_CELL, 2, nd, cells.data(), 0);
      ASSERT_EQ(Mat_VarWrite(mat, names, MAT_COMPRESSION_ZLIB), 0);
      Mat_VarFree(names);
      Mat_Close(mat);
    }
  }
  static void TearDownTestSuite() { dir_.reset(); }
  static std::string in(const char* d) { return (dir_->path() / d).string(); }
  static std::string logs() { return "exp_T_psi exp_T_theta exp_F_z"; }
  static std::unique_ptr<TempDir> dir_;
};
std::unique_ptr<TempDir> MatLogCli::dir_;

TEST_F(MatLogCli, FrfAndIdentify_GiveByteIdenticalOutputsFromCsvAndMatLogs) {
  for (const char* d : {"csv", "v5", "v5z", "v73"}) {
    SCOPED_TRACE(d);
    const RunResult f = run_lpvid("frf --excitation v1,v2,v3 --output q1,q2,q3 --quantity G --out G.csv " + logs(), "", in(d));
    ASSERT_EQ(f.exit_code, 0) << f.err;
    const RunResult i = run_lpvid("identify --method era --controller ../sim/middle_1000hz/controller.json --excitation "
                                  "v1,v2,v3 --output q1,q2,q3 --out res " + logs(),
                                  "", in(d));
    ASSERT_EQ(i.exit_code, 0) << i.err;
  }
  const std::string g = slurp(in("csv") + "/G.csv");
  ASSERT_GT(g.size(), 1000u);
  for (const char* d : {"v5", "v5z", "v73"}) {
    SCOPED_TRACE(d);
    EXPECT_EQ(slurp(in(d) + "/G.csv"), g);
    int files = 0;
    for (const auto& e : fs::directory_iterator(in("csv") + "/res")) {
      EXPECT_EQ(slurp(in(d) + "/res/" + e.path().filename().string()), slurp(e.path())) << e.path().filename();
      ++files;
    }
    EXPECT_GE(files, 5);
  }
}

// `lpvid excite` writes .mat as data + names + excitation_design: every log command
// reads it, and frf gives the bytes it gives from the same design written as CSV.
TEST_F(MatLogCli, ExcitesMatFile_ReadsAsALogGivingTheCsvsOutputs) {
  TempDir d("matlogexcite");
  const std::string design =
      "excite --kind multisine --rate-hz 1000 --period-samples 500 --periods 4 --transient-periods 1 --band-hz 1,200 "
      "--channels 2 --mimo hadamard --rms 0.05,1 --out ";
  for (const char* f : {"ex.csv", "ex.mat"}) {
    const RunResult r = run_lpvid(design + f, "", d.path().string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  for (const char* f : {"ex.csv", "ex.mat"}) {
    const RunResult r = run_lpvid(std::string("frf --excitation v1 --output v2 --quantity H --out H_") + f + ".csv " + f,
                                  "", d.path().string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // The provenance comment names the log ("from 1 log(s)" only, no path): whole files compare.
  EXPECT_EQ(slurp(d / "H_ex.mat.csv"), slurp(d / "H_ex.csv.csv"));
  EXPECT_GT(slurp(d / "H_ex.csv.csv").size(), 1000u);
}

TEST_F(MatLogCli, BadMatLog_IsOneLineExit2AndNothingWritten) {
  TempDir out("matlogbad");
  const Log log = read_log(in("csv") + "/exp_T_psi");
  Eigen::MatrixXd bad = log.data;
  bad(1206, 2) = std::numeric_limits<double>::quiet_NaN();
  const std::string p = out / "run.mat";
  {
    // A NaN written through libmatio (lpvid's writer refuses it).
    mat_t* mat = Mat_CreateVer(p.c_str(), nullptr, MAT_FT_MAT5);
    size_t dims[2] = {static_cast<size_t>(bad.rows()), static_cast<size_t>(bad.cols())};
    matvar_t* data = Mat_VarCreate("data", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, bad.data(), 0);
    Mat_VarWrite(mat, data, MAT_COMPRESSION_NONE);
    Mat_VarFree(data);
    std::vector<matvar_t*> cells;
    for (const std::string& n : log.names) {
      size_t cd[2] = {1, n.size()};
      cells.push_back(Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UTF8, 2, cd, const_cast<char*>(n.data()), 0));
    }
    size_t nd[2] = {1, cells.size()};
    matvar_t* names = Mat_VarCreate("names", MAT_C_CELL, MAT_T_CELL, 2, nd, cells.data(), 0);
    Mat_VarWrite(mat, names, MAT_COMPRESSION_NONE);
    Mat_VarFree(names);
    Mat_Close(mat);
  }
  const RunResult r = run_lpvid("frf --excitation v1,v2,v3 --output q1,q2,q3 --quantity G --out " + (out / "G.csv") + " " + p);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(p + ":data: column 3 ('" + log.names[2] + "') holds a NaN at row 1207;"), std::string::npos) << r.err;
  EXPECT_EQ(count_files(out.path()), 1);  // run.mat only
}

// A periodic experiment as a .mat log carries its design in the char variable
// excitation_design (the JSON of the CSV log's '# lpvid-excitation:' line), and
// frf --method periodic takes the layout from it without flags: the same FRD bytes as
// from the CSV log (v5 and v7.3).  A malformed design variable is one line naming
// file.mat:excitation_design and the column, exit 2, nothing written.
TEST(MatLogDesign, PeriodicFrfFromAMatLogReadsItsDesignVariableAsTheCsvsLine) {
  TempDir dir("matlogdesign");
  RunResult r = run_lpvid("excite --kind multisine --rate-hz 1000 --period-samples 500 --periods 2 --transient-periods 1 "
                          "--band-hz 2,100 --channels 3 --mimo one-at-a-time --rms 0.05,0.05,1 --out " + (dir / "ms.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  r = run_lpvid("simulate platform --excitation " + (dir / "ms.csv") + " --positions middle --out " + (dir / "rig"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string csv = dir / "rig/middle_1000hz/exp_excitation.csv";
  const Log log = read_log(csv);
  const std::optional<ExcitationDesign> design = read_excitation_design(csv);
  ASSERT_TRUE(design.has_value());
  const std::string json = excitation_design_json(*design);
  write_log_mat(dir / "v5.mat", log.names, log.data, false, {{kExcitationDesignVariable, json}});
  write_log_mat(dir / "v73.mat", log.names, log.data, true, {{kExcitationDesignVariable, json}});
  const std::string frf = "frf --method periodic --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 --out ";
  for (const char* f : {"exp_excitation.csv", "v5.mat", "v73.mat"}) {
    SCOPED_TRACE(f);
    const std::string in = std::string(f) == "exp_excitation.csv" ? csv : dir / f;
    r = run_lpvid(frf + (dir / (std::string("P_") + f + ".csv")) + " " + in);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const std::string from_csv = slurp(dir / "P_exp_excitation.csv.csv");
  EXPECT_GT(from_csv.size(), 1000u);
  EXPECT_EQ(slurp(dir / "P_v5.mat.csv"), from_csv);
  EXPECT_EQ(slurp(dir / "P_v73.mat.csv"), from_csv);

  // Without the variable the .mat log needs the flags, and says so.
  write_log_mat(dir / "none.mat", log.names, log.data);
  r = run_lpvid(frf + (dir / "P_none.csv") + " " + (dir / "none.mat"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("the variable excitation_design of a .mat log"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "P_none.csv"));

  // A malformed design: a JSON syntax error, and a design key with a bad value.
  const std::string cut = json.substr(0, json.size() / 2);
  std::string chirp = json;
  chirp.replace(chirp.find("\"multisine\""), 11, "\"chirp\"    ");
  int case_no = 0;
  for (const std::string& text : {cut, chirp}) {
    SCOPED_TRACE(case_no);
    const std::string bad = dir / fmt::format("bad{}.mat", case_no++);
    write_log_mat(bad, log.names, log.data, false, {{kExcitationDesignVariable, text}});
    const std::string out = bad + ".P.csv";
    r = run_lpvid(frf + out + " " + bad);
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(bad + ":excitation_design:1:"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
  }
  EXPECT_NE(r.err.find("kind"), std::string::npos) << r.err;
}

}  // namespace mat_log_cli_test
}  // namespace lpvid
