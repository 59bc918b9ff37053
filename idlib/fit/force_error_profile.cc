// lpvid — the force-error fit with its shape parameters (idlib/fit/force_error.h,
// fit_force_error; docs/math.md §9b).  Every other parameter enters the force balance
// linearly and is solved exactly by the bounded least squares of force_error.cc; a
// shape parameter — a Stribeck velocity scale v_s (its regressor exp(−(q'/v_s)²) sign q'),
// an input's limit w_max (the applied input clip(w, ±w_max)), a ripple's period p (its
// regressors sin and cos of 2π q/p) — is found by a profile search: the linear fit at
// each trial value, the cost n_eff ln RSS.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/fit/force_error.h"
#include "idlib/fit/force_error_detail.h"

namespace lpvid {
namespace {

using force_error_detail::fit_with_fixed_shape;

// The profile's cost at the model's current values: n_eff ln RSS (−2 log-likelihood up
// to a constant, the residual's variance profiled out).
double profile_cost(const PhysicalModel& m, const ForceErrorData& d) {
  const ForceErrorFit f = fit_with_fixed_shape(m, d);
  return f.n_eff * std::log(std::max(f.rss, 1e-300));
}

// The median and the largest of |x| over the entries above `floor`.
std::pair<double, double> median_and_largest(const Eigen::VectorXd& x, double floor) {
  std::vector<double> a;
  a.reserve(static_cast<std::size_t>(x.size()));
  for (Index k = 0; k < x.size(); ++k)
    if (std::abs(x(k)) > floor) a.push_back(std::abs(x(k)));
  if (a.empty()) return {0.0, 0.0};
  const double largest = *std::max_element(a.begin(), a.end());
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
  return {a[a.size() / 2], largest};
}

// The search range of a shape parameter, within its bounds:
//  - a Stribeck velocity scale: from twice the speed the log resolves (v_eps) to the
//    median speed of the moving samples (a Stribeck curve is a low-speed effect: a scale
//    above most of the motion would make it Coulomb friction);
//  - an input's limit: from the median |w| to the largest (a drive saturating more than
//    half of the time is not at a limit but out of its range; at the largest nothing is
//    clipped: the edge says the log shows no saturation);
//  - a ripple's period: from one kernel length at the median speed to a third of the
//    travel (force_error_detail::ripple_grid).
std::pair<double, double> search_range(const ForceErrorData& d, const force_error_detail::ShapeParameter& s,
                                       const PhysicalParameter& q) {
  double lo = 0.0, hi = 0.0;
  if (s.kind == force_error_detail::ShapeParameter::Kind::kStribeckScale) {
    lo = 2.0 * d.v_eps(s.channel);
    hi = median_and_largest(d.v_raw.col(s.channel), d.v_eps(s.channel)).first;
  } else if (s.kind == force_error_detail::ShapeParameter::Kind::kRipplePeriod) {
    const force_error_detail::RippleGrid g = force_error_detail::ripple_grid(d, s.channel);
    lo = g.period_min, hi = g.period_max;  // lo >= hi when the travel holds no three periods
  } else {
    std::tie(lo, hi) = median_and_largest(d.w_log.col(s.channel), 0.0);
  }
  return {std::max(lo, q.lower), std::min(hi, q.upper)};
}

// Every stride-th row of d (the rows' own samples, so each term is what the full set has
// there): the profile search's data on a long log.
ForceErrorData every_nth_row(const ForceErrorData& d, Index stride) {
  ForceErrorData s = d;
  const Index n = (d.n() + stride - 1) / stride;
  auto pick = [&](const Eigen::MatrixXd& m) {
    Eigen::MatrixXd out(n, m.cols());
    for (Index r = 0; r < n; ++r) out.row(r) = m.row(r * stride);
    return out;
  };
  s.q = pick(d.q);
  s.qd = pick(d.qd);
  s.qdd = pick(d.qdd);
  s.w = pick(d.w);
  s.sign_v = pick(d.sign_v);
  s.sample.resize(n);
  for (Index r = 0; r < n; ++r) s.sample(r) = d.sample(r * stride);
  return s;
}

using force_error_detail::RippleGrid;
using force_error_detail::ShapeParameter;
constexpr int kGrid = 16, kGolden = 14, kCycles = 2;
// On a long log the search runs on every stride-th row (at most kSearchRows; the optimum
// of a 10⁵-row profile lies within its own standard error of the full one's), the final
// fit and the curvature on every row.
constexpr Index kSearchRows = 100000;

// The profile search over a model's free shape parameters: each held while the others
// and the linear parameters are fitted, moved in turn (twice when there are several).
class ProfileSearch {
 public:
  ProfileSearch(const PhysicalModel& start, const ForceErrorData& d, std::vector<ShapeParameter> shapes);
  void run() {
    for (int cycle = 0; cycle < (scales_.size() > 1 ? kCycles : 1); ++cycle)
      for (std::size_t j = 0; j < scales_.size(); ++j)
        if (shapes_[j].kind == ShapeParameter::Kind::kRipplePeriod)
          search_ripple(j, cycle);
        else
          search_grid(j);
  }
  ForceErrorFit finish();

