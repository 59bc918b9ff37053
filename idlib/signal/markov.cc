#include "idlib/signal/markov.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "idlib/core/parallel.h"
#include "idlib/signal/markov_arx.h"
#include "idlib/signal/markov_regularized.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {
namespace {

using signal_detail::ChannelView;
using signal_detail::ComplexArray;
using signal_detail::RealArray;
using signal_detail::RealFft;

// kCorrelation: an experiment counts as exciting input j when the RMS of v_j there is
// at least this fraction of the largest RMS of v_j over all experiments; smaller
// levels are leakage or sensor noise in experiments meant for other inputs.
constexpr double kExcitedFractionOfLargestRms = 0.1;

// Inputs are reported as linearly dependent when the smallest eigenvalue of their
// normalised zero-lag correlation matrix (unit diagonal) is below this: the normal
// equations would then lose more than 8 of the 16 significant digits.
constexpr double kDependentInputsEigenvalue = 1e-8;
// ... naming the inputs whose component in that eigenvector exceeds this (a unit
// vector spread over k inputs has components ~1/sqrt(k) >= 0.3 for k <= 10).
constexpr double kDependentInputComponent = 0.2;

// Least squares: the residual energy is taken from the normal equations,
//   ||e_i||^2 = ||q_i||^2 - 2 g_i . b_i + g_i . Phi g_i   (O(L log L)),
// whose round-off is ~1e-14 ||q_i||^2.  When the model explains all but this fraction
// of the output energy, that formula has fewer than 8 correct digits and the residual
// is recomputed by FFT convolution over the data (O(N log L)).
constexpr double kAnalyticResidualMinFraction = 1e-6;

// kRegularized: up to this many unknowns m (L + 1) the posterior mean is solved exactly
// (a dense normal matrix, 128 MB at the limit, and one Cholesky per output: about 1 s
// each at 2500 unknowns on the reference machine); above it by CG, which on strongly
// coloured excitations stops short of the tolerance (measured: relative residual 3e-4
// after 500 iterations at 2502 unknowns).
constexpr Index kMaxDenseRegularizedUnknowns = 4096;
// ... and its noise variance re-estimated over all L lags in this many rounds (below).
constexpr int kNoiseRounds = 3;

struct ColumnStats {
  double offset = 0.0;         // subtracted from every sample
  double sum_sq = 0.0;         // sum_t (x(t) - offset)^2
  bool active = false;         // false: the column is treated as identically zero
};

// One pass-pair over a column: finiteness, mean and centred energy.  The sums are
// taken about the first sample, so a constant column gives exactly zero energy.
ColumnStats column_stats(const Eigen::Ref<const Eigen::MatrixXd>& a, Index c, bool remove_mean,
                         Index experiment, const char* what) {
  const Index n = a.rows();
  ColumnStats s;
  if (n == 0) return s;
  const auto col = a.col(c).array();
  const double shift = remove_mean ? a(0, c) : 0.0;
  const double s1 = (col - shift).sum();
  const double s2 = (col - shift).square().sum();
  if (!std::isfinite(s1) || !std::isfinite(s2)) {
    for (Index t = 0; t < n; ++t)
      if (!std::isfinite(a(t, c)))
        throw InputError(fmt::format("estimate_markov: experiment {}: {}({}, {}) = {}; every sample must be finite: "
                                     "remove or interpolate the bad samples first",
                                     experiment + 1, what, t + 1, c + 1, a(t, c)));
    throw InputError(fmt::format("estimate_markov: experiment {}: {} column {} overflows a double when squared and "
                                 "summed; rescale the signal (e.g. to SI units)",
                                 experiment + 1, what, c + 1));
  }
  const double dn = static_cast<double>(n);
  if (remove_mean) {
    s.offset = shift + s1 / dn;
    s.sum_sq = std::max(0.0, s2 - s1 * s1 / dn);
  } else {
    s.sum_sq = s2;
  }
  s.active = s.sum_sq > 0.0;
  if (!s.active) s.sum_sq = 0.0;
  return s;
}

// Products with the normal matrix Phi = blocktoeplitz(R_vv) - sum_e T_e T_e^T of the
// covariance method, by FFT.  Unknown layout: H(k * m + a, c) = g[k](c, a), i.e. one
// column per output, m (L + 1) rows, lag-major.
//
//   Toeplitz part: (T h)(j) = sum_k K(j - k) h(k), K(n) = R(n)^T (n >= 0), R(-n) (n < 0).
//   Correction:    (C h)(j) = sum_r w(j - r) z(r),  z(r) = sum_k w(k - r)^T h(k),
//                  w(s) = v(N - s) for s = 1..L (zero elsewhere), r = 0..L-1,
//   which is C(j, k) = sum_{t=N}^{N-1+min(j,k)} v(t - j) v(t - k)^T with t = N + r.
// FFT size M >= 2L + 2 keeps every product free of wrap-around (the smallest 2^a 3^b).
class NormalOperator {
 public:
  // lag_means[e] (empty, or m (L+1) in the unknowns' layout) and lag_count[e]: the
  // intercept correction -sum_e N_e mu_e mu_e^T (see estimate_markov).
  NormalOperator(const std::vector<Eigen::MatrixXd>& rvv, const std::vector<Eigen::MatrixXd>& tails,
                 Index m, Index L, Index p, std::vector<Eigen::VectorXd> lag_means = {},
                 std::vector<double> lag_count = {})
      : lag_means_(std::move(lag_means)), lag_count_(std::move(lag_count)), m_(m), L_(L), p_(p), fft_(signal_detail::next_fft_size(2 * L + 2)), nb_(fft_.bins()),
        num_exp_(static_cast<Index>(tails.size())),
        kernel_(signal_detail::alloc_complex(m * m * nb_)),
        tail_(signal_detail::alloc_complex(num_exp_ * m * nb_)),
        hspec_(signal_detail::alloc_complex(p * m * nb_)),
        yspec_(signal_detail::alloc_complex(p * m * nb_)),
        zspec_(signal_detail::alloc_complex(num_exp_ * p * nb_)),
        buf_(static_cast<std::size_t>(std::max(p * m, num_exp_ * p))) {
    for (auto& b : buf_) b = signal_detail::alloc_real(fft_.size());
    const Index M = fft_.size();
    double* b = buf_.front().get();
    for (Index a = 0; a < m; ++a) {
      for (Index c = 0; c < m; ++c) {
        std::fill(b, b + M, 0.0);
        for (Index n = 0; n <= L; ++n) b[n] = rvv[n](c, a);
        for (Index n = 1; n <= L; ++n) b[M - n] = rvv[n](a, c);
        fft_.forward(b, kernel_.get() + (a * m + c) * nb_);
      }
    }
    for (Index e = 0; e < num_exp_; ++e) {
      const Eigen::MatrixXd& w = tails[e];  // row s-1 holds v(N - s)
      for (Index a = 0; a < m; ++a) {
        std::fill(b, b + M, 0.0);
        for (Index s = 1; s <= L; ++s) b[s] = w(s - 1, a);
        fft_.forward(b, tail_.get() + (e * m + a) * nb_);
      }
    }
  }

