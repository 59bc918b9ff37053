#include "formats/plot/sv_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

using plot::HAlign;
using plot::Tick;
using plot::VAlign;

// Figure layout, in pixels.
constexpr int kWidth = 760;
constexpr int kHeight = 480;
constexpr int kMargin = 14;
constexpr int kYLabelWidth = 24;
constexpr int kYTickWidth = 48;
constexpr int kRightMargin = 26;
constexpr int kTitleHeight = 40;
constexpr int kXTickHeight = 24;
constexpr int kXLabelHeight = 28;
// Minor (2..9) grid lines only when a decade is at least this tall.
constexpr double kMinDecadeForMinorGrid = 40.0;
constexpr int kMarkerSize = 8;
constexpr int kStemWidth = 2;

const cv::Scalar kDiscardedColor(150, 150, 150);

void validate(const Eigen::VectorXd& sv, const SingularValuePlotOptions& options) {
  if (sv.size() == 0) {
    throw InputError("singular value plot: no singular values to draw");
  }
  for (Index k = 0; k < sv.size(); ++k) {
    if (!std::isfinite(sv[k]) || sv[k] < 0.0) {
      throw InputError(fmt::format(
          "singular value plot: singular value {} is {}; values must be finite and >= 0",
          k + 1, sv[k]));
    }
  }
  if (options.count < 1) {
    throw InputError(fmt::format("singular value plot: count {} must be >= 1", options.count));
  }
  if (options.chosen_order < 0 || options.chosen_order > sv.size()) {
    throw InputError(fmt::format(
        "singular value plot: chosen_order {} is outside 0..{} (the number of singular values)",
        options.chosen_order, sv.size()));
  }
  if (!std::isfinite(options.noise_floor) || options.noise_floor < 0.0) {
    throw InputError(fmt::format(
        "singular value plot: noise_floor {} must be finite and >= 0 (0 = no line)",
        options.noise_floor));
  }
}

std::string short_number(double v) { return fmt::format("{:.2g}", v); }

}  // namespace

SingularValueLayout layout_singular_values(const Eigen::VectorXd& sv,
                                           const SingularValuePlotOptions& options) {
  validate(sv, options);
  SingularValueLayout layout;
  layout.shown = std::min<Index>(sv.size(), std::max(options.count, options.chosen_order + 1));
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  for (Index k = 0; k < layout.shown; ++k) {
    if (sv[k] > 0.0) {
      lo = std::min(lo, sv[k]);
      hi = std::max(hi, sv[k]);
    }
  }
  if (hi == 0.0) {
    throw InputError(fmt::format(
        "singular value plot: the {} values shown are all zero; a log axis cannot show them",
        layout.shown));
  }
  if (options.noise_floor > 0.0) {
    lo = std::min(lo, options.noise_floor);
    hi = std::max(hi, options.noise_floor);
  }
  double dlo = std::pow(10.0, std::floor(std::log10(lo) + 1e-9));
  double dhi = std::pow(10.0, std::ceil(std::log10(hi) - 1e-9));
  if (dhi <= dlo) {
    dlo /= 10.0;
    dhi *= 10.0;
  }
  const int top = options.title.empty() ? kMargin + 6 : kMargin + kTitleHeight;
  const int left = kMargin + kYLabelWidth + kYTickWidth;
  const int bottom = kHeight - kMargin - kXTickHeight - kXLabelHeight;
  layout.figure = cv::Size(kWidth, kHeight);
  layout.axes_px = cv::Rect(left, top, kWidth - kRightMargin - left, bottom - top);
  const cv::Rect& a = layout.axes_px;
  layout.index = {0.5, layout.shown + 0.5, static_cast<double>(a.x),
                  static_cast<double>(a.x + a.width - 1), false};
  layout.value = {dlo, dhi, static_cast<double>(a.y + a.height - 1), static_cast<double>(a.y),
                  true};
  return layout;
}

