// lpvid — the regularised (kernel-based) Markov estimate's pieces: the TC ("tuned /
// correlated") kernel prior of Chen, Ohlsson & Ljung (Automatica 48, 2012) and Pillonetto
// & De Nicolao (2010), its hyperparameters by marginal likelihood (empirical Bayes), and the
// change of coordinates that makes the posterior mean a well-conditioned ridge problem.
//
// Model per output i (one row of g, the unknowns h in the layout k m + a of markov.cc):
//   q_i = X h + e,  e ~ N(0, σ² I),  h_a = (g[0..L](i, a)) ~ N(0, c_a K(λ_a)),
//   K(λ)(k, l) = λ^max(k, l)  (TC: smooth and exponentially decaying, stable by prior).
// K = U D Uᵀ with U the upper-triangular matrix of ones and D = diag(d_k),
//   d_k = λ^k (1 − λ) for k < L, d_L = λ^L,
// so hᵀ K⁻¹ h = Σ_{k<L} w_k (h_k − h_{k+1})² + w_L h_L², w_k = 1 / d_k: a tridiagonal
// inverse.  w_k is capped at e^kMaxLogTcWeight (the prior then pins h_k to zero; the cap
// is part of the kernel, so the likelihood stays consistent with it).
//
// With γ_a = σ² / c_a and A = Φ + Σ_a γ_a K_a⁻¹ (Φ = XᵀX, b = Xᵀ q_i, yy = q_iᵀ q_i, all
// after the intercepts are projected out, N' = samples − intercepts), σ² profiled out
// (σ̂² = Q / N', Q = yy − bᵀ A⁻¹ b):
//   −2 log p(q_i) = N' log(Q / N') + N' − Σ_a (L + 1) log γ_a − Σ_a Σ_k log w_{a,k} + log det A
// (up to a constant).  Posterior mean ĥ = A⁻¹ b.
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid::markov_detail {

inline constexpr double kMaxLogTcWeight = 230.0;  // w_k <= e^230 ≈ 1e100

// The kernel of one output: per input a, the ratio γ_a = σ² / c_a and the decay rate
// r_a = −log λ_a per lag.
struct TcKernel {
  Eigen::VectorXd gamma, rate;
};

// w_0..w_L of K(λ)⁻¹ = U⁻ᵀ diag(w) U⁻¹, λ = e^(−rate), capped as above.
Eigen::VectorXd tc_inverse_weights(double rate, Index L);

struct TcTuning {
  TcKernel kernel;
  double noise_variance = 0.0;  // σ̂² = Q / N'
  double objective = 0.0;       // −2 log p at the optimum (up to a constant)
  int evaluations = 0;
};

// Hyperparameters of one output by maximum marginal likelihood (NLopt BOBYQA over
// log γ_a and log r_a, two starts).  | phi: n × n, n = m (L + 1) | b: n |
// @throws InputError  shapes that do not match.
TcTuning tune_tc_kernel(const Eigen::MatrixXd& phi, const Eigen::VectorXd& b, double yy, double samples, Index m);

// −2 log p for the given kernel (the objective above); +inf when A is not positive
// definite.  Exposed for the tests.
double tc_objective(const Eigen::MatrixXd& phi, const Eigen::VectorXd& b, double yy, double samples, Index m,
                    const TcKernel& kernel, double* noise_variance = nullptr, Eigen::VectorXd* mean = nullptr);

// The whitening map of one output's unknowns: h = T β with T = blockdiag_a(U diag(w_a)^(−1/2)),
// so that hᵀ K_a⁻¹ h = βᵀβ per block; to_unknowns applies T, to_whitened applies Tᵀ.
// | beta, h: n = m (L + 1) | weights: (L + 1) × m, column a = tc_inverse_weights of input a |
void tc_to_unknowns(const Eigen::Ref<const Eigen::VectorXd>& beta, const Eigen::MatrixXd& weights,
                    Eigen::Ref<Eigen::VectorXd> h);
void tc_to_whitened(const Eigen::Ref<const Eigen::VectorXd>& h, const Eigen::MatrixXd& weights,
                    Eigen::Ref<Eigen::VectorXd> beta);

}  // namespace lpvid::markov_detail
