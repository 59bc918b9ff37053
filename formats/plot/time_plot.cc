#include "formats/plot/time_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

using plot::HAlign;
using plot::Tick;
using plot::VAlign;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Layout, in pixels.
constexpr int kMargin = 14;
constexpr int kYLabelWidth = 24;
constexpr int kYTickWidth = 64;     // room for "-1.5e-4"
constexpr int kRightMargin = 26;
constexpr int kTitleHeight = 40;
constexpr int kPanelGap = 16;
constexpr int kXTickHeight = 24;
constexpr int kXLabelHeight = 26;
constexpr int kMinWidth = 300;
constexpr int kMinPanelHeight = 60;
constexpr int kMaxTimeIntervals = 10;
constexpr int kMaxValueIntervals = 6;
// Fraction of a channel's span added above and below.
constexpr double kPadFraction = 0.05;
constexpr int kLineWidth = 2;

std::string series_name(const TimeSeries& s, std::size_t index) {
  return s.label.empty() ? fmt::format("#{}", index + 1) : "'" + s.label + "'";
}

void validate(const std::vector<TimeSeries>& series, const TimePlotOptions& options) {
  if (series.empty()) throw InputError("time plot: no series to draw; pass at least one signal");
  const Index channels = series.front().values.cols();
  for (std::size_t s = 0; s < series.size(); ++s) {
    const TimeSeries& ts = series[s];
    const std::string name = series_name(ts, s);
    if (ts.t_s.size() == 0) throw InputError(fmt::format("time plot: series {} has no samples", name));
    if (ts.t_s.size() != ts.values.rows()) {
      throw InputError(fmt::format(
          "time plot: series {} has {} time stamps for {} sample rows; they must match", name,
          ts.t_s.size(), ts.values.rows()));
    }
    if (ts.values.cols() == 0) {
      throw InputError(fmt::format("time plot: series {} has no channels", name));
    }
    if (ts.values.cols() != channels) {
      throw InputError(fmt::format(
          "time plot: series {} has {} channels but series {} has {}; all series must share "
          "the channels",
          name, ts.values.cols(), series_name(series.front(), 0), channels));
    }
    for (Index k = 0; k < ts.t_s.size(); ++k) {
      if (!std::isfinite(ts.t_s[k]) || (k > 0 && ts.t_s[k] < ts.t_s[k - 1])) {
        throw InputError(fmt::format(
            "time plot: series {} time stamp {} is {} s; time stamps must be finite and "
            "non-decreasing",
            name, k, ts.t_s[k]));
      }
    }
  }
  if (!options.channel_labels.empty() &&
      static_cast<Index>(options.channel_labels.size()) != channels) {
    throw InputError(fmt::format("time plot: {} channel labels given for {} channels",
                                 options.channel_labels.size(), channels));
  }
  if (options.width_px < kMinWidth || options.panel_height_px < kMinPanelHeight) {
    throw InputError(fmt::format(
        "time plot: size {} x {} px is too small; width_px must be >= {} and panel_height_px "
        ">= {}",
        options.width_px, options.panel_height_px, kMinWidth, kMinPanelHeight));
  }
}

std::vector<plot::LegendEntry> legend_entries(const std::vector<TimeSeries>& series) {
  std::vector<plot::LegendEntry> entries;
  for (std::size_t s = 0; s < series.size(); ++s) {
    entries.push_back({series[s].label.empty() ? fmt::format("series {}", s + 1) : series[s].label,
                       plot::series_color(s), plot::LineStyle::kSolid, plot::Marker::kNone});
  }
  return entries;
}

}  // namespace