  // Three rounds of tasks (parallel.h), each writing only its own spectra and buffer:
  // the transforms of h per (c, a); the record-end corrections z per (e, c); the sums
  // and inverse transforms per (c, a), in the same order of terms as one thread would.
  void apply(const Eigen::MatrixXd& h, Eigen::MatrixXd& y) {
    const Index M = fft_.size();
    const Index m = m_, L = L_, nb = nb_;
    y.resize(m * (L + 1), p_);
    const double scale = 1.0 / static_cast<double>(M);
    parallel_for(p_ * m, [&](Index task) {
      const Index c = task / m, a = task % m;
      double* b = buf(task);
      std::fill(b, b + M, 0.0);
      for (Index k = 0; k <= L; ++k) b[k] = h(k * m + a, c);
      fft_.forward(b, hspec(c, a));
    });
    parallel_for(num_exp_ * p_, [&](Index task) {
      const Index e = task / p_, c = task % p_;
      double* b = buf(task);
      Complex* z = zspec(e, c);
      std::fill(z, z + nb, Complex(0.0, 0.0));
      for (Index a = 0; a < m; ++a) mac_conj(hspec(c, a), tail(e, a), z);
      fft_.inverse(z, b);
      // Keep z(r) for r = 0..L-1 only; fold in the -1 of Phi = T - C and the 1/M.
      for (Index r = 0; r < L; ++r) b[r] *= -scale;
      std::fill(b + L, b + M, 0.0);
      fft_.forward(b, z);
    });
    parallel_for(p_ * m, [&](Index task) {
      const Index c = task / m, a = task % m;
      double* b = buf(task);
      Complex* ys = yspec(c, a);
      std::fill(ys, ys + nb, Complex(0.0, 0.0));
      for (Index d = 0; d < m; ++d) mac(kernel_.get() + (a * m + d) * nb, hspec(c, d), ys);
      for (Index e = 0; e < num_exp_; ++e) mac(tail(e, a), zspec(e, c), ys);
      fft_.inverse(ys, b);
      for (Index k = 0; k <= L; ++k) y(k * m + a, c) = b[k] * scale;
    });
    for (std::size_t e = 0; e < lag_means_.size(); ++e)
      for (Index c = 0; c < p_; ++c)
        y.col(c) -= (lag_count_[e] * lag_means_[e].dot(h.col(c))) * lag_means_[e];
  }

 private:
  Complex* hspec(Index c, Index a) { return hspec_.get() + (c * m_ + a) * nb_; }
  Complex* yspec(Index c, Index a) { return yspec_.get() + (c * m_ + a) * nb_; }
  const Complex* tail(Index e, Index a) const { return tail_.get() + (e * m_ + a) * nb_; }
  Complex* zspec(Index e, Index c) { return zspec_.get() + (e * p_ + c) * nb_; }
  double* buf(Index task) { return buf_[static_cast<std::size_t>(task)].get(); }

  // acc += x * z, acc += x * conj(z): the real-arithmetic loops of real_fft.h (std::complex
  // products check for NaN and do not vectorise).
  void mac(const Complex* x, const Complex* z, Complex* acc) const { signal_detail::mac(x, z, acc, nb_); }
  void mac_conj(const Complex* x, const Complex* z, Complex* acc) const { signal_detail::mac_conj(x, z, acc, nb_); }

