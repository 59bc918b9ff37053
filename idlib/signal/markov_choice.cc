// lpvid — choosing between Markov estimates: the truncation test and the held-out
// comparison (markov.h).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/signal/markov.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

MarkovTail markov_tail(const MarkovResult& r, const std::vector<Index>& record_lengths) {
  MarkovTail t;
  const Index L = static_cast<Index>(r.g.size()) - 1;
  if (L < 1 || r.noise_std.size() == 0 || !(r.noise_std.minCoeff() > 0.0) || record_lengths.empty()) return t;
  const Index m = r.noise_std.cols();
  double total = 0.0;
  for (const Index n : record_lengths) total += static_cast<double>(n);
  t.lags = std::min(L + 1, std::max<Index>(8, (L + 1 + 9) / 10));
  double s = 0.0, mean = 0.0, var = 0.0;
  const double entries = static_cast<double>(r.noise_std.size());
  for (Index k = L + 1 - t.lags; k <= L; ++k) {
    s += r.g[static_cast<std::size_t>(k)].cwiseQuotient(r.noise_std).squaredNorm();
    double reach = -static_cast<double>(m * (L + 1));
    for (const Index n : record_lengths) reach += static_cast<double>(std::max<Index>(n - k, 0));
    const double rk = reach > 0.0 ? total / reach : std::numeric_limits<double>::infinity();
    mean += entries * rk;
    var += 2.0 * entries * rk * rk;
  }
  if (!std::isfinite(mean)) return t;  // too few samples reach the last lags to judge them
  t.energy_ratio = s / mean;
  t.truncated = s > mean + 5.0 * std::sqrt(var);
  return t;
}

namespace {

// Σ over t in [t0, t1) of the residual of g as a finite impulse response, e(t) = q(t) −
// Σ_k g[k] v(t − k) with the record's whole excitation history (zero before its start),
// about its mean over [t0, t1) (an offset per half): per output.
Eigen::VectorXd held_out_energy(const ExperimentView& x, const MarkovSequence& g, Index t0, Index t1) {
  using signal_detail::ChannelView;
  const Index n = x.output.rows(), p = x.output.cols();
  std::vector<ChannelView> vs, qs;
  // Columns of an Eigen::Ref may not be contiguous: copy (one record, once per estimate).
  const Eigen::MatrixXd v = x.excitation, q = x.output;
  for (Index a = 0; a < v.cols(); ++a) vs.push_back({v.col(a).data(), 0.0, true});
  for (Index i = 0; i < p; ++i) qs.push_back({q.col(i).data(), 0.0, true});
  Eigen::VectorXd s1 = Eigen::VectorXd::Zero(p), s2 = Eigen::VectorXd::Zero(p);
  signal_detail::for_each_fir_residual_block(vs, qs, n, g, [&](Index i, Index b0, Index b1, const double* e) {
    for (Index t = std::max(b0, t0); t < std::min(b1, t1); ++t) {
      s1(i) += e[t - b0];
      s2(i) += e[t - b0] * e[t - b0];
    }
  });
  return (s2.array() - s1.array().square() / static_cast<double>(t1 - t0)).max(0.0).matrix();
}

}  // namespace

MarkovHeldOut markov_held_out_error(const std::vector<ExperimentView>& experiments, const MarkovOptions& options) {
  LPVID_ASSERT(!experiments.empty());
  std::vector<ExperimentView> first, second;
  Index shortest = experiments.front().output.rows(), total = 0;
  for (const ExperimentView& x : experiments) {
    const Index n = x.output.rows(), h = n / 2;
    first.push_back({x.excitation.topRows(h), x.output.topRows(h)});
    second.push_back({x.excitation.bottomRows(n - h), x.output.bottomRows(n - h)});
    shortest = std::min(shortest, h);
    total += h;
  }
  MarkovHeldOut out;
  const Index m = experiments.front().excitation.cols(), p = experiments.front().output.cols();
  out.lags = std::min({options.num_lags, shortest / 4, total / (4 * m)});
  if (out.lags < kMinDefaultMarkovLags)
    throw InputError(fmt::format("held-out Markov comparison: halves of {} samples support only {} lags, fewer than "
                                 "{}",
                                 shortest, out.lags, kMinDefaultMarkovLags));
  MarkovOptions o = options;
  o.num_lags = out.lags;
  o.initial_guess.clear();
  MarkovResult on_first = estimate_markov(first, o), on_second = estimate_markov(second, o);
  Index longest = 0;
  for (const ExperimentView& x : experiments) longest = std::max(longest, x.output.rows());
  for (MarkovResult* r : {&on_first, &on_second}) {
    const Eigen::VectorXd& a = r->arx_denominator;
    if (a.size() == 0) continue;
    while (static_cast<Index>(r->g.size()) < longest) {  // beyond lag n: g[k] = Σ_j a_j g[k − j]
      Eigen::MatrixXd gk = Eigen::MatrixXd::Zero(p, m);
      for (Index j = 1; j <= a.size(); ++j) gk += a(j - 1) * r->g[r->g.size() - static_cast<std::size_t>(j)];
      r->g.push_back(std::move(gk));
    }
  }
  Eigen::VectorXd residual = Eigen::VectorXd::Zero(p), energy = Eigen::VectorXd::Zero(p);
  for (const ExperimentView& x : experiments) {
    const Index n = x.output.rows(), h = n / 2;
    residual += held_out_energy(x, on_first.g, h, n) + held_out_energy(x, on_second.g, 0, h);
    for (const auto& [t0, t1] : {std::pair<Index, Index>{0, h}, std::pair<Index, Index>{h, n}}) {
      const Eigen::MatrixXd q = x.output.middleRows(t0, t1 - t0);
      energy += (q.rowwise() - q.colwise().mean()).colwise().squaredNorm().transpose();
    }
  }
  out.relative_error = (residual.array() / energy.array().max(1e-300)).mean();
  return out;
}

}  // namespace lpvid
