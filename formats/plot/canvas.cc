#include "formats/plot/canvas.h"

#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace lpvid::plot {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Relative slack when deciding whether a tick lies on an axis end: tick
// values are computed as i * step and carry rounding errors of a few ulps.
constexpr double kTickSlack = 1e-9;
// Sub-pixel bits for cv::line / cv::circle (coordinates are multiplied by 16).
constexpr int kShift = 4;
constexpr double kShiftScale = 16.0;
// Dash pattern in pixels (on, off), chosen to read as dashed at 2 px width.
constexpr double kDashOn = 8.0;
constexpr double kDashOff = 5.0;

cv::Point to_fixed(cv::Point2d p) {
  return {static_cast<int>(std::lround(p.x * kShiftScale)),
          static_cast<int>(std::lround(p.y * kShiftScale))};
}

bool finite(cv::Point2d p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// Liang-Barsky: clips segment a-b to the box [x0, x1] x [y0, y1]; false if
// nothing is left.
bool clip_segment(cv::Point2d& a, cv::Point2d& b, double x0, double y0, double x1, double y1) {
  double t0 = 0.0, t1 = 1.0;
  const double dx = b.x - a.x, dy = b.y - a.y;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {a.x - x0, x1 - a.x, a.y - y0, y1 - a.y};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) return false;
    } else {
      const double r = q[i] / p[i];
      if (p[i] < 0.0) {
        t0 = std::max(t0, r);
      } else {
        t1 = std::min(t1, r);
      }
      if (t0 > t1) return false;
    }
  }
  const cv::Point2d a0 = a;
  a = a0 + t0 * cv::Point2d(dx, dy);
  b = a0 + t1 * cv::Point2d(dx, dy);
  return true;
}

void line_aa(cv::Mat& image, cv::Point2d a, cv::Point2d b, const cv::Scalar& color,
             int thickness) {
  cv::line(image, to_fixed(a), to_fixed(b), color, thickness, cv::LINE_AA, kShift);
}

// Appends the UTF-8 code point cp, transliterated to ASCII, to out.
void append_ascii(std::string& out, char32_t cp) {
  static const char* const kGreek[] = {
      "alpha", "beta", "gamma", "delta", "epsilon", "zeta",  "eta",     "theta", "iota",
      "kappa", "lambda", "mu",  "nu",    "xi",      "omicron", "pi",    "rho",   "sigma",
      "sigma", "tau",  "upsilon", "phi", "chi",     "psi",   "omega"};
  if (cp >= 0x3B1 && cp <= 0x3C9) {
    out += kGreek[cp - 0x3B1];
    return;
  }
  switch (cp) {
    case 0x2192: out += "->"; return;
    case 0x2190: out += "<-"; return;
    case 0x00B5: out += "u"; return;
    case 0x00B0: out += "deg"; return;
    case 0x00B2: out += "^2"; return;
    case 0x00B3: out += "^3"; return;
    case 0x00D7: out += "x"; return;
    case 0x00B7: out += "*"; return;
    case 0x2212: case 0x2013: case 0x2014: out += "-"; return;
    case 0x0394: out += "Delta"; return;
    case 0x03A9: out += "Omega"; return;
    default: out += '?'; return;
  }
}

}  // namespace

// ---------------------------------------------------------------- ticks --

double nice_step(double span, int max_intervals) {
  const double raw = span / max_intervals;
  double base = std::pow(10.0, std::floor(std::log10(raw)));
  for (int guard = 0; guard < 4; ++guard, base *= 10.0) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double step = m * base;
      if (span / step <= max_intervals * (1.0 + kTickSlack)) return step;
    }
  }
  return base;
}

std::vector<Tick> linear_ticks(double lo, double hi, double step) {
  std::vector<Tick> ticks;
  const double i0 = std::ceil(lo / step - kTickSlack);
  const double i1 = std::floor(hi / step + kTickSlack);
  for (double i = i0; i <= i1; i += 1.0) {
    double v = i * step;
    if (std::abs(v) < step * kTickSlack) v = 0.0;
    ticks.push_back({v, format_tick(v, step)});
  }
  return ticks;
}

Range snap_outward(double lo, double hi, double step) {
  return {std::floor(lo / step + kTickSlack) * step, std::ceil(hi / step - kTickSlack) * step};
}

