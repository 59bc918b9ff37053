// lpvid — time-domain comparison plots (measured vs simulated signals).
//
// One panel per channel, stacked vertically and sharing the time axis; every
// series draws each of its channels in its panel, in its own colour.  Signal
// layout as in idlib/core/types.h: values is N x channels, row k at t_s[k].
//
// Axes: time spans exactly [min t, max t] over all series; each panel's y
// range covers its channel over all series with a little padding, snapped to
// 1-2-5 ticks.  Tick labels use plot::format_tick ("0.25", "1.5e-4").
// Drawing decimates to one (min, max) pair per pixel column, so 1e6 samples
// draw in milliseconds and the envelope stays exact.  NaN/inf samples break
// the line.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "formats/plot/canvas.h"
#include "idlib/core/types.h"

namespace lpvid {

struct TimeSeries {
  std::string label;      // legend entry
  Eigen::VectorXd t_s;    // N time stamps, finite and non-decreasing
  Eigen::MatrixXd values; // N x channels
};

struct TimePlotOptions {
  // Y axis label of each panel, with units ("x [m]"); empty = "channel 1"...
  // When given, one per channel.
  std::vector<std::string> channel_labels;
  std::string title;        // figure title; empty = none
  int width_px = 1000;      // whole figure width, >= 300
  int panel_height_px = 220;  // height of each panel's axes, >= 60
  std::string x_label = "Time [s]";  // the shared axis (a residual against position: "x [m]")
};

struct TimePlotLayout {
  cv::Size figure;
  plot::AxisMap time;                 // x of every panel
  std::vector<cv::Rect> panels_px;    // axes of channel c
  std::vector<plot::AxisMap> values;  // y of channel c
  std::vector<double> value_steps;    // tick spacing of channel c
  double time_step = 0.0;             // tick spacing of the time axis
  cv::Rect legend_px;
};

// @throws InputError (one line) when series is empty; a series has no
//   samples, a time-stamp count different from its row count, non-finite or
//   decreasing time stamps, or a channel count of 0 or different from the
//   first series'; channel_labels has the wrong count; or the sizes are below
//   the minimums above.
TimePlotLayout layout_time_plot(const std::vector<TimeSeries>& series,
                                const TimePlotOptions& options);
cv::Mat render_time_plot(const std::vector<TimeSeries>& series, const TimePlotOptions& options);
std::vector<unsigned char> time_plot_png(const std::vector<TimeSeries>& series,
                                         const TimePlotOptions& options);

// A time window to mark on one panel (e.g. where a model fails).
struct TimeWindowMark {
  std::size_t panel = 0;  // index into layout.panels_px
  double t_start_s = 0.0, t_end_s = 0.0;
};
// Shades each window across its panel in translucent red (25 %, so the curves
// stay readable), clipped to the panel.  A panel index out of range is skipped.
void shade_time_windows(cv::Mat& image, const TimePlotLayout& layout, const std::vector<TimeWindowMark>& marks);

// A model's prediction of a log (compare --log, every route): per channel a panel of the
// measured and the predicted signal, then per channel a panel of the residual with the
// failing windows shaded.  measured, predicted and residual are N × k with the same k;
// value_labels and residual_labels one per channel; a mark's panel is the channel's
// index 0..k-1 (its residual panel is shaded).
struct FitOverlay {
  Eigen::VectorXd t_s;
  Eigen::MatrixXd measured, predicted, residual;
  std::vector<std::string> value_labels, residual_labels;
  std::vector<TimeWindowMark> failures;
  std::string title;
  int panel_height_px = 150;
};
// @throws InputError  shapes or label counts that differ (as render_time_plot).
std::vector<unsigned char> fit_overlay_png(const FitOverlay& overlay);

// Below a fit overlay, per channel its residual against another variable — a position,
// where a force that repeats with position (cogging, a screw's lead error) shows as a
// wave that the time axis hides — the samples sorted by that variable, non-finite ones
// skipped; one panel each, as wide as the overlay.
struct ResidualAgainst {
  std::string x_label, y_label;  // "x [m]", "x: residual"
  Eigen::VectorXd x, residual;   // the same length
};
// @throws InputError  as fit_overlay_png; x and residual of different lengths, or no
//   finite pair.
std::vector<unsigned char> fit_overlay_png(const FitOverlay& overlay, const std::vector<ResidualAgainst>& below);

// The polyline drawn for samples (t, v): with x = time.to_px(t), one point per
// sample when there are at most 2 per pixel column, otherwise per column the
// minimum and the maximum (in the order they occur) at the column's centre.
// A non-finite value gives a (NaN, NaN) break point.  Exposed for tests.
std::vector<cv::Point2d> decimated_polyline(const Eigen::VectorXd& t_s,
                                            const Eigen::Ref<const Eigen::VectorXd>& v,
                                            const plot::AxisMap& time,
                                            const plot::AxisMap& value);

}  // namespace lpvid
