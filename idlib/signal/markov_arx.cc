#include "idlib/signal/markov_arx.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/signal/correlation.h"

namespace lpvid {
namespace {

// The largest order the criterion is evaluated at, whatever the horizon: the observer of
// a plant of n states needs about n / p lags; 60 covers 60 p states with room for the
// noise's own colour.
constexpr Index kMaxArxOrder = 60;
// Samples per unknown of one output's regression at the largest order tried.
constexpr double kSamplesPerUnknown = 8.0;
// A residual below this fraction of the output energy is round-off: noise-free data,
// the first order that reaches it is the order (a 100 dB signal-to-noise ratio no
// measurement reaches; measured at the exact order of noise-free logs: 6e-12, the
// Cholesky jitter's level, against 6e-5 one order below).
constexpr double kRoundOffResidual = 1e-10;
// When the best-scored order grows and the best order that does not grow scores worse
// by more than this (in AICc), the data give the decaying order no support — a
// difference of 10 is a relative likelihood exp(-5) < 1 % (Burnham & Anderson, Model
// Selection and Multimodel Inference, 2002, §2.6) — and the estimate says so.  It is a
// warning, not a refusal: on the steel subframe (a stable structure, 28 outputs) order 60
// with a pole at |z| 1.014 scores 1.09e4 below order 54, which predicts held-out halves
// far better than least squares (2.52 % against 7.41 % missed): with N = 28 x 8463
// residuals, AICc differences grow with N, and a spurious pole can win by thousands.
constexpr double kGrowthEvidence = 10.0;
// Added to the unit diagonal of a Jacobi-scaled Gram matrix whose Cholesky factorisation
// fails: lags that are exactly collinear (noise-free data, orders above the true one)
// then factor, at a relative perturbation far below any noise.
constexpr double kCholeskyJitter = 1e-13;

struct Normal {
  Eigen::MatrixXd psi;      // W x W, W = (n_max + 1) nz: Σ_t w_t w_tᵀ, each window centred
  Index samples = 0;        // Σ_e (N_e − n_max)
};

// Σ_{t=n..N-1} w_t w_tᵀ with w_t = [z_t; z_{t-1}; ...; z_{t-n}] from the correlations
// R[d] = Σ_{s=d}^{N-1} z_s z_{s-d}ᵀ and the terms at the record's two ends that the
// window leaves out; then the window's own mean removed (the intercept).
void accumulate(const Eigen::MatrixXd& z, Index n, Normal& out) {
  const Index N = z.rows(), nz = z.cols();
  const std::vector<Eigen::MatrixXd> R = autocorrelation(z, n);
  for (Index i = 0; i <= n; ++i)
    for (Index j = i; j <= n; ++j) {
      const Index d = j - i;
      Eigen::MatrixXd blk = R[static_cast<std::size_t>(d)];
      for (Index s = d; s <= n - i - 1; ++s) blk.noalias() -= z.row(s).transpose() * z.row(s - d);
      for (Index s = std::max(N - i, d); s <= N - 1; ++s) blk.noalias() -= z.row(s).transpose() * z.row(s - d);
      out.psi.block(i * nz, j * nz, nz, nz) += blk;
      if (j != i) out.psi.block(j * nz, i * nz, nz, nz) += blk.transpose();
    }
  Eigen::VectorXd sum((n + 1) * nz);
  for (Index i = 0; i <= n; ++i) sum.segment(i * nz, nz) = z.middleRows(n - i, N - n).colwise().sum().transpose();
  const double count = static_cast<double>(N - n);
  out.psi.noalias() -= sum * sum.transpose() / count;
  out.samples += N - n;
}

// The largest order the records support: N' >= kSamplesPerUnknown (m + n (1 + m)), the
// unknowns of one output's regression.
Index supported_order(const std::vector<ExperimentView>& experiments, Index n_limit, Index m) {
  for (Index n = n_limit; n >= 1; --n) {
    double samples = 0.0;
    bool fits = true;
    for (const ExperimentView& x : experiments) {
      fits = fits && x.output.rows() > n + 1;
      samples += static_cast<double>(x.output.rows() - n - 1);  // − 1: the intercept
    }
    if (fits && samples >= kSamplesPerUnknown * static_cast<double>(m + n * (1 + m))) return n;
  }
  return 0;
}

// Solves a symmetric positive semidefinite system after Jacobi scaling.
Eigen::MatrixXd solve_spd(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  Eigen::VectorXd scale = a.diagonal().cwiseSqrt();
  for (Index k = 0; k < scale.size(); ++k) scale(k) = scale(k) > 0.0 ? 1.0 / scale(k) : 1.0;
  const Eigen::MatrixXd as = scale.asDiagonal() * a * scale.asDiagonal();
  return scale.asDiagonal() * Eigen::MatrixXd(as.ldlt().solve(scale.asDiagonal() * b));
}

// The common-denominator ARX at one order n:
//   q_i(t) = Σ_{k=1}^{n} a_k q_i(t − k) + Σ_{k=0}^{n} B_{i,k} v(t − k) + c_{i,e} + e_i(t),
// a shared by every output (a linear system's outputs share its characteristic
// polynomial), each output weighted by the inverse of its energy (units do not matter).
// With the B_i eliminated (variable projection: for given a each B_i is least squares on
// the lagged excitation V), a solves Σ_i w_i Ỹ_iᵀ Ỹ_i a = Σ_i w_i Ỹ_iᵀ q̃_i, with x̃ = x
// minus its projection on V; every term from the Gram matrices of [q_i, v] at lags 0..n.
struct OrderFit {
  Eigen::VectorXd a;       // n
  Eigen::MatrixXd b;       // m (n + 1) x p: column i = B_{i,0..n} stacked lag-major
  Eigen::VectorXd residual;  // p: Σ_t e_i(t)²
  double radius = 0.0;     // largest |root| of z^n − a_1 z^(n−1) − ... − a_n
};

OrderFit solve_order(const std::vector<Eigen::MatrixXd>& psi, Index n, Index m) {
  const Index nz = 1 + m, p = static_cast<Index>(psi.size()), dv = m * (n + 1), d = dv + n;
  // Per output the Gram matrix of the regressors ordered [V, Y], Jacobi-scaled (D), and its
  // Cholesky factor L = [L11 0; L21 L22]; c = L⁻¹ D Xᵀq s (s = 1 / ‖q‖).  Then Ỹᵀ Ỹ =
  // D_Y⁻¹ L22 L22ᵀ D_Y⁻¹ and Ỹᵀ q̃ = D_Y⁻¹ L22 c_Y / s, formed from the factor and so free
  // of the cancellation Gyy − Gyv Gvv⁻¹ Gvy suffers when the outputs are nearly a filtered
  // copy of the excitation (measured on the DaISy robot arm: residuals that rose with the
  // order and spurious poles outside).  A round-off jitter on the diagonal only when the
  // regressors are exactly collinear (noise-free data above the plant's order).
  std::vector<Index> idx;
  for (Index k = 0; k <= n; ++k)
    for (Index a = 0; a < m; ++a) idx.push_back(k * nz + 1 + a);
  for (Index k = 1; k <= n; ++k) idx.push_back(k * nz);
  const std::vector<Index> qi{0};
  struct Factored {
    Eigen::MatrixXd L;
    Eigen::VectorXd c, sc;
    double sq = 1.0;
  };
  std::vector<Factored> fs(static_cast<std::size_t>(p));
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd r = Eigen::VectorXd::Zero(n);
  for (Index i = 0; i < p; ++i) {
    const Eigen::MatrixXd& P = psi[static_cast<std::size_t>(i)];
    Factored& F = fs[static_cast<std::size_t>(i)];
    Eigen::MatrixXd g = P(idx, idx);
    F.sc = g.diagonal().cwiseSqrt();
    for (Index k = 0; k < d; ++k) F.sc(k) = F.sc(k) > 0.0 ? 1.0 / F.sc(k) : 1.0;
    F.sq = P(0, 0) > 0.0 ? 1.0 / std::sqrt(P(0, 0)) : 1.0;
    g = F.sc.asDiagonal() * g * F.sc.asDiagonal();
    Eigen::LLT<Eigen::MatrixXd> llt(g);
    if (llt.info() != Eigen::Success) {
      g.diagonal().array() += kCholeskyJitter;
      llt.compute(g);
    }
    F.L = llt.matrixL();
    F.c = F.L.triangularView<Eigen::Lower>().solve(F.sc.cwiseProduct(P(idx, qi).col(0)) * F.sq);
    const Eigen::VectorXd dy = F.sc.tail(n).cwiseInverse();
    const Eigen::MatrixXd L22 = F.L.bottomRightCorner(n, n);
    // weight 1 / ‖q_i‖²: Ỹᵀ Ỹ / ‖q‖² and Ỹᵀ q̃ / ‖q‖² in the scaled factor's terms
    M += (dy.asDiagonal() * L22 * L22.transpose() * dy.asDiagonal()) * F.sq * F.sq;
    r += dy.asDiagonal() * (L22 * F.c.tail(n)) * F.sq;
  }
  OrderFit f;
  f.a = solve_spd(0.5 * (M + M.transpose()), r);
  f.b.resize(dv, p);
  f.residual.resize(p);
  for (Index i = 0; i < p; ++i) {
    const Factored& F = fs[static_cast<std::size_t>(i)];
    // In the scaled coordinates a_s = s D_Y⁻¹ a: residual (‖c_Y − L22ᵀ a_s‖² + 1 − ‖c‖²) / s²;
    // the excitation's coefficients b_s = L11⁻ᵀ (c_V − L21ᵀ a_s), b = D_V b_s / s.
    const Eigen::VectorXd as = F.sq * F.sc.tail(n).cwiseInverse().cwiseProduct(f.a);
    const double rest = std::max(0.0, 1.0 - F.c.squaredNorm());
    f.residual(i) = ((F.c.tail(n) - F.L.bottomRightCorner(n, n).transpose() * as).squaredNorm() + rest) / (F.sq * F.sq);
    const Eigen::VectorXd rhs = F.c.head(dv) - F.L.block(dv, 0, n, dv).transpose() * as;
    const Eigen::VectorXd bs = F.L.topLeftCorner(dv, dv).transpose().triangularView<Eigen::Upper>().solve(rhs);
    f.b.col(i) = F.sc.head(dv).cwiseProduct(bs) / F.sq;
  }
  Eigen::MatrixXd comp = Eigen::MatrixXd::Zero(n, n);
  comp.row(0) = f.a.transpose();
  if (n > 1) comp.bottomLeftCorner(n - 1, n - 1).setIdentity();
  f.radius = Eigen::EigenSolver<Eigen::MatrixXd>(comp, false).eigenvalues().cwiseAbs().maxCoeff();
  return f;
}

}  // namespace

MarkovResult estimate_markov_arx(const std::vector<ExperimentView>& experiments, const MarkovOptions& options) {
  const Index L = options.num_lags;
  const Index m = experiments[0].excitation.cols(), p = experiments[0].output.cols(), nz = 1 + m;
  const Index limit = options.arx_order > 0 ? options.arx_order : std::min(L, kMaxArxOrder);
  const Index n_max = supported_order(experiments, limit, m);
  if (n_max < 1 || (options.arx_order > 0 && n_max < options.arx_order))
    throw InputError(fmt::format(
        "estimate_markov (arx): the records support ARX order {} at most ({} samples per unknown of an output), not "
        "{}; give a lower --arx-order, or record longer",
        n_max, kSamplesPerUnknown, options.arx_order > 0 ? options.arx_order : Index{1}));

  // Per output the Gram matrix of [q_i, v] at lags 0..n_max over the common samples.
  std::vector<Eigen::MatrixXd> psi(static_cast<std::size_t>(p));
  Index window = 0;
  for (Index i = 0; i < p; ++i) {
    Normal nq;
    nq.psi = Eigen::MatrixXd::Zero((n_max + 1) * nz, (n_max + 1) * nz);
    for (const ExperimentView& x : experiments) {
      Eigen::MatrixXd z(x.output.rows(), nz);
      z << x.output.col(i), x.excitation;
      z.rowwise() -= z.colwise().mean();  // numerics only: the intercept is exact
      accumulate(z, n_max, nq);
    }
    psi[static_cast<std::size_t>(i)] = std::move(nq.psi);
    window = nq.samples;
  }
  const double samples = static_cast<double>(window - static_cast<Index>(experiments.size()));

  MarkovResult res;
  res.arx_max_order = n_max;
  res.arx_criterion = Eigen::VectorXd::Constant(n_max, std::numeric_limits<double>::infinity());
  // AICc over the outputs (each its own noise variance): Σ_i N' log σ̂²_i + 2 k N (N − k − 1)⁻¹
  // with N = p N' residuals and k = n + p m (n + 1) unknowns; noise-free data stop at the
  // first order whose residuals are round-off.  Then the best-scored order whose
  // autoregressive part lets the response decay, or hold as an integrator does (|z| up to
  // 1 + 0.1 / L: a growth of at most e^0.1 over the horizon).
  const double growth_limit = 1.0 + 0.1 / static_cast<double>(std::max<Index>(L, 1));
  std::vector<OrderFit> fits;
  Index chosen = 0, rejected = 0, growing_best = 0;
  double growing_gap = 0.0;
  bool exact = false;
  if (options.arx_order > 0) {
    fits.push_back(solve_order(psi, options.arx_order, m));
    chosen = options.arx_order;
    if (fits.front().radius > growth_limit)
      throw NumericalError(fmt::format(
          "estimate_markov (arx): ARX order {} has a pole at |z| = {:.6g}, so its response grows without bound over "
          "the {} lags; give another --arx-order, or leave it out for the criterion's choice among the orders whose "
          "response does not grow",
          chosen, fits.front().radius, L));
  } else {
    Eigen::VectorXd energy(p);
    for (Index i = 0; i < p; ++i) energy(i) = psi[static_cast<std::size_t>(i)](0, 0);
    for (Index n = 1; n <= n_max && !exact; ++n) {
      fits.push_back(solve_order(psi, n, m));
      const OrderFit& f = fits.back();
      const double N = samples * static_cast<double>(p), k = static_cast<double>(n + p * m * (n + 1));
      double loglik = 0.0;
      for (Index i = 0; i < p; ++i)
        loglik += samples * std::log(std::max(f.residual(i), kRoundOffResidual * energy(i)) / samples);
      res.arx_criterion(n - 1) =
          N - k - 1.0 > 0.0 ? loglik + 2.0 * k * N / (N - k - 1.0) : std::numeric_limits<double>::infinity();
      exact = (f.residual.array() <= kRoundOffResidual * energy.array()).all() && f.radius <= growth_limit;
      if (exact) chosen = n;
    }
    if (!exact) {
      std::vector<Index> order;
      for (Index n = 1; n <= n_max; ++n)
        if (std::isfinite(res.arx_criterion(n - 1))) order.push_back(n);
      std::stable_sort(order.begin(), order.end(),
                       [&](Index a, Index b) { return res.arx_criterion(a - 1) < res.arx_criterion(b - 1); });
      for (const Index n : order) {
        if (fits[static_cast<std::size_t>(n - 1)].radius <= growth_limit) {
          chosen = n;
          break;
        }
        ++rejected;
      }
      if (chosen > 0 && rejected > 0) {
        growing_best = order.front();
        growing_gap = res.arx_criterion(chosen - 1) - res.arx_criterion(growing_best - 1);
      }
    }
  }
  if (chosen == 0)
    throw NumericalError(fmt::format(
        "estimate_markov (arx): every ARX order 1..{} these records support has a pole outside the unit circle, so "
        "its response grows without bound; use least squares (--method ls) or the regularised estimate",
        n_max));
  const OrderFit& f = options.arx_order > 0 ? fits.front() : fits[static_cast<std::size_t>(chosen - 1)];

  // Markov parameters by the recursion in the header.
  res.g.assign(static_cast<std::size_t>(L + 1), Eigen::MatrixXd::Zero(p, m));
  for (Index k = 0; k <= L; ++k) {
    Eigen::MatrixXd gk = Eigen::MatrixXd::Zero(p, m);
    if (k <= chosen)
      for (Index i = 0; i < p; ++i) gk.row(i) = f.b.col(i).segment(k * m, m).transpose();
    for (Index j = 1; j <= std::min(k, chosen); ++j) gk += f.a(j - 1) * res.g[static_cast<std::size_t>(k - j)];
    res.g[static_cast<std::size_t>(k)] = std::move(gk);
  }
  res.arx_order = chosen;
  res.arx_denominator = f.a;
  res.arx_spectral_radius = f.radius;
  const std::string rule =
      options.arx_order > 0 ? std::string("given")
      : exact               ? std::string("noise-free data: the first order whose residuals are at round-off")
      : rejected == 0       ? std::string("the smallest corrected Akaike criterion (AICc)")
                            : fmt::format("the smallest corrected Akaike criterion (AICc) among the orders whose "
                                          "response does not grow; {} better-scored order(s) had a pole outside, the "
                                          "best of them order {}, {:.3g} lower",
                                          rejected, growing_best, growing_gap);
  res.report.termination = fmt::format(
      "ARX order {} with one denominator for every output ({}; orders 1..{} tried on the same {} samples), Markov "
      "parameters by its recursion",
      chosen, rule, n_max, window);
  if (res.arx_spectral_radius >= 1.0)
    res.report.warnings.push_back(fmt::format(
        "the ARX model's autoregressive part has a pole at |z| = {:.6g}: its impulse response does not decay (an "
        "integrating or unstable response, or too little data for the order)",
        res.arx_spectral_radius));
  if (growing_gap > kGrowthEvidence)
    res.report.warnings.push_back(fmt::format(
        "the best-scored ARX order, {}, has a pole at |z| = {:.6g} and scores {:.3g} below order {}, the best whose "
        "response does not grow (a difference above {:g} leaves the smaller order no support): either the plant's "
        "response truly grows, which no decaying ARX model describes, or the higher orders fit a spurious pole; judge "
        "the estimate on data it did not see (the default method compares it with least squares on held-out halves)",
        growing_best, fits[static_cast<std::size_t>(growing_best - 1)].radius, growing_gap, chosen, kGrowthEvidence));
  if (options.arx_order == 0 && chosen == n_max && n_max < kMaxArxOrder)
    res.report.warnings.push_back(fmt::format(
        "the criterion was still falling at order {}, the largest these records support: a longer record would "
        "allow a higher order",
        n_max));
  return res;
}

}  // namespace lpvid
