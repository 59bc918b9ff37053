#include "idlib/signal/noise_spectrum.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <memory>

#include "idlib/core/error.h"
#include "idlib/core/parallel.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

namespace {

void check_experiments(const char* what, const std::vector<ExperimentView>& experiments, Index p, Index m,
                       Index min_samples, const std::vector<Eigen::MatrixXd>& output_correction) {
  if (!output_correction.empty() && output_correction.size() != experiments.size())
    throw InputError(fmt::format("{}: one output correction per experiment, or none", what));
  for (std::size_t e = 0; e < experiments.size(); ++e) {
    const auto& x = experiments[e];
    if (x.excitation.cols() != m || x.output.cols() != p || x.excitation.rows() != x.output.rows())
      throw InputError(fmt::format("{}: experiment {} is not {} inputs and {} outputs over one record", what, e, m, p));
    if (x.excitation.rows() < min_samples)
      throw InputError(fmt::format("{}: experiment {} has {} samples, fewer than a segment of {}", what, e,
                                   x.excitation.rows(), min_samples));
    if (!output_correction.empty() &&
        (output_correction[e].rows() != x.output.rows() || output_correction[e].cols() != p))
      throw InputError(fmt::format("{}: the correction of experiment {} is not {} x {}", what, e, x.output.rows(), p));
  }
}
}  // namespace

void fir_residual(const ExperimentView& ex, const MarkovSequence& g, const Eigen::MatrixXd* correction,
                  Eigen::MatrixXd& e) {
  if (g.empty() || g.front().rows() != ex.output.cols() || g.front().cols() != ex.excitation.cols() ||
      ex.excitation.rows() != ex.output.rows())
    throw InputError("FIR residual: g and the experiment's channels or lengths do not match");
  if (correction != nullptr && (correction->rows() != ex.output.rows() || correction->cols() != ex.output.cols()))
    throw InputError("FIR residual: the correction is not the shape of the output");
  using signal_detail::ChannelView;
  const Index n = ex.excitation.rows(), m = ex.excitation.cols(), p = ex.output.cols();
  std::vector<ChannelView> vs, qs;
  for (Index a = 0; a < m; ++a) {
    const double* d = ex.excitation.data() + a * ex.excitation.outerStride();
    bool active = false;
    for (Index t = 0; t < n && !active; ++t) active = d[t] != d[0];
    vs.push_back({d, 0.0, active});  // a constant column counts as zero (as in estimate_markov)
  }
  for (Index i = 0; i < p; ++i) qs.push_back({ex.output.data() + i * ex.output.outerStride(), 0.0, true});
  e.resize(n, p);
  signal_detail::for_each_fir_residual_block(vs, qs, n, g, [&](Index i, Index t0, Index t1, const double* r) {
    for (Index t = t0; t < t1; ++t) e(t, i) = r[t - t0];
  });
  if (correction != nullptr) e -= *correction;
  e.rowwise() -= e.colwise().mean();
}

std::vector<Eigen::MatrixXcd> fir_residual_spectrum(const std::vector<ExperimentView>& experiments,
                                                    const MarkovSequence& g, Index segment_length, Index num_bins,
                                                    const std::vector<Eigen::MatrixXd>& output_correction) {
  if (experiments.empty()) throw InputError("residual spectrum: no experiments");
  if (g.empty()) throw InputError("residual spectrum: no Markov parameters");
  const Index p = g.front().rows(), m = g.front().cols();
  if (segment_length < 2) throw InputError(fmt::format("residual spectrum: segment length {} < 2", segment_length));
  if (num_bins < 1 || num_bins > segment_length / 2 + 1)
    throw InputError(fmt::format("residual spectrum: {} bins asked of {}-sample segments; 1..{} are available", num_bins,
                                 segment_length, segment_length / 2 + 1));
  check_experiments("residual spectrum", experiments, p, m, segment_length, output_correction);
  const signal_detail::RealFft fft(segment_length);
  Eigen::VectorXd window(segment_length);
  for (Index t = 0; t < segment_length; ++t)
    window(t) = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(t) / static_cast<double>(segment_length));
  const double window_energy = window.squaredNorm();
  const Index hop = segment_length / 2;
  // One task per experiment (idlib/core/parallel.h), summed in experiment order.
  const Index E = static_cast<Index>(experiments.size());
  std::vector<std::vector<Eigen::MatrixXcd>> part(static_cast<std::size_t>(E));
  std::vector<Index> part_segments(static_cast<std::size_t>(E), 0);
  parallel_for(E, [&](Index x) {
    auto buf = signal_detail::alloc_real(segment_length);
    auto spec = signal_detail::alloc_complex(p * fft.bins());
    std::vector<Eigen::MatrixXcd>& psd = part[static_cast<std::size_t>(x)];
    psd.assign(static_cast<std::size_t>(num_bins), Eigen::MatrixXcd::Zero(p, p));
    const auto& ex = experiments[static_cast<std::size_t>(x)];
    const Index n = ex.excitation.rows();
    Eigen::MatrixXd e;  // residual of the experiment, N × p
    fir_residual(ex, g, output_correction.empty() ? nullptr : &output_correction[static_cast<std::size_t>(x)], e);
    for (Index s0 = 0; s0 + segment_length <= n; s0 += hop) {
      for (Index i = 0; i < p; ++i) {
        for (Index t = 0; t < segment_length; ++t) buf[t] = window(t) * e(s0 + t, i);
        fft.forward(buf.get(), spec.get() + i * fft.bins());
      }
      for (Index f = 0; f < num_bins; ++f)
        for (Index j = 0; j < p; ++j)
          for (Index i = 0; i < p; ++i)
            psd[static_cast<std::size_t>(f)](i, j) += spec[i * fft.bins() + f] * std::conj(spec[j * fft.bins() + f]);
      ++part_segments[static_cast<std::size_t>(x)];
    }
  });
  std::vector<Eigen::MatrixXcd> psd = std::move(part.front());
  Index segments = part_segments.front();
  for (Index x = 1; x < E; ++x) {
    for (Index f = 0; f < num_bins; ++f) psd[static_cast<std::size_t>(f)] += part[static_cast<std::size_t>(x)][static_cast<std::size_t>(f)];
    segments += part_segments[static_cast<std::size_t>(x)];
  }
  const double scale = 1.0 / (static_cast<double>(segments) * window_energy);
  for (auto& s : psd) s *= scale;
  return psd;
}

