#include "idlib/signal/correlation.h"

#include <fmt/format.h>

#include <cmath>

#include "idlib/core/error.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {
namespace {

void require_finite(const Eigen::Ref<const Eigen::MatrixXd>& a, const char* name) {
  if (a.allFinite()) return;
  for (Index c = 0; c < a.cols(); ++c)
    for (Index r = 0; r < a.rows(); ++r)
      if (!std::isfinite(a(r, c)))
        throw InputError(fmt::format(
            "cross_correlation: {}({}, {}) = {}; every sample must be finite: remove or "
            "interpolate the bad samples first",
            name, r, c, a(r, c)));
}

std::vector<signal_detail::ChannelView> columns(const Eigen::Ref<const Eigen::MatrixXd>& a) {
  std::vector<signal_detail::ChannelView> v(static_cast<size_t>(a.cols()));
  for (Index c = 0; c < a.cols(); ++c) v[static_cast<size_t>(c)].data = a.data() + c * a.outerStride();
  return v;
}

}  // namespace

std::vector<Eigen::MatrixXd> cross_correlation(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                               const Eigen::Ref<const Eigen::MatrixXd>& y,
                                               Index max_lag) {
  if (x.rows() != y.rows())
    throw InputError(fmt::format(
        "cross_correlation: x has {} samples and y has {}; both signals must have the same "
        "number of rows (samples)",
        x.rows(), y.rows()));
  if (max_lag < 0)
    throw InputError(fmt::format("cross_correlation: max_lag = {}; it must be >= 0", max_lag));
  if (max_lag >= x.rows())
    throw InputError(fmt::format(
        "cross_correlation: max_lag = {} with {} samples; max_lag must be smaller than the "
        "number of samples",
        max_lag, x.rows()));
  require_finite(x, "x");
  require_finite(y, "y");
  std::vector<Eigen::MatrixXd> out(static_cast<size_t>(max_lag + 1),
                                   Eigen::MatrixXd::Zero(x.cols(), y.cols()));
  signal_detail::accumulate_cross_correlation(columns(x), columns(y), x.rows(), max_lag, out);
  return out;
}

std::vector<Eigen::MatrixXd> autocorrelation(const Eigen::Ref<const Eigen::MatrixXd>& x,
                                             Index max_lag) {
  auto r = cross_correlation(x, x, max_lag);
  r[0] = 0.5 * (r[0] + r[0].transpose()).eval();
  return r;
}

}  // namespace lpvid
