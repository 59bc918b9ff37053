// lpvid — Markov parameters (impulse response) of the map excitation v -> output q
// from (closed-loop) experiment logs.
//
// Model (DESIGN.md, math item 1; Gajdušek et al., eqs 10-12):
//
//   q(t) = sum_{k=0}^{L} g[k] v(t - k) + e(t),   t = 0..N-1,
//
// with v(t) = 0 for t < 0 (each experiment starts its excitation with the record).
// In closed loop, correlate with the injected excitation v, never with the plant
// input u; g is then the closed-loop map v -> q, e collects noise and disturbances
// (uncorrelated with v).  Signals follow idlib/core/types.h (N x channels).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

struct MarkovOptions {
  // L: estimate g[0..L].  Required > 0.
  Index num_lags = 0;

  // kLeastSquares (default): exact least squares over t = 0..N-1 ("covariance
  //   method"), unbiased for any excitation spectrum and for several inputs excited
  //   at once.
  // kCorrelation: the plain recipe g[k](i,j) = R_qv(k)(i,j) / sum_t v_j(t)^2 over the
  //   experiments that excite input j.  BIASED: the sample autocorrelation of finite
  //   white noise is not a delta (off-peak values ~ 1/sqrt(N)) and the record end
  //   truncates late lags, so expect errors of several percent on typical records;
  //   kept to reproduce the paper.
  // kRegularized: the posterior mean under a TC-kernel prior (smooth, exponentially
  //   decaying g; markov_regularized.h), its hyperparameters per output by marginal
  //   likelihood on the first `regularized_tuning_lags` lags (dense), the estimate over
  //   all L lags by conjugate gradients in the prior's whitened coordinates.  For
  //   excitations so coloured that least squares is ill-posed (its normal equations'
  //   condition number beyond what PCG resolves: noise amplified by the inverse input
  //   spectrum where the input has no power) — MATLAB's impulseest default.  Biased
  //   toward the prior by design; the same intercept as kLeastSquares.
  // kArx: the impulse response of a high-order ARX model (markov_arx.h): for a response
  //   slower than the record supports as a finite impulse response (a lightly damped mode
  //   whose tail is still above the noise at lag L, which least squares truncates).
  enum class Method { kLeastSquares, kCorrelation, kRegularized, kArx } method = Method::kLeastSquares;

  // kArx: the ARX order n (0: by the corrected Akaike criterion, markov_arx.h).
  Index arx_order = 0;

  // kRegularized: the lags over which the hyperparameters are tuned (a dense m (T + 1)
  // square Cholesky per likelihood evaluation); min(this, L).  Must be >= 2.
  Index regularized_tuning_lags = 300;

  // Constant offsets (e.g. a sensor bias, a logged equilibrium).
  // kLeastSquares: each experiment's output gets a constant offset c_e that is
  //   estimated jointly with g (an intercept: q(t) = sum_k g[k] v(t - k) + c_e + e(t)),
  //   so the excitation is used exactly as logged (zero before the record) and the
  //   estimate stays exact on noise-free data from rest.  (Subtracting v's sample
  //   mean instead, as earlier versions did, perturbed the first lags: measured as a
  //   0.09 % floor of the plant error identified from noise-free closed-loop logs.)
  // kCorrelation: each channel's sample mean is subtracted (the paper's recipe).
  // Either way a column that is constant (e.g. identically zero) in an experiment is
  // treated as exactly zero there.
  bool remove_mean = true;

  // kLeastSquares (kRegularized: its CG): stop PCG when ||residual|| <= tolerance * ||rhs|| for every output
  // (relative residual of the normal equations).  Must be in (0, 1).
  double tolerance = 1e-10;

  // kLeastSquares: PCG iteration limit.  Must be > 0.
  int max_iterations = 500;

  // kLeastSquares: a starting point for PCG (e.g. the estimate at a shorter horizon, or
  // before a small change of the outputs): lags beyond its size start at zero, lags
  // beyond num_lags are ignored.  Same tolerance, so the same estimate to within it;
  // fewer iterations when the guess is close.  Empty: start from zero.  Each entry p x m.
  MarkovSequence initial_guess;

  // @throws InputError naming the first broken rule (num_lags <= 0, tolerance not in
  //         (0, 1), max_iterations <= 0).
  void validate() const;
};

// One experiment: excitation and output logged over the same N samples.
//
// | field      | shape | meaning                                        |
// |------------|-------|------------------------------------------------|
// | excitation | N x m | injected excitation v (column j = input j)     |
// | output     | N x p | measured output q                              |
struct ExperimentView {
  Eigen::Ref<const Eigen::MatrixXd> excitation;
  Eigen::Ref<const Eigen::MatrixXd> output;
};