cv::Mat render_singular_values(const Eigen::VectorXd& sv,
                               const SingularValuePlotOptions& options) {
  const SingularValueLayout layout = layout_singular_values(sv, options);
  cv::Mat image(layout.figure, CV_8UC3, plot::kWhite);
  const cv::Rect& a = layout.axes_px;
  const plot::AxisMap& x = layout.index;
  const plot::AxisMap& y = layout.value;

  if (!options.title.empty()) {
    plot::put_title(image, options.title, kMargin, kMargin + kTitleHeight / 2.0 - 4);
  }

  // Grid and ticks.
  const std::vector<Tick> y_ticks = plot::decade_ticks(y.lo, y.hi, plot::DecadeLabels::kScientific);
  const double decade_px = a.height / std::log10(y.hi / y.lo);
  if (decade_px >= kMinDecadeForMinorGrid) {
    plot::draw_grid_y(image, a, y, plot::minor_log_ticks(y.lo, y.hi), plot::kGridMinor);
  }
  std::vector<double> decades;
  for (const Tick& t : y_ticks) decades.push_back(t.value);
  plot::draw_grid_y(image, a, y, decades, plot::kGridMajor);
  // Integer index ticks: every index when they fit, else a 1-2-5 step.
  const double step = std::max(1.0, plot::nice_step(static_cast<double>(layout.shown), 20));
  std::vector<Tick> x_ticks;
  for (double v = step == 1.0 ? 1.0 : step; v <= layout.shown + 1e-9; v += step) {
    x_ticks.push_back({v, fmt::format("{}", static_cast<long long>(v))});
  }
  std::vector<double> x_grid;
  for (const Tick& t : x_ticks) x_grid.push_back(t.value);
  plot::draw_grid_x(image, a, x, x_grid, plot::kGridMinor);

  // Noise floor (under the stems).
  if (options.noise_floor > 0.0) {
    const double py = y.to_px(options.noise_floor);
    plot::draw_polyline(image, {{static_cast<double>(a.x), py}, {static_cast<double>(a.br().x), py}},
                        plot::kFlagColor, 2, plot::LineStyle::kDashed, a);
    plot::put_text(image, "noise floor " + short_number(options.noise_floor),
                   {a.br().x - 8.0, py - 6.0}, plot::label_text(), HAlign::kRight,
                   VAlign::kBottom);
  }

  // Stems and markers over the frame: a value on a decade at the axis end
  // (often the largest, scaled to 1) shows its whole marker.
  plot::draw_frame(image, a);
  const cv::Rect marker_clip(a.x - kMarkerSize, a.y - kMarkerSize, a.width + 2 * kMarkerSize,
                             a.height + 2 * kMarkerSize);
  const double base = y.px_lo;
  for (Index k = 0; k < layout.shown; ++k) {
    if (sv[k] <= 0.0) continue;
    const bool kept = options.chosen_order == 0 || k < options.chosen_order;
    const cv::Scalar color = kept ? plot::series_color(0) : kDiscardedColor;
    const double px = x.to_px(static_cast<double>(k + 1));
    const double py = y.to_px(sv[k]);
    plot::draw_polyline(image, {{px, base}, {px, py}}, color, kStemWidth, plot::LineStyle::kSolid,
                        a);
    plot::draw_marker(image, {px, py}, plot::Marker::kCircle, color, kMarkerSize, marker_clip);
  }

  // Chosen order: between the last kept and the first discarded value.
  if (options.chosen_order > 0) {
    const double px = x.to_px(options.chosen_order + 0.5);
    plot::draw_polyline(image, {{px, static_cast<double>(a.y)}, {px, static_cast<double>(a.br().y)}},
                        plot::kAxisColor, 2, plot::LineStyle::kDashed, a);
    const std::string label = fmt::format("order {}", options.chosen_order);
    const int w = plot::text_size(label, plot::label_text()).width;
    const bool right = px + 8 + w < a.br().x - 4;
    plot::put_text(image, label, {right ? px + 8 : px - 8, a.y + 8.0}, plot::label_text(),
                   right ? HAlign::kLeft : HAlign::kRight, VAlign::kTop);
  }

  plot::draw_x_tick_labels(image, a, x, x_ticks);
  plot::draw_y_tick_labels(image, a, y, y_ticks);
  plot::put_text(image, "index", {a.x + a.width / 2.0, a.br().y + kXTickHeight + 2.0},
                 plot::label_text(), HAlign::kCenter, VAlign::kTop);
  plot::put_text_vertical(image, "singular value (scaled)",
                          {kMargin + kYLabelWidth / 2.0, a.y + a.height / 2.0},
                          plot::label_text());

  // Legend, top right inside the axes, when there is more than one kind of mark.
  std::vector<plot::LegendEntry> entries;
  if (options.chosen_order > 0) {
    entries.push_back({"kept", plot::series_color(0), plot::LineStyle::kNone, plot::Marker::kCircle});
    if (options.chosen_order < layout.shown) {
      entries.push_back({"discarded", kDiscardedColor, plot::LineStyle::kNone, plot::Marker::kCircle});
    }
  }
  if (options.noise_floor > 0.0) {
    entries.push_back({"noise floor", plot::kFlagColor, plot::LineStyle::kDashed, plot::Marker::kNone});
  }
  if (!entries.empty()) {
    const cv::Size s = plot::legend_size(entries, a.width - 20);
    plot::draw_legend(image, entries, {a.br().x - 10 - s.width, a.y + 36}, a.width - 20);
  }
  return image;
}

std::vector<unsigned char> singular_values_png(const Eigen::VectorXd& sv,
                                               const SingularValuePlotOptions& options) {
  return plot::encode_png(render_singular_values(sv, options));
}

}  // namespace lpvid