  std::vector<Eigen::VectorXd> lag_means_;
  std::vector<double> lag_count_;
  Index m_, L_, p_;
  RealFft fft_;
  Index nb_;
  Index num_exp_;
  ComplexArray kernel_, tail_, hspec_, yspec_, zspec_;
  std::vector<RealArray> buf_;  // one per task of a round
};

struct PcgOutcome {
  Eigen::MatrixXd x;
  Index iterations = 0;
  double worst_relative_residual = 0.0;
  bool converged = false;
};

// Preconditioned CG on Phi X = B, one independent CG per column run in lockstep so
// that the FFTs of all columns are shared.  Preconditioner: the same m x m block
// R_vv(0)^{-1} applied to every lag.
// The lockstep CG itself: apply(h, y) sets y = M h for every column, precondition(r, z)
// sets z = P⁻¹ r.
template <class Apply, class Precondition>
PcgOutcome solve_cg_lockstep(Apply&& apply, Precondition&& precondition, const Eigen::MatrixXd& rhs,
                             double tolerance, int max_iterations, const Eigen::MatrixXd* x0) {
  const Index n = rhs.rows(), p = rhs.cols();
  PcgOutcome out;
  out.x = Eigen::MatrixXd::Zero(n, p);
  Eigen::MatrixXd r = rhs, z, q;
  if (x0 != nullptr) {  // warm start: the same tolerance, relative to ||rhs||
    out.x = *x0;
    apply(out.x, q);
    r -= q;
  }
  Eigen::VectorXd bnorm(p), rz(p);
  std::vector<bool> done(static_cast<size_t>(p));
  auto relres = [&](Index c) { return bnorm(c) > 0.0 ? r.col(c).norm() / bnorm(c) : 0.0; };
  bool all_done = true;
  for (Index c = 0; c < p; ++c) {
    bnorm(c) = rhs.col(c).norm();
    done[c] = relres(c) <= tolerance;
    all_done = all_done && done[c];
  }
  precondition(r, z);
  Eigen::MatrixXd dir = z;
  for (Index c = 0; c < p; ++c) rz(c) = r.col(c).dot(z.col(c));
  Index it = 0;
  while (!all_done && it < max_iterations) {
    ++it;
    apply(dir, q);
    all_done = true;
    for (Index c = 0; c < p; ++c) {
      if (done[c]) continue;
      const double alpha = rz(c) / dir.col(c).dot(q.col(c));
      out.x.col(c) += alpha * dir.col(c);
      r.col(c) -= alpha * q.col(c);
      done[c] = relres(c) <= tolerance;
      all_done = all_done && done[c];
    }
    if (all_done) break;
    precondition(r, z);
    for (Index c = 0; c < p; ++c) {
      if (done[c]) continue;
      const double rz_new = r.col(c).dot(z.col(c));
      dir.col(c) = z.col(c) + (rz_new / rz(c)) * dir.col(c);
      rz(c) = rz_new;
    }
  }
  out.iterations = it;
  out.converged = all_done;
  for (Index c = 0; c < p; ++c) out.worst_relative_residual = std::max(out.worst_relative_residual, relres(c));
  return out;
}

PcgOutcome solve_pcg(NormalOperator& op, const Eigen::MatrixXd& rhs,
                     const Eigen::LLT<Eigen::MatrixXd>& r0, Index m, Index L, double tolerance,
                     int max_iterations, const Eigen::MatrixXd* x0 = nullptr) {
  const Index p = rhs.cols();
  auto precondition = [&](const Eigen::MatrixXd& r, Eigen::MatrixXd& z) {
    z = r;
    for (Index c = 0; c < p; ++c) {
      Eigen::Map<Eigen::MatrixXd> blocks(z.col(c).data(), m, L + 1);
      r0.solveInPlace(blocks);
    }
  };
  return solve_cg_lockstep([&](const Eigen::MatrixXd& h, Eigen::MatrixXd& y) { op.apply(h, y); }, precondition, rhs,
                           tolerance, max_iterations, x0);
}

// mean_t v(t − k) over a record of n samples (v = 0 before it), for k = 0..L.
Eigen::VectorXd lag_means_of(const double* v, Index n, Index L) {
  Eigen::VectorXd mu(L + 1);
  double sum = 0.0;
  for (Index t = 0; t < n; ++t) sum += v[t];
  for (Index k = 0; k <= L; ++k) {
    mu(k) = sum / static_cast<double>(n);
    if (k < n) sum -= v[n - 1 - k];
  }
  return mu;
}

// kRegularized (markov.h, markov_regularized.h): each output's TC kernel tuned on the first
// T lags (the dense normal matrix is the operator applied to the identity), then every
// output's posterior mean over all L lags by lockstep CG in the prior's whitened
// coordinates β (h = T_i β), where the system is Tᵢᵀ Φ Tᵢ β + γ β = Tᵢᵀ b: a ridge problem,
// well conditioned however coloured the excitation (no preconditioner needed).
PcgOutcome solve_regularized(NormalOperator& op, const std::vector<Eigen::MatrixXd>& rvv,
                             const std::vector<Eigen::MatrixXd>& tails, const std::vector<Eigen::VectorXd>& lag_means,
                             const std::vector<double>& lag_count, const Eigen::MatrixXd& rhs,
                             const Eigen::VectorXd& q_energy, double samples, Index m, Index L,
                             const MarkovOptions& options, MarkovResult& res) {
  const Index p = rhs.cols();
  const Index T = std::min(L, options.regularized_tuning_lags);
  const Index nt = m * (T + 1);
  std::vector<Eigen::MatrixXd> rvv_t(rvv.begin(), rvv.begin() + T + 1), tails_t;
  for (const auto& w : tails) tails_t.push_back(w.topRows(T));
  std::vector<Eigen::VectorXd> means_t;
  for (const auto& mu : lag_means) means_t.push_back(mu.head(nt));
  Eigen::MatrixXd phi;
  {
    NormalOperator small(rvv_t, tails_t, m, T, nt, means_t, lag_count);
    small.apply(Eigen::MatrixXd::Identity(nt, nt), phi);
  }
  phi = (0.5 * (phi + phi.transpose())).eval();
  res.kernel_tuning_lags = T;
  res.kernel_decay.resize(p, m);
  res.kernel_gamma.resize(p, m);
  res.kernel_noise_variance.resize(p);
  std::vector<Eigen::MatrixXd> weights(static_cast<std::size_t>(p));
  parallel_for(p, [&](Index i) {
    const markov_detail::TcTuning t =
        markov_detail::tune_tc_kernel(phi, rhs.col(i).head(nt), q_energy(i), samples, m);
    Eigen::MatrixXd w(L + 1, m);
    for (Index a = 0; a < m; ++a) {
      res.kernel_decay(i, a) = std::exp(-t.kernel.rate(a));
      res.kernel_gamma(i, a) = t.kernel.gamma(a);
      w.col(a) = markov_detail::tc_inverse_weights(t.kernel.rate(a), L);
    }
    res.kernel_noise_variance(i) = t.noise_variance;
    weights[static_cast<std::size_t>(i)] = std::move(w);
  });
  const Index n = m * (L + 1);
  if (n <= kMaxDenseRegularizedUnknowns) {
    // Exact: the dense normal matrix (the operator applied to the identity, a chunk of
    // columns at a time) and one Cholesky per output.
    Eigen::MatrixXd dense(n, n);
    const Index chunk = std::min<Index>(n, 256);
    NormalOperator cols(rvv, tails, m, L, chunk, lag_means, lag_count);
    Eigen::MatrixXd e, y;
    for (Index c0 = 0; c0 < n; c0 += chunk) {
      const Index w = std::min(chunk, n - c0);
      e = Eigen::MatrixXd::Zero(n, chunk);
      for (Index c = 0; c < w; ++c) e(c0 + c, c) = 1.0;
      cols.apply(e, y);
      dense.middleCols(c0, w) = y.leftCols(w);
    }
    dense = (0.5 * (dense + dense.transpose())).eval();
    PcgOutcome sol;
    sol.x.resize(n, p);
    std::vector<char> solved(static_cast<std::size_t>(p), 1);
    parallel_for(p, [&](Index i) {  // each task writes only its own output's column and rows
      markov_detail::TcKernel kernel;
      kernel.gamma = res.kernel_gamma.row(i).transpose();
      kernel.rate = (-res.kernel_decay.row(i).array().log()).matrix().transpose();
      // The tuning window leaves the response beyond T lags unexplained, which inflates its
      // noise variance and with it γ = σ²/c (over-smoothing).  Keep the prior's scale c and
      // decay, and re-estimate σ² on all L lags (its profiled value Q / N'), a few rounds.
      const Eigen::VectorXd scale = res.kernel_noise_variance(i) * kernel.gamma.cwiseInverse();
      double sigma2 = res.kernel_noise_variance(i);
      for (int round = 0; round < kNoiseRounds; ++round) {
        kernel.gamma = sigma2 * scale.cwiseInverse();
        double next = sigma2;
        if (!std::isfinite(markov_detail::tc_objective(dense, rhs.col(i), q_energy(i), samples, m, kernel, &next)))
          break;
        sigma2 = next;
      }
      kernel.gamma = sigma2 * scale.cwiseInverse();
      res.kernel_gamma.row(i) = kernel.gamma.transpose();
      res.kernel_noise_variance(i) = sigma2;
      Eigen::VectorXd mean;
      if (!std::isfinite(
              markov_detail::tc_objective(dense, rhs.col(i), q_energy(i), samples, m, kernel, nullptr, &mean))) {
        solved[static_cast<std::size_t>(i)] = 0;
        mean = Eigen::VectorXd::Zero(n);
      }
      sol.x.col(i) = mean;
    });
    sol.converged = std::all_of(solved.begin(), solved.end(), [](char c) { return c != 0; });
    return sol;
  }
  // Too many unknowns for a dense matrix: lockstep CG in the prior's whitened coordinates.
  Eigen::MatrixXd rhs_w(n, p), h(n, p), phi_h;
  for (Index i = 0; i < p; ++i) markov_detail::tc_to_whitened(rhs.col(i), weights[static_cast<std::size_t>(i)], rhs_w.col(i));
  auto apply = [&](const Eigen::MatrixXd& beta, Eigen::MatrixXd& y) {
    for (Index i = 0; i < p; ++i) markov_detail::tc_to_unknowns(beta.col(i), weights[static_cast<std::size_t>(i)], h.col(i));
    op.apply(h, phi_h);
    y.resize(n, p);
    for (Index i = 0; i < p; ++i) {
      markov_detail::tc_to_whitened(phi_h.col(i), weights[static_cast<std::size_t>(i)], y.col(i));
      for (Index k = 0; k <= L; ++k)
        for (Index a = 0; a < m; ++a) y(k * m + a, i) += res.kernel_gamma(i, a) * beta(k * m + a, i);
    }
  };
  auto identity = [](const Eigen::MatrixXd& r, Eigen::MatrixXd& z) { z = r; };
  PcgOutcome sol = solve_cg_lockstep(apply, identity, rhs_w, options.tolerance, options.max_iterations, nullptr);
  for (Index i = 0; i < p; ++i) markov_detail::tc_to_unknowns(sol.x.col(i), weights[static_cast<std::size_t>(i)], h.col(i));
  sol.x = h;
  return sol;
}

// The records' shapes against each other and the horizon; returns the total samples.
Index check_markov_experiments(const std::vector<ExperimentView>& experiments, Index L) {
  if (experiments.empty())
    throw InputError("estimate_markov: no experiments; pass at least one experiment (excitation and output logs)");
  const Index E = static_cast<Index>(experiments.size());
  const Index m = experiments[0].excitation.cols();
  const Index p = experiments[0].output.cols();
  if (m == 0 || p == 0)
    throw InputError(fmt::format(
        "estimate_markov: experiment 1 has {} excitation and {} output columns; each needs at least one", m, p));
  Index total = 0;
  for (Index e = 0; e < E; ++e) {
    const ExperimentView& x = experiments[e];
    if (x.excitation.rows() != x.output.rows())
      throw InputError(fmt::format("estimate_markov: experiment {}: excitation has {} samples and output has {}; both "
                                   "must cover the same N samples",
                                   e + 1, x.excitation.rows(), x.output.rows()));
    if (x.excitation.cols() != m || x.output.cols() != p)
      throw InputError(fmt::format("estimate_markov: experiment {} has {} excitation and {} output channels, "
                                   "experiment 1 has {} and {}; every experiment must log the same channels",
                                   e + 1, x.excitation.cols(), x.output.cols(), m, p));
    if (x.excitation.rows() <= L)
      throw InputError(fmt::format("estimate_markov: experiment {} has N = {} samples for num_lags = {}; each record "
                                   "needs N > num_lags: use fewer lags or a longer record",
                                   e + 1, x.excitation.rows(), L));
    total += x.excitation.rows();
  }
  if (total < 2 * m * (L + 1))
    throw InputError(fmt::format("estimate_markov: {} samples in all for {} inputs and num_lags = {}; the rule is "
                                 "total samples >= 2 * inputs * (num_lags + 1) = {}: add experiments, use longer "
                                 "records or fewer lags",
                                 total, m, L, 2 * m * (L + 1)));
  return total;
}

// Per experiment the views of the excitation (vs) and output (qs) columns with their
// offsets, and their centred energies (E x m, E x p).
struct MarkovChannels {
  std::vector<std::vector<ChannelView>> vs, qs;
  Eigen::MatrixXd v_energy, q_energy;  // sum_t (centred)^2
};

// Per-experiment column statistics (also the finiteness check).
MarkovChannels markov_channels(const std::vector<ExperimentView>& experiments, bool remove_mean, bool intercept) {
  const Index E = static_cast<Index>(experiments.size());
  const Index m = experiments[0].excitation.cols();
  const Index p = experiments[0].output.cols();
  MarkovChannels ch;
  ch.vs.resize(E);
  ch.qs.resize(E);
  ch.v_energy.resize(E, m);
  ch.q_energy.resize(E, p);
  for (Index e = 0; e < E; ++e) {
    const ExperimentView& x = experiments[e];
    for (Index a = 0; a < m; ++a) {
      const ColumnStats s = column_stats(x.excitation, a, remove_mean, e, "excitation");
      ch.vs[e].push_back({x.excitation.data() + a * x.excitation.outerStride(), intercept ? 0.0 : s.offset, s.active});
      ch.v_energy(e, a) = s.sum_sq;
    }
    for (Index i = 0; i < p; ++i) {
      const ColumnStats s = column_stats(x.output, i, remove_mean, e, "output");
      ch.qs[e].push_back({x.output.data() + i * x.output.outerStride(), s.offset, s.active});
      ch.q_energy(e, i) = s.sum_sq;
    }
  }
  return ch;
}

// kCorrelation: g[k] = R_qv(k) / sum v^2, each experiment counting only for the inputs
// it excites.
void estimate_by_correlation(const std::vector<ExperimentView>& experiments, const MarkovChannels& ch, Index L,
                             MarkovResult& res) {
  const Index E = static_cast<Index>(experiments.size());
  const Index m = ch.v_energy.cols(), p = ch.q_energy.cols();
  const Eigen::MatrixXd& v_energy = ch.v_energy;
  Eigen::VectorXd denom = Eigen::VectorXd::Zero(m);
  std::vector<Eigen::MatrixXd> rqv(static_cast<size_t>(L + 1));
  for (Index e = 0; e < E; ++e) {
    // RMS ratio >= fraction  <=>  mean-square ratio >= fraction^2 (records may differ
    // in length, so compare mean squares, not energies).
    const double n_e = static_cast<double>(experiments[e].excitation.rows());
    std::vector<ChannelView> excited = ch.vs[e];
    std::vector<Index> names;
    for (Index a = 0; a < m; ++a) {
      double largest_ms = 0.0;
      for (Index f = 0; f < E; ++f)
        largest_ms = std::max(largest_ms, v_energy(f, a) / static_cast<double>(experiments[f].excitation.rows()));
      const double ms = v_energy(e, a) / n_e;
      const bool is_excited = excited[a].active &&
          ms >= kExcitedFractionOfLargestRms * kExcitedFractionOfLargestRms * largest_ms;
      excited[a].active = is_excited;
      if (is_excited) {
        denom(a) += v_energy(e, a);
        names.push_back(a);
      }
    }
    if (names.size() > 1)
      res.report.warnings.push_back(fmt::format("experiment {} excites inputs {} at once: the correlation method "
                                                "ignores their cross-correlation; use the least-squares method",
                                                e, names));
    std::fill(rqv.begin(), rqv.end(), Eigen::MatrixXd::Zero(p, m));
    signal_detail::accumulate_cross_correlation(ch.qs[e], excited, experiments[e].excitation.rows(), L, rqv);
    for (Index k = 0; k <= L; ++k) res.g[k] += rqv[k];
  }
  for (Index k = 0; k <= L; ++k) res.g[k] = res.g[k] * denom.cwiseInverse().asDiagonal();
  res.report.termination = "correlation estimate g[k] = R_qv(k) / sum v^2 (biased: finite-sample autocorrelation of "
                           "the excitation is not a delta)";
  res.report.warnings.push_back("the correlation method is biased by the finite-sample autocorrelation of the "
                                "excitation and by the record end; use the least-squares method for accurate Markov "
                                "parameters");
}

// One pass per experiment: x = [q v] against y = v gives R_qv and R_vv together
// (rows 0..p-1 and p..p+m-1 of corr[k]); with `reuse`, see the header.
std::vector<Eigen::MatrixXd> output_input_correlations(const std::vector<ExperimentView>& experiments,
                                                       const MarkovChannels& ch, Index L,
                                                       MarkovCorrelations* reuse) {
  const Index E = static_cast<Index>(experiments.size());
  const Index m = ch.v_energy.cols(), p = ch.q_energy.cols();
  std::vector<Eigen::MatrixXd> corr(static_cast<size_t>(L + 1), Eigen::MatrixXd::Zero(p + m, m));
  if (reuse != nullptr && reuse->max_lag >= L && !reuse->vv.empty()) {
    if (static_cast<Index>(reuse->vv.size()) != reuse->max_lag + 1 || reuse->vv.front().rows() != m ||
        (!reuse->qv.empty() && (reuse->qv.size() != reuse->vv.size() || reuse->qv.front().rows() != p)))
      throw InputError("estimate_markov: the reused correlations do not match these experiments' channels");
    for (Index k = 0; k <= L; ++k) corr[k].bottomRows(m) = reuse->vv[static_cast<std::size_t>(k)];
    if (!reuse->qv.empty()) {
      for (Index k = 0; k <= L; ++k) corr[k].topRows(p) = reuse->qv[static_cast<std::size_t>(k)];
    } else {
      std::vector<Eigen::MatrixXd> qv(static_cast<size_t>(L + 1), Eigen::MatrixXd::Zero(p, m));
      for (Index e = 0; e < E; ++e)
        signal_detail::accumulate_cross_correlation(ch.qs[e], ch.vs[e], experiments[e].excitation.rows(), L, qv);
      for (Index k = 0; k <= L; ++k) corr[k].topRows(p) = qv[static_cast<std::size_t>(k)];
    }
    return corr;
  }
  const bool store = reuse != nullptr && reuse->max_lag > 0;
  const Index Lc = store ? std::max(reuse->max_lag, L) : L;
  if (store) {
    // The longest lag must leave N > Lc in every record (the FFT blocks' rule).
    Index shortest = experiments[0].excitation.rows();
    for (Index e = 1; e < E; ++e) shortest = std::min<Index>(shortest, experiments[e].excitation.rows());
    if (Lc >= shortest) throw InputError(fmt::format("estimate_markov: correlations up to lag {} asked of a "
                                                     "record of {} samples", Lc, shortest));
  }
  std::vector<Eigen::MatrixXd> full(store ? static_cast<size_t>(Lc + 1) : 0, Eigen::MatrixXd::Zero(p + m, m));
  for (Index e = 0; e < E; ++e) {
    std::vector<ChannelView> xs = ch.qs[e];
    xs.insert(xs.end(), ch.vs[e].begin(), ch.vs[e].end());
    signal_detail::accumulate_cross_correlation(xs, ch.vs[e], experiments[e].excitation.rows(), Lc,
                                                store ? full : corr);
  }
  if (store) {
    reuse->max_lag = Lc;
    reuse->vv.clear();
    reuse->qv.clear();
    for (Index k = 0; k <= Lc; ++k) {
      reuse->qv.push_back(full[static_cast<std::size_t>(k)].topRows(p));
      reuse->vv.push_back(full[static_cast<std::size_t>(k)].bottomRows(m));
    }
    for (Index k = 0; k <= L; ++k) corr[k] = full[static_cast<std::size_t>(k)];
  }
  return corr;
}

// Intercept: with the per-experiment offsets c_e eliminated, the normal matrix is
// Phi - sum_e N_e mu_e mu_e^T, mu_e(k m + a) = mean_t v_a(t - k) over the record
// (v = 0 before it), and the right-hand side is that of the centred outputs.
void intercept_lag_means(const std::vector<ExperimentView>& experiments, const MarkovChannels& ch, Index L,
                         std::vector<Eigen::VectorXd>& lag_means, std::vector<double>& lag_count) {
  const Index E = static_cast<Index>(experiments.size());
  const Index m = ch.v_energy.cols();
  for (Index e = 0; e < E; ++e) {
    const Index n = experiments[e].excitation.rows();
    Eigen::VectorXd mu = Eigen::VectorXd::Zero(m * (L + 1));
    for (Index a = 0; a < m; ++a) {
      if (!ch.vs[e][a].active) continue;
      const Eigen::VectorXd means = lag_means_of(ch.vs[e][a].data, n, L);
      for (Index k = 0; k <= L; ++k) mu(k * m + a) = means(k);
    }
    lag_means.push_back(std::move(mu));
    lag_count.push_back(static_cast<double>(n));
  }
}

// The least-squares solve's termination line, and its usability.
void report_markov_solve(const PcgOutcome& sol, bool regularized, const MarkovOptions& options, MarkovResult& res) {
  if (regularized) {
    res.report.termination = fmt::format(
        "regularised: TC kernel, hyperparameters by marginal likelihood on the first {} lags "
        "(decay per lag {:.4g}..{:.4g}); {}",
        res.kernel_tuning_lags, res.kernel_decay.minCoeff(), res.kernel_decay.maxCoeff(),
        sol.iterations == 0 ? std::string(sol.converged ? "solved exactly (dense Cholesky)" : "the dense solve failed")
                            : fmt::format("CG {} in {} iterations (relative residual {:.2e})",
                                          sol.converged ? "converged" : "stopped", sol.iterations,
                                          sol.worst_relative_residual));
    if (!sol.converged) res.report.usable = false;
  } else if (sol.converged) {
    res.report.termination = fmt::format("PCG converged in {} iterations (relative residual {:.2e} <= tolerance "
                                         "{:.1e})",
                                         sol.iterations, sol.worst_relative_residual, options.tolerance);
  } else {
    res.report.usable = false;
    res.report.termination = fmt::format("PCG stopped at max_iterations = {} with relative residual {:.2e} > tolerance "
                                         "{:.1e}; raise max_iterations or check the excitation (strongly coloured or "
                                         "nearly dependent inputs)",
                                         sol.iterations, sol.worst_relative_residual, options.tolerance);
  }
}

// kLeastSquares and kRegularized: the normal equations from the correlations, solved by
// PCG (or the regularised solve); sum_sq gets the residual energy per output from the
// normal equations.  Returns whether that energy is accurate (kAnalyticResidualMinFraction).
bool estimate_by_least_squares(const std::vector<ExperimentView>& experiments, const MarkovChannels& ch,
                               const MarkovOptions& options, bool intercept, Index total, MarkovCorrelations* reuse,
                               MarkovResult& res, Eigen::VectorXd& sum_sq) {
  const Index L = options.num_lags;
  const Index E = static_cast<Index>(experiments.size());
  const Index m = ch.v_energy.cols(), p = ch.q_energy.cols();
  const Eigen::MatrixXd& q_energy = ch.q_energy;
  const std::vector<Eigen::MatrixXd> corr = output_input_correlations(experiments, ch, L, reuse);
  std::vector<Eigen::MatrixXd> tails;
  for (Index e = 0; e < E; ++e) {
    const Index n = experiments[e].excitation.rows();
    Eigen::MatrixXd w = Eigen::MatrixXd::Zero(L, m);  // row s-1: v(N - s), s = 1..L
    for (Index a = 0; a < m; ++a) {
      if (!ch.vs[e][a].active) continue;
      for (Index s = 1; s <= L && n - s >= 0; ++s) w(s - 1, a) = ch.vs[e][a].data[n - s] - ch.vs[e][a].offset;
    }
    tails.push_back(std::move(w));
  }
  std::vector<Eigen::MatrixXd> rvv(static_cast<size_t>(L + 1));
  Eigen::MatrixXd rhs(m * (L + 1), p);
  for (Index k = 0; k <= L; ++k) {
    rvv[k] = corr[k].bottomRows(m);
    for (Index a = 0; a < m; ++a)
      for (Index i = 0; i < p; ++i) rhs(k * m + a, i) = corr[k](i, a);
  }
  rvv[0] = 0.5 * (rvv[0] + rvv[0].transpose()).eval();
  // Linearly dependent inputs make Phi singular: name them.
  const Eigen::VectorXd inv_sqrt = rvv[0].diagonal().cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd normalised = inv_sqrt.asDiagonal() * rvv[0] * inv_sqrt.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(normalised);
  if (eig.eigenvalues()(0) < kDependentInputsEigenvalue) {
    std::vector<Index> names;
    for (Index a = 0; a < m; ++a)
      if (std::abs(eig.eigenvectors()(a, 0)) > kDependentInputComponent) names.push_back(a + 1);  // 1-based
    throw InputError(fmt::format("estimate_markov: excitation inputs {} are linearly dependent over all experiments "
                                 "(e.g. identical): their Markov parameters cannot be separated; excite them "
                                 "independently (different signals or separate experiments)",
                                 names));
  }
  std::vector<Eigen::VectorXd> lag_means;
  std::vector<double> lag_count;
  if (intercept) intercept_lag_means(experiments, ch, L, lag_means, lag_count);
  const Eigen::LLT<Eigen::MatrixXd> r0(rvv[0]);
  NormalOperator op(rvv, tails, m, L, p, lag_means, lag_count);
  Eigen::MatrixXd x0;
  if (!options.initial_guess.empty()) {
    x0 = Eigen::MatrixXd::Zero(m * (L + 1), p);
    const Index K = std::min<Index>(L + 1, static_cast<Index>(options.initial_guess.size()));
    for (Index k = 0; k < K; ++k) {
      const Eigen::MatrixXd& gk = options.initial_guess[static_cast<std::size_t>(k)];
      if (gk.rows() != p || gk.cols() != m)
        throw InputError(fmt::format("estimate_markov: the initial guess is {}x{} at lag {}; the data are {}x{}",
                                     gk.rows(), gk.cols(), k, p, m));
      for (Index a = 0; a < m; ++a)
        for (Index i = 0; i < p; ++i) x0(k * m + a, i) = gk(i, a);
    }
  }
  const bool regularized = options.method == MarkovOptions::Method::kRegularized;
  const PcgOutcome sol =
      regularized ? solve_regularized(op, rvv, tails, lag_means, lag_count, rhs, q_energy.colwise().sum().transpose(),
                                      static_cast<double>(total - (intercept ? E : 0)), m, L, options, res)
                  : solve_pcg(op, rhs, r0, m, L, options.tolerance, options.max_iterations,
                              options.initial_guess.empty() ? nullptr : &x0);
  for (Index k = 0; k <= L; ++k)
    for (Index a = 0; a < m; ++a)
      for (Index i = 0; i < p; ++i) res.g[k](i, a) = sol.x(k * m + a, i);
  res.iterations = sol.iterations;
  Eigen::MatrixXd phi_x;
  op.apply(sol.x, phi_x);
  const Eigen::VectorXd q_energy_total = q_energy.colwise().sum().transpose();
  bool residual_known = true;
  for (Index i = 0; i < p; ++i) {
    sum_sq(i) = q_energy_total(i) - 2.0 * sol.x.col(i).dot(rhs.col(i)) + sol.x.col(i).dot(phi_x.col(i));
    residual_known = residual_known && sum_sq(i) >= kAnalyticResidualMinFraction * q_energy_total(i);
  }
  report_markov_solve(sol, regularized, options, res);
  return residual_known;
}

// Residual energy per output of the estimated model by FFT convolution over the data.
Eigen::VectorXd markov_residual_energy(const std::vector<ExperimentView>& experiments, const MarkovChannels& ch,
                                       const MarkovSequence& g, Index L, bool intercept) {
  const Index E = static_cast<Index>(experiments.size());
  const Index m = ch.v_energy.cols(), p = ch.q_energy.cols();
  Eigen::VectorXd sum_sq = Eigen::VectorXd::Zero(p);
  for (Index e = 0; e < E; ++e) {
    const Index n = experiments[e].excitation.rows();
    Eigen::VectorXd part = Eigen::VectorXd::Zero(p);
    signal_detail::accumulate_fir_residual_energy(ch.vs[e], ch.qs[e], n, g, part);
    if (intercept) {
      // e'(t) = (q - mean q) - sum_k g[k] v(t - k) has mean -delta_e with
      // delta_e = sum_k g[k] mu_e(k); the residual e' + delta_e has energy
      // sum e'^2 - n |delta_e|^2 per output.
      Eigen::VectorXd delta = Eigen::VectorXd::Zero(p);
      for (Index a = 0; a < m; ++a) {
        if (!ch.vs[e][a].active) continue;
        const Eigen::VectorXd means = lag_means_of(ch.vs[e][a].data, n, L);
        for (Index k = 0; k <= L; ++k) delta += g[k].col(a) * means(k);
      }
      part -= static_cast<double>(n) * delta.cwiseAbs2();
    }
    sum_sq += part.cwiseMax(0.0);
  }
  return sum_sq;
}

}  // namespace