std::string format_tick(double value, double step) {
  if (value == 0.0 || std::abs(value) < step * kTickSlack) return "0";
  const int step_exp = static_cast<int>(std::floor(std::log10(step) + kTickSlack));
  const bool scientific = step < 1e-3 || step >= 1e4;
  if (!scientific) {
    const int decimals = std::max(0, -step_exp);
    return fmt::format("{:.{}f}", value, decimals);
  }
  int e = static_cast<int>(std::floor(std::log10(std::abs(value))));
  const int decimals = std::clamp(e - step_exp, 0, 6);
  double mantissa = value / std::pow(10.0, e);
  std::string m = fmt::format("{:.{}f}", mantissa, decimals);
  if (std::abs(std::stod(m)) >= 10.0) {  // rounding carried into a new digit
    ++e;
    mantissa /= 10.0;
    m = fmt::format("{:.{}f}", mantissa, decimals);
  }
  if (m.find('.') != std::string::npos) {
    while (m.back() == '0') m.pop_back();
    if (m.back() == '.') m.pop_back();
  }
  return fmt::format("{}e{}", m, e);
}

std::string format_decade(int exponent, DecadeLabels style) {
  const bool plain = style == DecadeLabels::kPlain ? (exponent >= -2 && exponent <= 4)
                                                   : (exponent == 0 || exponent == 1);
  if (!plain) return fmt::format("1e{}", exponent);
  if (exponent >= 0) return "1" + std::string(static_cast<std::size_t>(exponent), '0');
  return "0." + std::string(static_cast<std::size_t>(-exponent - 1), '0') + "1";
}

std::vector<Tick> decade_ticks(double lo, double hi, DecadeLabels style) {
  std::vector<Tick> ticks;
  const int k0 = static_cast<int>(std::ceil(std::log10(lo) - kTickSlack));
  const int k1 = static_cast<int>(std::floor(std::log10(hi) + kTickSlack));
  for (int k = k0; k <= k1; ++k) ticks.push_back({std::pow(10.0, k), format_decade(k, style)});
  return ticks;
}

std::vector<double> minor_log_ticks(double lo, double hi) {
  std::vector<double> values;
  const int k0 = static_cast<int>(std::floor(std::log10(lo)));
  const int k1 = static_cast<int>(std::floor(std::log10(hi)));
  for (int k = k0; k <= k1; ++k) {
    const double decade = std::pow(10.0, k);
    for (int d = 2; d <= 9; ++d) {
      const double v = d * decade;
      if (v > lo * (1.0 + kTickSlack) && v < hi * (1.0 - kTickSlack)) values.push_back(v);
    }
  }
  return values;
}

// ----------------------------------------------------------------- axes --

double AxisMap::to_px(double value) const {
  if (!std::isfinite(value)) return kNaN;
  double t = 0.0;
  if (log) {
    if (value <= 0.0) return kNaN;
    t = (std::log10(value) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
  } else {
    t = (value - lo) / (hi - lo);
  }
  return px_lo + t * (px_hi - px_lo);
}

// ----------------------------------------------------------------- style --

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kAxisColor(60, 60, 60);
const cv::Scalar kGridMajor(205, 205, 205);
const cv::Scalar kGridMinor(236, 236, 236);
const cv::Scalar kTextColor(30, 30, 30);
const cv::Scalar kFlagColor(0x28, 0x27, 0xd6);  // tab10 red

cv::Scalar series_color(std::size_t i) {
  // tab10 (matplotlib), BGR, red removed.
  static const cv::Scalar kPalette[] = {
      {0xb4, 0x77, 0x1f}, {0x0e, 0x7f, 0xff}, {0x2c, 0xa0, 0x2c},
      {0xbd, 0x67, 0x94}, {0x4b, 0x56, 0x8c}, {0xc2, 0x77, 0xe3},
      {0x7f, 0x7f, 0x7f}, {0x22, 0xbd, 0xbc}, {0xcf, 0xbe, 0x17}};
  return kPalette[i % (sizeof(kPalette) / sizeof(kPalette[0]))];
}

TextStyle tick_text() { return {cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, kTextColor}; }
TextStyle label_text() { return {cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, kTextColor}; }
TextStyle panel_title_text() { return {cv::FONT_HERSHEY_DUPLEX, 0.5, 1, kTextColor}; }
TextStyle title_text() { return {cv::FONT_HERSHEY_DUPLEX, 0.7, 1, kTextColor}; }

std::string ascii_text(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      out += (c >= 32 && c < 127) ? static_cast<char>(c) : (c == '\t' ? ' ' : '?');
      ++i;
      continue;
    }
    std::size_t len = (c >= 0xF0) ? 4 : (c >= 0xE0) ? 3 : (c >= 0xC0) ? 2 : 1;
    char32_t cp = (len == 4) ? (c & 0x07) : (len == 3) ? (c & 0x0F) : (c & 0x1F);
    bool valid = len > 1 && i + len <= text.size();
    for (std::size_t k = 1; valid && k < len; ++k) {
      const auto cc = static_cast<unsigned char>(text[i + k]);
      valid = (cc & 0xC0) == 0x80;
      cp = (cp << 6) | (cc & 0x3F);
    }
    if (valid) {
      append_ascii(out, cp);
      i += len;
    } else {
      out += '?';
      ++i;
    }
  }
  return out;
}