TimePlotLayout layout_time_plot(const std::vector<TimeSeries>& series,
                                const TimePlotOptions& options) {
  validate(series, options);
  TimePlotLayout layout;
  const Index channels = series.front().values.cols();
  const int left = kMargin + kYLabelWidth + kYTickWidth;
  const int axes_width = options.width_px - left - kRightMargin;
  const int top = options.title.empty() ? kMargin + 4 : kMargin + kTitleHeight;

  double t0 = std::numeric_limits<double>::infinity(), t1 = -t0;
  for (const TimeSeries& s : series) {
    t0 = std::min(t0, s.t_s[0]);
    t1 = std::max(t1, s.t_s[s.t_s.size() - 1]);
  }
  if (t1 <= t0) {  // a single instant: centre it
    const double half = t0 != 0.0 ? std::abs(t0) * 0.1 : 0.5;
    t0 -= half;
    t1 += half;
  }
  layout.time = {t0, t1, static_cast<double>(left), static_cast<double>(left + axes_width - 1),
                 false};
  layout.time_step = plot::nice_step(t1 - t0, kMaxTimeIntervals);

  for (Index c = 0; c < channels; ++c) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const TimeSeries& s : series) {
      for (Index k = 0; k < s.values.rows(); ++k) {
        const double v = s.values(k, c);
        if (std::isfinite(v)) {
          lo = std::min(lo, v);
          hi = std::max(hi, v);
        }
      }
    }
    if (!(lo <= hi)) {  // no finite sample
      lo = -1.0;
      hi = 1.0;
    } else if (hi == lo) {
      const double half = lo != 0.0 ? std::abs(lo) * 0.1 : 1.0;
      lo -= half;
      hi += half;
    } else {
      const double pad = (hi - lo) * kPadFraction;
      lo -= pad;
      hi += pad;
    }
    double step = plot::nice_step(hi - lo, kMaxValueIntervals);
    plot::Range r = plot::snap_outward(lo, hi, step);
    if ((r.hi - r.lo) / step > kMaxValueIntervals + 1e-9) {  // snapping added an interval
      step = plot::nice_step(r.hi - r.lo, kMaxValueIntervals);
      r = plot::snap_outward(lo, hi, step);
    }
    const int y = top + static_cast<int>(c) * (options.panel_height_px + kPanelGap);
    layout.panels_px.emplace_back(left, y, axes_width, options.panel_height_px);
    layout.values.push_back({r.lo, r.hi, static_cast<double>(y + options.panel_height_px - 1),
                             static_cast<double>(y), false});
    layout.value_steps.push_back(step);
  }
  const int grid_bottom = layout.panels_px.back().br().y;
  const auto entries = legend_entries(series);
  const cv::Size legend = plot::legend_size(entries, options.width_px - 2 * kMargin);
  const int legend_top = grid_bottom + kXTickHeight + kXLabelHeight + 4;
  layout.legend_px =
      cv::Rect((options.width_px - legend.width) / 2, legend_top, legend.width, legend.height);
  layout.figure = cv::Size(options.width_px, legend_top + legend.height + kMargin);
  return layout;
}

std::vector<cv::Point2d> decimated_polyline(const Eigen::VectorXd& t_s,
                                            const Eigen::Ref<const Eigen::VectorXd>& v,
                                            const plot::AxisMap& time,
                                            const plot::AxisMap& value) {
  std::vector<cv::Point2d> out;
  const Index n = t_s.size();
  const double columns = std::abs(time.px_hi - time.px_lo) + 1.0;
  if (n <= 2 * static_cast<Index>(columns)) {
    out.reserve(static_cast<std::size_t>(n));
    for (Index k = 0; k < n; ++k) {
      if (!std::isfinite(v[k])) {
        out.emplace_back(kNaN, kNaN);
      } else {
        out.emplace_back(time.to_px(t_s[k]), value.to_px(v[k]));
      }
    }
    return out;
  }
  out.reserve(static_cast<std::size_t>(4 * columns));
  // The bucket of the current pixel column.
  bool open = false;
  double column = 0.0, vmin = 0.0, vmax = 0.0;
  Index kmin = 0, kmax = 0;
  auto flush = [&] {
    if (!open) return;
    const double x = column;
    if (vmin == vmax) {
      out.emplace_back(x, value.to_px(vmin));
    } else if (kmin < kmax) {
      out.emplace_back(x, value.to_px(vmin));
      out.emplace_back(x, value.to_px(vmax));
    } else {
      out.emplace_back(x, value.to_px(vmax));
      out.emplace_back(x, value.to_px(vmin));
    }
    open = false;
  };
  for (Index k = 0; k < n; ++k) {
    if (!std::isfinite(v[k])) {
      flush();
      if (out.empty() || std::isfinite(out.back().x)) out.emplace_back(kNaN, kNaN);
      continue;
    }
    const double c = std::round(time.to_px(t_s[k]));
    if (open && c == column) {
      if (v[k] < vmin) {
        vmin = v[k];
        kmin = k;
      }
      if (v[k] > vmax) {
        vmax = v[k];
        kmax = k;
      }
      continue;
    }
    flush();
    open = true;
    column = c;
    vmin = vmax = v[k];
    kmin = kmax = k;
  }
  flush();
  return out;
}

