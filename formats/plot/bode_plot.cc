#include "formats/plot/bode_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

using plot::AxisMap;
using plot::HAlign;
using plot::Tick;
using plot::VAlign;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Layout, in pixels.
constexpr int kMargin = 14;         // outer margin
constexpr int kYLabelWidth = 24;    // rotated "Magnitude [dB]" column
constexpr int kYTickWidth = 50;     // tick labels left of each panel
constexpr int kColumnGap = 22;      // right of each panel
constexpr int kTitleHeight = 40;    // figure title band
constexpr int kPanelTitleHeight = 24;
constexpr int kAxesGap = 18;        // between magnitude and phase axes (room for edge labels)
constexpr int kRowGap = 10;         // between rows of panels
constexpr int kXTickHeight = 24;    // tick labels under the bottom row
constexpr int kXLabelHeight = 26;   // "Frequency [rad/s]"
constexpr int kMinAxesPx = 60;      // smallest usable axes side

// Magnitude axis: no narrower than 20 dB (one gain decade); at most 6
// intervals.  Phase axis: no narrower than 90 deg; at most 5 intervals.
constexpr double kMinMagnitudeSpanDb = 20.0;
constexpr int kMaxMagnitudeIntervals = 6;
constexpr double kMinPhaseSpanDeg = 90.0;
constexpr int kMaxPhaseIntervals = 5;
// Fraction of the data span added above and below before snapping to ticks,
// so that a curve does not run along the frame.
constexpr double kPadFraction = 0.03;

constexpr int kMarkerSize = 6;  // kMarkers style, px
constexpr int kFlagSize = 9;    // red cross on flagged frequencies, px

