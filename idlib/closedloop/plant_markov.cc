#include "idlib/closedloop/plant_markov.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "idlib/core/error.h"
#include "idlib/core/parallel.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {

namespace {
// The transform length is at least this many times the longer of the two sequences,
// so that the aliased copies p̂[k + M] of a response that decays within the horizon
// are far out in its tail.
constexpr Index kLengthFactor = 4;
// The bins run as this many tasks (a fixed number: the result does not depend on the
// machine; more than the cores, so that they balance).
constexpr Index kBinChunks = 8;
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
  // Tasks (idlib/core/parallel.h): the transforms per channel pair, then the bins in
  // kBinChunks contiguous runs, then the inverse transforms; every value is computed as
  // one thread would compute it.
  std::vector<signal_detail::ComplexArray> spec(static_cast<std::size_t>(p * m)), out(spec.size());
  parallel_for(p * m, [&](Index c) {
    auto buf = signal_detail::alloc_real(2 * M);
    std::fill(buf.get(), buf.get() + 2 * M, 0.0);
    for (Index k = 0; k <= L; ++k) buf[k] = g[static_cast<std::size_t>(k)](c / m, c % m);
    spec[static_cast<std::size_t>(c)] = signal_detail::alloc_complex(nb);
    fft.forward(buf.get(), spec[static_cast<std::size_t>(c)].get());
    out[static_cast<std::size_t>(c)] = signal_detail::alloc_complex(nb);
  });
  // Odd bins b = 2f + 1 < M + 1 cover the upper half plane; the rest follow by symmetry.
  const Index F = M / 2;
  parallel_for(kBinChunks, [&](Index chunk) {
    const Index f0 = chunk * F / kBinChunks, f1 = (chunk + 1) * F / kBinChunks;
    if (f1 <= f0) return;
    Eigen::VectorXd omega(f1 - f0);
    for (Index f = f0; f < f1; ++f)
      omega(f - f0) = M_PI * static_cast<double>(2 * f + 1) / (static_cast<double>(M) * controller.sample_period_s);
    const auto C = evaluate_response(controller, omega);
    Eigen::MatrixXcd G(p, m), S(m, m);
    for (Index f = f0; f < f1; ++f) {
      const Index b = 2 * f + 1;
      for (Index i = 0; i < p; ++i)
        for (Index j = 0; j < m; ++j) G(i, j) = spec[static_cast<std::size_t>(i * m + j)][b];
      S = Eigen::MatrixXcd::Identity(m, m) - C[static_cast<std::size_t>(f - f0)] * G;
      const Eigen::FullPivLU<Eigen::MatrixXcd> lu(S);
      if (!lu.isInvertible())
        throw NumericalError(fmt::format("plant Markov parameters: I - C G is singular at {:.6g} rad/s", omega(f - f0)));
      const Eigen::MatrixXcd P = G * lu.inverse();
      for (Index i = 0; i < p; ++i)
        for (Index j = 0; j < m; ++j) out[static_cast<std::size_t>(i * m + j)][b] = P(i, j);
    }
  });
  MarkovSequence result(static_cast<std::size_t>(num_lags + 1), Eigen::MatrixXd::Zero(p, m));
  parallel_for(p * m, [&](Index c) {
    auto buf = signal_detail::alloc_real(2 * M);
    // Real inverse of the half spectrum: y(k) = Σ over all 2M bins = 2 Re Σ_{odd b < M} (+ nothing at DC/M).
    fft.inverse(out[static_cast<std::size_t>(c)].get(), buf.get());
    for (Index k = 0; k <= num_lags && k < 2 * M; ++k)
      result[static_cast<std::size_t>(k)](c / m, c % m) = buf[k] / static_cast<double>(M);
  });
  return result;
}

}  // namespace lpvid