cv::Mat render_time_plot(const std::vector<TimeSeries>& series, const TimePlotOptions& options) {
  const TimePlotLayout layout = layout_time_plot(series, options);
  cv::Mat image(layout.figure, CV_8UC3, plot::kWhite);
  if (!options.title.empty()) {
    plot::put_title(image, options.title, kMargin, kMargin + kTitleHeight / 2.0 - 4);
  }
  const std::vector<Tick> t_ticks =
      plot::linear_ticks(layout.time.lo, layout.time.hi, layout.time_step);
  std::vector<double> t_grid;
  for (const Tick& t : t_ticks) t_grid.push_back(t.value);
  const std::size_t channels = layout.panels_px.size();
  for (std::size_t c = 0; c < channels; ++c) {
    const cv::Rect& a = layout.panels_px[c];
    const plot::AxisMap& y = layout.values[c];
    const std::vector<Tick> y_ticks = plot::linear_ticks(y.lo, y.hi, layout.value_steps[c]);
    std::vector<double> y_grid;
    for (const Tick& t : y_ticks) y_grid.push_back(t.value);
    plot::draw_grid_x(image, a, layout.time, t_grid, plot::kGridMajor);
    plot::draw_grid_y(image, a, y, y_grid, plot::kGridMajor);
    for (std::size_t s = 0; s < series.size(); ++s) {
      const auto points = decimated_polyline(series[s].t_s, series[s].values.col(static_cast<Index>(c)),
                                             layout.time, y);
      plot::draw_polyline(image, points, plot::series_color(s), kLineWidth, plot::LineStyle::kSolid,
                          a);
    }
    plot::draw_frame(image, a);
    plot::draw_y_tick_labels(image, a, y, y_ticks);
    std::vector<Tick> x_ticks = t_ticks;
    if (c + 1 < channels) {
      for (Tick& t : x_ticks) t.label.clear();
    }
    plot::draw_x_tick_labels(image, a, layout.time, x_ticks);
    // Channel label, rotated, shrunk to the panel height if it is long.
    const std::string label = options.channel_labels.empty() ? fmt::format("channel {}", c + 1)
                                                             : options.channel_labels[c];
    plot::TextStyle style = plot::label_text();
    while (style.scale > 0.36 && plot::text_size(label, style).width > a.height - 4) {
      style.scale -= 0.02;
    }
    plot::put_text_vertical(image, label, {kMargin + kYLabelWidth / 2.0, a.y + a.height / 2.0},
                            style);
  }
  const cv::Rect& last = layout.panels_px.back();
  plot::put_text(image, options.x_label, {last.x + last.width / 2.0, last.br().y + kXTickHeight + 2.0},
                 plot::label_text(), HAlign::kCenter, VAlign::kTop);
  plot::draw_legend(image, legend_entries(series), layout.legend_px.tl(),
                    options.width_px - 2 * kMargin);
  return image;
}

std::vector<unsigned char> time_plot_png(const std::vector<TimeSeries>& series,
                                         const TimePlotOptions& options) {
  return plot::encode_png(render_time_plot(series, options));
}