bool finite(const Complex& z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

std::string series_name(const BodeSeries& s, std::size_t index) {
  return s.label.empty() ? fmt::format("#{}", index + 1) : "'" + s.label + "'";
}

void validate(const std::vector<BodeSeries>& series, const BodePlotOptions& options) {
  if (series.empty()) throw InputError("bode plot: no series to draw; pass at least one response");
  const Index p = series.front().response.num_outputs();
  const Index m = series.front().response.num_inputs();
  for (std::size_t s = 0; s < series.size(); ++s) {
    const FrequencyResponse& r = series[s].response;
    const std::string name = series_name(series[s], s);
    const Index n = r.num_frequencies();
    if (n == 0) throw InputError(fmt::format("bode plot: series {} has no frequencies", name));
    if (static_cast<Index>(r.response.size()) != n) {
      throw InputError(fmt::format(
          "bode plot: series {} has {} response matrices for {} frequencies; they must match",
          name, r.response.size(), n));
    }
    if (!r.flagged.empty() && static_cast<Index>(r.flagged.size()) != n) {
      throw InputError(fmt::format(
          "bode plot: series {} has {} flagged entries for {} frequencies; give none or one "
          "per frequency",
          name, r.flagged.size(), n));
    }
    for (Index k = 0; k < n; ++k) {
      const Eigen::MatrixXcd& h = r.response[static_cast<std::size_t>(k)];
      if (h.rows() != p || h.cols() != m) {
        throw InputError(fmt::format(
            "bode plot: series {} has a {}x{} response at frequency index {} but series {} is "
            "{}x{} (outputs x inputs); all responses must share one shape",
            name, h.rows(), h.cols(), k, series_name(series.front(), 0), p, m));
      }
      const double w = r.omega_rad_s[k];
      if (!std::isfinite(w) || w <= 0.0) {
        throw InputError(fmt::format(
            "bode plot: series {} has frequency {} rad/s at index {}; a log frequency axis "
            "needs finite frequencies > 0",
            name, w, k));
      }
    }
    if (p == 0 || m == 0) {
      throw InputError(fmt::format("bode plot: series {} has an empty {}x{} response", name, p, m));
    }
  }
  if (options.panel_width_px < kMinAxesPx || options.magnitude_height_px < kMinAxesPx ||
      (options.show_phase && options.phase_height_px < kMinAxesPx)) {
    throw InputError(fmt::format(
        "bode plot: panel size {}x{} (+ phase {}) px is too small; each side must be >= {} px",
        options.panel_width_px, options.magnitude_height_px, options.phase_height_px,
        kMinAxesPx));
  }
  for (double w : {options.min_omega_rad_s, options.max_omega_rad_s}) {
    if (!std::isfinite(w) || w < 0.0) {
      throw InputError(fmt::format(
          "bode plot: frequency limit {} rad/s is invalid; use a value > 0, or 0 for 'from data'",
          w));
    }
  }
  if (options.min_omega_rad_s > 0 && options.max_omega_rad_s > 0 &&
      options.min_omega_rad_s >= options.max_omega_rad_s) {
    throw InputError(fmt::format(
        "bode plot: min_omega_rad_s {} must be below max_omega_rad_s {}",
        options.min_omega_rad_s, options.max_omega_rad_s));
  }
  if (!options.input_labels.empty() && static_cast<Index>(options.input_labels.size()) != m) {
    throw InputError(fmt::format("bode plot: {} input labels given for {} inputs",
                                 options.input_labels.size(), m));
  }
  if (!options.output_labels.empty() && static_cast<Index>(options.output_labels.size()) != p) {
    throw InputError(fmt::format("bode plot: {} output labels given for {} outputs",
                                 options.output_labels.size(), p));
  }
}

// The displayed frequency of omega (rad/s or Hz).
double display_frequency(double omega_rad_s, const BodePlotOptions& options) {
  return options.frequency_in_hz ? omega_rad_s / (2.0 * std::numbers::pi) : omega_rad_s;
}

plot::Range frequency_range(const std::vector<BodeSeries>& series,
                            const BodePlotOptions& options) {
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  for (const BodeSeries& s : series) {
    lo = std::min(lo, s.response.omega_rad_s.minCoeff());
    hi = std::max(hi, s.response.omega_rad_s.maxCoeff());
  }
  lo = display_frequency(lo, options);
  hi = display_frequency(hi, options);
  // Whole decades around the data.
  double dlo = std::pow(10.0, std::floor(std::log10(lo) + 1e-9));
  double dhi = std::pow(10.0, std::ceil(std::log10(hi) - 1e-9));
  if (dhi <= dlo) dhi = dlo * 10.0;
  if (options.min_omega_rad_s > 0) dlo = display_frequency(options.min_omega_rad_s, options);
  if (options.max_omega_rad_s > 0) dhi = display_frequency(options.max_omega_rad_s, options);
  if (dlo >= dhi) {
    throw InputError(fmt::format(
        "bode plot: frequency axis [{}, {}] {} is empty; check min_omega_rad_s / "
        "max_omega_rad_s against the data",
        dlo, dhi, options.frequency_in_hz ? "Hz" : "rad/s"));
  }
  return {dlo, dhi};
}

// Pads [lo, hi] to at least min_span, then picks a tick step from the
// candidates (the first giving <= max_intervals) and snaps outward.
plot::Range axis_range(double lo, double hi, double min_span, const std::vector<double>& steps,
                       int max_intervals, double* step_out) {
  if (!(lo <= hi)) {  // no finite data
    lo = -min_span / 2.0;
    hi = min_span / 2.0;
  }
  const double pad = (hi - lo) * kPadFraction;
  lo -= pad;
  hi += pad;
  if (hi - lo < min_span) {
    const double mid = (lo + hi) / 2.0;
    lo = mid - min_span / 2.0;
    hi = mid + min_span / 2.0;
  }
  double step = 0.0;
  for (double candidate : steps) {
    if (std::ceil(hi / candidate - 1e-9) - std::floor(lo / candidate + 1e-9) <= max_intervals) {
      step = candidate;
      break;
    }
  }
  // Beyond the candidates: a 1-2-5 step, doubled to leave room for snapping.
  if (step == 0.0) step = plot::nice_step(hi - lo, max_intervals) * 2.0;
  *step_out = step;
  return plot::snap_outward(lo, hi, step);
}

std::vector<double> magnitude_steps() { return {1, 2, 5, 10, 20, 40, 60, 100, 200, 500, 1000}; }
std::vector<double> phase_steps() { return {15, 45, 90, 180, 360, 720, 1440, 2880, 5760}; }

// Indices of the series' frequencies in increasing order.
std::vector<std::size_t> frequency_order(const FrequencyResponse& r) {
  std::vector<std::size_t> order(static_cast<std::size_t>(r.num_frequencies()));
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return r.omega_rad_s[static_cast<Index>(a)] < r.omega_rad_s[static_cast<Index>(b)];
  });
  return order;
}

