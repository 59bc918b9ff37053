// lpvid — the force-error fit with its shape parameters (idlib/fit/force_error.h,
// fit_force_error; docs/math.md §9b).  Every other parameter enters the force balance
// linearly and is solved exactly by the bounded least squares of force_error.cc; a
// shape parameter — a Stribeck velocity scale v_s (its regressor exp(−(q'/v_s)²) sign q'),
// an input's limit w_max (the applied input clip(w, ±w_max)) — is found by a profile
// search: the linear fit at each trial value, the cost n_eff ln RSS.
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
//    clipped: the edge says the log shows no saturation).
std::pair<double, double> search_range(const ForceErrorData& d, const force_error_detail::ShapeParameter& s,
                                       const PhysicalParameter& q) {
  double lo = 0.0, hi = 0.0;
  if (s.kind == force_error_detail::ShapeParameter::Kind::kStribeckScale) {
    lo = 2.0 * d.v_eps(s.channel);
    hi = median_and_largest(d.v_raw.col(s.channel), d.v_eps(s.channel)).first;
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

}  // namespace

ForceErrorFit fit_force_error(const PhysicalModel& start, const ForceErrorData& d) {
  std::vector<force_error_detail::ShapeParameter> shapes;
  for (const auto& sp : force_error_detail::shape_parameters(start))
    if (start.parameters[static_cast<std::size_t>(sp.param)].free) shapes.push_back(sp);
  if (shapes.empty()) return fit_with_fixed_shape(start, d);
  std::vector<Index> scales;
  for (const auto& sp : shapes) scales.push_back(sp.param);

  // Held during the profile search, each moved in turn (twice when there are several)
  PhysicalModel inner = start;
  for (const Index v : scales) inner.parameters[static_cast<std::size_t>(v)].free = false;
  std::vector<std::pair<double, double>> range(scales.size());
  for (std::size_t j = 0; j < scales.size(); ++j) {
    const PhysicalParameter& q = start.parameters[static_cast<std::size_t>(scales[j])];
    range[j] = search_range(d, shapes[j], q);
    if (!(range[j].second > range[j].first))
      throw InputError(fmt::format(
          "{}: the log leaves no range to search (from {:.3g} to {:.3g}: {}); fix it at a known value (lpvid model "
          "set --model MODEL.json --set {}=VALUE --fix {}) or {}",
          q.name, range[j].first, range[j].second, q.name, q.name,
          shapes[j].kind == force_error_detail::ShapeParameter::Kind::kStribeckScale ? "the moving speeds"
                                                                                     : "the command's sizes",
          shapes[j].kind == force_error_detail::ShapeParameter::Kind::kStribeckScale ? "log a slower motion"
                                                                                     : "log a command that varies"));
  }
  constexpr int kGrid = 16, kGolden = 14, kCycles = 2;
  // On a long log the search runs on every stride-th row (at most kSearchRows; the
  // optimum of a 10⁵-row profile lies within its own standard error of the full one's),
  // the final fit and the curvature on every row.
  constexpr Index kSearchRows = 100000;
  ForceErrorData sub;
  if (d.n() > kSearchRows) sub = every_nth_row(d, (d.n() + kSearchRows - 1) / kSearchRows);
  const ForceErrorData* on = d.n() > kSearchRows ? &sub : &d;
  auto cost_at = [&](std::size_t j, double log_v) {
    inner.parameters[static_cast<std::size_t>(scales[j])].value = std::exp(log_v);
    return profile_cost(inner, *on);
  };
  for (int cycle = 0; cycle < (scales.size() > 1 ? kCycles : 1); ++cycle)
    for (std::size_t j = 0; j < scales.size(); ++j) {
      const double a = std::log(range[j].first), b = std::log(range[j].second);
      std::vector<double> grid(kGrid), cost(kGrid);
      for (int g = 0; g < kGrid; ++g) {
        grid[static_cast<std::size_t>(g)] = a + (b - a) * g / (kGrid - 1);
        cost[static_cast<std::size_t>(g)] = cost_at(j, grid[static_cast<std::size_t>(g)]);
      }
      const auto best = static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
      double lo = grid[static_cast<std::size_t>(std::max(best - 1, 0))];
      double hi = grid[static_cast<std::size_t>(std::min(best + 1, kGrid - 1))];
      // golden section inside the best grid cell pair
      const double phi = 0.5 * (std::sqrt(5.0) - 1.0);
      double x1 = hi - phi * (hi - lo), x2 = lo + phi * (hi - lo);
      double f1 = cost_at(j, x1), f2 = cost_at(j, x2);
      for (int it = 0; it < kGolden; ++it) {
        if (f1 <= f2) {
          hi = x2, x2 = x1, f2 = f1;
          x1 = hi - phi * (hi - lo), f1 = cost_at(j, x1);
        } else {
          lo = x1, x1 = x2, f1 = f2;
          x2 = lo + phi * (hi - lo), f2 = cost_at(j, x2);
        }
      }
      double x = f1 <= f2 ? x1 : x2, fx = std::min(f1, f2);
      if (cost[static_cast<std::size_t>(best)] < fx) x = grid[static_cast<std::size_t>(best)];
      inner.parameters[static_cast<std::size_t>(scales[j])].value = std::exp(x);
    }

  // The fit at the optimum, with the shape parameters free again: their standard errors
  // from the profile's curvature in ln x (var ≈ 2 / (d²cost/d(ln x)²)), BIC counting them
  on = &d;
  ForceErrorFit fit = fit_with_fixed_shape(inner, d);
  for (const Index v : scales) fit.model.parameters[static_cast<std::size_t>(v)].free = true;
  fit.bic += static_cast<double>(scales.size()) * std::log(fit.n_eff);
  std::vector<ForceErrorParameter> ordered;
  for (const Index idx : start.free_indices()) {
    const PhysicalParameter& q = fit.model.parameters[static_cast<std::size_t>(idx)];
    const auto it = std::find(scales.begin(), scales.end(), idx);
    if (it == scales.end()) {
      for (const auto& e : fit.parameters)
        if (e.name == q.name) ordered.push_back(e);
      continue;
    }
    const std::size_t j = static_cast<std::size_t>(it - scales.begin());
    const double x = std::log(q.value), h = 0.05;
    const double c0 = cost_at(j, x), cp = cost_at(j, x + h), cm = cost_at(j, x - h);
    inner.parameters[static_cast<std::size_t>(idx)].value = q.value;
    const double curvature = (cp - 2.0 * c0 + cm) / (h * h);
    ForceErrorParameter e;
    e.name = q.name;
    e.unit = q.unit;
    e.value = q.value;
    e.std_error = curvature > 0.0 ? q.value * std::sqrt(2.0 / curvature) : std::numeric_limits<double>::quiet_NaN();
    // on the search range's edge: within 1 % of its width (the golden section closes in
    // on an edge without reaching it)
    const double a = std::log(range[j].first), b = std::log(range[j].second), edge = 0.01 * (b - a);
    e.at_bound = x <= a + edge || x >= b - edge;
    ordered.push_back(e);
  }
  fit.parameters = ordered;
  // A Stribeck force that ends at zero leaves its scale undetermined; a limit on the
  // range's top edge (the largest command) clips nothing
  for (std::size_t j = 0; j < shapes.size(); ++j) {
    const ForceErrorParameter* e = nullptr;
    for (const auto& x : fit.parameters)
      if (x.name == start.parameters[static_cast<std::size_t>(shapes[j].param)].name) e = &x;
    if (shapes[j].kind == force_error_detail::ShapeParameter::Kind::kInputLimit) {
      if (e != nullptr && e->at_bound && std::log(e->value) > 0.5 * (std::log(range[j].first) + std::log(range[j].second)))
        fit.unidentifiable.push_back(fmt::format(
            "{} ends at the largest command ({:.4g}): the log shows no saturation, so the limit is not determined",
            e->name, e->value));
      continue;
    }
    // the effect's parameters: F_s per DOF, then v_s per DOF
    const std::string& force =
        start.effect_info("stribeck_friction")->parameters[static_cast<std::size_t>(shapes[j].channel)].name;
    for (const auto& x : fit.parameters)
      if (x.name == force && x.at_bound && x.value == 0.0)
        fit.unidentifiable.push_back(fmt::format(
            "{} ends at zero: the Stribeck velocity scale beside it is not determined by this log", force));
  }
  return fit;
}

}  // namespace lpvid
