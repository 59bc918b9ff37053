#include "formats/plot/bode_plot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <opencv2/imgcodecs.hpp>

#include "tests/formats/plot/plot_test_util.h"

namespace lpvid {
namespace bode_plot_test {

using plot_test::count_color;
using plot_test::input_error;

Eigen::VectorXd log_grid(double lo_exp, double hi_exp, Index n) {
  return Eigen::VectorXd::LinSpaced(n, lo_exp, hi_exp).unaryExpr([](double e) {
    return std::pow(10.0, e);
  });
}

// Every entry equal to `gain` at every frequency.
FrequencyResponse constant(const Eigen::VectorXd& omega, Index p, Index m, Complex gain) {
  FrequencyResponse r;
  r.omega_rad_s = omega;
  for (Index k = 0; k < omega.size(); ++k) {
    r.response.push_back(Eigen::MatrixXcd::Constant(p, m, gain));
  }
  return r;
}

BodeSeries series(const std::string& label, FrequencyResponse r,
                  BodeSeries::Style style = BodeSeries::Style::kLine) {
  return BodeSeries{label, std::move(r), style};
}

TEST(BodePng, DecodesToLayoutSizeOfA3x3Grid) {
  const std::vector<BodeSeries> s = {series("P", constant(log_grid(0, 3, 50), 3, 3, 1.0))};
  BodePlotOptions options;
  options.title = "Plant";
  const BodeLayout layout = layout_bode(s, options);
  const cv::Mat decoded = cv::imdecode(bode_png(s, options), cv::IMREAD_COLOR);
  ASSERT_FALSE(decoded.empty());
  EXPECT_EQ(decoded.cols, layout.figure.width);
  EXPECT_EQ(decoded.rows, layout.figure.height);
  ASSERT_EQ(layout.panels.size(), 9u);
  // Three columns of 420 px and three rows of 260 + 150 px axes fit inside.
  EXPECT_GT(decoded.cols, 3 * 420);
  EXPECT_GT(decoded.rows, 3 * (260 + 150));
  // Row = output, column = input: panels step right along inputs, down along outputs.
  EXPECT_GT(layout.panel(0, 1).magnitude_px.x, layout.panel(0, 0).magnitude_px.br().x);
  EXPECT_GT(layout.panel(1, 0).magnitude_px.y, layout.panel(0, 0).phase_px.br().y);
  EXPECT_EQ(layout.panel(2, 2).magnitude_px.size(), cv::Size(420, 260));
  EXPECT_EQ(layout.panel(2, 2).phase_px.size(), cv::Size(420, 150));
  EXPECT_GT(layout.panel(0, 0).phase_px.y, layout.panel(0, 0).magnitude_px.br().y);
  // The whole grid and the legend lie inside the image.
  const cv::Rect image(0, 0, decoded.cols, decoded.rows);
  EXPECT_EQ(layout.legend_px & image, layout.legend_px);
  EXPECT_EQ(layout.panel(2, 2).phase_px & image, layout.panel(2, 2).phase_px);
}

TEST(BodePng, WithoutPhaseThePanelsAreMagnitudeOnlyAndShorter) {
  const std::vector<BodeSeries> s = {series("P", constant(log_grid(0, 3, 50), 2, 1, 1.0))};
  BodePlotOptions with_phase, without;
  without.show_phase = false;
  const BodeLayout a = layout_bode(s, with_phase), b = layout_bode(s, without);
  EXPECT_TRUE(b.panel(1, 0).phase_px.empty());
  EXPECT_EQ(a.figure.height - b.figure.height, 2 * (150 + 18));
  const cv::Mat image = render_bode(s, without);
  EXPECT_EQ(image.size(), b.figure);
}

TEST(RenderBode, ConstantGainOf20dBDrawsOnThe20dBRow) {
  const std::vector<BodeSeries> s = {series("gain 10", constant(log_grid(0, 3, 60), 1, 1, 10.0))};
  BodePlotOptions options;
  const BodeLayout layout = layout_bode(s, options);
  const BodeAxes& axes = layout.panel(0, 0);
  // The range covers 20 dB with ticks on whole dB steps.
  EXPECT_LE(axes.magnitude_db.lo, 20.0 - 5.0);
  EXPECT_GE(axes.magnitude_db.hi, 20.0 + 5.0);
  const cv::Mat image = render_bode(s, options);
  const int row = static_cast<int>(std::lround(axes.magnitude_db.to_px(20.0)));
  const cv::Rect& m = axes.magnitude_px;
  const cv::Scalar color = plot::series_color(0);
  // Across the data (1 .. 1000 rad/s = the whole axis), the curve's colour is
  // on the 20 dB row, and not 10 px above or below it.
  const cv::Rect on_row(m.x + 10, row, m.width - 20, 1);
  EXPECT_GE(count_color(image, on_row, color), on_row.width * 9 / 10);
  EXPECT_EQ(count_color(image, on_row - cv::Point(0, 10), color), 0);
  EXPECT_EQ(count_color(image, on_row + cv::Point(0, 10), color), 0);
  // Phase 0 deg likewise.
  const int phase_row = static_cast<int>(std::lround(axes.phase_deg.to_px(0.0)));
  const cv::Rect phase_line(m.x + 10, phase_row, m.width - 20, 1);
  EXPECT_GE(count_color(image, phase_line, color), phase_line.width * 9 / 10);
}

TEST(RenderBode, FrequencyAxisSnapsToDecadesAndConvertsToHz) {
  FrequencyResponse r = constant(log_grid(std::log10(1.5), std::log10(800.0), 30), 1, 1, 1.0);
  const std::vector<BodeSeries> s = {series("P", r)};
  BodePlotOptions options;
  const BodeLayout rad = layout_bode(s, options);
  EXPECT_DOUBLE_EQ(rad.panel(0, 0).frequency.lo, 1.0);
  EXPECT_DOUBLE_EQ(rad.panel(0, 0).frequency.hi, 1000.0);
  EXPECT_TRUE(rad.panel(0, 0).frequency.log);
  options.frequency_in_hz = true;
  options.min_omega_rad_s = 2.0 * std::numbers::pi;  // 1 Hz
  options.max_omega_rad_s = 2.0 * std::numbers::pi * 100.0;
  const BodeLayout hz = layout_bode(s, options);
  EXPECT_NEAR(hz.panel(0, 0).frequency.lo, 1.0, 1e-12);
  EXPECT_NEAR(hz.panel(0, 0).frequency.hi, 100.0, 1e-12);
}

TEST(RenderBode, SeriesOnDifferentGridsEachDrawInTheirOwnColour) {
  const std::vector<BodeSeries> s = {
      series("data", constant(log_grid(0, 2, 25), 1, 1, 1.0), BodeSeries::Style::kMarkers),
      series("model", constant(log_grid(1, 3, 200), 1, 1, 0.1), BodeSeries::Style::kDashed)};
  const BodePlotOptions options;
  const BodeAxes axes = layout_bode(s, options).panel(0, 0);
  const cv::Mat image = render_bode(s, options);
  const cv::Rect& m = axes.magnitude_px;
  // Data at 0 dB over 1..100 rad/s: left two thirds of the axis only.
  const int row0 = static_cast<int>(std::lround(axes.magnitude_db.to_px(0.0)));
  const int x100 = static_cast<int>(std::lround(axes.frequency.to_px(100.0)));
  EXPECT_GT(count_color(image, cv::Rect(m.x, row0 - 2, x100 - m.x, 5), plot::series_color(0)), 50);
  EXPECT_EQ(count_color(image, cv::Rect(x100 + 8, row0 - 3, m.br().x - x100 - 8, 7),
                        plot::series_color(0)),
            0);
  // Model at -20 dB, dashed: present, but with gaps.
  const int row20 = static_cast<int>(std::lround(axes.magnitude_db.to_px(-20.0)));
  const int x10 = static_cast<int>(std::lround(axes.frequency.to_px(10.0)));
  const cv::Rect dash_row(x10 + 5, row20, m.br().x - x10 - 10, 1);
  const int dashed = count_color(image, dash_row, plot::series_color(1));
  EXPECT_GT(dashed, dash_row.width / 3);
  EXPECT_LT(dashed, dash_row.width * 9 / 10);
}

TEST(RenderBode, FlaggedFrequenciesGetRedCrossesOnlyWhenFlagged) {
  FrequencyResponse r = constant(log_grid(0, 3, 40), 1, 1, 1.0);
  const std::vector<BodeSeries> clean = {series("P", r)};
  r.flagged.assign(40, false);
  r.flagged[20] = true;
  const std::vector<BodeSeries> flagged = {series("P", r)};
  const BodePlotOptions options;
  const BodeAxes axes = layout_bode(flagged, options).panel(0, 0);
  EXPECT_EQ(count_color(render_bode(clean, options), axes.magnitude_px, plot::kFlagColor), 0);
  const cv::Mat image = render_bode(flagged, options);
  const cv::Point2d at(axes.frequency.to_px(r.omega_rad_s[20]), axes.magnitude_db.to_px(0.0));
  const cv::Rect around(static_cast<int>(at.x) - 6, static_cast<int>(at.y) - 6, 13, 13);
  EXPECT_GT(count_color(image, around, plot::kFlagColor), 8);
}

TEST(RenderBode, ZeroMagnitudeIsSkippedAndNaNBreaksTheLine) {
  FrequencyResponse r = constant(log_grid(0, 3, 61), 1, 1, 1.0);
  r.response[10](0, 0) = 0.0;                                       // -inf dB: skipped
  for (int k = 30; k <= 40; ++k) r.response[static_cast<std::size_t>(k)](0, 0) = Complex(NAN, 0.0);
  const std::vector<BodeSeries> s = {series("P", r)};
  const BodePlotOptions options;
  const BodeAxes axes = layout_bode(s, options).panel(0, 0);
  const cv::Mat image = render_bode(s, options);
  const int row = static_cast<int>(std::lround(axes.magnitude_db.to_px(0.0)));
  auto px = [&](double w) { return static_cast<int>(std::lround(axes.frequency.to_px(w))); };
  const double w = [&](int k) { return r.omega_rad_s[k]; }(10);
  // Around the zero the line continues at 0 dB.
  EXPECT_GT(count_color(image, cv::Rect(px(w) - 3, row, 7, 1), plot::series_color(0)), 5);
  // Between the NaNs (k = 31 .. 39) there is no line.
  const cv::Rect gap(px(r.omega_rad_s[31]), row - 3, px(r.omega_rad_s[39]) - px(r.omega_rad_s[31]), 7);
  EXPECT_EQ(count_color(image, gap, plot::series_color(0)), 0);
}

TEST(UnwrappedPhase, RemovesJumpsAndStartsInMinus270To90) {
  // A pure delay e^{-j w} over w = 0.1 .. 10 rad: phase -w rad, continuous.
  std::vector<Complex> delay;
  for (int k = 0; k <= 99; ++k) delay.push_back(std::polar(1.0, -(0.1 + 0.1 * k)));
  const auto phase = unwrapped_phase_deg(delay);
  for (std::size_t k = 0; k < phase.size(); ++k) {
    EXPECT_NEAR(phase[k], -(0.1 + 0.1 * static_cast<double>(k)) * 180.0 / std::numbers::pi, 1e-9);
  }
  // A negative real gain starts at -180, not +180; a gap (0 / NaN) keeps unwrapping.
  const auto neg = unwrapped_phase_deg({Complex(-1.0, 1e-12), 0.0, Complex(NAN, 0.0),
                                        Complex(-1.0, -1e-12)});
  EXPECT_NEAR(neg[0], -180.0, 1e-6);
  EXPECT_TRUE(std::isnan(neg[1]));
  EXPECT_TRUE(std::isnan(neg[2]));
  EXPECT_NEAR(neg[3], -180.0, 1e-6);
  EXPECT_NEAR(unwrapped_phase_deg({Complex(0.0, 1.0)})[0], 90.0, 1e-12);
}

// Two responses 2 degrees apart whose phases lie on either side of +90 deg: each unwrapped
// alone starts in (-270, 90], one at +89 and one at -269 (= +91 - 360), 358 deg apart.
// The panel aligns them, so the phase axis spans tens of degrees, not 360; a
// magnitude-only series (a band envelope) adds nothing to the phase range.
TEST(RenderBode, PhasesOfOnePanelAreAlignedAndMagnitudeOnlySeriesHaveNone) {
  const Eigen::VectorXd omega = log_grid(0, 2, 20);
  const Complex a = std::polar(1.0, 89.0 * M_PI / 180.0), b = std::polar(1.0, 91.0 * M_PI / 180.0);
  ASSERT_GT(unwrapped_phase_deg({a})[0] - unwrapped_phase_deg({b})[0], 300.0);  // the case being fixed
  BodeSeries band = series("band", constant(omega, 1, 1, Complex(-5.0, 0.0)));
  band.show_phase = false;  // phase -180 deg if it were drawn
  const BodeLayout layout =
      layout_bode({series("a", constant(omega, 1, 1, a)), series("b", constant(omega, 1, 1, b)), band}, {});
  const plot::AxisMap& ph = layout.panel(0, 0).phase_deg;
  EXPECT_LT(ph.hi - ph.lo, 100.0) << ph.lo << " .. " << ph.hi;
  EXPECT_LE(ph.lo, 89.0);
  EXPECT_GE(ph.hi, 91.0);
}

TEST(BodeErrors, MessagesNameTheProblem) {
  const FrequencyResponse good = constant(log_grid(0, 2, 5), 2, 2, 1.0);
  auto msg = [&](std::vector<BodeSeries> s, BodePlotOptions o = BodePlotOptions{}) {
    return input_error([&] { bode_png(s, o); });
  };
  EXPECT_EQ(msg({}), "bode plot: no series to draw; pass at least one response");

  FrequencyResponse empty;
  EXPECT_EQ(msg({series("P", empty)}), "bode plot: series 'P' has no frequencies");

  FrequencyResponse short_r = good;
  short_r.response.pop_back();
  EXPECT_EQ(msg({series("P", short_r)}),
            "bode plot: series 'P' has 4 response matrices for 5 frequencies; they must match");

  FrequencyResponse negative = good;
  negative.omega_rad_s[0] = -1.0;
  EXPECT_EQ(msg({series("P", negative)}),
            "bode plot: series 'P' has frequency -1 rad/s at index 0; a log frequency axis "
            "needs finite frequencies > 0");
  FrequencyResponse zero = good;
  zero.omega_rad_s[2] = 0.0;
  EXPECT_EQ(msg({series("P", zero)}),
            "bode plot: series 'P' has frequency 0 rad/s at index 2; a log frequency axis "
            "needs finite frequencies > 0");

  EXPECT_EQ(msg({series("P", good), series("Q", constant(log_grid(0, 2, 5), 3, 2, 1.0))}),
            "bode plot: series 'Q' has a 3x2 response at frequency index 0 but series 'P' is "
            "2x2 (outputs x inputs); all responses must share one shape");

  FrequencyResponse flags = good;
  flags.flagged = {true, false};
  EXPECT_EQ(msg({series("P", flags)}),
            "bode plot: series 'P' has 2 flagged entries for 5 frequencies; give none or one "
            "per frequency");

  BodePlotOptions labels;
  labels.input_labels = {"u"};
  EXPECT_EQ(msg({series("P", good)}, labels), "bode plot: 1 input labels given for 2 inputs");

  BodePlotOptions limits;
  limits.min_omega_rad_s = 10.0;
  limits.max_omega_rad_s = 1.0;
  EXPECT_EQ(msg({series("P", good)}, limits),
            "bode plot: min_omega_rad_s 10 must be below max_omega_rad_s 1");

  BodePlotOptions small;
  small.panel_width_px = 10;
  EXPECT_EQ(msg({series("P", good)}, small),
            "bode plot: panel size 10x260 (+ phase 150) px is too small; each side must be >= 60 px");
}

}  // namespace bode_plot_test
}  // namespace lpvid