cv::Size text_size(const std::string& text, const TextStyle& style) {
  int baseline = 0;
  const cv::Size s =
      cv::getTextSize(ascii_text(text), style.font, style.scale, style.thickness, &baseline);
  return {s.width, s.height + baseline};
}

void put_text(cv::Mat& image, const std::string& text, cv::Point2d anchor,
              const TextStyle& style, HAlign h, VAlign v) {
  const std::string ascii = ascii_text(text);
  int baseline = 0;
  const cv::Size s = cv::getTextSize(ascii, style.font, style.scale, style.thickness, &baseline);
  double x = anchor.x;
  if (h == HAlign::kCenter) x -= s.width / 2.0;
  if (h == HAlign::kRight) x -= s.width;
  double y = anchor.y;  // baseline
  if (v == VAlign::kTop) y += s.height;
  if (v == VAlign::kCenter) y += s.height / 2.0;
  if (v == VAlign::kBottom) y -= baseline;
  cv::putText(image, ascii, cv::Point(static_cast<int>(std::lround(x)), static_cast<int>(std::lround(y))),
              style.font, style.scale, style.color, style.thickness, cv::LINE_AA);
}

void put_text_vertical(cv::Mat& image, const std::string& text, cv::Point2d center,
                       const TextStyle& style) {
  const std::string ascii = ascii_text(text);
  int baseline = 0;
  const cv::Size s = cv::getTextSize(ascii, style.font, style.scale, style.thickness, &baseline);
  constexpr int kPad = 2;
  cv::Mat strip(s.height + baseline + 2 * kPad, s.width + 2 * kPad, image.type(), kWhite);
  cv::putText(strip, ascii, cv::Point(kPad, kPad + s.height), style.font, style.scale,
              style.color, style.thickness, cv::LINE_AA);
  cv::Mat rotated;
  cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const cv::Rect target(static_cast<int>(std::lround(center.x - rotated.cols / 2.0)),
                        static_cast<int>(std::lround(center.y - rotated.rows / 2.0)),
                        rotated.cols, rotated.rows);
  const cv::Rect inside = target & cv::Rect(0, 0, image.cols, image.rows);
  if (inside.empty()) return;
  cv::Mat dst = image(inside);
  const cv::Mat src = rotated(cv::Rect(inside.x - target.x, inside.y - target.y, inside.width,
                                       inside.height));
  cv::min(dst, src, dst);  // dark text over a light background
}

// ------------------------------------------------------------- drawing --

void draw_polyline(cv::Mat& image, const std::vector<cv::Point2d>& points,
                   const cv::Scalar& color, int thickness, LineStyle style,
                   const cv::Rect& clip) {
  if (style == LineStyle::kNone) return;
  const cv::Rect area = clip & cv::Rect(0, 0, image.cols, image.rows);
  if (area.empty()) return;
  cv::Mat roi = image(area);
  const cv::Point2d offset(area.x, area.y);
  // Clip against a box a little larger than the ROI so that line caps at the
  // border are drawn (and cut) by OpenCV rather than stopping short.
  const double margin = thickness + 2.0;
  const double x0 = -margin, y0 = -margin;
  const double x1 = area.width - 1 + margin, y1 = area.height - 1 + margin;
  double dash_pos = 0.0;  // distance along the current dash period
  for (std::size_t i = 1; i < points.size(); ++i) {
    if (!finite(points[i - 1]) || !finite(points[i])) {
      dash_pos = 0.0;
      continue;
    }
    cv::Point2d a = points[i - 1] - offset, b = points[i] - offset;
    const double full_len = std::hypot(b.x - a.x, b.y - a.y);
    if (style == LineStyle::kSolid) {
      if (clip_segment(a, b, x0, y0, x1, y1)) line_aa(roi, a, b, color, thickness);
      continue;
    }
    // Dashed: walk the segment, drawing the "on" parts of the period.
    if (full_len <= 0.0) continue;
    const cv::Point2d dir = (b - a) * (1.0 / full_len);
    double s = 0.0;
    while (s < full_len) {
      const double period_left = (dash_pos < kDashOn) ? kDashOn - dash_pos
                                                      : kDashOn + kDashOff - dash_pos;
      const double piece = std::min(period_left, full_len - s);
      if (dash_pos < kDashOn) {
        cv::Point2d p = a + dir * s, q = a + dir * (s + piece);
        if (clip_segment(p, q, x0, y0, x1, y1)) line_aa(roi, p, q, color, thickness);
      }
      s += piece;
      dash_pos += piece;
      if (dash_pos >= kDashOn + kDashOff - 1e-9) dash_pos = 0.0;
    }
  }
}