struct MarkovResult {
  MarkovSequence g;  // L+1 matrices, p x m; units of q per unit of v
  // p x m: standard error of each g[k] entry (same for every lag k), approximated as
  //   noise_std(i, j) = sigma_e_i / sqrt(sum over all experiments of sum_t v_j(t)^2),
  // sigma_e_i^2 = (sum_t e_i(t)^2) / (total_samples - m (L + 1) - offsets), with e the residual
  // of the estimated model.  Exact for white, mutually uncorrelated excitations and
  // white noise e; with coloured excitation the true standard error of individual
  // lags is larger (it is sigma_e times the square root of the diagonal of the
  // inverse normal matrix), and with coloured noise it is only indicative.
  // The residual energy comes, for kLeastSquares, from the normal equations
  // (||q||^2 - 2 g.b + g.Phi g, O(L log L)); when that leaves fewer than ~8 correct
  // digits (residual < 1e-6 of the output energy) and always for kCorrelation, it
  // is computed by FFT convolution e = q - sum_k g[k] v(t - k) over the data.
  Eigen::MatrixXd noise_std;
  Eigen::VectorXd excitation_rms;  // m: RMS of each excitation over all experiments (after mean removal)
  Eigen::VectorXd output_rms;      // p: RMS of each output over all experiments (after mean removal)
  Index total_samples = 0;         // sum of N over the experiments
  Index iterations = 0;            // PCG iterations (0 for kCorrelation)
  // kRegularized: per output i and input a, the TC kernel's decay λ = e^(−rate) per lag and
  // the noise-to-prior ratio γ (p × m each), the marginal likelihood's noise variance per
  // output (p), and the lags the hyperparameters were tuned on.  Empty otherwise.
  Eigen::MatrixXd kernel_decay, kernel_gamma;
  Eigen::VectorXd kernel_noise_variance;
  Index kernel_tuning_lags = 0;
  // kArx: the order used, the largest tried and the criterion at orders 1..arx_max_order
  // (AICc, markov_arx.h; +inf where not computed); the largest |pole| of the ARX model's
  // autoregressive part (>= 1: the response does not decay).  Zero / empty otherwise.
  Index arx_order = 0, arx_max_order = 0;
  Eigen::VectorXd arx_criterion;
  Eigen::VectorXd arx_denominator;  // a_1..a_n: beyond lag n, g[k] = Σ_j a_j g[k − j] (markov_arx.h)
  double arx_spectral_radius = 0.0;
  Report report;                   // usable == false when PCG did not reach the tolerance
};

// Estimates g[0..L] from one or more experiments, summed into one set of normal
// equations (never concatenated, which would correlate across the seam).
//
// kLeastSquares solves exactly, for each output row i,
//   sum_{k=0}^{L} Phi(j, k) g[k](i, :)^T = sum_t v(t - j) q_i(t),   j = 0..L,
//   Phi(j, k) = sum_experiments sum_{t=0}^{N-1} v(t - j) v(t - k)^T,
// where Phi = block-Toeplitz[R_vv] - C, R_vv(d) = sum_t v(t + d) v(t)^T, and the
// end-of-record correction C(j, k) = sum_{t=N}^{N-1+min(j,k)} v(t - j) v(t - k)^T
// depends only on the last L samples of v.  Solver: preconditioned conjugate
// gradient (preconditioner: inverse of the m x m zero-lag block R_vv(0)), all outputs
// at once; products with Phi by FFT in O(m p L log L).  The dense m(L+1) square
// matrix is never formed.  Correlations by blocked FFT (cross_correlation).
//
// Cost: O(N (m + p) log L) for the correlations and the residual, plus
// O(iterations m p L log L); measured 41 ms (10 PCG iterations) for m = p = 3,
// N = 1e6, L = 2000, white excitation, on the 2-core reference machine.  Memory O(m p L); the data are read in place, never copied.
//
// An experiment counts as exciting input j (kCorrelation only) when the RMS of v_j
// there is at least 10 % of the largest RMS of v_j over all experiments.
//
// Record-length rule: every experiment needs N > L, and the total number of samples
// must be at least 2 m (L + 1) (twice the unknowns per output).
//
// @throws InputError for: invalid options; no experiments; an experiment whose
//   excitation and output have different N; channel counts that differ between
//   experiments (or are zero); a NaN/Inf sample; a record too short for the lags (the
//   rule above); an excitation column that is constant (e.g. zero) in every
//   experiment; inputs that are linearly dependent over all experiments (e.g. two
//   inputs always identical), naming them.
// Returns report.usable == false (with the reached residual in report.termination)
// when PCG stops at max_iterations without reaching the tolerance.
//
// `reuse` (kLeastSquares only; ignored by kCorrelation): correlations kept between calls
// on the same excitation, so that a longer horizon or new outputs do not recompute what
// has not changed.  The caller guarantees what the fields say:
//   - max_lag > 0 and vv empty (or max_lag < L): this call computes R_vv and R_qv up
//     to lag max(max_lag, L) (at about the cost of computing them up to L: the FFT
//     blocks grow with the lag, their number shrinks) and stores them there; later calls
//     with L <= max_lag take them from here.
//   - vv filled: taken as R_vv of these experiments' excitation (same remove_mean);
//   - qv filled: taken as R_qv of these experiments' outputs, which must be the very
//     outputs it was computed from; clear qv (keep vv) for new outputs over the same
//     excitation (e.g. corrected ones): then only R_qv (p x m channel pairs, not
//     (p + m) x m) is computed, up to L, and not stored.
// The estimate equals that of a call without `reuse` to round-off (the FFT block
// length differs when max_lag > L).
struct MarkovCorrelations {
  Index max_lag = 0;
  std::vector<Eigen::MatrixXd> vv;  // [k] m x m: sum over experiments of sum_t v(t) v(t - k)^T, k = 0..max_lag
  std::vector<Eigen::MatrixXd> qv;  // [k] p x m: sum over experiments of sum_t q(t) v(t - k)^T (q centred per experiment)
};

