// The optional distortion-variance columns of FRD files (dvar_<i>_<j> in CSV, 'dvar'
// in .mat): round trip, old files unchanged, and the rules (needs var, 0 <= dvar <= var).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace frd_dvar_test {

using ::testing::HasSubstr;

class FrdDvar : public test::TempDirTest {};

FrequencyResponse sample() {
  FrequencyResponse f;
  f.omega_rad_s = Eigen::Vector2d(1.0, 2.0);
  for (int k = 0; k < 2; ++k) {
    Eigen::MatrixXcd h(2, 1);
    h << Complex(1.0 + k, -0.5), Complex(0.25, 0.125 * k);
    f.response.push_back(h);
    f.variance.push_back((Eigen::MatrixXd(2, 1) << 0.01 * (k + 1), 0.03).finished());
    f.distortion_variance.push_back((Eigen::MatrixXd(2, 1) << 0.004 * (k + 1), 0.0).finished());
  }
  return f;
}

TEST_F(FrdDvar, CsvAndMatRoundTripTheDistortionVariance) {
  const FrequencyResponse f = sample();
  write_frd_csv(path("g.csv"), f, "G");
  EXPECT_THAT(read(path("g.csv")), HasSubstr("var_2_1,dvar_1_1,dvar_2_1"));
  write_frd_mat(path("g.mat"), f, "G");
  for (const FrequencyResponse& back : {read_frd_csv(path("g.csv")), read_frd_mat(path("g.mat"))}) {
    ASSERT_EQ(back.distortion_variance.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      EXPECT_EQ(back.distortion_variance[k], f.distortion_variance[k]);  // exact: shortest round-trip digits / doubles
      EXPECT_EQ(back.variance[k], f.variance[k]);
    }
  }
}

TEST_F(FrdDvar, FilesWithoutDvarReadAsBefore) {
  FrequencyResponse f = sample();
  f.distortion_variance.clear();
  write_frd_csv(path("g.csv"), f, "G");
  EXPECT_TRUE(read_frd_csv(path("g.csv")).distortion_variance.empty());
}

TEST_F(FrdDvar, RefusesDvarWithoutVarAboveVarOrForSomePairsOnly) {
  auto message = [&](const std::string& text) {
    try {
      read_frd_csv(write("x.csv", text));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(message("freq_hz,G_1_1_re,G_1_1_im,dvar_1_1\n1,1,0,0.1\n"),
              HasSubstr("gives a distortion variance but there is no column 'var_1_1'"));
  EXPECT_THAT(message("freq_hz,G_1_1_re,G_1_1_im,var_1_1,dvar_1_1\n1,1,0,0.1,0.2\n"),
              HasSubstr("x.csv:2:11: distortion variance 0.2 in column 'dvar_1_1' exceeds the total variance"));
  EXPECT_THAT(message("freq_hz,G_1_1_re,G_1_1_im,G_2_1_re,G_2_1_im,var_1_1,var_2_1,dvar_1_1\n1,1,0,1,0,0.1,0.1,0\n"),
              HasSubstr("no column 'dvar_2_1'"));
  FrequencyResponse f = sample();
  f.distortion_variance[1](0, 0) = 1.0;  // above var
  EXPECT_THROW(write_frd_csv(path("y.csv"), f, "G"), InputError);
  EXPECT_FALSE(std::filesystem::exists(path("y.csv")));
}

}  // namespace frd_dvar_test
}  // namespace lpvid