void MarkovOptions::validate() const {
  if (num_lags <= 0)
    throw InputError(fmt::format(
        "Markov options: num_lags = {}; it must be > 0 (the number L of lags, g[0..L] is estimated)", num_lags));
  if (!(tolerance > 0.0 && tolerance < 1.0))
    throw InputError(fmt::format(
        "Markov options: tolerance = {}; it must be in (0, 1) (relative residual of the iterative solve, e.g. 1e-10)",
        tolerance));
  if (max_iterations <= 0)
    throw InputError(fmt::format("Markov options: max_iterations = {}; it must be > 0", max_iterations));
  if (arx_order < 0)
    throw InputError(fmt::format("Markov options: arx_order = {}; it must be >= 0 (0: chosen from the data)", arx_order));
  if (regularized_tuning_lags < 2)
    throw InputError(fmt::format("Markov options: regularized_tuning_lags = {}; it must be >= 2",
                                 regularized_tuning_lags));
}

Index default_markov_lags(Index shortest_record, Index total_samples, Index num_excitations) {
  if (shortest_record < 1 || total_samples < shortest_record || num_excitations < 1)
    throw InputError(fmt::format("default Markov horizon: {} samples in the shortest record, {} in all, {} excitation "
                                 "column(s); give records and at least one excitation",
                                 shortest_record, total_samples, num_excitations));
  const Index by_record = shortest_record / 4, by_data = total_samples / (4 * num_excitations);
  const Index lags = std::min({by_record, by_data, kMaxDefaultMarkovLags});
  if (lags < kMinDefaultMarkovLags) {
    if (by_record < kMinDefaultMarkovLags)
      throw InputError(fmt::format("a record of {} samples supports only {} lags by default (a quarter of the "
                                   "shortest record), fewer than {}; record at least {} samples, or give --lags",
                                   shortest_record, by_record, kMinDefaultMarkovLags, 4 * kMinDefaultMarkovLags));
    throw InputError(fmt::format("{} samples in all for {} excitation columns support only {} lags by default (4 "
                                 "samples per unknown), fewer than {}; record at least {} samples in all, or give "
                                 "--lags",
                                 total_samples, num_excitations, by_data, kMinDefaultMarkovLags,
                                 4 * num_excitations * kMinDefaultMarkovLags));
  }
  return lags;
}