// H(i, j) of the series along increasing frequency.
std::vector<Complex> channel(const FrequencyResponse& r, const std::vector<std::size_t>& order,
                             Index i, Index j) {
  std::vector<Complex> v;
  v.reserve(order.size());
  for (std::size_t k : order) v.push_back(r.response[k](i, j));
  return v;
}

std::string label_or(const std::vector<std::string>& given, const std::vector<std::string>& names,
                     Index count, Index k, const char* prefix) {
  if (static_cast<Index>(given.size()) == count) return given[static_cast<std::size_t>(k)];
  if (static_cast<Index>(names.size()) == count && !names[static_cast<std::size_t>(k)].empty()) {
    return names[static_cast<std::size_t>(k)];
  }
  return fmt::format("{}{}", prefix, k + 1);
}

std::vector<plot::LegendEntry> legend_entries(const std::vector<BodeSeries>& series) {
  std::vector<plot::LegendEntry> entries;
  bool any_flag = false;
  for (std::size_t s = 0; s < series.size(); ++s) {
    plot::LegendEntry e{series[s].label.empty() ? fmt::format("series {}", s + 1) : series[s].label,
                        plot::series_color(s), plot::LineStyle::kSolid, plot::Marker::kNone};
    if (series[s].style == BodeSeries::Style::kDashed) e.line = plot::LineStyle::kDashed;
    if (series[s].style == BodeSeries::Style::kMarkers) {
      e.line = plot::LineStyle::kNone;
      e.marker = plot::Marker::kCircle;
    }
    entries.push_back(e);
    const auto& f = series[s].response.flagged;
    any_flag = any_flag || std::find(f.begin(), f.end(), true) != f.end();
  }
  if (any_flag) {
    entries.push_back({"flagged (untrusted)", plot::kFlagColor, plot::LineStyle::kNone,
                       plot::Marker::kCross});
  }
  return entries;
}

// Ticks of the log frequency axis: labelled decades, and when fewer than two
// decades are visible, labelled minor ticks as well.
std::vector<Tick> frequency_ticks(const AxisMap& x) {
  std::vector<Tick> ticks = plot::decade_ticks(x.lo, x.hi, plot::DecadeLabels::kPlain);
  if (ticks.size() < 2) {
    for (double v : plot::minor_log_ticks(x.lo, x.hi)) ticks.push_back({v, fmt::format("{:g}", v)});
    std::sort(ticks.begin(), ticks.end(),
              [](const Tick& a, const Tick& b) { return a.value < b.value; });
  }
  return ticks;
}

}  // namespace

