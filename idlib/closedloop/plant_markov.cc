#include "idlib/closedloop/plant_markov.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

namespace {
// The transform length is at least this many times the longer of the two sequences,
// so that the aliased copies p̂[k + M] of a response that decays within the horizon
// are far out in its tail.
constexpr Index kLengthFactor = 4;
}  // namespace

MarkovSequence plant_markov_from_closed_loop(const MarkovSequence& g, const StateSpace& controller, Index num_lags) {
  if (g.empty()) throw InputError("plant Markov parameters: the closed-loop sequence is empty");
  const Index p = g.front().rows(), m = g.front().cols();
  for (const auto& x : g)
    if (x.rows() != p || x.cols() != m)
      throw InputError("plant Markov parameters: every closed-loop lag must have one shape");
  controller.validate();
  if (!controller.is_discrete())
    throw InputError("plant Markov parameters: the controller must be discrete (the logs' controller)");
  if (controller.num_inputs() != p || controller.num_outputs() != m)
    throw InputError(fmt::format("plant Markov parameters: the controller is {}x{} but the loop needs {}x{}",
                                 controller.num_outputs(), controller.num_inputs(), m, p));
  if (num_lags < 1) throw InputError("plant Markov parameters: num_lags must be >= 1");
  const Index L = static_cast<Index>(g.size()) - 1;
  const Index M = signal_detail::next_pow2(kLengthFactor * (std::max(L, num_lags) + 1));
  // The half-bin-shifted M-point transform is the odd bins of the 2M-point one.
  const signal_detail::RealFft fft(2 * M);
  const Index nb = fft.bins();  // M + 1
  auto buf = signal_detail::alloc_real(2 * M);
  std::vector<signal_detail::ComplexArray> spec;
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      std::fill(buf.get(), buf.get() + 2 * M, 0.0);
      for (Index k = 0; k <= L; ++k) buf[k] = g[static_cast<std::size_t>(k)](i, j);
      spec.push_back(signal_detail::alloc_complex(nb));
      fft.forward(buf.get(), spec.back().get());
    }
  // Odd bins b = 2f + 1 < M + 1 cover the upper half plane; the rest follow by symmetry.
  Eigen::VectorXd omega(M / 2);
  for (Index f = 0; f < M / 2; ++f)
    omega(f) = M_PI * static_cast<double>(2 * f + 1) / (static_cast<double>(M) * controller.sample_period_s);
  const auto C = evaluate_response(controller, omega);
  std::vector<signal_detail::ComplexArray> out;
  for (Index c = 0; c < p * m; ++c) out.push_back(signal_detail::alloc_complex(nb));
  Eigen::MatrixXcd G(p, m), S(m, m);
  for (Index f = 0; f < M / 2; ++f) {
    const Index b = 2 * f + 1;
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) G(i, j) = spec[static_cast<std::size_t>(i * m + j)][b];
    S = Eigen::MatrixXcd::Identity(m, m) - C[static_cast<std::size_t>(f)] * G;
    const Eigen::FullPivLU<Eigen::MatrixXcd> lu(S);
    if (!lu.isInvertible())
      throw NumericalError(fmt::format("plant Markov parameters: I - C G is singular at {:.6g} rad/s", omega(f)));
    const Eigen::MatrixXcd P = G * lu.inverse();
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) out[static_cast<std::size_t>(i * m + j)][b] = P(i, j);
  }
  MarkovSequence result(static_cast<std::size_t>(num_lags + 1), Eigen::MatrixXd::Zero(p, m));
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      // Real inverse of the half spectrum: y(k) = Σ over all 2M bins = 2 Re Σ_{odd b < M} (+ nothing at DC/M).
      fft.inverse(out[static_cast<std::size_t>(i * m + j)].get(), buf.get());
      for (Index k = 0; k <= num_lags && k < 2 * M; ++k)
        result[static_cast<std::size_t>(k)](i, j) = buf[k] / static_cast<double>(M);
    }
  return result;
}

}  // namespace lpvid