void draw_marker(cv::Mat& image, cv::Point2d p, Marker marker, const cv::Scalar& color,
                 int size, const cv::Rect& clip) {
  if (marker == Marker::kNone || !finite(p)) return;
  if (p.x < clip.x - 0.5 || p.y < clip.y - 0.5 || p.x > clip.x + clip.width - 0.5 ||
      p.y > clip.y + clip.height - 0.5) {
    return;
  }
  const double r = size / 2.0;
  switch (marker) {
    case Marker::kCircle:
      cv::circle(image, to_fixed(p), static_cast<int>(std::lround(r * kShiftScale)), color,
                 cv::FILLED, cv::LINE_AA, kShift);
      break;
    case Marker::kCross:
      line_aa(image, p + cv::Point2d(-r, -r), p + cv::Point2d(r, r), color, 2);
      line_aa(image, p + cv::Point2d(-r, r), p + cv::Point2d(r, -r), color, 2);
      break;
    case Marker::kSquare:
      cv::rectangle(image, to_fixed(p + cv::Point2d(-r, -r)), to_fixed(p + cv::Point2d(r, r)),
                    color, cv::FILLED, cv::LINE_AA, kShift);
      break;
    case Marker::kNone:
      break;
  }
}

void draw_grid_x(cv::Mat& image, const cv::Rect& area, const AxisMap& x,
                 const std::vector<double>& values, const cv::Scalar& color) {
  for (double v : values) {
    const double px = std::round(x.to_px(v));
    if (!std::isfinite(px) || px < area.x || px > area.x + area.width - 1) continue;
    const int ix = static_cast<int>(px);
    cv::line(image, {ix, area.y}, {ix, area.y + area.height - 1}, color, 1, cv::LINE_8);
  }
}

void draw_grid_y(cv::Mat& image, const cv::Rect& area, const AxisMap& y,
                 const std::vector<double>& values, const cv::Scalar& color) {
  for (double v : values) {
    const double py = std::round(y.to_px(v));
    if (!std::isfinite(py) || py < area.y || py > area.y + area.height - 1) continue;
    const int iy = static_cast<int>(py);
    cv::line(image, {area.x, iy}, {area.x + area.width - 1, iy}, color, 1, cv::LINE_8);
  }
}

void draw_frame(cv::Mat& image, const cv::Rect& area) {
  cv::rectangle(image, area, kAxisColor, 1, cv::LINE_8);
}

namespace {

// The smallest stride k such that labelling every k-th tick leaves `gap`
// pixels between neighbouring labels along the axis.
std::size_t label_stride(const std::vector<double>& px, const std::vector<int>& extent, int gap) {
  for (std::size_t stride = 1; stride < px.size(); ++stride) {
    bool ok = true;
    for (std::size_t i = stride; ok && i < px.size(); i += stride) {
      const double need = (extent[i - stride] + extent[i]) / 2.0 + gap;
      ok = std::abs(px[i] - px[i - stride]) >= need;
    }
    if (ok) return stride;
  }
  return std::max<std::size_t>(px.size(), 1);
}

}  // namespace

