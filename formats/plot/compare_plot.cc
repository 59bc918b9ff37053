#include "formats/plot/compare_plot.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

using plot::AxisMap;
using plot::HAlign;
using plot::Tick;
using plot::VAlign;

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Layout, in pixels (as bode_plot.cc).
constexpr int kMargin = 14;
constexpr int kYLabelWidth = 24;
constexpr int kYTickWidth = 50;
constexpr int kColumnGap = 22;
constexpr int kTitleHeight = 40;
constexpr int kPanelTitleHeight = 24;
constexpr int kAxesGap = 14;
constexpr int kRowGap = 12;
constexpr int kXTickHeight = 24;
constexpr int kXLabelHeight = 26;
constexpr int kMinAxesPx = 60;
// Magnitude: at least 20 dB shown, at most 5 intervals.
constexpr double kMinMagnitudeSpanDb = 20.0;
constexpr int kMaxMagnitudeIntervals = 5;
// Error axis: whole decades of percent within 0.01 % .. 10^4 %; at least two decades.
constexpr double kModelReachDb = 40.0;
constexpr double kErrorFloorPercent = 1e-2, kErrorCeilPercent = 1e4;

const cv::Scalar kNoiseFill(225, 225, 225);   // light grey
const cv::Scalar kFailFill(200, 200, 255);    // light red (BGR)
const cv::Scalar kFailEdge(60, 60, 220);
constexpr double kFailAlpha = 0.55;           // opacity of the red over grid and grey

double db(const Complex& z) { return 20.0 * std::log10(std::abs(z)); }

std::string label_or(const std::vector<std::string>& given, Index count, Index k, const char* prefix) {
  if (static_cast<Index>(given.size()) == count && !given[static_cast<std::size_t>(k)].empty())
    return given[static_cast<std::size_t>(k)];
  return fmt::format("{}{}", prefix, k + 1);
}

void validate(const std::vector<CompareSeries>& series, const ComparePlotOptions& o) {
  if (series.empty()) throw InputError("compare plot: no measurement to draw");
  const auto& first = series.front();
  if (first.data.empty()) throw InputError("compare plot: the first measurement has no frequencies");
  const Index p = first.data.front().rows(), m = first.data.front().cols();
  for (std::size_t s = 0; s < series.size(); ++s) {
    const auto& c = series[s];
    const std::size_t F = static_cast<std::size_t>(c.omega_rad_s.size());
    if (F == 0 || c.data.size() != F || c.model.size() != F || c.radius.size() != F || c.scale.size() != F ||
        (!c.skipped.empty() && c.skipped.size() != F))
      throw InputError(fmt::format("compare plot: series '{}' has {} frequencies but {} data, {} model, {} band and "
                                   "{} scale entries; they must match",
                                   c.label, F, c.data.size(), c.model.size(), c.radius.size(), c.scale.size()));
    for (std::size_t f = 0; f < F; ++f) {
      if (!std::isfinite(c.omega_rad_s(f)) || c.omega_rad_s(f) <= 0)
        throw InputError(fmt::format("compare plot: series '{}' has frequency {}; the axis is logarithmic, so > 0",
                                     c.label, c.omega_rad_s(f)));
      if (c.data[f].rows() != p || c.data[f].cols() != m || c.model[f].rows() != p || c.model[f].cols() != m ||
          c.radius[f].rows() != p || c.radius[f].cols() != m || c.scale[f].rows() != p || c.scale[f].cols() != m)
        throw InputError(fmt::format("compare plot: series '{}' is not {}x{} at every frequency", c.label, p, m));
      if (!c.scale[f].allFinite() || (c.scale[f].array() < 0).any())
        throw InputError(fmt::format("compare plot: series '{}' has a scale that is negative or not finite at "
                                     "{:g} rad/s; the error figure's scale s_ij is >= 0",
                                     c.label, c.omega_rad_s(f)));
    }
  }
  if ((!o.input_labels.empty() && static_cast<Index>(o.input_labels.size()) != m) ||
      (!o.output_labels.empty() && static_cast<Index>(o.output_labels.size()) != p))
    throw InputError(fmt::format("compare plot: {} input and {} output labels for a {}x{} response",
                                 o.input_labels.size(), o.output_labels.size(), p, m));
  if (o.panel_width_px < kMinAxesPx || o.magnitude_height_px < kMinAxesPx || o.error_height_px < kMinAxesPx)
    throw InputError(fmt::format("compare plot: panel sizes must be >= {} px", kMinAxesPx));
}

