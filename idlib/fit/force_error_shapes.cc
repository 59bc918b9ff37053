// lpvid — the force-error route's terms whose shape depends on a parameter
// (idlib/fit/force_error.h; docs/math.md §9b): the Stribeck regressor at a velocity scale
// v_s, an input clipped at its limit w_max, and a ripple's sine and cosine at a period p
// with the periodogram over position that seeds p's search.  Each is built from the log's
// unsmoothed signal and smoothed by the route's kernel like every term.
#include <algorithm>
#include <cmath>
#include <vector>

#include "idlib/fit/force_error_detail.h"

namespace lpvid::force_error_detail {

using Eigen::VectorXd;

namespace {

// k ∗ s at each kept row of d, s's entry j being the log's sample `offset` + j: a profile
// search on a subsample of the rows pays for those rows alone.
VectorXd smoothed_at_rows(const ForceErrorData& d, const VectorXd& s, Index offset) {
  const Index half = (d.kernel.size() - 1) / 2;
  VectorXd out(d.n());
  for (Index r = 0; r < d.n(); ++r) out(r) = d.kernel.dot(s.segment(d.sample(r) - offset - half, d.kernel.size()));
  return out;
}

double median_of(std::vector<double> a) {
  if (a.empty()) return 0.0;
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
  return a[a.size() / 2];
}

}  // namespace

VectorXd stribeck_regressor(const ForceErrorData& d, Index i, double v_s) {
  const VectorXd v = d.v_raw.col(i);
  VectorXd s(v.size());
  for (Index k = 0; k < v.size(); ++k) {
    const double x = v(k) / v_s;
    s(k) = std::clamp(v(k) / d.v_eps(i), -1.0, 1.0) * std::exp(-x * x);
  }
  return smoothed_at_rows(d, s, d.kernel_reach);  // s(j) is sample H + j
}

VectorXd saturated_input(const ForceErrorData& d, Index j, double limit) {
  VectorXd c = d.w_log.col(j).cwiseMax(-limit).cwiseMin(limit);
  if (d.held_input)
    for (Index k = c.size() - 1; k > 0; --k) c(k) = 0.5 * (c(k) + c(k - 1));
  return smoothed_at_rows(d, c, 0);
}

std::pair<VectorXd, VectorXd> ripple_regressors(const ForceErrorData& d, Index i, double period) {
  const VectorXd q = d.q_raw.col(i);
  const double w = 2.0 * M_PI / period;
  VectorXd s(q.size()), c(q.size());
  // (sincos: one argument reduction for both, measured 1.6x faster than sin and cos on a
  // 10⁶-sample log, where they were most of the ripple's profile search)
  for (Index k = 0; k < q.size(); ++k) ::sincos(w * q(k), &s(k), &c(k));
  return {smoothed_at_rows(d, s, 0), smoothed_at_rows(d, c, 0)};
}

RippleGrid ripple_grid(const ForceErrorData& d, Index i) {
  RippleGrid g;
  const VectorXd q = d.q.col(i);
  g.travel = q.size() > 0 ? q.maxCoeff() - q.minCoeff() : 0.0;
  std::vector<double> moving;
  for (Index k = 0; k < d.v_raw.rows(); ++k)
    if (std::abs(d.v_raw(k, i)) > d.v_eps(i)) moving.push_back(std::abs(d.v_raw(k, i)));
  g.median_speed = median_of(moving);
  // Longest: three periods over the travel (fewer is a slow force along the travel, not a
  // ripple).  Shortest: one period per kernel length at the median speed (a shorter one
  // is smoothed away at most speeds: the Hann kernel's first zero is at 2 / its length)
  // and 20x the position noise.
  g.period_max = g.travel / 3.0;
  g.period_min = std::max({g.median_speed * static_cast<double>(d.window) * d.sample_period_s, 20.0 * d.q_noise(i),
                           1e-12});
  if (!(g.period_max > g.period_min)) return g;
  // The spatial frequencies 1/period_max .. 1/period_min, four lines per 1/travel (a peak's
  // width), at most kMaxLines (then the shortest periods are dropped)
  constexpr Index kMaxLines = 2000;
  g.step = 1.0 / (4.0 * g.travel);
  g.first = 1.0 / g.period_max;
  g.lines = std::min<Index>(kMaxLines, static_cast<Index>(std::floor((1.0 / g.period_min - g.first) / g.step)) + 1);
  g.period_min = 1.0 / (g.first + static_cast<double>(g.lines - 1) * g.step);
  return g;
}

VectorXd ripple_periodogram(const ForceErrorData& d, Index i, const VectorXd& residual, const RippleGrid& g) {
  VectorXd out = VectorXd::Zero(g.lines);
  if (g.lines <= 0 || residual.size() != d.n()) return out;
  // Per line: the share of the residual's sum of squares (about its mean) that its
  // least-squares fit by a sin(2 pi f q) + b cos(2 pi f q) + c explains — the floating
  // mean, so that a constant force missing (an offset: the positions are not spread
  // evenly over the periods) is not read as a ripple.  On the smoothed position (the
  // kernel passes these periods), each row's phase advanced line by line by a rotation;
  // on at most kRows rows (every stride-th).
  constexpr Index kRows = 50000;
  const Index stride = std::max<Index>(1, (d.n() + kRows - 1) / kRows);
  std::vector<double> ss(static_cast<std::size_t>(g.lines), 0.0), cc(ss), sc(ss), rs(ss), rc(ss), s1(ss), c1(ss);
  double rr = 0.0, r1 = 0.0, count = 0.0;
  for (Index r = 0; r < d.n(); r += stride) {
    const double q = d.q(r, i), e = residual(r);
    rr += e * e;
    r1 += e;
    count += 1.0;
    double s = std::sin(2.0 * M_PI * g.first * q), c = std::cos(2.0 * M_PI * g.first * q);
    const double ds = std::sin(2.0 * M_PI * g.step * q), dc = std::cos(2.0 * M_PI * g.step * q);
    for (std::size_t k = 0; k < ss.size(); ++k) {
      ss[k] += s * s;
      cc[k] += c * c;
      sc[k] += s * c;
      rs[k] += e * s;
      rc[k] += e * c;
      s1[k] += s;
      c1[k] += c;
      const double s2 = s * dc + c * ds;
      c = c * dc - s * ds;
      s = s2;
    }
  }
  rr -= r1 * r1 / count;
  if (!(rr > 0.0)) return out;
  for (std::size_t k = 0; k < ss.size(); ++k) {
    ss[k] -= s1[k] * s1[k] / count;
    cc[k] -= c1[k] * c1[k] / count;
    sc[k] -= s1[k] * c1[k] / count;
    rs[k] -= r1 * s1[k] / count;
    rc[k] -= r1 * c1[k] / count;
    const double det = ss[k] * cc[k] - sc[k] * sc[k];
    if (!(det > 1e-12 * ss[k] * cc[k])) continue;
    const double explained = (cc[k] * rs[k] * rs[k] - 2.0 * sc[k] * rs[k] * rc[k] + ss[k] * rc[k] * rc[k]) / det;
    out(static_cast<Index>(k)) = explained / rr;
  }
  return out;
}

std::vector<Index> periodogram_peaks(const VectorXd& power, Index count) {
  std::vector<Index> peaks;
  for (Index k = 0; k < power.size(); ++k) {
    const bool left = k == 0 || power(k) >= power(k - 1), right = k + 1 == power.size() || power(k) >= power(k + 1);
    if (left && right && power(k) > 0.0) peaks.push_back(k);
  }
  std::sort(peaks.begin(), peaks.end(), [&](Index a, Index b) { return power(a) > power(b); });
  if (static_cast<Index>(peaks.size()) > count) peaks.resize(static_cast<std::size_t>(count));
  return peaks;
}

double periodogram_median(const VectorXd& power) {
  return median_of(std::vector<double>(power.data(), power.data() + power.size()));
}

}  // namespace lpvid::force_error_detail