void draw_x_tick_labels(cv::Mat& image, const cv::Rect& area, const AxisMap& x,
                        const std::vector<Tick>& ticks) {
  constexpr int kTickLength = 5;
  const TextStyle style = tick_text();
  std::vector<double> px;
  std::vector<int> widths;
  std::vector<const Tick*> shown;
  for (const Tick& t : ticks) {
    const double p = x.to_px(t.value);
    if (!std::isfinite(p) || p < area.x - 0.5 || p > area.x + area.width - 0.5) continue;
    px.push_back(p);
    widths.push_back(text_size(t.label, style).width);
    shown.push_back(&t);
  }
  const std::size_t stride = label_stride(px, widths, 8);
  const int bottom = area.y + area.height - 1;
  for (std::size_t i = 0; i < px.size(); ++i) {
    const int ix = static_cast<int>(std::lround(px[i]));
    cv::line(image, {ix, bottom}, {ix, bottom - kTickLength}, kAxisColor, 1, cv::LINE_8);
    if (i % stride == 0 && !shown[i]->label.empty()) {
      put_text(image, shown[i]->label, {px[i], bottom + 7.0}, style, HAlign::kCenter,
               VAlign::kTop);
    }
  }
}

void draw_y_tick_labels(cv::Mat& image, const cv::Rect& area, const AxisMap& y,
                        const std::vector<Tick>& ticks) {
  constexpr int kTickLength = 5;
  const TextStyle style = tick_text();
  std::vector<double> py;
  std::vector<int> heights;
  std::vector<const Tick*> shown;
  for (const Tick& t : ticks) {
    const double p = y.to_px(t.value);
    if (!std::isfinite(p) || p < area.y - 0.5 || p > area.y + area.height - 0.5) continue;
    py.push_back(p);
    heights.push_back(text_size(t.label, style).height);
    shown.push_back(&t);
  }
  const std::size_t stride = label_stride(py, heights, 4);
  for (std::size_t i = 0; i < py.size(); ++i) {
    const int iy = static_cast<int>(std::lround(py[i]));
    cv::line(image, {area.x, iy}, {area.x + kTickLength, iy}, kAxisColor, 1, cv::LINE_8);
    if (i % stride == 0 && !shown[i]->label.empty()) {
      put_text(image, shown[i]->label, {area.x - 7.0, py[i]}, style, HAlign::kRight,
               VAlign::kCenter);
    }
  }
}

// ---------------------------------------------------------------- legend --

namespace {

constexpr int kLegendPad = 8;
constexpr int kLegendSample = 30;   // length of the line sample
constexpr int kLegendSampleGap = 6; // between sample and text
constexpr int kLegendEntryGap = 22; // between entries on one row
constexpr int kLegendRow = 22;

int entry_width(const LegendEntry& e) {
  return kLegendSample + kLegendSampleGap + text_size(e.label, label_text()).width;
}

// Rows of entry indices, wrapped to max_width_px (inside the padding).
std::vector<std::vector<std::size_t>> legend_rows(const std::vector<LegendEntry>& entries,
                                                  int max_width_px) {
  std::vector<std::vector<std::size_t>> rows;
  int used = 0;
  const int inner = std::max(1, max_width_px - 2 * kLegendPad);
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const int w = entry_width(entries[i]);
    if (rows.empty() || used + kLegendEntryGap + w > inner) {
      rows.push_back({i});
      used = w;
    } else {
      rows.back().push_back(i);
      used += kLegendEntryGap + w;
    }
  }
  return rows;
}

int row_width(const std::vector<LegendEntry>& entries, const std::vector<std::size_t>& row) {
  int w = 0;
  for (std::size_t k = 0; k < row.size(); ++k) {
    w += entry_width(entries[row[k]]) + (k > 0 ? kLegendEntryGap : 0);
  }
  return w;
}

}  // namespace

cv::Size legend_size(const std::vector<LegendEntry>& entries, int max_width_px) {
  if (entries.empty()) return {0, 0};
  const auto rows = legend_rows(entries, max_width_px);
  int width = 0;
  for (const auto& row : rows) width = std::max(width, row_width(entries, row));
  return {width + 2 * kLegendPad, static_cast<int>(rows.size()) * kLegendRow + 2 * kLegendPad - 4};
}

