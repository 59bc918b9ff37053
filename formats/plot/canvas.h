// lpvid — shared drawing toolkit for the plot writers (bode_plot, sv_plot,
// time_plot): tick generation, axis mapping, text, lines, markers, legends and
// PNG encoding.  Internal to formats/plot; the plot headers expose AxisMap and
// Tick so that tests can check where a value lands.
//
// Conventions: images are CV_8UC3 in BGR order on a white background; pixel
// coordinates are (x right, y down) with sub-pixel precision (cv::Point2d).
// All text is drawn with OpenCV's Hershey fonts, anti-aliased; Hershey fonts
// have ASCII glyphs only, so text is passed through ascii_text() first.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <string>
#include <vector>

namespace lpvid::plot {

// ---------------------------------------------------------------- ticks --

// One tick on an axis: its value in data units and the text drawn beside it.
struct Tick {
  double value = 0.0;
  std::string label;
};

// The smallest step of the form {1, 2, 5} x 10^k such that span / step <=
// max_intervals.  Preconditions: span > 0 and finite, max_intervals >= 1.
double nice_step(double span, int max_intervals);

// Every multiple of step in [lo, hi] (with a tolerance of 1e-9 step at both
// ends), labelled with format_tick(value, step).  Precondition: step > 0.
std::vector<Tick> linear_ticks(double lo, double hi, double step);

// [floor(lo / step) * step, ceil(hi / step) * step].
struct Range {
  double lo = 0.0;
  double hi = 1.0;
};
Range snap_outward(double lo, double hi, double step);

// Text for a tick value on an axis whose ticks are `step` apart: the fewest
// decimals that tell neighbouring ticks apart ("0.25", "-40", "1500"); values
// with magnitude >= 1e5 or steps < 1e-3 use scientific notation without
// padding ("1.5e-4", "2e6").  Exact zero prints "0".
std::string format_tick(double value, double step);

// How decade labels on a log axis read.
enum class DecadeLabels {
  kPlain,       // 0.01, 0.1, 1, 10, 100, 1000, 10000; 1e-3 / 1e5 beyond
  kScientific,  // 1e-3, 0.01 -> "1e-2", ...; 1 and 10 stay "1" and "10"
};
std::string format_decade(int exponent, DecadeLabels style);

// The decades 10^k inside [lo, hi] (0 < lo < hi), labelled with format_decade.
std::vector<Tick> decade_ticks(double lo, double hi, DecadeLabels style);

// The values d x 10^k, d = 2..9, strictly inside (lo, hi) (0 < lo < hi).
std::vector<double> minor_log_ticks(double lo, double hi);

// ----------------------------------------------------------------- axes --

// Maps a data value to a pixel coordinate along one axis: lo -> px_lo and
// hi -> px_hi, linearly in the value (log = false) or in log10 of the value
// (log = true).  For a y axis pass px_lo = bottom edge, px_hi = top edge.
// A log axis maps values <= 0 to NaN; non-finite values map to NaN.
struct AxisMap {
  double lo = 0.0;
  double hi = 1.0;
  double px_lo = 0.0;
  double px_hi = 1.0;
  bool log = false;

  double to_px(double value) const;
};

// ----------------------------------------------------------------- style --

// Colours (BGR).
extern const cv::Scalar kWhite, kBlack, kAxisColor, kGridMajor, kGridMinor, kTextColor,
    kFlagColor;

// Series colour i (cycles): the tab10 qualitative palette without its red,
// which is kept for flagged points.
cv::Scalar series_color(std::size_t i);

enum class LineStyle { kSolid, kDashed, kNone };
enum class Marker { kNone, kCircle, kCross, kSquare };

struct TextStyle {
  int font = cv::FONT_HERSHEY_SIMPLEX;
  double scale = 0.45;
  int thickness = 1;
  cv::Scalar color = cv::Scalar(30, 30, 30);
};
// The text sizes used by all plots.
TextStyle tick_text();        // 0.45, tick labels
TextStyle label_text();       // 0.5, axis labels and legend
TextStyle panel_title_text(); // 0.5 duplex, panel titles
TextStyle title_text();       // 0.7 duplex, figure titles

// Replaces what Hershey fonts cannot draw: common UTF-8 symbols by ASCII
// ("→" -> "->", "µ" -> "u", "°" -> "deg", Greek letters by their names) and
// every other non-ASCII or control byte by '?'.
std::string ascii_text(const std::string& text);

enum class HAlign { kLeft, kCenter, kRight };
enum class VAlign { kTop, kCenter, kBaseline, kBottom };

// Width and height (ascent + descent) of the text in pixels.
cv::Size text_size(const std::string& text, const TextStyle& style);

// The text, cut to fit max_width pixels with "..." at its end when it does not.
std::string fit_text(const std::string& text, const TextStyle& style, int max_width);

// A figure's title centred at height y between margins of `margin` pixels: a narrow
// figure (one panel) gets a smaller title (down to the label size) before it is cut.
void put_title(cv::Mat& image, const std::string& title, int margin, double y);

// Draws the text so that its box is aligned to `anchor` as asked.
void put_text(cv::Mat& image, const std::string& text, cv::Point2d anchor,
              const TextStyle& style, HAlign h, VAlign v);

// Draws the text rotated 90 degrees counter-clockwise (reading bottom to top),
// centred on `center`.
void put_text_vertical(cv::Mat& image, const std::string& text, cv::Point2d center,
                       const TextStyle& style);

// ------------------------------------------------------------- drawing --

// Draws a polyline through the points, clipped to `clip`.  A point with a
// non-finite coordinate breaks the line; it resumes at the next finite point.
void draw_polyline(cv::Mat& image, const std::vector<cv::Point2d>& points,
                   const cv::Scalar& color, int thickness, LineStyle style,
                   const cv::Rect& clip);

// Draws a marker of `size` pixels centred on p, clipped to `clip`.
void draw_marker(cv::Mat& image, cv::Point2d p, Marker marker, const cv::Scalar& color,
                 int size, const cv::Rect& clip);

// Light grid lines at the given data values (vertical for the x map,
// horizontal for the y map) across `area`.
void draw_grid_x(cv::Mat& image, const cv::Rect& area, const AxisMap& x,
                 const std::vector<double>& values, const cv::Scalar& color);
void draw_grid_y(cv::Mat& image, const cv::Rect& area, const AxisMap& y,
                 const std::vector<double>& values, const cv::Scalar& color);

// The axes box and short inward tick marks.
void draw_frame(cv::Mat& image, const cv::Rect& area);
void draw_x_tick_labels(cv::Mat& image, const cv::Rect& area, const AxisMap& x,
                        const std::vector<Tick>& ticks);
void draw_y_tick_labels(cv::Mat& image, const cv::Rect& area, const AxisMap& y,
                        const std::vector<Tick>& ticks);

// ---------------------------------------------------------------- legend --

struct LegendEntry {
  std::string label;
  cv::Scalar color;
  LineStyle line = LineStyle::kSolid;
  Marker marker = Marker::kNone;
};

// Size of the boxed legend when its entries are laid out left to right and
// wrapped so that no row is wider than max_width_px.
cv::Size legend_size(const std::vector<LegendEntry>& entries, int max_width_px);
void draw_legend(cv::Mat& image, const std::vector<LegendEntry>& entries,
                 cv::Point top_left, int max_width_px);

// ------------------------------------------------------------------ png --

// PNG bytes of a CV_8UC3 image.  Throws std::runtime_error if OpenCV cannot
// encode (a bug or a broken OpenCV install, not bad input).
std::vector<unsigned char> encode_png(const cv::Mat& image);

}  // namespace lpvid::plot
