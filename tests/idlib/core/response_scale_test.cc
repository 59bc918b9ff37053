// response_scales (idlib/core/types.h): the size each entry's error is measured
// against, checked on matrices whose scales are worked out by hand here.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <complex>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {
namespace response_scale_test {

using C = std::complex<double>;

// |H| = [[4, 1], [18, 9]]: the diagonals' geometric mean is sqrt(4·9) = 6 off the
// diagonal; entry (2,1) = 18 exceeds it and is measured against itself.
TEST(ResponseScale, GeometricMeanOfTheDiagonalsOrTheEntryWhereLarger) {
  Eigen::MatrixXcd h(2, 2);
  h << C(0, 4), C(1, 0), C(18, 0), C(0, -9);
  const std::vector<Eigen::MatrixXd> s = response_scales({h}, 0.0);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_DOUBLE_EQ(s[0](0, 0), 4.0);
  EXPECT_DOUBLE_EQ(s[0](1, 1), 9.0);
  EXPECT_DOUBLE_EQ(s[0](0, 1), 6.0);
  EXPECT_DOUBLE_EQ(s[0](1, 0), 18.0);
}

// Non-square: the row's largest |H|.
TEST(ResponseScale, NonSquareUsesTheRowMaximum) {
  Eigen::MatrixXcd h(1, 3);
  h << C(3, 4), C(1, 0), C(0, 2);
  const std::vector<Eigen::MatrixXd> s = response_scales({h}, 0.0);
  EXPECT_DOUBLE_EQ(s[0](0, 0), 5.0);
  EXPECT_DOUBLE_EQ(s[0](0, 2), 5.0);
}

// The floor is relative to the largest DIAGONAL scale over all frequencies (here 10
// at the first), not to a large coupling entry (1000 at the second): a diagonal zero
// (the second frequency's) is floored at 1e-3 × 10.
TEST(ResponseScale, FloorIsRelativeToTheLargestDiagonalScaleOverTheSet) {
  Eigen::MatrixXcd a(2, 2), b(2, 2);
  a << C(10, 0), C(0, 0), C(0, 0), C(10, 0);
  b << C(0, 0), C(0, 0), C(1000, 0), C(1, 0);
  const std::vector<Eigen::MatrixXd> s = response_scales({a, b}, 1e-3);
  EXPECT_DOUBLE_EQ(s[1](0, 0), 1e-2);
  EXPECT_DOUBLE_EQ(s[1](0, 1), 1e-2);
  EXPECT_DOUBLE_EQ(s[1](1, 0), 1000.0);
  EXPECT_DOUBLE_EQ(s[1](1, 1), 1.0);
  EXPECT_DOUBLE_EQ(s[0](0, 1), 10.0);
}

}  // namespace response_scale_test
}  // namespace lpvid
