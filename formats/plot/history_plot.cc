#include "formats/plot/history_plot.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "formats/plot/canvas.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using plot::HAlign;
using plot::VAlign;

constexpr int kMargin = 14;
constexpr int kYLabelWidth = 24;
constexpr int kYTickWidth = 56;
constexpr int kTitleHeight = 40;
constexpr int kAxesHeight = 360;
constexpr int kBarSlot = 70;       // px per fit
constexpr int kMinAxesWidth = 420;
constexpr int kLabelMaxPx = 300;   // rotated labels under the axes
constexpr int kMarkerSize = 10;

std::string fit(const std::string& text, const plot::TextStyle& style, int max_width) {
  std::string t = plot::ascii_text(text);
  if (plot::text_size(t, style).width <= max_width) return t;
  while (!t.empty() && plot::text_size(t + "...", style).width > max_width) t.pop_back();
  return t + "...";
}

}  // namespace

cv::Mat render_history(const std::vector<HistoryBar>& bars, const std::string& title) {
  if (bars.empty()) throw InputError("history plot: no fit to draw");
  double lo = 1e300, hi = 0;
  for (std::size_t k = 0; k < bars.size(); ++k) {
    const auto& b = bars[k];
    if (!std::isfinite(b.mean_percent) || !std::isfinite(b.max_percent) || b.mean_percent <= 0 ||
        b.max_percent < b.mean_percent)
      throw InputError(fmt::format("history plot: fit {} has mean {} % and max {} %; both finite, > 0, max >= mean",
                                   k + 1, b.mean_percent, b.max_percent));
    if (!std::isnan(b.floor_percent) && !(std::isfinite(b.floor_percent) && b.floor_percent > 0))
      throw InputError(fmt::format("history plot: fit {} has a noise floor of {} %; finite and > 0, or none", k + 1,
                                   b.floor_percent));
    lo = std::min(lo, b.mean_percent);
    if (std::isfinite(b.floor_percent)) lo = std::min(lo, b.floor_percent);
    hi = std::max(hi, b.max_percent);
  }
  lo = std::pow(10.0, std::floor(std::log10(lo) - 1e-9));
  hi = std::pow(10.0, std::ceil(std::log10(hi) + 1e-9));
  const plot::TextStyle lt = plot::label_text();
  int label_h = 0;
  std::vector<std::string> labels;
  for (const auto& b : bars) {
    labels.push_back(fit(b.label, lt, kLabelMaxPx));
    label_h = std::max(label_h, plot::text_size(labels.back(), lt).width);
  }
  const int axes_w = std::max(kMinAxesWidth, static_cast<int>(bars.size()) * kBarSlot);
  const int left = kMargin + kYLabelWidth + kYTickWidth;
  const int top = kMargin + (title.empty() ? 6 : kTitleHeight);
  const cv::Rect a(left, top, axes_w, kAxesHeight);
  const int width = a.br().x + 2 * kMargin;
  const int height = a.br().y + 12 + label_h + 30 + 40 + kMargin;
  cv::Mat image(height, width, CV_8UC3, plot::kWhite);
  if (!title.empty())
    plot::put_title(image, title, kMargin, kMargin + kTitleHeight / 2.0 - 4);
  const plot::AxisMap y{lo, hi, static_cast<double>(a.br().y - 1), static_cast<double>(a.y), true};
  const plot::AxisMap x{0.5, bars.size() + 0.5, static_cast<double>(a.x), static_cast<double>(a.br().x - 1), false};
  auto ticks = plot::decade_ticks(lo, hi, plot::DecadeLabels::kPlain);
  for (auto& t : ticks) t.label += "%";
  std::vector<double> tv;
  for (const auto& t : ticks) tv.push_back(t.value);
  if (a.height / std::log10(hi / lo) >= 40) plot::draw_grid_y(image, a, y, plot::minor_log_ticks(lo, hi), plot::kGridMinor);
  plot::draw_grid_y(image, a, y, tv, plot::kGridMajor);
  const double half = 0.3 * (x.to_px(2) - x.to_px(1));
  std::vector<cv::Point2d> trend;
  bool any_floor = false;
  for (std::size_t k = 0; k < bars.size(); ++k) {
    const double px = x.to_px(static_cast<double>(k + 1));
    cv::rectangle(image, cv::Point2d(px - half, y.to_px(bars[k].mean_percent)), cv::Point2d(px + half, a.br().y - 1),
                  plot::series_color(0), cv::FILLED);
    plot::draw_marker(image, {px, y.to_px(bars[k].max_percent)}, plot::Marker::kSquare, plot::series_color(1),
                      kMarkerSize, a);
    trend.emplace_back(px, y.to_px(bars[k].max_percent));
    if (std::isfinite(bars[k].floor_percent)) {
      const double fy = y.to_px(bars[k].floor_percent);
      plot::draw_polyline(image, {{px - 1.4 * half, fy}, {px + 1.4 * half, fy}}, plot::series_color(2), 2,
                          plot::LineStyle::kSolid, a);
      any_floor = true;
    }
    plot::put_text(image, fmt::format("{:.3g}%", bars[k].mean_percent), {px, y.to_px(bars[k].mean_percent) - 4},
                   plot::tick_text(), HAlign::kCenter, VAlign::kBottom);
    plot::put_text_vertical(image, labels[k], {px, a.br().y + 12.0 + plot::text_size(labels[k], lt).width / 2.0}, lt);
  }
  plot::draw_polyline(image, trend, plot::series_color(1), 1, plot::LineStyle::kDashed, a);
  plot::draw_frame(image, a);
  plot::draw_y_tick_labels(image, a, y, ticks);
  plot::put_text_vertical(image, "model error [%] (log)", {kMargin + kYLabelWidth / 2.0, a.y + a.height / 2.0}, lt);
  std::vector<plot::LegendEntry> legend = {
      {"model error (bar)", plot::series_color(0), plot::LineStyle::kNone, plot::Marker::kSquare},
      {"largest channel error", plot::series_color(1), plot::LineStyle::kDashed, plot::Marker::kSquare}};
  if (any_floor)
    legend.push_back({"noise floor of the data", plot::series_color(2), plot::LineStyle::kSolid, plot::Marker::kNone});
  const cv::Size ls = plot::legend_size(legend, width - 2 * kMargin);
  plot::draw_legend(image, legend, {(width - ls.width) / 2, height - kMargin - ls.height}, width - 2 * kMargin);
  return image;
}

std::vector<unsigned char> history_png(const std::vector<HistoryBar>& bars, const std::string& title) {
  return plot::encode_png(render_history(bars, title));
}

}  // namespace lpvid