void shade_time_windows(cv::Mat& image, const TimePlotLayout& layout, const std::vector<TimeWindowMark>& marks) {
  cv::Mat shade = image.clone();
  for (const auto& w : marks) {
    if (w.panel >= layout.panels_px.size()) continue;
    const cv::Rect& panel = layout.panels_px[w.panel];
    const int x0 = static_cast<int>(std::floor(layout.time.to_px(w.t_start_s)));
    const int x1 = static_cast<int>(std::ceil(layout.time.to_px(w.t_end_s)));
    cv::rectangle(shade, cv::Rect(cv::Point(std::max(x0, panel.x), panel.y),
                                  cv::Point(std::min(x1, panel.x + panel.width), panel.y + panel.height)),
                  cv::Scalar(80, 80, 255), cv::FILLED);
  }
  constexpr double kShadeAlpha = 0.25;
  cv::addWeighted(shade, kShadeAlpha, image, 1.0 - kShadeAlpha, 0.0, image);
}

namespace {

cv::Mat render_fit_overlay(const FitOverlay& o) {
  const Index N = o.t_s.size(), k = o.measured.cols();
  if (o.predicted.cols() != k || o.residual.cols() != k || o.measured.rows() != N || o.predicted.rows() != N ||
      o.residual.rows() != N || o.value_labels.size() != static_cast<std::size_t>(k) ||
      o.residual_labels.size() != static_cast<std::size_t>(k))
    throw InputError("fit overlay: the measured, predicted and residual signals and their labels must have one column "
                     "per channel and one row per time");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixXd meas = Eigen::MatrixXd::Constant(N, 2 * k, nan), model = meas, resid = meas;
  meas.leftCols(k) = o.measured;
  model.leftCols(k) = o.predicted;
  resid.rightCols(k) = o.residual;
  const std::vector<TimeSeries> series = {
      {"measured", o.t_s, meas}, {"model", o.t_s, model}, {"residual (measured - model)", o.t_s, resid}};
  TimePlotOptions po;
  po.channel_labels = o.value_labels;
  po.channel_labels.insert(po.channel_labels.end(), o.residual_labels.begin(), o.residual_labels.end());
  po.title = o.title;
  po.panel_height_px = o.panel_height_px;
  cv::Mat image = render_time_plot(series, po);
  std::vector<TimeWindowMark> marks = o.failures;
  for (auto& m : marks) m.panel += static_cast<std::size_t>(k);
  shade_time_windows(image, layout_time_plot(series, po), marks);
  return image;
}

}  // namespace

std::vector<unsigned char> fit_overlay_png(const FitOverlay& o) { return plot::encode_png(render_fit_overlay(o)); }

std::vector<unsigned char> fit_overlay_png(const FitOverlay& o, const std::vector<ResidualAgainst>& below) {
  std::vector<cv::Mat> parts{render_fit_overlay(o)};
  for (const ResidualAgainst& b : below) {
    if (b.x.size() != b.residual.size())
      throw InputError(fmt::format("fit overlay: {} values of {} against {} residuals", b.x.size(), b.x_label,
                                   b.residual.size()));
    std::vector<Index> order;
    for (Index k = 0; k < b.x.size(); ++k)
      if (std::isfinite(b.x(k)) && std::isfinite(b.residual(k))) order.push_back(k);
    if (order.empty()) throw InputError(fmt::format("fit overlay: no finite residual against {}", b.x_label));
    std::stable_sort(order.begin(), order.end(), [&](Index a, Index c) { return b.x(a) < b.x(c); });
    TimeSeries ts{"residual against " + b.x_label, Eigen::VectorXd(static_cast<Index>(order.size())),
                  Eigen::MatrixXd(static_cast<Index>(order.size()), 1)};
    for (std::size_t r = 0; r < order.size(); ++r) {
      ts.t_s(static_cast<Index>(r)) = b.x(order[r]);
      ts.values(static_cast<Index>(r), 0) = b.residual(order[r]);
    }
    TimePlotOptions po;
    po.channel_labels = {b.y_label};
    po.x_label = b.x_label;
    po.width_px = parts.front().cols;
    po.panel_height_px = o.panel_height_px;
    parts.push_back(render_time_plot({ts}, po));
  }
  cv::Mat image;
  cv::vconcat(parts, image);
  return plot::encode_png(image);
}

}  // namespace lpvid