std::vector<double> values(const std::vector<Tick>& ticks) {
  std::vector<double> v;
  for (const Tick& t : ticks) v.push_back(t.value);
  return v;
}

std::vector<Tick> frequency_ticks(const AxisMap& x) {
  std::vector<Tick> ticks = plot::decade_ticks(x.lo, x.hi, plot::DecadeLabels::kPlain);
  if (ticks.size() < 2) {
    for (double v : plot::minor_log_ticks(x.lo, x.hi)) ticks.push_back({v, fmt::format("{:g}", v)});
    std::sort(ticks.begin(), ticks.end(), [](const Tick& a, const Tick& b) { return a.value < b.value; });
  }
  return ticks;
}

// Percent labels on the error axis: "0.1 %" reads better than "1e-1".
std::vector<Tick> percent_ticks(const AxisMap& y) {
  std::vector<Tick> ticks = plot::decade_ticks(y.lo, y.hi, plot::DecadeLabels::kPlain);
  for (Tick& t : ticks) t.label += "%";
  return ticks;
}

bool shown(const CompareSeries& s, std::size_t f) { return s.skipped.empty() || !s.skipped[f]; }

// 100 x / s_ij: a size on the error axis (NaN where the scale is 0: not drawn).
double percent_of_scale(const CompareSeries& s, std::size_t f, Index i, Index j, double x) {
  const double a = s.scale[f](i, j);
  return a > 0 ? 100.0 * x / a : kNaN;
}

CompareErrorAxis error_axis(const std::vector<CompareSeries>& series, Index i, Index j) {
  double elo = kInf, ehi = 0;
  for (const auto& s : series)
    for (std::size_t f = 0; f < s.data.size(); ++f) {
      if (!shown(s, f)) continue;
      const double e = percent_of_scale(s, f, i, j, std::abs(s.data[f](i, j) - s.model[f](i, j)));
      const double r = percent_of_scale(s, f, i, j, s.radius[f](i, j));
      for (double v : {e, r})
        if (std::isfinite(v) && v > 0) elo = std::min(elo, v), ehi = std::max(ehi, v);
    }
  if (!std::isfinite(elo)) elo = 1, ehi = 100;
  elo = std::clamp(std::pow(10.0, std::floor(std::log10(elo))), kErrorFloorPercent, kErrorCeilPercent / 100);
  ehi = std::clamp(std::pow(10.0, std::ceil(std::log10(ehi))), elo * 100, kErrorCeilPercent);
  return {elo, ehi};
}

// The shared frequency axis: whole decades around every series.
std::pair<double, double> compare_frequency_decades(const std::vector<CompareSeries>& series) {
  double wlo = kInf, whi = 0;
  for (const auto& s : series) {
    wlo = std::min(wlo, s.omega_rad_s.minCoeff());
    whi = std::max(whi, s.omega_rad_s.maxCoeff());
  }
  wlo = std::pow(10.0, std::floor(std::log10(wlo) + 1e-9));
  whi = std::pow(10.0, std::ceil(std::log10(whi) - 1e-9));
  if (whi <= wlo) whi = wlo * 10;
  return {wlo, whi};
}

std::vector<plot::LegendEntry> compare_legend(const std::vector<CompareSeries>& series,
                                              const std::vector<CompareBandMark>& bands, const ComparePlotOptions& o) {
  std::vector<plot::LegendEntry> legend;
  for (std::size_t s = 0; s < series.size(); ++s)
    legend.push_back({fmt::format("measured{}", series[s].label.empty() ? "" : " " + series[s].label),
                      plot::series_color(s), plot::LineStyle::kSolid, plot::Marker::kNone});
  if (o.same_model)
    legend.push_back({"model", plot::kBlack, plot::LineStyle::kSolid, plot::Marker::kNone});
  else
    legend.push_back({"model (dashed, colour of its measurement)", plot::kAxisColor, plot::LineStyle::kDashed,
                      plot::Marker::kNone});
  legend.push_back({"error |E| / s (lower axes)", plot::kAxisColor, plot::LineStyle::kSolid, plot::Marker::kNone});
  legend.push_back({o.band_label + " (grey)", kNoiseFill, plot::LineStyle::kSolid, plot::Marker::kSquare});
  if (!bands.empty())
    legend.push_back({"failing band (red)", cv::Scalar(150, 150, 250), plot::LineStyle::kSolid, plot::Marker::kSquare});
  return legend;
}

