#include "idlib/signal/noise_spectrum.h"

#include <fmt/format.h>

#include <cmath>

#include "idlib/core/error.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

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
  if (!output_correction.empty() && output_correction.size() != experiments.size())
    throw InputError("residual spectrum: one output correction per experiment, or none");
  for (std::size_t e = 0; e < experiments.size(); ++e) {
    const auto& x = experiments[e];
    if (x.excitation.cols() != m || x.output.cols() != p || x.excitation.rows() != x.output.rows())
      throw InputError(fmt::format("residual spectrum: experiment {} is not {} inputs and {} outputs over one record",
                                   e, m, p));
    if (x.excitation.rows() < segment_length)
      throw InputError(fmt::format("residual spectrum: experiment {} has {} samples, fewer than a segment of {}", e,
                                   x.excitation.rows(), segment_length));
    if (!output_correction.empty() &&
        (output_correction[e].rows() != x.output.rows() || output_correction[e].cols() != p))
      throw InputError(fmt::format("residual spectrum: the correction of experiment {} is not {} x {}", e,
                                   x.output.rows(), p));
  }
  using signal_detail::ChannelView;
  const signal_detail::RealFft fft(segment_length);
  auto buf = signal_detail::alloc_real(segment_length);
  auto spec = signal_detail::alloc_complex(p * fft.bins());
  Eigen::VectorXd window(segment_length);
  for (Index t = 0; t < segment_length; ++t)
    window(t) = 0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(t) / static_cast<double>(segment_length));
  const double window_energy = window.squaredNorm();
  std::vector<Eigen::MatrixXcd> psd(static_cast<std::size_t>(num_bins), Eigen::MatrixXcd::Zero(p, p));
  Index segments = 0;
  const Index hop = segment_length / 2;
  Eigen::MatrixXd e;  // residual of one experiment, N × p
  for (std::size_t x = 0; x < experiments.size(); ++x) {
    const auto& ex = experiments[x];
    const Index n = ex.excitation.rows();
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
    if (!output_correction.empty()) e -= output_correction[x];
    e.rowwise() -= e.colwise().mean();
    for (Index s0 = 0; s0 + segment_length <= n; s0 += hop) {
      for (Index i = 0; i < p; ++i) {
        for (Index t = 0; t < segment_length; ++t) buf[t] = window(t) * e(s0 + t, i);
        fft.forward(buf.get(), spec.get() + i * fft.bins());
      }
      for (Index f = 0; f < num_bins; ++f)
        for (Index j = 0; j < p; ++j)
          for (Index i = 0; i < p; ++i)
            psd[static_cast<std::size_t>(f)](i, j) += spec[i * fft.bins() + f] * std::conj(spec[j * fft.bins() + f]);
      ++segments;
    }
  }
  const double scale = 1.0 / (static_cast<double>(segments) * window_energy);
  for (auto& s : psd) s *= scale;
  return psd;
}

}  // namespace lpvid