std::vector<double> unwrapped_phase_deg(const std::vector<Complex>& values) {
  std::vector<double> out(values.size(), kNaN);
  double previous = kNaN;
  double offset = 0.0;  // multiple of 360 added to std::arg
  bool first = true;
  double shift = 0.0;
  for (std::size_t k = 0; k < values.size(); ++k) {
    const Complex z = values[k];
    if (!finite(z) || std::abs(z) == 0.0) continue;
    double deg = std::arg(z) * 180.0 / std::numbers::pi + offset;
    if (std::isfinite(previous)) {
      while (deg - previous > 180.0) {
        deg -= 360.0;
        offset -= 360.0;
      }
      while (deg - previous < -180.0) {
        deg += 360.0;
        offset += 360.0;
      }
    }
    if (first) {
      // First finite value into (-270, 90].
      while (deg + shift > 90.0) shift -= 360.0;
      while (deg + shift <= -270.0) shift += 360.0;
      first = false;
    }
    previous = deg;
    out[k] = deg + shift;
  }
  return out;
}

namespace {

// The unwrapped phases of one panel (output i, input j), one vector per series in display
// order (NaN for a series without phase).  Each curve is unwrapped on its own and then
// moved by a multiple of 360 deg to lie within 180 deg of the first series with a phase,
// at the nearest frequency where both have one: curves of nearly the same response are
// otherwise drawn 360 deg apart when their first points fall on either side of -180 deg.
std::vector<std::vector<double>> panel_phases(const std::vector<BodeSeries>& series,
                                              const std::vector<std::vector<std::size_t>>& orders, int i, int j) {
  std::vector<std::vector<double>> out(series.size());
  int reference = -1;
  for (std::size_t s = 0; s < series.size(); ++s) {
    const std::vector<Complex> h = channel(series[s].response, orders[s], i, j);
    out[s] = series[s].show_phase ? unwrapped_phase_deg(h) : std::vector<double>(h.size(), kNaN);
    if (!series[s].show_phase) continue;
    std::size_t k0 = 0;
    while (k0 < out[s].size() && !std::isfinite(out[s][k0])) ++k0;
    if (k0 == out[s].size()) continue;
    if (reference < 0) {
      reference = static_cast<int>(s);
      continue;
    }
    const auto& ref = series[static_cast<std::size_t>(reference)];
    const std::vector<double>& ref_phase = out[static_cast<std::size_t>(reference)];
    const double w0 = series[s].response.omega_rad_s[static_cast<Index>(orders[s][k0])];
    double best = std::numeric_limits<double>::infinity(), ref_deg = kNaN;
    for (std::size_t k = 0; k < ref_phase.size(); ++k) {
      if (!std::isfinite(ref_phase[k])) continue;
      const double w = ref.response.omega_rad_s[static_cast<Index>(orders[static_cast<std::size_t>(reference)][k])];
      const double d = std::abs(std::log(w / w0));
      if (d < best) best = d, ref_deg = ref_phase[k];
    }
    if (!std::isfinite(ref_deg)) continue;
    const double shift = 360.0 * std::round((ref_deg - out[s][k0]) / 360.0);
    for (double& deg : out[s]) deg += shift;
  }
  return out;
}

}  // namespace