// One channel's magnitude axis in dB, snapped to its step; `none` when neither data
// nor model has a finite magnitude there.
struct CompareMagnitudeRange {
  plot::Range range;
  double step = 0;
  bool none = false;
};

// Magnitude: the data's range, widened by the model's by at most kModelReachDb
// (a model that is numerically zero on a channel must not squash the data).
CompareMagnitudeRange compare_magnitude_range(const std::vector<CompareSeries>& series, Index i, Index j) {
  double dlo = kInf, dhi = -kInf, mlo = kInf, mhi = -kInf;
  for (const auto& s : series)
    for (std::size_t f = 0; f < s.data.size(); ++f) {
      if (!shown(s, f)) continue;
      const double vd = db(s.data[f](i, j)), vm = db(s.model[f](i, j));
      if (std::isfinite(vd)) dlo = std::min(dlo, vd), dhi = std::max(dhi, vd);
      if (std::isfinite(vm)) mlo = std::min(mlo, vm), mhi = std::max(mhi, vm);
    }
  if (std::isfinite(mlo)) {
    if (!std::isfinite(dlo)) dlo = mlo, dhi = mhi;
    dlo = std::min(dlo, std::max(mlo, dlo - kModelReachDb));
    dhi = std::max(dhi, std::min(mhi, dhi + kModelReachDb));
  }
  CompareMagnitudeRange out;
  out.none = !std::isfinite(dlo);
  if (out.none) dlo = -10, dhi = 10;
  const double mid = 0.5 * (dlo + dhi);
  const double span = std::max(dhi - dlo, kMinMagnitudeSpanDb);
  out.step = plot::nice_step(span * 1.06, kMaxMagnitudeIntervals);
  out.range = plot::snap_outward(mid - 0.53 * span, mid + 0.53 * span, out.step);
  return out;
}

// One channel's panel: the magnitude axes above the error axes, and their maps.
struct ComparePanel {
  Index i = 0, j = 0;  // output, input
  cv::Rect mag, err;
  AxisMap x, ym, ye;
};

// Noise region of each series (grey).
void draw_compare_noise_regions(cv::Mat& image, const std::vector<CompareSeries>& series, const ComparePanel& pn) {
  const Index i = pn.i, j = pn.j;
  const cv::Rect& err = pn.err;
  for (const auto& s : series) {
    std::vector<cv::Point> poly;
    const double base = err.br().y - 1;
    for (std::size_t f = 0; f < s.data.size(); ++f) {
      if (!shown(s, f)) continue;
      const double r = s.scale[f](i, j) > 0 ? percent_of_scale(s, f, i, j, s.radius[f](i, j)) : kInf;
      const double py = std::isfinite(r) ? std::clamp(pn.ye.to_px(std::max(r, pn.ye.lo)), double(err.y), base) : err.y;
      const double px = pn.x.to_px(s.omega_rad_s(f));
      if (poly.empty()) poly.emplace_back(cvRound(px), cvRound(base));
      poly.emplace_back(cvRound(px), cvRound(py));
    }
    if (!poly.empty()) {
      poly.emplace_back(poly.back().x, cvRound(base));
      cv::Mat roi = image(err);
      std::vector<cv::Point> shifted;
      for (const auto& q : poly) shifted.emplace_back(std::clamp(q.x - err.x, 0, err.width - 1), q.y - err.y);
      cv::fillPoly(roi, std::vector<std::vector<cv::Point>>{shifted}, kNoiseFill, cv::LINE_AA);
    }
  }
}

void draw_compare_failing_bands(cv::Mat& image, const std::vector<CompareBandMark>& bands, const ComparePanel& pn) {
  const AxisMap& x = pn.x;
  // Failing bands: a translucent red over the grids and the noise band.
  for (const auto& b : bands) {
    if (b.output != pn.i || b.input != pn.j) continue;
    for (const cv::Rect& r : {pn.mag, pn.err}) {
      double xa = std::max(x.to_px(b.lo_rad_s), static_cast<double>(r.x));
      double xb = std::min(x.to_px(b.hi_rad_s), static_cast<double>(r.br().x - 1));
      if (xb - xa < 3) xa -= 1.5, xb += 1.5;  // a band of one pixel stays visible
      const cv::Rect sr = cv::Rect(cv::Point(cvRound(xa), r.y), cv::Point(cvRound(xb) + 1, r.br().y)) & r;
      if (sr.area() == 0) continue;
      cv::Mat roi = image(sr);
      cv::Mat fill(roi.size(), roi.type(), kFailFill);
      cv::addWeighted(roi, 1.0 - kFailAlpha, fill, kFailAlpha, 0.0, roi);
    }
  }
  // The failing bands' edges.
  for (const auto& b : bands) {
    if (b.output != pn.i || b.input != pn.j) continue;
    for (double w : {b.lo_rad_s, b.hi_rad_s}) {
      const double px = x.to_px(w);
      for (const cv::Rect& r : {pn.mag, pn.err})
        plot::draw_polyline(image, {{px, double(r.y)}, {px, double(r.br().y - 1)}}, kFailEdge, 1,
                            plot::LineStyle::kDashed, r);
    }
  }
}

