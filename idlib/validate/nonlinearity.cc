#include "idlib/validate/nonlinearity.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/signal/correlation.h"
#include "idlib/validate/time_fit.h"

namespace lpvid {

namespace {

constexpr Index kMinSegments = 8;
constexpr Index kSegmentLags = 16;  // each segment at least 16 L samples
constexpr Index kLinearLags = 10;   // K: the features are made orthogonal to ŷ(t−K..t+K)

// Student's t quantile from the normal one (Abramowitz & Stegun 26.7.5, four terms).
double t_quantile_from_normal(double z, double nu) {
  const double z2 = z * z, z3 = z2 * z, z5 = z3 * z2, z7 = z5 * z2, z9 = z7 * z2;
  const double g1 = (z3 + z) / 4.0;
  const double g2 = (5 * z5 + 16 * z3 + 3 * z) / 96.0;
  const double g3 = (3 * z7 + 19 * z5 + 17 * z3 - 15 * z) / 384.0;
  const double g4 = (79 * z9 + 776 * z7 + 1482 * z5 - 1920 * z3 - 945 * z) / 92160.0;
  return z + g1 / nu + g2 / (nu * nu) + g3 / (nu * nu * nu) + g4 / (nu * nu * nu * nu);
}

}  // namespace

void NonlinearityOptions::validate() const {
  if (max_lag < 0) throw InputError(fmt::format("nonlinearity tests: max_lag {} must be >= 0", max_lag));
  if (segments < kMinSegments)
    throw InputError(fmt::format("nonlinearity tests: segments {} must be >= {}", segments, kMinSegments));
  if (!(confidence > 0.0 && confidence < 1.0))
    throw InputError(fmt::format("nonlinearity tests: confidence {} must be in (0, 1)", confidence));
}

NonlinearityResult nonlinearity_tests(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& simulated,
                                      const NonlinearityOptions& options) {
  options.validate();
  if (residual.rows() != simulated.rows() || residual.cols() != simulated.cols())
    throw InputError(fmt::format("nonlinearity tests: the residual is {} x {} but the simulation {} x {}",
                                 residual.rows(), residual.cols(), simulated.rows(), simulated.cols()));
  if (!residual.allFinite() || !simulated.allFinite())
    throw InputError("nonlinearity tests: the residual or the simulation holds NaN or Inf");
  NonlinearityResult out;
  const Index N = residual.rows(), p = residual.cols(), L = options.max_lag;
  const Index S = std::min(options.segments, N / std::max<Index>(1, kSegmentLags * std::max<Index>(L, 1)));
  if (S < kMinSegments || p == 0) {
    out.reason = fmt::format("not tested: {} samples do not make {} segments of {} samples", N, kMinSegments,
                             kSegmentLags * std::max<Index>(L, 1));
    return out;
  }
  // The features, three per simulated output, each orthogonalised against the linear span
  // of that output's simulation over lags −K..K (and a constant): whatever a linear filter
  // of ŷ can hold — a linear model error, for any signal distribution (Bussgang alone is
  // exact only for a Gaussian ŷ; a reference trajectory is not).
  const char* names[3] = {"sign of the rate", "square", "cube"};
  Eigen::MatrixXd F(N, 3 * p);
  for (Index j = 0; j < p; ++j) {
    const Eigen::VectorXd y = simulated.col(j);
    Eigen::VectorXd rate(N);
    for (Index t = 0; t + 1 < N; ++t) rate(t) = y(t + 1) - y(t);
    rate(N - 1) = N > 1 ? rate(N - 2) : 0.0;
    const Eigen::VectorXd sign = rate.unaryExpr([](double v) { return v > 0 ? 1.0 : v < 0 ? -1.0 : 0.0; });
    const Eigen::VectorXd yc = y.array() - y.mean();
    Eigen::MatrixXd raw(N, 3);
    raw.col(0) = sign;
    raw.col(1) = yc.array().square();
    raw.col(2) = yc.array().cube();
    // Least squares by the normal equations, the regressor rows streamed (no N × (2K + 2)
    // matrix held), solved by a complete orthogonal decomposition: the lags of a slow ŷ are
    // nearly collinear, and only the projection matters, not the coefficients.
    const Index q = 2 * kLinearLags + 2;
    const auto regressors = [&](Index t, Eigen::VectorXd& x) {
      x(0) = 1.0;
      for (Index k = -kLinearLags; k <= kLinearLags; ++k) x(k + kLinearLags + 1) = yc(std::clamp<Index>(t + k, 0, N - 1));
    };
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(q, q), Xr = Eigen::MatrixXd::Zero(q, 3);
    Eigen::VectorXd x(q);
    for (Index t = 0; t < N; ++t) {
      regressors(t, x);
      G.selfadjointView<Eigen::Lower>().rankUpdate(x);
      Xr.noalias() += x * raw.row(t);
    }
    G.triangularView<Eigen::StrictlyUpper>() = G.transpose();
    const Eigen::MatrixXd beta = G.completeOrthogonalDecomposition().solve(Xr);
    for (Index t = 0; t < N; ++t) {
      regressors(t, x);
      F.block(t, 3 * j, 1, 3) = raw.row(t) - x.transpose() * beta;
    }
  }
  const Eigen::MatrixXd e = residual.rowwise() - residual.colwise().mean();

  const Index Ns = N / S, lags = 2 * L + 1, k = F.cols();
  // sum and sum of squares over segments of r_s(τ), per (i, f, τ)
  std::vector<Eigen::MatrixXd> sum(static_cast<std::size_t>(lags), Eigen::MatrixXd::Zero(p, k)), sum2 = sum;
  for (Index s = 0; s < S; ++s) {
    const auto es = e.middleRows(s * Ns, Ns);
    const auto Fs = F.middleRows(s * Ns, Ns);
    // each segment's own correlation coefficient: bounded, so a segment with a rare large
    // excursion (a cube's tail) does not dominate the spread
    const Eigen::VectorXd ne = es.colwise().norm().transpose(), nf = Fs.colwise().norm().transpose();
    const auto Ref = cross_correlation(es, Fs, L);  // [τ](i, f) = Σ e(t+τ) F(t)
    const auto Rfe = cross_correlation(Fs, es, L);  // [τ](f, i) = Σ F(t+τ) e(t) = R_eF(−τ)
    for (Index tau = -L; tau <= L; ++tau) {
      const Eigen::MatrixXd R = tau >= 0 ? Ref[static_cast<std::size_t>(tau)]
                                         : Eigen::MatrixXd(Rfe[static_cast<std::size_t>(-tau)].transpose());
      Eigen::MatrixXd r(p, k);
      for (Index i = 0; i < p; ++i)
        for (Index f = 0; f < k; ++f)
          r(i, f) = ne(i) > 0 && nf(f) > 0 ? R(i, f) / (ne(i) * nf(f)) : 0.0;
      sum[static_cast<std::size_t>(tau + L)] += r;
      sum2[static_cast<std::size_t>(tau + L)] += r.cwiseAbs2();
    }
  }
  const double m = static_cast<double>(lags * k * p);
  const double z = standard_normal_quantile(1.0 - (1.0 - options.confidence) / (2.0 * m));
  out.ran = true;
  out.segments = S;
  out.threshold = t_quantile_from_normal(z, static_cast<double>(S - 1));
  for (Index i = 0; i < p; ++i)
    for (Index f = 0; f < k; ++f) {
      NonlinearityTest best;
      best.residual_channel = i;
      best.feature_channel = f / 3;
      best.feature = names[f % 3];
      for (Index at = 0; at < lags; ++at) {
        const double mean = sum[static_cast<std::size_t>(at)](i, f) / static_cast<double>(S);
        const double var = (sum2[static_cast<std::size_t>(at)](i, f) - static_cast<double>(S) * mean * mean) /
                           static_cast<double>(S - 1);
        const double t = var > 0 ? mean / std::sqrt(var / static_cast<double>(S)) : 0.0;
        if (std::abs(t) > std::abs(best.t)) {
          best.t = t;
          best.r = mean;
          best.lag = static_cast<int>(at - L);
        }
      }
      out.tests.push_back(best);
    }
  for (std::size_t q = 0; q < out.tests.size(); ++q)
    if (std::abs(out.tests[q].t) > out.threshold) out.significant.push_back(static_cast<Index>(q));
  std::sort(out.significant.begin(), out.significant.end(), [&](Index a, Index b) {
    return std::abs(out.tests[static_cast<std::size_t>(a)].t) > std::abs(out.tests[static_cast<std::size_t>(b)].t);
  });
  return out;
}

std::string nonlinearity_sentence(const NonlinearityResult& r, const std::vector<std::string>& names) {
  if (!r.ran) return r.reason;
  const auto name = [&](Index i) {
    return i < static_cast<Index>(names.size()) ? names[static_cast<std::size_t>(i)] : fmt::format("output {}", i + 1);
  };
  if (r.significant.empty())
    return fmt::format("none seen: the residual is uncorrelated with the sign of each simulated output's rate, its "
                       "square and its cube within their spread over {} segments (|t| <= {:.2f})",
                       r.segments, r.threshold);
  std::vector<std::string> parts;
  for (std::size_t q = 0; q < std::min<std::size_t>(3, r.significant.size()); ++q) {
    const NonlinearityTest& t = r.tests[static_cast<std::size_t>(r.significant[q])];
    parts.push_back(fmt::format("the residual of {} follows the {} of {} (r {:.2f} at lag {}, t {:.1f})",
                                name(t.residual_channel), t.feature, name(t.feature_channel), t.r, t.lag, t.t));
  }
  const NonlinearityTest& top = r.tests[static_cast<std::size_t>(r.significant.front())];
  const std::string what = top.feature == std::string("sign of the rate")
                               ? "friction-like: a force that flips with the velocity"
                           : top.feature == std::string("square") ? "an even nonlinearity: one-sided or gap-dependent"
                                                                  : "an odd nonlinearity: a stiffening or softening";
  return fmt::format("SEEN: {} (|t| > {:.2f} over {} segments); {}: a linear model of these logs is their best "
                     "linear approximation, not the plant's linear part, and no linear model can follow this",
                     fmt::format("{}", fmt::join(parts, "; ")), r.threshold, r.segments, what);
}

}  // namespace lpvid
