#include "idlib/signal/markov_regularized.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <nlopt.hpp>
#include <vector>

#include "idlib/core/error.h"

namespace lpvid::markov_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Problem {
  const Eigen::MatrixXd* phi;
  const Eigen::VectorXd* b;
  double yy, samples;
  Index m;
  int evaluations = 0;
};

TcKernel kernel_of(const double* x, Index m) {
  TcKernel k;
  k.gamma.resize(m);
  k.rate.resize(m);
  for (Index a = 0; a < m; ++a) {
    k.gamma(a) = std::exp(x[a]);
    k.rate(a) = std::exp(x[m + a]);
  }
  return k;
}

double objective(unsigned n, const double* x, double* /*grad*/, void* data) {
  auto* pr = static_cast<Problem*>(data);
  ++pr->evaluations;
  (void)n;
  const double f = tc_objective(*pr->phi, *pr->b, pr->yy, pr->samples, pr->m, kernel_of(x, pr->m));
  return std::isfinite(f) ? f : 1e300;
}

}  // namespace

Eigen::VectorXd tc_inverse_weights(double rate, Index L) {
  Eigen::VectorXd w(L + 1);
  // log(1 / (1 − λ)) = −log(−expm1(−r)), accurate for λ near 1.
  const double log_one_minus = std::log(-std::expm1(-rate));
  for (Index k = 0; k <= L; ++k) {
    const double log_w = static_cast<double>(k) * rate - (k < L ? log_one_minus : 0.0);
    w(k) = std::exp(std::min(log_w, kMaxLogTcWeight));
  }
  return w;
}

double tc_objective(const Eigen::MatrixXd& phi, const Eigen::VectorXd& b, double yy, double samples, Index m,
                    const TcKernel& kernel, double* noise_variance, Eigen::VectorXd* mean) {
  const Index n = phi.rows(), L = n / m - 1;
  Eigen::MatrixXd a = phi;
  double log_det_prior = 0.0;  // Σ_a [(L + 1) log γ_a + Σ_k log w_k]
  for (Index j = 0; j < m; ++j) {
    const Eigen::VectorXd w = tc_inverse_weights(kernel.rate(j), L);
    const double g = kernel.gamma(j);
    log_det_prior += static_cast<double>(L + 1) * std::log(g) + w.array().log().sum();
    for (Index k = 0; k <= L; ++k) {
      const Index i = k * m + j;
      a(i, i) += g * (w(k) + (k > 0 ? w(k - 1) : 0.0));
      if (k < L) {
        a(i, i + m) -= g * w(k);
        a(i + m, i) -= g * w(k);
      }
    }
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(a);
  if (llt.info() != Eigen::Success) return kInf;
  const Eigen::VectorXd h = llt.solve(b);
  const double q = yy - b.dot(h);
  if (!(q > 0.0)) return kInf;
  const double log_det_a = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  if (noise_variance != nullptr) *noise_variance = q / samples;
  if (mean != nullptr) *mean = h;
  return samples * std::log(q / samples) + samples - log_det_prior + log_det_a;
}

TcTuning tune_tc_kernel(const Eigen::MatrixXd& phi, const Eigen::VectorXd& b, double yy, double samples, Index m) {
  const Index n = phi.rows();
  if (m < 1 || n % m != 0 || n / m < 2 || phi.cols() != n || b.size() != n || !(samples > 0.0))
    throw InputError(fmt::format("tune_tc_kernel: a {}x{} normal matrix, {} right-hand side entries, {} inputs, {} "
                                 "samples do not fit together",
                                 phi.rows(), phi.cols(), b.size(), m, samples));
  const Index L = n / m - 1;
  // Bounds: γ_a relative to input a's energy Φ(a, a) (from 1e-11 to 1e4 of it), the decay
  // from a thousandth of the window's reciprocal (λ^L ≈ 1: no decay over it) to e^−3 per lag.
  std::vector<double> lo(2 * m), hi(2 * m);
  for (Index a = 0; a < m; ++a) {
    const double energy = std::max(phi(a, a), std::numeric_limits<double>::min());
    lo[a] = std::log(energy) - 25.0;
    hi[a] = std::log(energy) + 9.0;
    lo[m + a] = std::log(1e-3 / static_cast<double>(L));
    hi[m + a] = std::log(3.0);
  }
  Problem pr{&phi, &b, yy, samples, m};
  TcTuning best;
  best.objective = kInf;
  std::vector<double> x_best;
  // Two starts for the decay (the likelihood can have a local optimum in λ): the window
  // holding about 4 and about 0.5 time constants.
  for (const double periods : {4.0, 0.5}) {
    std::vector<double> x(2 * m);
    for (Index a = 0; a < m; ++a) {
      x[a] = std::log(std::max(phi(a, a), std::numeric_limits<double>::min())) - 8.0;
      x[m + a] = std::log(periods / static_cast<double>(L));
    }
    nlopt::opt opt(nlopt::LN_BOBYQA, static_cast<unsigned>(2 * m));
    opt.set_lower_bounds(lo);
    opt.set_upper_bounds(hi);
    opt.set_min_objective(objective, &pr);
    opt.set_maxeval(static_cast<int>(50 * 2 * m));
    // The objective is −2 log-likelihood: changes below 1e-2 do not move the estimate (a
    // likelihood ratio of 1.005); 50 evaluations per hyperparameter and start bound the work.
    opt.set_ftol_abs(1e-2);
    opt.set_initial_step(std::vector<double>(2 * m, 1.0));
    double f = kInf;
    try {
      opt.optimize(x, f);
    } catch (const std::exception&) {
      f = objective(static_cast<unsigned>(x.size()), x.data(), nullptr, &pr);  // keep the point reached
    }
    if (f < best.objective) {
      best.objective = f;
      x_best = x;
    }
  }
  best.kernel = kernel_of(x_best.data(), m);
  best.evaluations = pr.evaluations;
  tc_objective(phi, b, yy, samples, m, best.kernel, &best.noise_variance);
  return best;
}

void tc_to_unknowns(const Eigen::Ref<const Eigen::VectorXd>& beta, const Eigen::MatrixXd& weights,
                    Eigen::Ref<Eigen::VectorXd> h) {
  const Index m = weights.cols(), L = weights.rows() - 1;
  for (Index a = 0; a < m; ++a) {
    double sum = 0.0;
    for (Index k = L; k >= 0; --k) {
      sum += beta(k * m + a) / std::sqrt(weights(k, a));
      h(k * m + a) = sum;
    }
  }
}

void tc_to_whitened(const Eigen::Ref<const Eigen::VectorXd>& h, const Eigen::MatrixXd& weights,
                    Eigen::Ref<Eigen::VectorXd> beta) {
  const Index m = weights.cols(), L = weights.rows() - 1;
  for (Index a = 0; a < m; ++a) {
    double sum = 0.0;
    for (Index k = 0; k <= L; ++k) {
      sum += h(k * m + a);
      beta(k * m + a) = sum / std::sqrt(weights(k, a));
    }
  }
}

}  // namespace lpvid::markov_detail