 private:
  double cost_at(std::size_t j, double log_v) {
    inner_.parameters[static_cast<std::size_t>(scales_[j])].value = std::exp(log_v);
    return profile_cost(inner_, *on_);
  }
  std::pair<double, double> golden(std::size_t j, double lo, double hi, int iterations);
  void search_grid(std::size_t j);
  void search_ripple(std::size_t j, int cycle);
  ForceErrorParameter shape_estimate(std::size_t j, const PhysicalParameter& q);
  void say_undetermined(ForceErrorFit& fit) const;

  const PhysicalModel& start_;
  const ForceErrorData& d_;
  std::vector<ShapeParameter> shapes_;
  std::vector<Index> scales_;
  PhysicalModel inner_;  // the shape parameters held (not free) at their current values
  std::vector<std::pair<double, double>> range_;
  std::vector<RippleGrid> grids_;
  ForceErrorData sub_;
  const ForceErrorData* on_ = nullptr;
};

ProfileSearch::ProfileSearch(const PhysicalModel& start, const ForceErrorData& d, std::vector<ShapeParameter> shapes)
    : start_(start), d_(d), shapes_(std::move(shapes)), inner_(start) {
  for (const auto& sp : shapes_) scales_.push_back(sp.param);
  for (const Index v : scales_) inner_.parameters[static_cast<std::size_t>(v)].free = false;
  range_.resize(scales_.size());
  for (std::size_t j = 0; j < scales_.size(); ++j) {
    const PhysicalParameter& q = start.parameters[static_cast<std::size_t>(scales_[j])];
    range_[j] = search_range(d, shapes_[j], q);
    using Kind = ShapeParameter::Kind;
    const Kind kind = shapes_[j].kind;
    if (!(range_[j].second > range_[j].first))
      throw InputError(fmt::format(
          "{}: the log leaves no range to search (from {:.3g} to {:.3g}: {}); fix it at a known value (lpvid model "
          "set --model MODEL.json --set {}=VALUE --fix {}) or {}",
          q.name, range_[j].first, range_[j].second,
          kind == Kind::kStribeckScale  ? "the moving speeds"
          : kind == Kind::kInputLimit ? "the command's sizes"
                                      : "the shortest period the smoothing passes at the median speed, and a third "
                                        "of the travel",
          q.name, q.name,
          kind == Kind::kStribeckScale ? "log a slower motion"
          : kind == Kind::kInputLimit  ? "log a command that varies"
                                       : "log a longer travel or give a shorter --window-s"));
  }
  if (d.n() > kSearchRows) sub_ = every_nth_row(d, (d.n() + kSearchRows - 1) / kSearchRows);
  on_ = d.n() > kSearchRows ? &sub_ : &d;
  grids_.resize(scales_.size());
  for (std::size_t j = 0; j < scales_.size(); ++j)
    if (shapes_[j].kind == ShapeParameter::Kind::kRipplePeriod)
      grids_[j] = force_error_detail::ripple_grid(*on_, shapes_[j].channel);
}

// Golden section of cost_at(j, ·) over [lo, hi]: the best point and its cost.
std::pair<double, double> ProfileSearch::golden(std::size_t j, double lo, double hi, int iterations) {
  const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = hi - phi * (hi - lo), x2 = lo + phi * (hi - lo);
  double f1 = cost_at(j, x1), f2 = cost_at(j, x2);
  for (int it = 0; it < iterations; ++it) {
    if (f1 <= f2) {
      hi = x2, x2 = x1, f2 = f1;
      x1 = hi - phi * (hi - lo), f1 = cost_at(j, x1);
    } else {
      lo = x1, x1 = x2, f1 = f2;
      x2 = lo + phi * (hi - lo), f2 = cost_at(j, x2);
    }
  }
  return f1 <= f2 ? std::make_pair(x1, f1) : std::make_pair(x2, f2);
}

// A log-spaced grid over the range, then golden section inside the best grid cell pair.
void ProfileSearch::search_grid(std::size_t j) {
  const double a = std::log(range_[j].first), b = std::log(range_[j].second);
  std::vector<double> grid(kGrid), cost(kGrid);
  for (int g = 0; g < kGrid; ++g) {
    grid[static_cast<std::size_t>(g)] = a + (b - a) * g / (kGrid - 1);
    cost[static_cast<std::size_t>(g)] = cost_at(j, grid[static_cast<std::size_t>(g)]);
  }
  const auto best = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  auto [x, fx] = golden(j, grid[static_cast<std::size_t>(std::max(best - 1, 0))],
                        grid[static_cast<std::size_t>(std::min(best + 1, kGrid - 1))], kGolden);
  if (cost[static_cast<std::size_t>(best)] < fx) x = grid[static_cast<std::size_t>(best)];
  inner_.parameters[static_cast<std::size_t>(scales_[j])].value = std::exp(x);
}

// A ripple's period: the cost is a comb in the period (a peak per candidate period, each
// about 1/travel wide in spatial frequency), so a log-spaced grid would miss it.  The
// first cycle reads the periodogram of the residual without this ripple over position
// (four lines per peak width) and refines its three highest peaks, each within a line
// either side (coarsely, then the best in full); a later cycle refines the period it
// holds within a line either side.
void ProfileSearch::search_ripple(std::size_t j, int cycle) {
  const RippleGrid& g = grids_[j];
  const Index ch = shapes_[j].channel;
  auto cell = [&](double f) {  // ln p over [f − step, f + step] within the grid
    const double f_lo = std::max(f - g.step, g.first), f_hi = std::min(f + g.step, 1.0 / g.period_min);
    return std::make_pair(-std::log(f_hi), -std::log(f_lo));
  };
  std::vector<double> centres;
  if (cycle == 0) {
    PhysicalModel without = inner_;
    // the ripple effect this period belongs to (position_ripple or position_ripple_2)
    const std::string& period_name = start_.parameters[static_cast<std::size_t>(scales_[j])].name;
    const EffectInfo* effect = nullptr;
    for (const std::string& name : start_.effects)
      for (const PhysicalParameter& q : start_.effect_info(name)->parameters)
        if (q.name == period_name) effect = start_.effect_info(name);
    LPVID_ASSERT(effect != nullptr);
    const std::vector<PhysicalParameter>& own = effect->parameters;
    const Index nd = static_cast<Index>(own.size() / 3);  // a, b per DOF, then the periods
    for (const Index k : {ch, nd + ch}) {
      PhysicalParameter& amplitude =
          without.parameters[static_cast<std::size_t>(without.index_of(own[static_cast<std::size_t>(k)].name))];
      amplitude.value = 0.0;
      amplitude.free = false;
    }
    const ForceErrorFit f0 =
        without.free_indices().empty() ? evaluate_force_error(without, *on_) : fit_with_fixed_shape(without, *on_);
    const Eigen::VectorXd power = force_error_detail::ripple_periodogram(*on_, ch, f0.residual.col(ch), g);
    for (const Index k : force_error_detail::periodogram_peaks(power, 3))
      centres.push_back(g.first + static_cast<double>(k) * g.step);
  }
  if (centres.empty()) centres.push_back(1.0 / inner_.parameters[static_cast<std::size_t>(scales_[j])].value);
  // several peaks: each to a twentieth of its cell first (6 steps), the best then in full
  double best_x = 0.0, best_f = std::numeric_limits<double>::infinity(), best_c = 0.0;
  for (const double f : centres) {
    const auto [lo, hi] = cell(f);
    const auto [x, fx] = golden(j, lo, hi, centres.size() > 1 ? 6 : kGolden);
    if (fx < best_f) best_x = x, best_f = fx, best_c = f;
  }
  if (centres.size() > 1) {
    const auto [lo, hi] = cell(best_c);
    const auto [x, fx] = golden(j, lo, hi, kGolden);
    if (fx < best_f) best_x = x;
  }
  inner_.parameters[static_cast<std::size_t>(scales_[j])].value = std::exp(best_x);
}

// Shape parameter j at the optimum q: its standard error from the profile's curvature in
// ln x (var ≈ 2 / (d²cost/d(ln x)²)), on its bound when on the search range's edge.
ForceErrorParameter ProfileSearch::shape_estimate(std::size_t j, const PhysicalParameter& q) {
  const bool ripple = shapes_[j].kind == ShapeParameter::Kind::kRipplePeriod;
  // (a ripple's cost is a narrow peak in the period: a tenth of a periodogram line)
  const double x = std::log(q.value), h = ripple ? 0.1 * grids_[j].step * q.value : 0.05;
  const double c0 = cost_at(j, x), cp = cost_at(j, x + h), cm = cost_at(j, x - h);
  inner_.parameters[static_cast<std::size_t>(scales_[j])].value = q.value;
  const double curvature = (cp - 2.0 * c0 + cm) / (h * h);
  ForceErrorParameter e;
  e.name = q.name;
  e.unit = q.unit;
  e.value = q.value;
  e.std_error = curvature > 0.0 ? q.value * std::sqrt(2.0 / curvature) : std::numeric_limits<double>::quiet_NaN();
  // on the search range's edge: within 1 % of its width (the golden section closes in on
  // an edge without reaching it); a ripple's period within half a line of it
  const double a = std::log(range_[j].first), b = std::log(range_[j].second), edge = 0.01 * (b - a);
  e.at_bound = ripple ? x <= a + 0.5 * grids_[j].step * range_[j].first || x >= b - 0.5 * grids_[j].step * range_[j].second
                      : x <= a + edge || x >= b - edge;
  return e;
}

// A Stribeck force that ends at zero leaves its scale undetermined; a limit on the range's
// top edge (the largest command) clips nothing.
void ProfileSearch::say_undetermined(ForceErrorFit& fit) const {
  for (std::size_t j = 0; j < shapes_.size(); ++j) {
    const ForceErrorParameter* e = nullptr;
    for (const auto& x : fit.parameters)
      if (x.name == start_.parameters[static_cast<std::size_t>(shapes_[j].param)].name) e = &x;
    if (shapes_[j].kind == ShapeParameter::Kind::kRipplePeriod) continue;
    if (shapes_[j].kind == ShapeParameter::Kind::kInputLimit) {
      if (e != nullptr && e->at_bound &&
          std::log(e->value) > 0.5 * (std::log(range_[j].first) + std::log(range_[j].second)))
        fit.unidentifiable.push_back(fmt::format(
            "{} ends at the largest command ({:.4g}): the log shows no saturation, so the limit is not determined",
            e->name, e->value));
      continue;
    }
    // the effect's parameters: F_s per DOF, then v_s per DOF
    const std::string& force =
        start_.effect_info("stribeck_friction")->parameters[static_cast<std::size_t>(shapes_[j].channel)].name;
    for (const auto& x : fit.parameters)
      if (x.name == force && x.at_bound && x.value == 0.0)
        fit.unidentifiable.push_back(fmt::format(
            "{} ends at zero: the Stribeck velocity scale beside it is not determined by this log", force));
  }
}

// The fit at the optimum, with the shape parameters free again (BIC counting them), the
// parameters in model order.
ForceErrorFit ProfileSearch::finish() {
  on_ = &d_;
  ForceErrorFit fit = fit_with_fixed_shape(inner_, d_);
  for (const Index v : scales_) fit.model.parameters[static_cast<std::size_t>(v)].free = true;
  fit.bic += static_cast<double>(scales_.size()) * std::log(fit.n_eff);
  std::vector<ForceErrorParameter> ordered;
  for (const Index idx : start_.free_indices()) {
    const PhysicalParameter& q = fit.model.parameters[static_cast<std::size_t>(idx)];
    const auto it = std::find(scales_.begin(), scales_.end(), idx);
    if (it == scales_.end()) {
      for (const auto& e : fit.parameters)
        if (e.name == q.name) ordered.push_back(e);
      continue;
    }
    ordered.push_back(shape_estimate(static_cast<std::size_t>(it - scales_.begin()), q));
  }
  fit.parameters = ordered;
  say_undetermined(fit);
  return fit;
}

}  // namespace

ForceErrorFit fit_force_error(const PhysicalModel& start, const ForceErrorData& d) {
  std::vector<ShapeParameter> shapes;
  for (const auto& sp : force_error_detail::shape_parameters(start))
    if (start.parameters[static_cast<std::size_t>(sp.param)].free) shapes.push_back(sp);
  if (shapes.empty()) return fit_with_fixed_shape(start, d);
  ProfileSearch search(start, d, std::move(shapes));
  search.run();
  return search.finish();
}

}  // namespace lpvid
