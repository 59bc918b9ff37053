// lpvid — the force-error fit with Stribeck friction's velocity scales (idlib/fit/force_error.h,
// fit_force_error; docs/math.md §9b).  Every other parameter enters the force balance
// linearly and is solved exactly by the bounded least squares of force_error.cc; a free
// velocity scale v_s shapes its regressor, exp(−(q'/v_s)²) sign q', and is found by a
// profile search: the linear fit at each trial v_s, the cost n_eff ln RSS.
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

// The search range of DOF i's velocity scale: from twice the speed the log resolves
// (v_eps) to the median speed of its moving samples (a Stribeck curve is a low-speed
// effect: a scale above most of the motion would make it Coulomb friction), within the
// parameter's bounds.
std::pair<double, double> search_range(const ForceErrorData& d, Index i, const PhysicalParameter& q) {
  std::vector<double> speed;
  speed.reserve(static_cast<std::size_t>(d.v_raw.rows()));
  for (Index k = 0; k < d.v_raw.rows(); ++k)
    if (std::abs(d.v_raw(k, i)) > d.v_eps(i)) speed.push_back(std::abs(d.v_raw(k, i)));
  double hi = 0.0;
  if (!speed.empty()) {
    std::nth_element(speed.begin(), speed.begin() + static_cast<std::ptrdiff_t>(speed.size() / 2), speed.end());
    hi = speed[speed.size() / 2];
  }
  const double lo = std::max(2.0 * d.v_eps(i), q.lower);
  hi = std::min(hi, q.upper);
  return {lo, hi};
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
  std::vector<Index> scales;
  for (const Index v : force_error_detail::stribeck_scales(start))
    if (start.parameters[static_cast<std::size_t>(v)].free) scales.push_back(v);
  if (scales.empty()) return fit_with_fixed_shape(start, d);

  // Held during the profile search, each moved in turn (DOF by DOF, twice)
  PhysicalModel inner = start;
  for (const Index v : scales) inner.parameters[static_cast<std::size_t>(v)].free = false;
  const std::vector<Index> all = force_error_detail::stribeck_scales(start);
  std::vector<std::pair<double, double>> range(scales.size());
  for (std::size_t j = 0; j < scales.size(); ++j) {
    const Index dof = static_cast<Index>(std::find(all.begin(), all.end(), scales[j]) - all.begin());
    range[j] = search_range(d, dof, start.parameters[static_cast<std::size_t>(scales[j])]);
    if (!(range[j].second > range[j].first))
      throw InputError(fmt::format("{}: the log's moving speeds leave no range to search (from {:.3g} to {:.3g}); fix "
                                   "it at a known value (lpvid model set --fix) or log a slower motion",
                                   start.parameters[static_cast<std::size_t>(scales[j])].name, range[j].first,
                                   range[j].second));
  }
  constexpr int kGrid = 16, kGolden = 14, kCycles = 2;
  // On a long log the search runs on every stride-th row (at most kSearchRows; the
  // optimum of a 10⁵-row profile lies within its own standard error of the full one's),
  // the final fit and the curvature on every row.
  constexpr Index kSearchRows = 100000;
  const ForceErrorData sub = d.n() > kSearchRows ? every_nth_row(d, (d.n() + kSearchRows - 1) / kSearchRows) : d;
  const ForceErrorData* on = &sub;
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

  // The fit at the optimum, with the velocity scales free again: their standard errors
  // from the profile's curvature in ln v_s (var ≈ 2 / (d²cost/d(ln v)²)), BIC counting them
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
  // A Stribeck force that ends at zero leaves its scale undetermined
  for (const auto& e : fit.parameters)
    if (e.at_bound && e.value == 0.0 && e.name.rfind("stribeck_", 0) == 0)
      fit.unidentifiable.push_back(fmt::format(
          "{} ends at zero: the Stribeck velocity scale beside it is not determined by this log", e.name));
  return fit;
}

}  // namespace lpvid