MarkovResult estimate_markov(const std::vector<ExperimentView>& experiments,
                             const MarkovOptions& options, MarkovCorrelations* reuse) {
  options.validate();
  const Index L = options.num_lags;
  const Index total = check_markov_experiments(experiments, L);
  const Index E = static_cast<Index>(experiments.size());
  const Index m = experiments[0].excitation.cols();
  const Index p = experiments[0].output.cols();

  // Least squares with remove_mean: a constant output offset per experiment is
  // estimated jointly with g (an intercept), so the excitation stays as logged (zero
  // before the record) and only the outputs are centred; see the header.
  const bool intercept = options.remove_mean && options.method != MarkovOptions::Method::kCorrelation;
  const MarkovChannels ch = markov_channels(experiments, options.remove_mean, intercept);
  const Eigen::VectorXd v_energy_total = ch.v_energy.colwise().sum().transpose();
  for (Index a = 0; a < m; ++a)
    if (!(v_energy_total(a) > 0.0))
      throw InputError(fmt::format("estimate_markov: excitation input {} is constant{} in every experiment, so its "
                                   "Markov parameters are not identifiable: excite it in at least one experiment or "
                                   "drop the column",
                                   a + 1, options.remove_mean ? " (zero after mean removal)" : " zero"));

  MarkovResult res;
  if (options.method == MarkovOptions::Method::kArx) res = estimate_markov_arx(experiments, options);
  res.total_samples = total;
  res.excitation_rms = (v_energy_total / static_cast<double>(total)).cwiseSqrt();
  res.output_rms = (ch.q_energy.colwise().sum().transpose() / static_cast<double>(total)).cwiseSqrt();
  Eigen::VectorXd sum_sq = Eigen::VectorXd::Zero(p);  // residual energy per output
  bool residual_known = false;
  if (options.method != MarkovOptions::Method::kArx) res.g.assign(static_cast<size_t>(L + 1), Eigen::MatrixXd::Zero(p, m));
  if (options.method == MarkovOptions::Method::kCorrelation)
    estimate_by_correlation(experiments, ch, L, res);
  else if (options.method != MarkovOptions::Method::kArx)  // kArx: its residual as an FIR below
    residual_known = estimate_by_least_squares(experiments, ch, options, intercept, total, reuse, res, sum_sq);
  if (!residual_known) sum_sq = markov_residual_energy(experiments, ch, res.g, L, intercept);

  // kRegularized: the prior keeps the effective number of parameters far below m (L + 1);
  // the residual energy over the samples is its noise estimate (slightly high).
  // kArx: the noise as least squares defines it (the residual of g as a finite impulse
  // response, not the ARX model's one-step innovation, which is far smaller and would put
  // realize's floor under the estimate's own error), with the ARX model's unknowns.
  const Index unknowns = options.method == MarkovOptions::Method::kRegularized ? 0
                         : options.method == MarkovOptions::Method::kArx       ? m + res.arx_order * (1 + m)
                                                                               : m * (L + 1);
  const double dof = static_cast<double>(total - unknowns - (intercept ? E : 0));
  const Eigen::VectorXd sigma = (sum_sq / dof).cwiseSqrt();
  res.noise_std = sigma * v_energy_total.cwiseSqrt().cwiseInverse().transpose();
  // kRegularized: noise_std stays the formula above (the level realize's order rule is
  // calibrated on).  Measured on a 2 x 2 plant under a 15 Hz fourth-order low-pass input
  // with 10 % noise: the posterior standard deviation instead (RMS over the lags) raised
  // realize's floor above every singular value, the prior's variance in the directions the
  // input never excites dominating it.
  return res;
}

}  // namespace lpvid