MarkovResult estimate_markov(const std::vector<ExperimentView>& experiments,
                             const MarkovOptions& options, MarkovCorrelations* reuse = nullptr);

// Whether an estimate's response is cut off by its horizon: a finite impulse response of
// L lags describes a response that has died out by lag L; one that has not (a lightly
// damped or slow mode, a record too short for it) leaves its tail in the last lags, and
// least squares' last lag soaks up what lies beyond (the DaISy robot arm: 0.235 at lag
// 256 where the response there is about −0.03, the noise's standard error 0.019).
// Statistic: S = Σ over the last T = max(8, ⌈(L + 1) / 10⌉) lags and every entry of
// (g[k](i, j) / noise_std(i, j))², which for a response that has died out is noise alone.
// noise_std is the white-excitation standard error σ / √(Σ v²); least squares' error at
// lag k is larger by about r_k = N / (Σ_e (N_e − k) − m (L + 1)) (the inverse Wishart's
// mean with the m (L + 1) unknowns, and the N_e − k samples that reach lag k: measured
// 1.5–1.7 at the last lags of 500 from 4000 samples, two inputs), so S is compared with
// its mean under noise alone, p m Σ_k r_k, and truncated means S above it by more than
// 5 standard deviations, 5 √(2 p m Σ_k r_k²).  (Under a coloured excitation the last
// lags' true error is larger still, so the test errs towards "truncated" there; markov's
// default then compares the estimates on held-out data before it changes method.)
struct MarkovTail {
  bool truncated = false;
  Index lags = 0;             // T
  double energy_ratio = 0.0;  // S over its mean under noise alone: about 1 for noise alone
};
// | r.g: L + 1 matrices p × m (L >= 1) | r.noise_std: p × m, positive | record_lengths:
// N_e of each experiment |
MarkovTail markov_tail(const MarkovResult& r, const std::vector<Index>& record_lengths);

// How well the estimate of `options` predicts data it was not fitted on: each experiment
// is cut in two halves; the estimate on every first half predicts the second halves (as
// a finite impulse response from the excitation, with the record's history of it) and
// the estimate on the second halves predicts the first (the excitation before the
// record taken as zero, as the estimate takes it), an offset per half.  relative_error:
// the held-out residual energy over the outputs' energy about their means, averaged over
// the outputs (0: perfect; 1: no better than the mean).  The halves use
// lags = min(num_lags, the default horizon of the halves, markov.h's rule); an ARX
// estimate predicts with its whole response (continued by its recursion to the record's
// length), least squares with its L + 1 lags — each as the method describes the response.
// @throws InputError  halves too short for kMinDefaultMarkovLags lags, or what
//   estimate_markov throws on them.
struct MarkovHeldOut {
  double relative_error = 0.0;
  Index lags = 0;
};
MarkovHeldOut markov_held_out_error(const std::vector<ExperimentView>& experiments, const MarkovOptions& options);

// The default horizon when the caller gives neither lags nor a horizon in seconds: from
// the data, in SAMPLES (the sample time may be unknown, e.g. a log whose time column is
// the sample index): the longest horizon the records support,
//   L = min(⌊N_shortest / 4⌋, ⌊N_total / (4 m)⌋, 2000),
// i.e. the lag window is at most a quarter of every record, the m·L unknowns per
// output get at least 4 samples each (twice estimate_markov's minimum of 2), and at
// most kMaxDefaultMarkovLags lags (a bound on the work: `hankel` and `realize` grow with
// L; 2000 is the 2 s the default used to be at 1 kHz; a longer response needs --lags).  `hankel`
// and `realize` find the effective length of the response within it (era.h step 3), so
// a horizon longer than the response costs only computation.  Examples: 2 s at 1 kHz,
// three one-input-at-a-time logs (m = 3): 500 lags; the DaISy robot arm (1024 samples,
// m = 1): 256 lags.
// @throws InputError when that is below kMinDefaultMarkovLags (saying the shortest
//   record and total that would give it) or the counts are not positive.
inline constexpr Index kMinDefaultMarkovLags = 16;
inline constexpr Index kMaxDefaultMarkovLags = 2000;
Index default_markov_lags(Index shortest_record, Index total_samples, Index num_excitations);

}  // namespace lpvid
