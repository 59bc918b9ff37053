#include "formats/plot/compare_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "formats/plot/history_plot.h"
#include "tests/formats/plot/plot_test_util.h"

namespace lpvid {
namespace compare_plot_test {

using plot_test::input_error;

// A 1 x 2 response over 1..1000 rad/s: 1/(s+1) on both channels, model = data
// except a 20 % error on channel (0, 0) between 100 and 300 rad/s.
CompareSeries series() {
  CompareSeries s;
  s.omega_rad_s = Eigen::VectorXd::LinSpaced(200, 0, 3).unaryExpr([](double e) { return std::pow(10.0, e); });
  for (Index f = 0; f < s.omega_rad_s.size(); ++f) {
    const Complex p = 1.0 / Complex(1, s.omega_rad_s(f));
    Eigen::MatrixXcd d(1, 2), m(1, 2);
    d << p, p;
    m = d;
    if (s.omega_rad_s(f) > 100 && s.omega_rad_s(f) < 300) m(0, 0) *= 1.2;
    s.data.push_back(d);
    s.model.push_back(m);
    s.radius.push_back(Eigen::MatrixXd::Constant(1, 2, 0.05 * std::abs(p)));
    s.scale.push_back(Eigen::MatrixXd::Constant(1, 2, std::abs(p)));
  }
  return s;
}

// Pixels clearly redder than green: the translucent failing-band shade (the
// data series is blue and the model black, neither counts).
int reddish(const cv::Mat& image, const cv::Rect& r) {
  int n = 0;
  for (int y = r.y; y < r.br().y; ++y)
    for (int x = r.x; x < r.br().x; ++x) {
      const cv::Vec3b px = image.at<cv::Vec3b>(y, x);
      n += (px[2] > px[1] + 15) ? 1 : 0;
    }
  return n;
}

TEST(RenderCompare, FailingBandIsShadedOnItsChannelOnly) {
  const std::vector<CompareBandMark> bands = {{0, 0, 100, 300}};
  const cv::Mat image = render_compare({series()}, bands, {});
  // The panels occupy the upper part; the legend (with its red swatch) the bottom.
  const int panels_bottom = image.rows * 3 / 4;
  const cv::Rect left(0, 0, image.cols / 2, panels_bottom), right(image.cols / 2, 0, image.cols / 2, panels_bottom);
  // The shade spans about half a decade of a three-decade axis over both axes
  // (~60 x 300 px); thousands of pixels, while the other channel has none.
  EXPECT_GT(reddish(image, left), 5000);
  EXPECT_EQ(reddish(image, right), 0);
  const cv::Mat none = render_compare({series()}, {}, {});
  EXPECT_EQ(reddish(none, left), 0);
}

TEST(RenderCompare, BadInputIsAnInputError) {
  EXPECT_EQ(input_error([] { render_compare({}, {}, {}); }), "compare plot: no measurement to draw");
  CompareSeries s = series();
  s.radius.pop_back();
  EXPECT_NE(input_error([&] { render_compare({s}, {}, {}); }).find("they must match"), std::string::npos);
  s = series();
  s.scale.pop_back();
  EXPECT_NE(input_error([&] { render_compare({s}, {}, {}); }).find("band and 199 scale entries; they must match"),
            std::string::npos);
  s = series();
  s.scale[7](0, 1) = -1;
  EXPECT_NE(input_error([&] { render_compare({s}, {}, {}); }).find("scale that is negative or not finite"),
            std::string::npos);
  EXPECT_NE(input_error([&] { compare_error_axis({series()}, 1, 0); }).find("outside the 1x2 response"),
            std::string::npos);
  ComparePlotOptions o;
  o.input_labels = {"only one"};
  EXPECT_NE(input_error([&] { render_compare({series()}, {}, o); }).find("1 input and 0 output labels"),
            std::string::npos);
}

// The error axis measures |E| against the channel's scale s_ij, not against the entry
// itself: an off-diagonal entry a million times below its diagonals, modelled as zero
// (|E| / |P_ij| = 100 % at every line), is within 1e-4 % of the channel's size, and
// its axis says so; against |P_ij| (the scale set to |P_ij|, what the plot used to
// draw) the same curve reads 100 % and its noise band 5 * 10^4 %.  The values are
// worked out by hand from the series, not by the code under test.
TEST(RenderCompare, TheErrorAxisIsThePercentOfTheChannelScaleNotOfTheEntry) {
  CompareSeries s = series();
  for (std::size_t f = 0; f < s.data.size(); ++f) {
    const Complex p = s.data[f](0, 0);
    s.data[f](0, 1) = 1e-6 * p;
    s.model[f](0, 1) = 0;
    s.scale[f](0, 1) = std::abs(p);  // sqrt(|P_ii| |P_jj|) of a square plant whose diagonals are both |p|
  }
  // |E| / s = 1e-4 %, the band 5 %: decades 1e-4 .. 10 (at least two).
  CompareErrorAxis a = compare_error_axis({s}, 0, 1);
  EXPECT_DOUBLE_EQ(a.lo_percent, 1e-2);  // clamped at the axis floor, 0.01 %
  EXPECT_DOUBLE_EQ(a.hi_percent, 10);
  // Channel (0, 0): the 20 % error and the 5 % band: 1 .. 100 %.
  a = compare_error_axis({s}, 0, 0);
  EXPECT_DOUBLE_EQ(a.lo_percent, 1);
  EXPECT_DOUBLE_EQ(a.hi_percent, 100);
  // Measured against the entry itself: 100 % error, a 5 * 10^4 % band.
  for (std::size_t f = 0; f < s.data.size(); ++f) s.scale[f](0, 1) = std::abs(s.data[f](0, 1));
  a = compare_error_axis({s}, 0, 1);
  EXPECT_DOUBLE_EQ(a.lo_percent, 100);
  EXPECT_DOUBLE_EQ(a.hi_percent, 1e4);  // clamped at the axis ceiling
  // A zero scale is not drawn (nothing to measure against): the default 1 .. 100 %.
  for (std::size_t f = 0; f < s.data.size(); ++f) s.scale[f](0, 1) = 0;
  a = compare_error_axis({s}, 0, 1);
  EXPECT_DOUBLE_EQ(a.lo_percent, 1);
  EXPECT_DOUBLE_EQ(a.hi_percent, 100);
  EXPECT_FALSE(render_compare({s}, {}, {}).empty());
}

TEST(RenderHistory, OneBarPerFitAndBadValuesAreRejected) {
  const std::vector<HistoryBar> bars = {{"1: rigid body", 40, 90}, {"2: + suspension", 5, 20}, {"3: + delay", 1, 3}};
  const cv::Mat image = render_history(bars, "title");
  EXPECT_GT(image.cols, 400);
  EXPECT_EQ(input_error([] { render_history({}, ""); }), "history plot: no fit to draw");
  EXPECT_EQ(input_error([] { render_history({{"x", 0, 1}}, ""); }),
            "history plot: fit 1 has mean 0 % and max 1 %; both finite, > 0, max >= mean");
  EXPECT_EQ(input_error([] { render_history({{"x", 1, 2, -1.0}}, ""); }),
            "history plot: fit 1 has a noise floor of -1 %; finite and > 0, or none");
}

TEST(RenderHistory, TheNoiseFloorIsAGreenLineAtItsValue) {
  // the same bar with and without a floor: the drawing differs by the line and its
  // legend entry (the figure keeps its size)
  const cv::Mat with = render_history({{"1: fit", 10, 20, 0.1}}, "");
  const cv::Mat without = render_history({{"1: fit", 10, 20}}, "");
  ASSERT_EQ(with.size(), without.size());
  cv::Mat diff;
  cv::absdiff(with, without, diff);
  cv::Mat gray;
  cv::cvtColor(diff, gray, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(gray), 50);  // the line and its legend entry
}

}  // namespace compare_plot_test
}  // namespace lpvid
