// Tick generation, number formatting and axis mapping shared by the plots.
#include "formats/plot/canvas.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>

namespace lpvid::plot {
namespace canvas_test {

std::vector<double> values(const std::vector<Tick>& ticks) {
  std::vector<double> v;
  for (const Tick& t : ticks) v.push_back(t.value);
  return v;
}
std::vector<std::string> labels(const std::vector<Tick>& ticks) {
  std::vector<std::string> v;
  for (const Tick& t : ticks) v.push_back(t.label);
  return v;
}

TEST(NiceStep, PicksSmallest125StepWithinIntervalCount) {
  EXPECT_DOUBLE_EQ(nice_step(10.0, 5), 2.0);
  EXPECT_DOUBLE_EQ(nice_step(1.0, 5), 0.2);
  EXPECT_DOUBLE_EQ(nice_step(7.0, 6), 2.0);
  EXPECT_DOUBLE_EQ(nice_step(100.0, 5), 20.0);
  EXPECT_DOUBLE_EQ(nice_step(30.0, 6), 5.0);
  EXPECT_DOUBLE_EQ(nice_step(0.003, 6), 0.0005);
  EXPECT_DOUBLE_EQ(nice_step(2.0e5, 4), 5.0e4);
}

TEST(LinearTicks, MultiplesOfStepInsideRangeWithConsistentDecimals) {
  const auto t = linear_ticks(-1.0, 1.0, 0.5);
  EXPECT_EQ(values(t), (std::vector<double>{-1.0, -0.5, 0.0, 0.5, 1.0}));
  EXPECT_EQ(labels(t), (std::vector<std::string>{"-1.0", "-0.5", "0", "0.5", "1.0"}));
  // Ends that are not multiples are not ticks; 0.1 steps do not drift.
  EXPECT_EQ(labels(linear_ticks(0.05, 0.35, 0.1)), (std::vector<std::string>{"0.1", "0.2", "0.3"}));
  EXPECT_EQ(labels(linear_ticks(-160.0, -80.0, 20.0)),
            (std::vector<std::string>{"-160", "-140", "-120", "-100", "-80"}));
}

TEST(SnapOutward, RoundsRangeOutToStepMultiples) {
  const Range r = snap_outward(-37.0, 12.0, 20.0);
  EXPECT_DOUBLE_EQ(r.lo, -40.0);
  EXPECT_DOUBLE_EQ(r.hi, 20.0);
  const Range exact = snap_outward(-40.0, 20.0, 20.0);
  EXPECT_DOUBLE_EQ(exact.lo, -40.0);
  EXPECT_DOUBLE_EQ(exact.hi, 20.0);
}

TEST(FormatTick, PlainForOrdinaryStepsScientificForTinyOrHugeOnes) {
  EXPECT_EQ(format_tick(0.25, 0.05), "0.25");
  EXPECT_EQ(format_tick(-40.0, 20.0), "-40");
  EXPECT_EQ(format_tick(1500.0, 500.0), "1500");
  EXPECT_EQ(format_tick(0.0, 1e-4), "0");
  EXPECT_EQ(format_tick(1.5e-4, 5e-5), "1.5e-4");
  EXPECT_EQ(format_tick(2e-4, 1e-4), "2e-4");
  EXPECT_EQ(format_tick(-1e-4, 1e-4), "-1e-4");
  EXPECT_EQ(format_tick(2e6, 1e6), "2e6");
  EXPECT_EQ(format_tick(1.5e5, 5e4), "1.5e5");
}

TEST(DecadeTicks, PlainLabelsReadAsNumbers) {
  const auto t = decade_ticks(1.0, 1000.0, DecadeLabels::kPlain);
  EXPECT_EQ(values(t), (std::vector<double>{1.0, 10.0, 100.0, 1000.0}));
  EXPECT_EQ(labels(t), (std::vector<std::string>{"1", "10", "100", "1000"}));
  EXPECT_EQ(labels(decade_ticks(0.01, 0.1, DecadeLabels::kPlain)),
            (std::vector<std::string>{"0.01", "0.1"}));
  EXPECT_EQ(labels(decade_ticks(1e4, 1e5, DecadeLabels::kPlain)),
            (std::vector<std::string>{"10000", "1e5"}));
  EXPECT_EQ(labels(decade_ticks(1e-3, 1e-3 * 1.01, DecadeLabels::kPlain)),
            (std::vector<std::string>{"1e-3"}));
  // Only decades inside the range.
  EXPECT_EQ(values(decade_ticks(0.5, 50.0, DecadeLabels::kPlain)),
            (std::vector<double>{1.0, 10.0}));
}

TEST(DecadeTicks, ScientificLabelsForSingularValues) {
  EXPECT_EQ(labels(decade_ticks(1e-3, 10.0, DecadeLabels::kScientific)),
            (std::vector<std::string>{"1e-3", "1e-2", "1e-1", "1", "10"}));
}

TEST(MinorLogTicks, TwoToNineTimesEachDecadeStrictlyInside) {
  const auto v = minor_log_ticks(1.0, 100.0);
  ASSERT_EQ(v.size(), 16u);
  EXPECT_DOUBLE_EQ(v.front(), 2.0);
  EXPECT_DOUBLE_EQ(v[7], 9.0);
  EXPECT_DOUBLE_EQ(v[8], 20.0);
  EXPECT_DOUBLE_EQ(v.back(), 90.0);
  EXPECT_EQ(minor_log_ticks(1.5, 4.0), (std::vector<double>{2.0, 3.0}));
}

TEST(AxisMap, LinearMapsEndsAndMidpoint) {
  const AxisMap y{-40.0, 40.0, 299.0, 0.0, false};  // y axis: lo at the bottom
  EXPECT_DOUBLE_EQ(y.to_px(-40.0), 299.0);
  EXPECT_DOUBLE_EQ(y.to_px(40.0), 0.0);
  EXPECT_DOUBLE_EQ(y.to_px(0.0), 149.5);
  EXPECT_DOUBLE_EQ(y.to_px(20.0), 74.75);
  EXPECT_TRUE(std::isnan(y.to_px(std::nan(""))));
}

TEST(AxisMap, LogSpacesDecadesEquallyAndRejectsNonPositive) {
  const AxisMap x{1.0, 1000.0, 100.0, 400.0, true};
  EXPECT_DOUBLE_EQ(x.to_px(1.0), 100.0);
  EXPECT_NEAR(x.to_px(10.0), 200.0, 1e-9);
  EXPECT_NEAR(x.to_px(100.0), 300.0, 1e-9);
  EXPECT_DOUBLE_EQ(x.to_px(1000.0), 400.0);
  EXPECT_TRUE(std::isnan(x.to_px(0.0)));
  EXPECT_TRUE(std::isnan(x.to_px(-1.0)));
}

TEST(AsciiText, TransliteratesCommonSymbolsForHersheyFonts) {
  EXPECT_EQ(ascii_text("from T_\xCF\x88 \xE2\x86\x92 y"), "from T_psi -> y");
  EXPECT_EQ(ascii_text("x [\xC2\xB5m]"), "x [um]");
  EXPECT_EQ(ascii_text("tab\there"), "tab here");
  EXPECT_EQ(ascii_text("\xE6\x97\xA5"), "?");  // CJK: no glyph
}

TEST(EncodePng, RoundTripsThroughImdecode) {
  cv::Mat image(20, 30, CV_8UC3, kWhite);
  image.at<cv::Vec3b>(5, 7) = cv::Vec3b(1, 2, 3);
  const auto bytes = encode_png(image);
  const cv::Mat back = cv::imdecode(bytes, cv::IMREAD_COLOR);
  ASSERT_EQ(back.size(), image.size());
  EXPECT_EQ(back.at<cv::Vec3b>(5, 7), cv::Vec3b(1, 2, 3));
}

}  // namespace canvas_test
}  // namespace lpvid::plot