// Each series' measured magnitude and error, and the model's magnitude.
void draw_compare_curves(cv::Mat& image, const std::vector<CompareSeries>& series, const ComparePlotOptions& o,
                         const ComparePanel& pn) {
  const Index i = pn.i, j = pn.j;
  for (std::size_t si = 0; si < series.size(); ++si) {
    const auto& s = series[si];
    std::vector<cv::Point2d> pd, pm, pe;
    for (std::size_t f = 0; f < s.data.size(); ++f) {
      const double px = pn.x.to_px(s.omega_rad_s(f));
      if (!shown(s, f)) {
        pd.emplace_back(kNaN, kNaN);
        pe.emplace_back(kNaN, kNaN);
      } else {
        pd.emplace_back(px, pn.ym.to_px(db(s.data[f](i, j))));
        const double e = percent_of_scale(s, f, i, j, std::abs(s.data[f](i, j) - s.model[f](i, j)));
        pe.emplace_back(px, e > 0 ? pn.ye.to_px(std::max(e, pn.ye.lo)) : kNaN);
      }
      pm.emplace_back(px, pn.ym.to_px(db(s.model[f](i, j))));
    }
    const cv::Scalar c = plot::series_color(si);
    plot::draw_polyline(image, pd, c, 1, plot::LineStyle::kSolid, pn.mag);
    plot::draw_polyline(image, pe, c, 1, plot::LineStyle::kSolid, pn.err);
    if (!o.same_model)
      plot::draw_polyline(image, pm, c, 2, plot::LineStyle::kDashed, pn.mag);
    else if (si == 0)
      plot::draw_polyline(image, pm, plot::kBlack, 2, plot::LineStyle::kSolid, pn.mag);
  }
}

// The panel of output i and input j, its top-left corner at (x0, y0) (x0: the axes' left
// edge); the frequency tick labels only under the last row.
void draw_compare_panel(cv::Mat& image, const std::vector<CompareSeries>& series,
                        const std::vector<CompareBandMark>& bands, const ComparePlotOptions& o, Index i, Index j,
                        Index p, Index m, int x0, int y0, double wlo, double whi) {
  ComparePanel pn;
  pn.i = i;
  pn.j = j;
  pn.mag = cv::Rect(x0, y0 + kPanelTitleHeight, o.panel_width_px, o.magnitude_height_px);
  pn.err = cv::Rect(x0, pn.mag.br().y + kAxesGap, o.panel_width_px, o.error_height_px);
  const cv::Rect& mag = pn.mag;
  const cv::Rect& err = pn.err;
  pn.x = AxisMap{wlo, whi, static_cast<double>(mag.x), static_cast<double>(mag.br().x - 1), true};
  const AxisMap& x = pn.x;

  // Ranges.
  const CompareMagnitudeRange magnitude = compare_magnitude_range(series, i, j);
  const plot::Range& mr = magnitude.range;
  pn.ym = AxisMap{mr.lo, mr.hi, static_cast<double>(mag.br().y - 1), static_cast<double>(mag.y), false};
  const CompareErrorAxis ea = error_axis(series, i, j);
  pn.ye = AxisMap{ea.lo_percent, ea.hi_percent, static_cast<double>(err.br().y - 1), static_cast<double>(err.y), true};
  const AxisMap& ym = pn.ym;
  const AxisMap& ye = pn.ye;

  // Grids.
  const std::vector<Tick> xt = frequency_ticks(x);
  const std::vector<Tick> mt = plot::linear_ticks(mr.lo, mr.hi, magnitude.step);
  const std::vector<Tick> et = percent_ticks(ye);
  for (const auto& [area, yy, ticks] :
       {std::tuple{mag, ym, mt}, std::tuple{err, ye, et}}) {
    plot::draw_grid_x(image, area, x, plot::minor_log_ticks(x.lo, x.hi), plot::kGridMinor);
    plot::draw_grid_x(image, area, x, values(plot::decade_ticks(x.lo, x.hi, plot::DecadeLabels::kPlain)),
                      plot::kGridMajor);
    plot::draw_grid_y(image, area, yy, values(ticks), plot::kGridMajor);
  }
  // Noise region of each series (grey), then the curves.
  draw_compare_noise_regions(image, series, pn);
  draw_compare_failing_bands(image, bands, pn);
  draw_compare_curves(image, series, o, pn);
  for (const auto& [area, yy, ticks] : {std::tuple{mag, ym, mt}, std::tuple{err, ye, et}}) {
    plot::draw_frame(image, area);
    plot::draw_y_tick_labels(image, area, yy, ticks);
  }
  if (i == p - 1) plot::draw_x_tick_labels(image, err, x, xt);
  int failing = 0;
  for (const auto& b : bands) failing += (b.output == i && b.input == j) ? 1 : 0;
  const std::string title =
      fmt::format("from {} to {}{}{}", label_or(o.input_labels, m, j, "u"), label_or(o.output_labels, p, i, "y"),
                  failing ? fmt::format("  -  {} failing band{}", failing, failing > 1 ? "s" : "") : "",
                  magnitude.none ? "  (zero)" : "");
  plot::TextStyle ts = plot::panel_title_text();
  if (failing) ts.color = kFailEdge;
  plot::put_text(image, title, {mag.x + mag.width / 2.0, y0 + kPanelTitleHeight / 2.0}, ts, HAlign::kCenter,
                 VAlign::kCenter);
}

}  // namespace

