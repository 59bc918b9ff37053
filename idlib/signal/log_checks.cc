#include "idlib/signal/log_checks.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace lpvid {
namespace {

// The next level below the rail is within this fraction of the channel's range.
constexpr double kNearRail = 0.05;
// The rail holds at least this many times the samples of the three levels below it.
constexpr double kPileUp = 3.0;
constexpr double kBandLevels = 3.0;

// The saturation rule of log_checks.h on one side: sign +1 the maximum, −1 the minimum.
bool saturated(const Eigen::Ref<const Eigen::VectorXd>& x, double sign, double range, ChannelFinding& f) {
  const Index N = x.size();
  double rail = -std::numeric_limits<double>::infinity();
  for (Index t = 0; t < N; ++t) rail = std::max(rail, sign * x(t));
  double next = -std::numeric_limits<double>::infinity();
  Index at_rail = 0, run = 0, longest = 0, first = -1, last = -1;
  for (Index t = 0; t < N; ++t) {
    const double v = sign * x(t);
    if (v == rail) {
      ++at_rail;
      ++run;
      longest = std::max(longest, run);
      if (first < 0) first = t;
      last = t;
    } else {
      run = 0;
      next = std::max(next, v);
    }
  }
  if (at_rail < kMinSaturatedSamples || longest < 2) return false;
  if (!std::isfinite(next) || rail - next > kNearRail * range) return false;
  // A smooth extremum of a quantised signal (a parabola through the top levels) spends as
  // long at its top level as in the three below it (√4 − 1 = 1 top level's time), and 2.4x
  // as long as at the next one alone: a finely quantised encoder at the turning points of
  // a slow sine was called clipped by a next-level rule (8 samples against 2 on the
  // sample's two-sine log).  A clip piles up at the rail and crosses the levels below fast.
  const double band = kBandLevels * (rail - next);
  Index in_band = 0;
  for (Index t = 0; t < N; ++t) {
    const double v = sign * x(t);
    in_band += v < rail && rail - v <= band * (1.0 + 1e-9);
  }
  if (static_cast<double>(at_rail) < kPileUp * static_cast<double>(in_band)) return false;
  f.first_row = first;
  f.last_row = last;
  f.samples = at_rail;
  f.longest_run = longest;
  f.value = sign * rail;
  return true;
}

// The dwell rule of log_checks.h: within the rail runs of x (steps t−1 → t both at the
// rail), some other column of the context that varies over the log holds its value at
// least kDwellShare of those steps.
bool designed_dwell(const Eigen::Ref<const Eigen::VectorXd>& x, double rail, const Eigen::MatrixXd& context) {
  std::vector<Index> steps;
  for (Index t = 1; t < x.size(); ++t)
    if (x(t) == rail && x(t - 1) == rail) steps.push_back(t);
  if (steps.empty() || context.rows() != x.size()) return false;
  for (Index c = 0; c < context.cols(); ++c) {
    const auto y = context.col(c);
    if (y == x || !(y.maxCoeff() > y.minCoeff())) continue;  // the channel itself, or a constant column
    Index held = 0;
    for (const Index t : steps) held += y(t) == y(t - 1);
    if (static_cast<double>(held) >= kDwellShare * static_cast<double>(steps.size())) return true;
  }
  return false;
}

}  // namespace

std::vector<ChannelFinding> inspect_channels(const Eigen::Ref<const Eigen::MatrixXd>& data,
                                             const Eigen::MatrixXd* context) {
  std::vector<ChannelFinding> out;
  const Index N = data.rows();
  if (N < 8) return out;
  for (Index c = 0; c < data.cols(); ++c) {
    const auto x = data.col(c);
    const double range = x.maxCoeff() - x.minCoeff();
    if (!(range > 0.0) || !std::isfinite(range)) continue;
    for (const double sign : {1.0, -1.0}) {
      ChannelFinding f;
      f.kind = sign > 0 ? ChannelFinding::Kind::kSaturatedHigh : ChannelFinding::Kind::kSaturatedLow;
      f.channel = c;
      if (saturated(x, sign, range, f) && !(context != nullptr && designed_dwell(x, f.value, *context)))
        out.push_back(f);
    }
    // The least-squares line a + b s over s = t − (N − 1)/2 (centred: a = mean, b = Σ s x / Σ s²).
    const double half = 0.5 * static_cast<double>(N - 1);
    const double mean = x.mean();
    double sx = 0.0, ss = 0.0;
    for (Index t = 0; t < N; ++t) {
      const double s = static_cast<double>(t) - half;
      sx += s * (x(t) - mean);
      ss += s * s;
    }
    const double b = sx / ss;
    double resid = 0.0;
    for (Index t = 0; t < N; ++t) {
      const double e = x(t) - mean - b * (static_cast<double>(t) - half);
      resid += e * e;
    }
    const double rms = std::sqrt(resid / static_cast<double>(N));
    const double change = b * static_cast<double>(N - 1);
    if (N >= kMinDriftSamples && rms > 0.0 && std::abs(change) > kDriftRatio * rms) {
      ChannelFinding f;
      f.kind = ChannelFinding::Kind::kDrift;
      f.channel = c;
      f.first_row = 0;
      f.last_row = N - 1;
      f.value = change;
      f.ratio = std::abs(change) / rms;
      out.push_back(f);
    }
  }
  return out;
}

std::string describe_finding(const ChannelFinding& f, const std::string& name) {
  switch (f.kind) {
    case ChannelFinding::Kind::kSaturatedHigh:
    case ChannelFinding::Kind::kSaturatedLow:
      return fmt::format(
          "channel {} sits at its {} {:.6g} in {} samples (rows {}..{}, runs of up to {}): clipped (a saturated sensor, "
          "amplifier or actuator), or a designed dwell at that value; the methods take it as logged (a clipped "
          "stretch is not the linear plant's response: cut it out, or re-run below the limit)",
          name, f.kind == ChannelFinding::Kind::kSaturatedHigh ? "maximum" : "minimum", f.value, f.samples,
          f.first_row + 1, f.last_row + 1, f.longest_run);
    case ChannelFinding::Kind::kDrift:
      return fmt::format(
          "channel {} drifts by {:.4g} over the record (rows 1..{}), {:.1f} times its rms about that trend: a drift, "
          "or a slow or integrating response; the methods fit an offset, not a trend (remove the trend if it is not "
          "the plant's, or log longer)",
          name, f.value, f.last_row + 1, f.ratio);
  }
  return {};
}

}  // namespace lpvid