void draw_legend(cv::Mat& image, const std::vector<LegendEntry>& entries, cv::Point top_left,
                 int max_width_px) {
  if (entries.empty()) return;
  const cv::Size size = legend_size(entries, max_width_px);
  const cv::Rect box(top_left, size);
  cv::rectangle(image, box, kWhite, cv::FILLED);
  cv::rectangle(image, box, cv::Scalar(170, 170, 170), 1, cv::LINE_8);
  const auto rows = legend_rows(entries, max_width_px);
  const cv::Rect everywhere(0, 0, image.cols, image.rows);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const double cy = top_left.y + kLegendPad + r * kLegendRow + (kLegendRow - 4) / 2.0;
    double x = top_left.x + kLegendPad;
    for (std::size_t i : rows[r]) {
      const LegendEntry& e = entries[i];
      const std::vector<cv::Point2d> sample = {{x + 1, cy}, {x + kLegendSample - 1, cy}};
      draw_polyline(image, sample, e.color, 2, e.line, everywhere);
      draw_marker(image, {x + kLegendSample / 2.0, cy}, e.marker, e.color,
                  e.marker == Marker::kCross ? 9 : 7, everywhere);
      put_text(image, e.label, {x + kLegendSample + kLegendSampleGap, cy}, label_text(),
               HAlign::kLeft, VAlign::kCenter);
      x += entry_width(e) + kLegendEntryGap;
    }
  }
}

// ------------------------------------------------------------------ png --

// PNG encoding with libpng rather than OpenCV's imgcodecs: imgcodecs pulls in
// ~140 shared libraries (GDAL, GDCM, ...) whose relocation costs 0.18 s at the
// start of every lpvid run, measured.  libpng's defaults (adaptive filters, zlib
// level 6) took 0.15 s for a 1514 x 1492 Bode figure; plots are mostly flat
// white, so the UP filter with zlib level 3 is used: `lpvid bode` of a 3 x 3 model
// went from 0.36 s to 0.14 s and its PNG from 221 KB to 251 KB (measured).
namespace {

constexpr int kPngZlibLevel = 3;

void append_png_bytes(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + length);
}

void flush_png_bytes(png_structp) {}

// libpng reports errors by longjmp to the setjmp in write_png; that frame holds
// no C++ objects, so nothing is skipped (the canonical libpng pattern).
struct PngError {
  char message[256] = {0};
};

void png_failure(png_structp png, png_const_charp message) {
  auto* error = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(error->message, sizeof error->message, "%s", message);
  png_longjmp(png, 1);
}

void png_warning_ignored(png_structp, png_const_charp) {}

// Returns false (with error->message) when libpng fails.
bool write_png(const cv::Mat& rgb, std::vector<unsigned char>* bytes, PngError* error) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, error, png_failure, png_warning_ignored);
  if (!png) return false;
  png_infop info = png_create_info_struct(png);
  if (!info || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, bytes, append_png_bytes, flush_png_bytes);
  png_set_IHDR(png, info, static_cast<png_uint_32>(rgb.cols), static_cast<png_uint_32>(rgb.rows), 8,
               rgb.channels() == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
  png_set_compression_level(png, kPngZlibLevel);
  png_write_info(png, info);
  for (int r = 0; r < rgb.rows; ++r) png_write_row(png, const_cast<png_bytep>(rgb.ptr<png_byte>(r)));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

std::vector<unsigned char> encode_png(const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1))
    throw std::runtime_error("plot: encode_png needs an 8-bit BGR or grey image");
  cv::Mat rgb;
  if (image.channels() == 3) {
    cv::cvtColor(image, rgb, cv::COLOR_BGR2RGB);
  } else {
    rgb = image;
  }
  std::vector<unsigned char> bytes;
  bytes.reserve(static_cast<std::size_t>(rgb.total()) / 8);
  PngError error;
  if (!write_png(rgb, &bytes, &error))
    throw std::runtime_error(std::string("plot: libpng could not encode the figure: ") + error.message);
  return bytes;
}


std::string fit_text(const std::string& text, const TextStyle& style, int max_width) {
  if (text_size(text, style).width <= max_width) return text;
  std::string t = ascii_text(text);
  while (!t.empty() && text_size(t + "...", style).width > max_width) t.pop_back();
  return t + "...";
}

void put_title(cv::Mat& image, const std::string& title, int margin, double y) {
  TextStyle ts = title_text();
  const int room = image.cols - 2 * margin;
  const int wide = text_size(title, ts).width;
  if (wide > room) ts.scale = std::max(label_text().scale, ts.scale * room / wide);
  put_text(image, fit_text(title, ts, room), {image.cols / 2.0, y}, ts, HAlign::kCenter, VAlign::kCenter);
}

}  // namespace lpvid::plot