CompareErrorAxis compare_error_axis(const std::vector<CompareSeries>& series, Index i, Index j) {
  ComparePlotOptions o;
  validate(series, o);
  const Index p = series.front().data.front().rows(), m = series.front().data.front().cols();
  if (i < 0 || i >= p || j < 0 || j >= m)
    throw InputError(fmt::format("compare plot: channel ({}, {}) outside the {}x{} response", i, j, p, m));
  return error_axis(series, i, j);
}

cv::Mat render_compare(const std::vector<CompareSeries>& series, const std::vector<CompareBandMark>& bands,
                       const ComparePlotOptions& o) {
  validate(series, o);
  const Index p = series.front().data.front().rows(), m = series.front().data.front().cols();
  const auto [wlo, whi] = compare_frequency_decades(series);

  const int panel_h = kPanelTitleHeight + o.magnitude_height_px + kAxesGap + o.error_height_px;
  const int col_w = kYTickWidth + o.panel_width_px + kColumnGap;
  const int top = kMargin + (o.title.empty() ? 0 : kTitleHeight);
  const int grid_left = kMargin + kYLabelWidth;
  const int grid_bottom = top + static_cast<int>(p) * (panel_h + kRowGap) - kRowGap;

  // Legend entries.
  const std::vector<plot::LegendEntry> legend = compare_legend(series, bands, o);
  const int width = grid_left + static_cast<int>(m) * col_w + kMargin;
  const cv::Size leg = plot::legend_size(legend, width - 2 * kMargin);
  const int height = grid_bottom + kXTickHeight + kXLabelHeight + leg.height + 2 * kMargin;

  cv::Mat image(height, width, CV_8UC3, plot::kWhite);
  if (!o.title.empty()) plot::put_title(image, o.title, kMargin, kMargin + kTitleHeight / 2.0 - 4);

  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      const int x0 = grid_left + static_cast<int>(j) * col_w + kYTickWidth;
      const int y0 = top + static_cast<int>(i) * (panel_h + kRowGap);
      draw_compare_panel(image, series, bands, o, i, j, p, m, x0, y0, wlo, whi);
    }
  const double cy = top + (grid_bottom - top) / 2.0;
  plot::put_text_vertical(image, "magnitude [dB]  /  error [% of the channel scale s]", {kMargin + kYLabelWidth / 2.0, cy},
                          plot::label_text());
  plot::put_text(image, "Frequency [rad/s]", {width / 2.0, grid_bottom + kXTickHeight + 4.0}, plot::label_text(),
                 HAlign::kCenter, VAlign::kTop);
  plot::draw_legend(image, legend, {(width - leg.width) / 2, grid_bottom + kXTickHeight + kXLabelHeight + kMargin / 2},
                    width - 2 * kMargin);
  return image;
}

std::vector<unsigned char> compare_png(const std::vector<CompareSeries>& series,
                                       const std::vector<CompareBandMark>& bands, const ComparePlotOptions& options) {
  return plot::encode_png(render_compare(series, bands, options));
}

}  // namespace lpvid