BodeLayout layout_bode(const std::vector<BodeSeries>& series, const BodePlotOptions& options) {
  validate(series, options);
  BodeLayout layout;
  layout.outputs = series.front().response.num_outputs();
  layout.inputs = series.front().response.num_inputs();
  const int p = static_cast<int>(layout.outputs), m = static_cast<int>(layout.inputs);
  const int w = options.panel_width_px, hm = options.magnitude_height_px;
  const int hp = options.show_phase ? options.phase_height_px : 0;

  const int column_pitch = kYTickWidth + w + kColumnGap;
  const int width = kMargin + kYLabelWidth + m * column_pitch - kColumnGap + kMargin + 8;
  const int top = options.title.empty() ? kMargin : kMargin + kTitleHeight;
  const int row_pitch = kPanelTitleHeight + hm + (options.show_phase ? kAxesGap + hp : 0) + kRowGap;
  const int grid_bottom = top + p * row_pitch - kRowGap;

  const auto entries = legend_entries(series);
  const cv::Size legend = plot::legend_size(entries, width - 2 * kMargin);
  const int legend_top = grid_bottom + kXTickHeight + kXLabelHeight + 4;
  layout.legend_px = cv::Rect((width - legend.width) / 2, legend_top, legend.width, legend.height);
  layout.figure = cv::Size(width, legend_top + legend.height + kMargin);

  // Shared frequency axis.
  const plot::Range f = frequency_range(series, options);

  // Per-panel magnitude and phase ranges over all series.
  std::vector<std::vector<std::size_t>> orders;
  for (const BodeSeries& s : series) orders.push_back(frequency_order(s.response));
  for (int i = 0; i < p; ++i) {
    for (int j = 0; j < m; ++j) {
      double mlo = std::numeric_limits<double>::infinity(), mhi = -mlo;
      double plo = mlo, phi = -mlo;
      for (std::size_t s = 0; s < series.size(); ++s) {
        const std::vector<Complex> h = channel(series[s].response, orders[s], i, j);
        for (const Complex& z : h) {
          const double mag = std::abs(z);
          if (finite(z) && mag > 0.0) {
            const double db = 20.0 * std::log10(mag);
            mlo = std::min(mlo, db);
            mhi = std::max(mhi, db);
          }
        }
      }
      if (options.show_phase) {
        for (const std::vector<double>& phases : panel_phases(series, orders, i, j))
          for (double deg : phases) {
            if (std::isfinite(deg)) {
              plo = std::min(plo, deg);
              phi = std::max(phi, deg);
            }
          }
      }
      BodeAxes axes;
      const int x0 = kMargin + kYLabelWidth + j * column_pitch + kYTickWidth;
      const int y0 = top + i * row_pitch + kPanelTitleHeight;
      axes.magnitude_px = cv::Rect(x0, y0, w, hm);
      axes.frequency = {f.lo, f.hi, static_cast<double>(x0), static_cast<double>(x0 + w - 1), true};
      double step = 0.0;
      const plot::Range mr = axis_range(mlo, mhi, kMinMagnitudeSpanDb, magnitude_steps(),
                                        kMaxMagnitudeIntervals, &step);
      axes.magnitude_db = {mr.lo, mr.hi, static_cast<double>(y0 + hm - 1),
                           static_cast<double>(y0), false};
      axes.magnitude_step_db = step;
      if (options.show_phase) {
        const int yp = y0 + hm + kAxesGap;
        axes.phase_px = cv::Rect(x0, yp, w, hp);
        const plot::Range pr =
            axis_range(plo, phi, kMinPhaseSpanDeg, phase_steps(), kMaxPhaseIntervals, &step);
        axes.phase_deg = {pr.lo, pr.hi, static_cast<double>(yp + hp - 1),
                          static_cast<double>(yp), false};
        axes.phase_step_deg = step;
      }
      layout.panels.push_back(axes);
    }
  }
  return layout;
}

namespace {

std::vector<double> tick_values(const std::vector<Tick>& ticks) {
  std::vector<double> v;
  for (const Tick& t : ticks) v.push_back(t.value);
  return v;
}

void draw_axes_background(cv::Mat& image, const cv::Rect& area, const AxisMap& x,
                          const AxisMap& y, const std::vector<Tick>& y_ticks) {
  plot::draw_grid_x(image, area, x, plot::minor_log_ticks(x.lo, x.hi), plot::kGridMinor);
  plot::draw_grid_x(image, area, x, tick_values(plot::decade_ticks(x.lo, x.hi, plot::DecadeLabels::kPlain)),
                    plot::kGridMajor);
  plot::draw_grid_y(image, area, y, tick_values(y_ticks), plot::kGridMajor);
}

void draw_curve(cv::Mat& image, const cv::Rect& area, const std::vector<cv::Point2d>& points,
                const cv::Scalar& color, BodeSeries::Style style) {
  constexpr int kLineWidth = 2;
  switch (style) {
    case BodeSeries::Style::kLine:
      plot::draw_polyline(image, points, color, kLineWidth, plot::LineStyle::kSolid, area);
      break;
    case BodeSeries::Style::kDashed:
      plot::draw_polyline(image, points, color, kLineWidth, plot::LineStyle::kDashed, area);
      break;
    case BodeSeries::Style::kMarkers:
      for (const cv::Point2d& q : points) {
        plot::draw_marker(image, q, plot::Marker::kCircle, color, kMarkerSize, area);
      }
      break;
  }
}

}  // namespace

