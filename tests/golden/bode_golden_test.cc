// Golden test of `lpvid bode` (cli/bode.cc): the PNG of two hand-written SISO
// models (bode/resonance.json, continuous; bode/lowpass.json, discrete).
#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "tests/golden/golden_support.h"

namespace lpvid::golden {
namespace bode_golden_test {

using lpvid::testing::run_lpvid;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

// Largest fraction of pixels allowed to differ (any channel, any amount).  The
// figure is a deterministic drawing: one OpenCV build gives identical bytes.
// Another compiler may move a curve vertex by a last-bit amount, which flips the
// anti-aliasing of a pixel only when the vertex crosses one of the 1/16-px
// fixed-point steps the canvas draws with (formats/plot/canvas.cc, kShift), and
// another OpenCV release may shade text or line ends a little differently: a few
// hundred pixels at most of 301 040.  A real change is far larger: one wrong
// curve alone changes 12 % of the image (PixelToleranceStillDetects-
// AWrongCurve below draws the lowpass as a second resonance and sees it).
constexpr double kMaxDifferingPixelFraction = 1e-3;

cv::Mat decode(const std::string& path) {
  const std::string bytes = slurp(path);
  const std::vector<uchar> buffer(bytes.begin(), bytes.end());
  return cv::imdecode(buffer, cv::IMREAD_COLOR);
}

double differing_fraction(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat diff, any;
  cv::absdiff(a, b, diff);
  cv::transform(diff, any, cv::Matx13f(1, 1, 1));  // sum of the channel differences
  return static_cast<double>(cv::countNonZero(any)) / static_cast<double>(a.total());
}

std::string bode_args(const std::string& out) {
  return "bode --out " + out + " --labels resonance,lowpass " + data("bode/resonance.json") + " " +
         data("bode/lowpass.json");
}

TEST(BodeGolden, PngDecodesToTheGoldenSizeAndDiffersInAtMostOnePixelInAThousand) {
  TempDir dir("golden_bode");
  const auto r = run_lpvid(bode_args(dir / "bode.png"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cv::Mat a = decode(dir / "bode.png");
  const cv::Mat b = decode(data("bode/bode.png"));
  ASSERT_FALSE(a.empty()) << "the fresh PNG does not decode";
  ASSERT_FALSE(b.empty()) << "the golden PNG does not decode";
  ASSERT_EQ(a.size(), b.size());
  const double fraction = differing_fraction(a, b);
  std::cout << "[ pixels   ] bode: " << fraction << " of " << b.total() << " pixels differ\n";
  ::testing::Test::RecordProperty("bode_differing_pixel_fraction", std::to_string(fraction));
  EXPECT_LE(fraction, kMaxDifferingPixelFraction);
}

TEST(BodeGolden, PixelToleranceStillDetectsAWrongCurve) {
  TempDir dir("golden_bode_one");
  const auto r = run_lpvid("bode --out " + (dir / "one.png") + " --labels resonance,lowpass " +
                           data("bode/resonance.json") + " " + data("bode/resonance.json"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const cv::Mat a = decode(dir / "one.png");
  const cv::Mat b = decode(data("bode/bode.png"));
  ASSERT_EQ(a.size(), b.size());
  const double fraction = differing_fraction(a, b);
  std::cout << "[ pixels   ] bode with the lowpass replaced by the resonance: " << fraction << " differ\n";
  EXPECT_GT(fraction, 10 * kMaxDifferingPixelFraction);
}

}  // namespace bode_golden_test
}  // namespace lpvid::golden
