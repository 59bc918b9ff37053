#include "formats/plot/sv_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "tests/formats/plot/plot_test_util.h"

namespace lpvid {
namespace sv_plot_test {

using plot_test::count_color;
using plot_test::input_error;

// 9 dominant values 10^(-0.3 k), then a tail below 1e-3 (a 9th-order system
// in noise).
Eigen::VectorXd nine_plus_tail() {
  Eigen::VectorXd sv(30);
  for (int k = 0; k < 30; ++k) {
    sv[k] = k < 9 ? std::pow(10.0, -0.3 * k) : 2e-4 * std::pow(0.8, k - 9);
  }
  return sv;
}

cv::Rect around(double x, double y, int half) {
  return {static_cast<int>(std::lround(x)) - half, static_cast<int>(std::lround(y)) - half,
          2 * half + 1, 2 * half + 1};
}

TEST(SingularValuesPng, DecodesToTheLayoutSize) {
  SingularValuePlotOptions options;
  options.title = "Hankel singular values";
  const auto layout = layout_singular_values(nine_plus_tail(), options);
  const cv::Mat decoded =
      cv::imdecode(singular_values_png(nine_plus_tail(), options), cv::IMREAD_COLOR);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(decoded.size(), layout.figure);
  EXPECT_EQ(layout.shown, 20);
  EXPECT_DOUBLE_EQ(layout.index.lo, 0.5);
  EXPECT_DOUBLE_EQ(layout.index.hi, 20.5);
}

TEST(SingularValueLayout, LogAxisCoversValuesAndNoiseFloorInWholeDecades) {
  SingularValuePlotOptions options;
  options.count = 12;
  options.noise_floor = 5e-6;
  const auto layout = layout_singular_values(nine_plus_tail(), options);
  EXPECT_TRUE(layout.value.log);
  EXPECT_DOUBLE_EQ(layout.value.hi, 1.0);
  EXPECT_NEAR(layout.value.lo, 1e-6, 1e-21);
  // The order line needs a discarded value to its right: shown >= order + 1.
  options.chosen_order = 15;
  EXPECT_EQ(layout_singular_values(nine_plus_tail(), options).shown, 16);
}

TEST(RenderSingularValues, KeptAndDiscardedValuesHaveDifferentColours) {
  SingularValuePlotOptions options;
  options.chosen_order = 9;
  options.noise_floor = 5e-4;
  const Eigen::VectorXd sv = nine_plus_tail();
  const auto layout = layout_singular_values(sv, options);
  const cv::Mat image = render_singular_values(sv, options);
  const cv::Scalar kept = plot::series_color(0);
  const cv::Scalar discarded(150, 150, 150);
  // Marker of value 1 (kept) and of value 10 (discarded).
  const cv::Rect first = around(layout.index.to_px(1), layout.value.to_px(sv[0]), 2);
  const cv::Rect tenth = around(layout.index.to_px(10), layout.value.to_px(sv[9]), 2);
  EXPECT_GE(count_color(image, first, kept), 20);
  EXPECT_EQ(count_color(image, first, discarded), 0);
  EXPECT_GE(count_color(image, tenth, discarded, 10), 20);
  EXPECT_EQ(count_color(image, tenth, kept), 0);
  // The order line (dark, dashed) between index 9 and 10, over the axes height.
  const int x = static_cast<int>(std::lround(layout.index.to_px(9.5)));
  const cv::Rect order_line(x, layout.axes_px.y, 1, layout.axes_px.height);
  EXPECT_GT(count_color(image, order_line, plot::kAxisColor), layout.axes_px.height / 3);
  // The noise floor (red, dashed) on its row.
  const int y = static_cast<int>(std::lround(layout.value.to_px(5e-4)));
  const cv::Rect floor_row(layout.axes_px.x, y, layout.axes_px.width, 1);
  EXPECT_GT(count_color(image, floor_row, plot::kFlagColor), layout.axes_px.width / 3);
}

TEST(SingularValueErrors, MessagesNameTheProblem) {
  const SingularValuePlotOptions ok;
  auto msg = [](const Eigen::VectorXd& sv, const SingularValuePlotOptions& o) {
    return input_error([&] { singular_values_png(sv, o); });
  };
  EXPECT_EQ(msg(Eigen::VectorXd(), ok), "singular value plot: no singular values to draw");
  EXPECT_EQ(msg(Eigen::Vector3d(1.0, -0.5, 0.1), ok),
            "singular value plot: singular value 2 is -0.5; values must be finite and >= 0");
  EXPECT_EQ(msg(Eigen::Vector2d(1.0, NAN), ok),
            "singular value plot: singular value 2 is nan; values must be finite and >= 0");
  EXPECT_EQ(msg(Eigen::Vector3d::Zero(), ok),
            "singular value plot: the 3 values shown are all zero; a log axis cannot show them");
  SingularValuePlotOptions o = ok;
  o.count = 0;
  EXPECT_EQ(msg(Eigen::Vector2d(1.0, 0.1), o), "singular value plot: count 0 must be >= 1");
  o = ok;
  o.chosen_order = 3;
  EXPECT_EQ(msg(Eigen::Vector2d(1.0, 0.1), o),
            "singular value plot: chosen_order 3 is outside 0..2 (the number of singular values)");
  o = ok;
  o.noise_floor = -1e-3;
  EXPECT_EQ(msg(Eigen::Vector2d(1.0, 0.1), o),
            "singular value plot: noise_floor -0.001 must be finite and >= 0 (0 = no line)");
}

}  // namespace sv_plot_test
}  // namespace lpvid
