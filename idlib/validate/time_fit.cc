#include "idlib/validate/time_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"
#include "idlib/signal/correlation.h"

namespace lpvid {
namespace {

void require_finite(const Eigen::MatrixXd& m, const char* what) {
  if (!m.allFinite()) throw InputError(fmt::format("time-domain fit: the {} holds NaN or Inf", what));
}

void require_same_shape(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols())
    throw InputError(fmt::format("time-domain fit: measured is {} × {} but predicted is {} × {}; they must match",
                                 a.rows(), a.cols(), b.rows(), b.cols()));
  if (a.rows() < 2) throw InputError("time-domain fit: fewer than 2 samples");
}

Eigen::MatrixXd centred(const Eigen::MatrixXd& x) { return x.rowwise() - x.colwise().mean(); }

void finish(CorrelationTest& t, double z_lag, double z_family, double scale) {
  t.bound_per_lag = z_lag * scale;
  t.bound = z_family * scale;
  t.worst_ratio = 0.0;
  t.lags_outside_per_lag_bound = 0;
  for (Index i = 0; i < t.r.size(); ++i) {
    const double a = std::abs(t.r(i));
    if (a > t.bound_per_lag) ++t.lags_outside_per_lag_bound;
    const double ratio = t.bound > 0 ? a / t.bound : std::numeric_limits<double>::infinity();
    if (ratio > t.worst_ratio) {
      t.worst_ratio = ratio;
      t.worst_lag = t.lags(i);
    }
  }
  t.pass = t.worst_ratio <= 1.0;
}

void check_lag(Index N, const TimeFitOptions& options) {
  options.validate();
  if (N < options.max_lag + 2)
    throw InputError(fmt::format("time-domain fit: {} samples for max_lag = {}; give at least max_lag + 2 samples", N,
                                 options.max_lag));
}

}  // namespace

void TimeFitOptions::validate() const {
  if (max_lag < 1) throw InputError(fmt::format("time-domain fit: max_lag = {}; it must be >= 1", max_lag));
  if (!(confidence > 0.0 && confidence < 1.0))
    throw InputError(fmt::format("time-domain fit: confidence = {}; it must be in (0, 1), e.g. 0.99", confidence));
  if (!std::isfinite(window_s) || !(window_s > 0.0))
    throw InputError(fmt::format("time-domain fit: window_s = {}; it must be finite and > 0 (seconds)", window_s));
  if (!std::isfinite(window_threshold_percent) || !(window_threshold_percent > 0.0))
    throw InputError(fmt::format("time-domain fit: window threshold = {} %; it must be finite and > 0",
                                 window_threshold_percent));
  if (!std::isfinite(noise_factor) || !(noise_factor > 0.0))
    throw InputError(fmt::format("time-domain fit: noise_factor = {}; it must be finite and > 0", noise_factor));
}

double standard_normal_quantile(double p) {
  if (!(p > 0.0 && p < 1.0)) throw InputError(fmt::format("normal quantile: p = {}; it must be in (0, 1)", p));
  // Φ(z) = erfc(-z/√2)/2 is increasing; bisect on [-40, 40] to double precision.
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200 && hi - lo > 1e-14; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p)
      lo = mid;
    else
      hi = mid;
  }
  return 0.5 * (lo + hi);
}

Eigen::VectorXd nrmse_fit_percent(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted) {
  require_same_shape(measured, predicted);
  require_finite(measured, "measurement");
  require_finite(predicted, "prediction");
  Eigen::VectorXd fit(measured.cols());
  for (Index i = 0; i < measured.cols(); ++i) {
    const double err = (measured.col(i) - predicted.col(i)).norm();
    const double spread = (measured.col(i).array() - measured.col(i).mean()).matrix().norm();
    if (spread > 0.0)
      fit(i) = 100.0 * (1.0 - err / spread);
    else
      fit(i) = err == 0.0 ? 100.0 : -std::numeric_limits<double>::infinity();
  }
  return fit;
}