cv::Mat render_bode(const std::vector<BodeSeries>& series, const BodePlotOptions& options) {
  const BodeLayout layout = layout_bode(series, options);
  cv::Mat image(layout.figure, CV_8UC3, plot::kWhite);
  const Index p = layout.outputs, m = layout.inputs;
  const FrequencyResponse& first = series.front().response;

  if (!options.title.empty()) {
    // A narrow figure (one panel) gets a smaller title before it is cut short.
    plot::put_title(image, options.title, kMargin, kMargin + kTitleHeight / 2.0 - 4);
  }

  std::vector<std::vector<std::size_t>> orders;
  for (const BodeSeries& s : series) orders.push_back(frequency_order(s.response));

  for (Index i = 0; i < p; ++i) {
    for (Index j = 0; j < m; ++j) {
      const BodeAxes& axes = layout.panel(i, j);
      const std::vector<Tick> f_ticks = frequency_ticks(axes.frequency);
      const std::vector<Tick> m_ticks =
          plot::linear_ticks(axes.magnitude_db.lo, axes.magnitude_db.hi, axes.magnitude_step_db);
      const std::vector<Tick> p_ticks =
          options.show_phase
              ? plot::linear_ticks(axes.phase_deg.lo, axes.phase_deg.hi, axes.phase_step_deg)
              : std::vector<Tick>{};

      // Panel title.
      const std::string in = label_or(options.input_labels, first.input_names, m, j, "u");
      const std::string out = label_or(options.output_labels, first.output_names, p, i, "y");
      plot::put_text(image,
                     plot::fit_text(fmt::format("from {} to {}", in, out), plot::panel_title_text(),
                              axes.magnitude_px.width),
                     {axes.magnitude_px.x + axes.magnitude_px.width / 2.0,
                      axes.magnitude_px.y - 8.0},
                     plot::panel_title_text(), HAlign::kCenter, VAlign::kBottom);

      draw_axes_background(image, axes.magnitude_px, axes.frequency, axes.magnitude_db, m_ticks);
      if (options.show_phase) {
        draw_axes_background(image, axes.phase_px, axes.frequency, axes.phase_deg, p_ticks);
      }

      // Curves, then flagged crosses on top of all curves.
      std::vector<cv::Point2d> flag_mag, flag_phase;
      const std::vector<std::vector<double>> phases =
          options.show_phase ? panel_phases(series, orders, i, j) : std::vector<std::vector<double>>();
      // Magnitude-only series (a band's envelopes) first, so that the lines they bound
      // are drawn over them, not hidden where the band is tight; colours stay by index.
      std::vector<std::size_t> draw_order;
      for (std::size_t s = 0; s < series.size(); ++s)
        if (!series[s].show_phase) draw_order.push_back(s);
      for (std::size_t s = 0; s < series.size(); ++s)
        if (series[s].show_phase) draw_order.push_back(s);
      for (const std::size_t s : draw_order) {
        const FrequencyResponse& r = series[s].response;
        const std::vector<Complex> h = channel(r, orders[s], i, j);
        const std::vector<double> phase = options.show_phase ? phases[s] : std::vector<double>(h.size(), kNaN);
        std::vector<cv::Point2d> mag_pts, phase_pts;
        for (std::size_t k = 0; k < h.size(); ++k) {
          const std::size_t src = orders[s][k];
          const double x =
              axes.frequency.to_px(display_frequency(r.omega_rad_s[static_cast<Index>(src)], options));
          if (!finite(h[k])) {  // NaN / inf: break the line
            mag_pts.emplace_back(kNaN, kNaN);
            phase_pts.emplace_back(kNaN, kNaN);
            continue;
          }
          const double mag = std::abs(h[k]);
          if (mag == 0.0) continue;  // -inf dB: skip the point
          const cv::Point2d pm(x, axes.magnitude_db.to_px(20.0 * std::log10(mag)));
          const cv::Point2d pp(x, axes.phase_deg.to_px(phase[k]));
          mag_pts.push_back(pm);
          phase_pts.push_back(pp);
          if (!r.flagged.empty() && r.flagged[src]) {
            flag_mag.push_back(pm);
            flag_phase.push_back(pp);
          }
        }
        const cv::Scalar color = plot::series_color(s);
        draw_curve(image, axes.magnitude_px, mag_pts, color, series[s].style);
        if (options.show_phase && series[s].show_phase)
          draw_curve(image, axes.phase_px, phase_pts, color, series[s].style);
      }
      for (const cv::Point2d& q : flag_mag) {
        plot::draw_marker(image, q, plot::Marker::kCross, plot::kFlagColor, kFlagSize,
                          axes.magnitude_px);
      }
      for (const cv::Point2d& q : flag_phase) {
        plot::draw_marker(image, q, plot::Marker::kCross, plot::kFlagColor, kFlagSize,
                          axes.phase_px);
      }

      // Frames and ticks over the curves.
      plot::draw_frame(image, axes.magnitude_px);
      plot::draw_y_tick_labels(image, axes.magnitude_px, axes.magnitude_db, m_ticks);
      const cv::Rect& bottom_axes = options.show_phase ? axes.phase_px : axes.magnitude_px;
      if (options.show_phase) {
        plot::draw_frame(image, axes.phase_px);
        plot::draw_y_tick_labels(image, axes.phase_px, axes.phase_deg, p_ticks);
        // Tick marks (no labels) on the magnitude axes' bottom edge.
        std::vector<Tick> marks = f_ticks;
        for (Tick& t : marks) t.label.clear();
        plot::draw_x_tick_labels(image, axes.magnitude_px, axes.frequency, marks);
      }
      std::vector<Tick> bottom_ticks = f_ticks;
      if (i + 1 < p) {
        for (Tick& t : bottom_ticks) t.label.clear();  // labels on the bottom row only
      }
      plot::draw_x_tick_labels(image, bottom_axes, axes.frequency, bottom_ticks);

      if (j == 0) {
        const double x = kMargin + kYLabelWidth / 2.0;
        plot::put_text_vertical(image, "Magnitude [dB]",
                                {x, axes.magnitude_px.y + axes.magnitude_px.height / 2.0},
                                plot::label_text());
        if (options.show_phase) {
          plot::put_text_vertical(image, "Phase [deg]",
                                  {x, axes.phase_px.y + axes.phase_px.height / 2.0},
                                  plot::label_text());
        }
      }
    }
  }

  // Frequency label centred under the grid, then the legend.
  const BodeAxes& last = layout.panel(p - 1, m - 1);
  const BodeAxes& first_panel = layout.panel(p - 1, 0);
  const cv::Rect& bottom = options.show_phase ? last.phase_px : last.magnitude_px;
  const double grid_center = (first_panel.magnitude_px.x + last.magnitude_px.br().x) / 2.0;
  plot::put_text(image, options.frequency_in_hz ? "Frequency [Hz]" : "Frequency [rad/s]",
                 {grid_center, bottom.br().y + kXTickHeight + 4.0}, plot::label_text(),
                 HAlign::kCenter, VAlign::kTop);
  plot::draw_legend(image, legend_entries(series), layout.legend_px.tl(),
                    image.cols - 2 * kMargin);
  return image;
}

std::vector<unsigned char> bode_png(const std::vector<BodeSeries>& series,
                                    const BodePlotOptions& options) {
  return plot::encode_png(render_bode(series, options));
}

}  // namespace lpvid
