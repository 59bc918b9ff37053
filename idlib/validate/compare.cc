#include "idlib/validate/compare.h"
#include "idlib/core/eigen_decompositions.h"

#include <Eigen/SVD>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/validate/frequency_error.h"

namespace lpvid {

void CompareOptions::validate() const {
  if (band_min_rad_s < 0 || band_max_rad_s < 0 || (band_max_rad_s > 0 && band_max_rad_s <= band_min_rad_s))
    throw InputError(fmt::format("compare: band {} .. {} rad/s; need 0 <= min < max (0 = from the data)",
                                 band_min_rad_s, band_max_rad_s));
  if (!(bands_per_decade > 0) || !std::isfinite(bands_per_decade))
    throw InputError(fmt::format("compare: {} bands per decade; must be a positive number", bands_per_decade));
}

CompareResult compare_responses(const std::vector<Eigen::MatrixXcd>& estimate,
                                const std::vector<Eigen::MatrixXcd>& reference, const Eigen::VectorXd& omega,
                                const std::vector<bool>& flagged, const CompareOptions& options) {
  options.validate();
  const std::size_t F = reference.size();
  if (estimate.size() != F || static_cast<std::size_t>(omega.size()) != F || F == 0)
    throw InputError(fmt::format("compare: {} estimate and {} reference responses at {} frequencies; they must match",
                                 estimate.size(), reference.size(), omega.size()));
  const Index p = reference.front().rows(), m = reference.front().cols();
  if (estimate.front().rows() != p || estimate.front().cols() != m)
    throw InputError(fmt::format("compare: the estimate is {}x{} but the reference is {}x{}", estimate.front().rows(),
                                 estimate.front().cols(), p, m));
  if (!flagged.empty() && flagged.size() != F) throw InputError("compare: flags must have one entry per frequency");
  const Eigen::VectorXd wl = options.left_weight.size() ? options.left_weight : Eigen::VectorXd::Ones(p);
  const Eigen::VectorXd wr = options.right_weight.size() ? options.right_weight : Eigen::VectorXd::Ones(m);
  if (wl.size() != p || wr.size() != m)
    throw InputError(fmt::format("compare: {} output and {} input weights for a {}x{} response", wl.size(), wr.size(),
                                 p, m));
  const double lo = options.band_min_rad_s > 0 ? options.band_min_rad_s : omega(0);
  const double hi = options.band_max_rad_s > 0 ? options.band_max_rad_s : omega(static_cast<Index>(F) - 1);
  // Band edges, log-spaced; the last band ends exactly at hi.
  const Index nb = std::max<Index>(1, static_cast<Index>(std::ceil(std::log10(hi / lo) * options.bands_per_decade - 1e-9)));
  std::vector<double> edges;
  for (Index b = 0; b <= nb; ++b) edges.push_back(lo * std::pow(hi / lo, static_cast<double>(b) / nb));

  CompareResult out;
  std::vector<std::vector<Index>> members(static_cast<std::size_t>(nb));
  for (std::size_t k = 0; k < F; ++k) {
    if (omega(k) < lo || omega(k) > hi) continue;
    const Index b = std::min<Index>(nb - 1, static_cast<Index>(std::floor(std::log10(omega(k) / lo) /
                                                                           std::log10(hi / lo) * nb)));
    members[b].push_back(static_cast<Index>(k));
  }
  double sum = 0;
  Index used = 0;
  for (Index b = 0; b < nb; ++b) {
    BandError be;
    be.band_lo_rad_s = edges[b];
    be.band_hi_rad_s = edges[b + 1];
    std::vector<ChannelBandError> ch(static_cast<std::size_t>(p * m));
    for (Index k : members[b]) {
      if (!flagged.empty() && flagged[k]) {
        ++be.flagged;
        continue;
      }
      const Eigen::MatrixXcd& R = reference[k];
      const Eigen::MatrixXcd& A = estimate[k];
      const double e = weighted_matrix_error(A, R, wl, wr);
      const Eigen::MatrixXcd WR = wl.asDiagonal() * R * wr.asDiagonal();
      const double scale = Eigen::JacobiSVD<Eigen::MatrixXcd>(WR).singularValues()(0);
      be.weighted_mean += e;
      be.weighted_max = std::max(be.weighted_max, e);
      if (e > out.weighted_max) {
        out.weighted_max = e;
        out.omega_at_max_rad_s = omega(k);
      }
      sum += e;
      ++used;
      ++be.points;
      for (Index i = 0; i < p; ++i)
        for (Index j = 0; j < m; ++j) {
          auto& c = ch[static_cast<std::size_t>(i * m + j)];
          const double share = 100.0 * std::abs(A(i, j) - R(i, j)) * wl(i) * wr(j) / std::max(scale, 1e-300);
          c.share_percent = std::max(c.share_percent, share);
          // Gain and phase errors mean something only where the channel carries a
          // visible part of the matrix gain (a coupling that is ~0 in the
          // reference has no meaningful dB or phase error).
          if (std::abs(A(i, j)) > 0 && std::abs(R(i, j)) * wl(i) * wr(j) >= kMinChannelShare * scale) {
            c.gain_db += std::abs(20.0 * std::log10(std::abs(A(i, j)) / std::abs(R(i, j))));
            c.phase_deg += std::abs(std::arg(A(i, j) / R(i, j))) * 180.0 / M_PI;
            ++c.gain_points;
          }
          ++c.points;
        }
    }
    if (be.points > 0) be.weighted_mean /= static_cast<double>(be.points);
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) {
        auto c = ch[static_cast<std::size_t>(i * m + j)];
        if (c.points == 0) continue;
        c.output = i;
        c.input = j;
        c.band_lo_rad_s = be.band_lo_rad_s;
        c.band_hi_rad_s = be.band_hi_rad_s;
        if (c.gain_points > 0) {
          c.gain_db /= static_cast<double>(c.gain_points);
          c.phase_deg /= static_cast<double>(c.gain_points);
        } else {
          c.gain_db = c.phase_deg = std::nan("");
        }
        out.channels.push_back(c);
      }
    out.bands.push_back(be);
  }
  if (used == 0)
    throw InputError(fmt::format("compare: no (unflagged) frequency between {:.6g} and {:.6g} rad/s; widen the band", lo,
                                 hi));
  out.weighted_mean = sum / static_cast<double>(used);
  std::stable_sort(out.channels.begin(), out.channels.end(),
                   [](const ChannelBandError& a, const ChannelBandError& b) { return a.share_percent > b.share_percent; });
  return out;
}

}  // namespace lpvid
