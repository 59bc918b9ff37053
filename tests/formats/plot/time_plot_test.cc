#include "formats/plot/time_plot.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "tests/formats/plot/plot_test_util.h"

namespace lpvid {
namespace time_plot_test {

using plot_test::count_color;
using plot_test::input_error;

TimeSeries ramp_and_constant(Index n, double t_end_s) {
  TimeSeries s{"measured", Eigen::VectorXd::LinSpaced(n, 0.0, t_end_s), Eigen::MatrixXd(n, 2)};
  s.values.col(0) = Eigen::VectorXd::LinSpaced(n, -1.0, 1.0);
  s.values.col(1).setConstant(2.0);
  return s;
}

TEST(TimePlotPng, DecodesToLayoutSizeWithOnePanelPerChannel) {
  TimePlotOptions options;
  options.channel_labels = {"x [m]", "F_x [N]"};
  options.title = "Validation";
  const std::vector<TimeSeries> s = {ramp_and_constant(100, 1.0)};
  const TimePlotLayout layout = layout_time_plot(s, options);
  const cv::Mat decoded = cv::imdecode(time_plot_png(s, options), cv::IMREAD_COLOR);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(decoded.size(), layout.figure);
  EXPECT_EQ(decoded.cols, 1000);
  ASSERT_EQ(layout.panels_px.size(), 2u);
  EXPECT_EQ(layout.panels_px[0].height, 220);
  EXPECT_GT(layout.panels_px[1].y, layout.panels_px[0].br().y);  // stacked
  EXPECT_GT(decoded.rows, 2 * 220);
}

TEST(TimePlotLayout, TimeAxisIsTightAndValueAxesSnapTo125Ticks) {
  const std::vector<TimeSeries> s = {ramp_and_constant(100, 2.0)};
  const TimePlotLayout layout = layout_time_plot(s, TimePlotOptions{});
  EXPECT_DOUBLE_EQ(layout.time.lo, 0.0);
  EXPECT_DOUBLE_EQ(layout.time.hi, 2.0);
  EXPECT_DOUBLE_EQ(layout.time_step, 0.2);
  // Ramp -1 .. 1 padded by 5 %: -1.1 .. 1.1 snapped to 0.5 steps.
  EXPECT_DOUBLE_EQ(layout.value_steps[0], 0.5);
  EXPECT_DOUBLE_EQ(layout.values[0].lo, -1.5);
  EXPECT_DOUBLE_EQ(layout.values[0].hi, 1.5);
}

TEST(RenderTimePlot, ConstantChannelDrawsOnItsValueRow) {
  const std::vector<TimeSeries> s = {ramp_and_constant(500, 1.0)};
  const TimePlotOptions options;
  const TimePlotLayout layout = layout_time_plot(s, options);
  const cv::Mat image = render_time_plot(s, options);
  const cv::Rect& a = layout.panels_px[1];
  const int row = static_cast<int>(std::lround(layout.values[1].to_px(2.0)));
  const cv::Rect on_row(a.x + 5, row, a.width - 10, 1);
  EXPECT_GE(count_color(image, on_row, plot::series_color(0)), on_row.width * 9 / 10);
  EXPECT_EQ(count_color(image, on_row - cv::Point(0, 10), plot::series_color(0)), 0);
}

TEST(DecimatedPolyline, MillionSamplesKeepTheEnvelopeInFewPoints) {
  const Index n = 1000000;
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(n, 0.0, 1.0);
  Eigen::VectorXd v(n);
  for (Index k = 0; k < n; ++k) v[k] = std::sin(200.0 * t[k]) + (k == 123456 ? 5.0 : 0.0);
  const plot::AxisMap time{0.0, 1.0, 100.0, 899.0, false};
  const plot::AxisMap value{-6.0, 6.0, 299.0, 0.0, false};
  const auto start = std::chrono::steady_clock::now();
  const auto points = decimated_polyline(t, v, time, value);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LE(points.size(), 2u * 800u + 2u);
  // The one-sample spike survives decimation.
  double top = 1e9;
  for (const auto& p : points) top = std::min(top, p.y);
  EXPECT_NEAR(top, value.to_px(5.0 + std::sin(200.0 * t[123456])), 1e-9);
  // Generous bound (unoptimised, shared CI cores): the loop is O(N), ~10 ms at -O2.
  EXPECT_LT(seconds, 1.0);
}

TEST(DecimatedPolyline, FewSamplesAreDrawnOneToOneAndNaNBreaks) {
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(5, 0.0, 4.0);
  const Eigen::VectorXd v = (Eigen::VectorXd(5) << 0.0, 1.0, NAN, 3.0, 4.0).finished();
  const plot::AxisMap time{0.0, 4.0, 0.0, 400.0, false};
  const plot::AxisMap value{0.0, 4.0, 400.0, 0.0, false};
  const auto points = decimated_polyline(t, v, time, value);
  ASSERT_EQ(points.size(), 5u);
  EXPECT_DOUBLE_EQ(points[1].x, 100.0);
  EXPECT_DOUBLE_EQ(points[1].y, 300.0);
  EXPECT_TRUE(std::isnan(points[2].x));
}

TEST(TimePlotErrors, MessagesNameTheProblem) {
  auto msg = [](std::vector<TimeSeries> s, TimePlotOptions o = TimePlotOptions{}) {
    return input_error([&] { time_plot_png(s, o); });
  };
  EXPECT_EQ(msg({}), "time plot: no series to draw; pass at least one signal");
  EXPECT_EQ(msg({TimeSeries{"y", Eigen::VectorXd(), Eigen::MatrixXd(0, 1)}}),
            "time plot: series 'y' has no samples");
  EXPECT_EQ(msg({TimeSeries{"y", Eigen::VectorXd::LinSpaced(4, 0, 1), Eigen::MatrixXd::Zero(3, 1)}}),
            "time plot: series 'y' has 4 time stamps for 3 sample rows; they must match");
  EXPECT_EQ(msg({ramp_and_constant(10, 1.0),
                 TimeSeries{"sim", Eigen::VectorXd::LinSpaced(4, 0, 1), Eigen::MatrixXd::Zero(4, 3)}}),
            "time plot: series 'sim' has 3 channels but series 'measured' has 2; all series "
            "must share the channels");
  TimeSeries back = ramp_and_constant(10, 1.0);
  back.t_s[5] = 0.0;
  EXPECT_EQ(msg({back}),
            "time plot: series 'measured' time stamp 5 is 0 s; time stamps must be finite and "
            "non-decreasing");
  TimePlotOptions labels;
  labels.channel_labels = {"x [m]"};
  EXPECT_EQ(msg({ramp_and_constant(10, 1.0)}, labels),
            "time plot: 1 channel labels given for 2 channels");
  TimePlotOptions small;
  small.width_px = 100;
  EXPECT_EQ(msg({ramp_and_constant(10, 1.0)}, small),
            "time plot: size 100 x 220 px is too small; width_px must be >= 300 and "
            "panel_height_px >= 60");
}

// The residual against a position, below a fit overlay: samples given out of order (a
// motion back and forth) are drawn sorted by the position, so a force periodic in
// position (here sin(2π x / 0.25 m)) is a wave: at x = 0.0625 m (a crest) the curve is
// at +1 and not at -1, at x = 0.1875 m (a trough) the other way round.  Mismatched
// lengths are refused in one line.
TEST(FitOverlayPng, AResidualAgainstPositionIsDrawnSortedBelowTheOverlay) {
  const Index n = 4000;
  FitOverlay ov;
  ov.t_s = Eigen::VectorXd::LinSpaced(n, 0.0, 4.0);
  ov.measured = Eigen::MatrixXd::Zero(n, 1);
  ov.predicted = ov.measured;
  ov.value_labels = {"x: force"};
  ov.residual_labels = {"x: residual"};
  Eigen::VectorXd x(n), r(n);
  for (Index k = 0; k < n; ++k) {
    x(k) = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(k) / 1000.0);  // back and forth over [0, 1]
    r(k) = std::sin(2.0 * M_PI * x(k) / 0.25);
  }
  ov.residual = r;
  const cv::Mat top = cv::imdecode(fit_overlay_png(ov), cv::IMREAD_COLOR);
  const cv::Mat both = cv::imdecode(fit_overlay_png(ov, {{"position x [m]", "x: residual", x, r}}), cv::IMREAD_COLOR);
  ASSERT_FALSE(top.empty());
  ASSERT_EQ(both.cols, top.cols);
  ASSERT_GT(both.rows, top.rows + ov.panel_height_px);
  // the lower part is the sorted series' plot (its layout from the same options)
  std::vector<Index> order(static_cast<std::size_t>(n));
  for (Index k = 0; k < n; ++k) order[static_cast<std::size_t>(k)] = k;
  std::stable_sort(order.begin(), order.end(), [&](Index a, Index b) { return x(a) < x(b); });
  TimeSeries sorted{"residual against position x [m]", Eigen::VectorXd(n), Eigen::MatrixXd(n, 1)};
  for (Index k = 0; k < n; ++k) {
    sorted.t_s(k) = x(order[static_cast<std::size_t>(k)]);
    sorted.values(k, 0) = r(order[static_cast<std::size_t>(k)]);
  }
  TimePlotOptions po;
  po.channel_labels = {"x: residual"};
  po.x_label = "position x [m]";
  po.width_px = top.cols;
  po.panel_height_px = ov.panel_height_px;
  const TimePlotLayout lay = layout_time_plot({sorted}, po);
  auto at = [&](double xv, double v) {
    const int col = static_cast<int>(std::lround(lay.time.to_px(xv)));
    const int row = top.rows + static_cast<int>(std::lround(lay.values[0].to_px(v)));
    return count_color(both, cv::Rect(col - 2, row - 3, 5, 7), plot::series_color(0));
  };
  EXPECT_GT(at(0.0625, 1.0), 0);
  EXPECT_EQ(at(0.0625, -1.0), 0);
  EXPECT_GT(at(0.1875, -1.0), 0);
  EXPECT_EQ(at(0.1875, 1.0), 0);
  EXPECT_EQ(input_error([&] { fit_overlay_png(ov, {{"position x [m]", "x: residual", x.head(10), r}}); }),
            "fit overlay: 10 values of position x [m] against 4000 residuals");
}

}  // namespace time_plot_test
}  // namespace lpvid