std::vector<CorrelationTest> residual_whiteness(const Eigen::MatrixXd& residual, const TimeFitOptions& options) {
  const Index N = residual.rows(), L = options.max_lag;
  check_lag(N, options);
  require_finite(residual, "residual");
  const Eigen::MatrixXd e = centred(residual);
  const auto R = autocorrelation(e, L);
  const double z_lag = standard_normal_quantile(0.5 * (1.0 + options.confidence));
  const double z_fam = standard_normal_quantile(1.0 - (1.0 - options.confidence) / (2.0 * static_cast<double>(L)));
  std::vector<CorrelationTest> out;
  for (Index i = 0; i < e.cols(); ++i) {
    CorrelationTest t;
    t.channel = i;
    t.lags.resize(L);
    t.r.resize(L);
    const double r0 = R[0](i, i);
    for (Index k = 1; k <= L; ++k) {
      t.lags(k - 1) = static_cast<int>(k);
      t.r(k - 1) = r0 > 0 ? R[k](i, i) / r0 : 0.0;
    }
    finish(t, z_lag, z_fam, 1.0 / std::sqrt(static_cast<double>(N)));
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<CorrelationTest> residual_input_correlation(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& input,
                                                        const TimeFitOptions& options) {
  const Index N = residual.rows(), L = options.max_lag;
  if (input.rows() != N)
    throw InputError(fmt::format("time-domain fit: the residual has {} samples but the input {}; they must match", N,
                                 input.rows()));
  check_lag(N, options);
  require_finite(residual, "residual");
  require_finite(input, "input");
  std::vector<CorrelationTest> out;
  if (input.cols() == 0) return out;
  const Eigen::MatrixXd e = centred(residual), u = centred(input);
  const auto Ree = autocorrelation(e, L), Ruu = autocorrelation(u, L);
  const auto Reu = cross_correlation(e, u, L);  // [τ](i,j) = Σ e(t+τ,i) u(t,j)
  const auto Rue = cross_correlation(u, e, L);  // [τ](j,i) = Σ u(t+τ,j) e(t,i) = R_eu(-τ)(i,j)
  const Index m = 2 * L + 1;
  const double z_lag = standard_normal_quantile(0.5 * (1.0 + options.confidence));
  const double z_fam = standard_normal_quantile(1.0 - (1.0 - options.confidence) / (2.0 * static_cast<double>(m)));
  for (Index i = 0; i < e.cols(); ++i) {
    for (Index j = 0; j < u.cols(); ++j) {
      const double ee = Ree[0](i, i), uu = Ruu[0](j, j);
      if (!(uu > 0.0)) continue;  // not excited
      CorrelationTest t;
      t.channel = i;
      t.input = j;
      t.lags.resize(m);
      t.r.resize(m);
      const double norm = ee > 0 ? 1.0 / std::sqrt(ee * uu) : 0.0;
      double P = 1.0;  // k = 0 term: r_ee(0) r_uu(0) = 1
      for (Index k = 1; k <= L; ++k) P += 2.0 * (ee > 0 ? Ree[k](i, i) / ee : 0.0) * (Ruu[k](j, j) / uu);
      P = std::max(P, 1.0 / static_cast<double>(m));  // guard: a finite-sample P can dip below its true value
      for (Index k = -L; k <= L; ++k) {
        const Index at = k + L;
        t.lags(at) = static_cast<int>(k);
        t.r(at) = norm * (k >= 0 ? Reu[k](i, j) : Rue[-k](j, i));
      }
      finish(t, z_lag, z_fam, std::sqrt(P / static_cast<double>(N)));
      out.push_back(std::move(t));
    }
  }
  return out;
}

std::vector<FailingWindow> failing_windows(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted,
                                           double start_s, double sample_period_s, const TimeFitOptions& options) {
  options.validate();
  require_same_shape(measured, predicted);
  if (!std::isfinite(sample_period_s) || !(sample_period_s > 0.0) || !std::isfinite(start_s))
    throw InputError(fmt::format("time-domain fit: sample period {} s, start {} s; give a finite positive period",
                                 sample_period_s, start_s));
  const Index N = measured.rows();
  const Index W = std::min(N, std::max<Index>(2, std::llround(options.window_s / sample_period_s)));
  const Index step = std::max<Index>(1, W / 2);
  std::vector<Index> starts;
  for (Index s = 0; s + W < N; s += step) starts.push_back(s);
  starts.push_back(N - W);
  std::vector<FailingWindow> out;
  for (Index i = 0; i < measured.cols(); ++i) {
    const double spread = std::sqrt((measured.col(i).array() - measured.col(i).mean()).square().mean());
    // Prefix sums of e² make each window O(1).
    Eigen::VectorXd cum(N + 1);
    cum(0) = 0.0;
    for (Index k = 0; k < N; ++k) {
      const double e = measured(k, i) - predicted(k, i);
      cum(k + 1) = cum(k) + e * e;
    }
    double diff2 = 0.0;
    for (Index k = 1; k < N; ++k) {
      const double d = (measured(k, i) - predicted(k, i)) - (measured(k - 1, i) - predicted(k - 1, i));
      diff2 += d * d;
    }
    const double noise_floor = std::sqrt(diff2 / (2.0 * static_cast<double>(N - 1)));
    bool open = false;
    FailingWindow cur;
    for (const Index s : starts) {
      const double rms = std::sqrt(std::max(0.0, cum(s + W) - cum(s)) / static_cast<double>(W));
      const double size = spread > 0 ? 100.0 * rms / spread : (rms > 0 ? std::numeric_limits<double>::infinity() : 0.0);
      const double t0 = start_s + static_cast<double>(s) * sample_period_s;
      const double t1 = start_s + static_cast<double>(s + W - 1) * sample_period_s;
      if (size > options.window_threshold_percent && rms > options.noise_factor * noise_floor) {
        if (open && t0 <= cur.t_end_s) {
          cur.t_end_s = t1;
          cur.size_percent = std::max(cur.size_percent, size);
        } else {
          if (open) out.push_back(cur);
          cur = {i, t0, t1, size};
          open = true;
        }
      }
    }
    if (open) out.push_back(cur);
  }
  return out;
}

TimeFitResult time_fit(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted, const Eigen::MatrixXd& input,
                       double start_s, double sample_period_s, const TimeFitOptions& options,
                       const Eigen::MatrixXd& test_predicted) {
  TimeFitResult r;
  r.fit_percent = nrmse_fit_percent(measured, predicted);
  r.residual = measured - predicted;
  const Index N = measured.rows();
  r.noise_floor.resize(measured.cols());
  r.fit_ceiling_percent.resize(measured.cols());
  for (Index i = 0; i < measured.cols(); ++i) {
    const auto e = r.residual.col(i);
    r.noise_floor(i) = std::sqrt((e.tail(N - 1) - e.head(N - 1)).squaredNorm() / (2.0 * static_cast<double>(N - 1)));
    const double spread = std::sqrt((measured.col(i).array() - measured.col(i).mean()).square().mean());
    r.fit_ceiling_percent(i) = spread > 0 ? 100.0 * (1.0 - r.noise_floor(i) / spread) : 0.0;
  }
  Eigen::MatrixXd test_residual;
  if (test_predicted.size() > 0) {
    require_same_shape(measured, test_predicted);
    require_finite(test_predicted, "prediction for the residual tests");
    test_residual = measured - test_predicted;
  }
  const Eigen::MatrixXd& e = test_predicted.size() > 0 ? test_residual : r.residual;
  r.whiteness = residual_whiteness(e, options);
  r.cross = residual_input_correlation(e, input, options);
  r.failures = failing_windows(measured, predicted, start_s, sample_period_s, options);
  return r;
}

}  // namespace lpvid