std::vector<std::vector<Eigen::MatrixXcd>> markov_error_replicates(const std::vector<ExperimentView>& experiments,
                                                                   const MarkovSequence& g,
                                                                   const Eigen::MatrixXd& excitation_gram,
                                                                   Index segment_length, Index num_lags, Index num_bins,
                                                                   const std::vector<Eigen::MatrixXd>& output_correction) {
  const char* what = "Markov error replicates";
  if (experiments.empty()) throw InputError(fmt::format("{}: no experiments", what));
  if (g.empty()) throw InputError(fmt::format("{}: no Markov parameters", what));
  const Index p = g.front().rows(), m = g.front().cols(), K = num_lags;
  if (K < 2) throw InputError(fmt::format("{}: num_lags = {}; at least 2 are needed", what, K));
  if (num_bins < 1 || num_bins > K / 2 + 1)
    throw InputError(fmt::format("{}: {} bins asked of a {}-point transform; 1..{} are available", what, num_bins, K,
                                 K / 2 + 1));
  if (segment_length < 1) throw InputError(fmt::format("{}: segment length {} < 1", what, segment_length));
  if (excitation_gram.rows() != m || excitation_gram.cols() != m)
    throw InputError(fmt::format("{}: excitation_gram is {}x{} for {} inputs", what, excitation_gram.rows(),
                                 excitation_gram.cols(), m));
  check_experiments(what, experiments, p, m, segment_length, output_correction);
  const Eigen::LDLT<Eigen::MatrixXd> gram(excitation_gram);
  if (gram.info() != Eigen::Success || !(gram.vectorD().minCoeff() > 0.0))
    throw InputError(fmt::format("{}: the excitation Gram matrix is singular (an input is never excited)", what));
  const Eigen::MatrixXd R0inv = gram.solve(Eigen::MatrixXd::Identity(m, m));

  const signal_detail::RealFft dft(K);
  // Tasks (idlib/core/parallel.h): the residual of each experiment, then each segment;
  // the replicates are in experiment, then segment order.
  const std::size_t E = experiments.size();
  std::vector<Eigen::MatrixXd> residual(E);
  parallel_for(static_cast<Index>(E), [&](Index x) {
    fir_residual(experiments[static_cast<std::size_t>(x)], g,
                 output_correction.empty() ? nullptr : &output_correction[static_cast<std::size_t>(x)],
                 residual[static_cast<std::size_t>(x)]);
  });
  struct Segment {
    std::size_t x;
    Index t0, t1;
    double dof_scale;
    std::vector<Index> active;
  };
  std::vector<Segment> segs;
  for (std::size_t x = 0; x < E; ++x) {
    const auto& ex = experiments[x];
    const Index n = ex.excitation.rows();
    std::vector<Index> active;
    for (Index a = 0; a < m; ++a) {
      const auto col = ex.excitation.col(a);
      if ((col.array() != col(0)).any()) active.push_back(a);
    }
    // Degrees of freedom: e is the residual of m_active (L + 1) fitted lags per output,
    // so Σ_s z_s z_sᵀ is low by (1 − m_a(L+1)/N) and R₀⁻¹ stands for E[Φ⁻¹], which is
    // higher by 1 / (1 − m_a(L+1)/N) (inverse Wishart): the replicates are scaled by
    // N / (N − m_a (L + 1)).
    const double used = static_cast<double>(active.size()) * static_cast<double>(g.size());
    const double dof_scale = static_cast<double>(n) / std::max(static_cast<double>(n) - used, 1.0);
    const Index segments = std::max<Index>(1, n / segment_length);
    for (Index s = 0; s < segments; ++s) {
      const Index t0 = s * segment_length, t1 = s + 1 == segments ? n : t0 + segment_length;
      segs.push_back({x, t0, t1, dof_scale, active});
    }
  }
  // One transform per segment length (the plans are made once, before the tasks).
  std::vector<std::unique_ptr<signal_detail::RealFft>> ffts;
  auto fft_for = [&](Index M) -> const signal_detail::RealFft* {
    for (const auto& f : ffts)
      if (f->size() == M) return f.get();
    return nullptr;
  };
  for (const Segment& sg : segs) {
    const Index M = signal_detail::next_fft_size(sg.t1 - sg.t0 + K);
    if (fft_for(M) == nullptr) ffts.push_back(std::make_unique<signal_detail::RealFft>(M));
  }
  // w^-(f+1), w = e^(2πi/K): the K-point transform's bins shifted by one lag.
  std::vector<Complex> shift(static_cast<std::size_t>(num_bins));
  for (Index f = 0; f < num_bins; ++f)
    shift[static_cast<std::size_t>(f)] = std::polar(1.0, -2.0 * M_PI * static_cast<double>(f) / static_cast<double>(K));
  std::vector<std::vector<Eigen::MatrixXcd>> out(segs.size());
  parallel_for(static_cast<Index>(segs.size()), [&](Index si) {
    const Segment& sg = segs[static_cast<std::size_t>(si)];
    const auto& ex = experiments[sg.x];
    const Eigen::MatrixXd& e = residual[sg.x];
    const Index n = ex.excitation.rows(), t0 = sg.t0, Ls = sg.t1 - sg.t0;
    const signal_detail::RealFft& fft = *fft_for(signal_detail::next_fft_size(Ls + K));
    const Index M = fft.size();
    auto kin = signal_detail::alloc_real(K);
    auto kout = signal_detail::alloc_complex(dft.bins());
    auto buf = signal_detail::alloc_real(M);
    auto X = signal_detail::alloc_complex(p * fft.bins());
    auto Y = signal_detail::alloc_complex(fft.bins());
    auto prod = signal_detail::alloc_complex(fft.bins());
    for (Index i = 0; i < p; ++i) {
      std::fill(buf.get(), buf.get() + M, 0.0);
      for (Index t = 0; t < Ls; ++t) buf[t] = e(t0 + t, i);
      fft.forward(buf.get(), X.get() + i * fft.bins());
    }
    // Z_f(i, a): the K-point transform of z(k) = Σ_{t∈s} e_i(t) v_a(t − k), k = 1..K.
    std::vector<Eigen::MatrixXcd> Z(static_cast<std::size_t>(num_bins), Eigen::MatrixXcd::Zero(p, m));
    for (const Index a : sg.active) {
      std::fill(buf.get(), buf.get() + M, 0.0);
      for (Index tau = 0; tau < Ls + K; ++tau) {  // y(τ) = v_a(t0 − K + τ), zero before the record
        const Index t = t0 - K + tau;
        if (t >= 0 && t < n) buf[tau] = ex.excitation(t, a);
      }
      fft.forward(buf.get(), Y.get());
      for (Index i = 0; i < p; ++i) {
        for (Index f = 0; f < fft.bins(); ++f) prod[f] = std::conj(X[i * fft.bins() + f]) * Y[f];
        fft.inverse(prod.get(), buf.get());  // M · c(d), c(d) = Σ_τ x(τ) y(τ + d); z(k) = c(K − k)
        for (Index k = 1; k <= K; ++k) kin[k - 1] = buf[K - k] / static_cast<double>(M);
        dft.forward(kin.get(), kout.get());
        for (Index f = 0; f < num_bins; ++f)  // Σ_{k≥1} z(k) w^-k = w^-1 Σ_{k'≥0} z(k'+1) w^-k'
          Z[static_cast<std::size_t>(f)](i, a) = kout[f] * shift[static_cast<std::size_t>(f)];
      }
    }
    for (auto& z : Z) z = sg.dof_scale * (z * R0inv);
    out[static_cast<std::size_t>(si)] = std::move(Z);
  });
  return out;
}

}  // namespace lpvid
