// lpvid — frequency responses from PERIODIC excitation (multisines): per-period
// averaging with the noise (co)variance per line, MIMO designs with several
// experiments, the closed-loop plant by the indirect (ratio) route, and the Best
// Linear Approximation (BLA) with separate noise and nonlinear-distortion variances
// from several random-phase realisations.
//
// References: R. Pintelon, J. Schoukens, System Identification: A Frequency Domain
// Approach, 2nd ed., Wiley-IEEE 2012 (below "P&S"): §2.4 (sample mean and sample
// covariance over periods), §3.4 and §4.3 (the BLA and the "robust method"), §2.6 and
// §9.18 (FRF in feedback from the reference: indirect route).  docs/math.md,
// "Periodic FRF and the BLA", writes every formula out.
//
// Layout of the samples (fixed contract, shared with `lpvid excite`):
//   the N samples are blocks in the order realisation r = 0..R−1 (outer), experiment
//   e = 0..E−1 (inner); a block is (T + P)·L samples: T transient periods (discarded),
//   then P periods of the same L samples.  Samples after R·E·(T+P)·L are ignored
//   (with a warning in the report).
//
// Per block b, period p, channel c: X_c^[p](k) = Σ_{t<L} x_c(t0 + pL + t) e^{−2πi kt/L}
// (unnormalised DFT; every scale cancels in the ratios).
//
// The excitation (reference) v is MEASURED: a generator's output logged by an ADC repeats
// from period to period only up to its measurement noise.  Per block, excitation column
// j and bin k (1 <= k < L/2): the period mean V̄_j(k) (the DFT of the time-domain period
// mean) and the noise variance of that mean from the period-to-period scatter,
//   N_j(k) = 1/((P−1)P) Σ_p |V_j^[p](k) − V̄_j(k)|²      (P&S §2.4).
// Excited lines (when not given): the bins where, summed over blocks and columns,
//   S(k) = Σ |V̄(k)|²  >=  kExcitedLineFraction · max_k S(k)              (not round-off)
//   S(k)             >=  kExcitedLineSnr · max(N(k), median N over k ± kLineNoiseHalfWidth)
// (the period mean stands far above its own scatter: a periodic component, not noise;
// for a noise-only bin S/N is an F(2, 2(P−1)) variate of mean ≈ 1).  An exact reference
// (N ≡ 0, e.g. written by lpvid excite) keeps only the first rule.
// Periodicity of block b: the power of its period mean at the excited lines over the
// noise power of that mean summed over EVERY bin 1..L/2−1,
//   ρ_b = Σ_j Σ_lines |V̄_j(k)|² / Σ_j Σ_{k=1}^{L/2−1} N_j(k),
// must be >= kMinExcitationPeriodicity.  A periodic generator has ρ ≫ 1 (the F-16 GVT
// voltage: 3·10⁸); random noise or a wrong period length gives ρ <~ 1 (the period mean of
// a non-repeating signal is no larger than its scatter, at any set of bins).  And the
// scatter at the lines must be at the noise level of the other bins (q_b below), where
// the lines' SNR is not overwhelming: a period off by a sample passes ρ but not this.
//
// The measured channels w = [z; v] (z the nz measured responses, v the m excitation
// columns when they are measured, i.e. some N > 0): per line and block the sample mean
// W̄(k) = 1/P Σ_p W^[p](k) and the sample covariance
//   Ĉ_W(k) = 1/(P−1) Σ_p (W^[p] − W̄)(W^[p] − W̄)ᴴ     (nw × nw, P−1 degrees of freedom),
// so that the noise covariance of the mean is Ĉ_W/P (P&S §2.4).  With an exact
// reference w = z (the reference's variance is zero).
//
// Per realisation r and line k, with the E experiments side by side
// (V̄: m × E, Z̄: nz × E; m <= E, V̄ of full row rank):
//   Ĝ_z = Z̄ V̄⁺,   V̄⁺ = V̄ᴴ (V̄ V̄ᴴ)⁻¹                   (nz × m)
// Open loop / closed-loop map (no plant inputs): Ĝ = Ĝ_z.  Plant (z = [y; u], the last
// m channels the plant inputs u): Ŝ = the last m rows of Ĝ_z (v → u), P̂S = the first
// ny rows (v → y), and P̂ = P̂S Ŝ⁻¹ (the indirect or ratio route).  Linearised noise
// (errors in variables: δĜ_z = (δZ̄ − Ĝ_z δV̄) V̄⁺ to first order):
//   δĜ = W [I  −Ĝ_z] δW̄ M,  W = I (open loop) or [I  −P̂] (plant),  M = V̄⁺ (or V̄⁺ Ŝ⁻¹),
//   E|δĜ_ij|² = Σ_e |M_ej|² (W_e (Ĉ_W,e / P) W_eᴴ)_ii,   W_e = W [I  −Ĝ_z] (W alone for
//   an exact reference),
// which keeps the joint period-to-period covariance of y, u and v (their noises are
// correlated in feedback: δP = (δ(PS) − P δS) S⁻¹).  For the plant W [I −Ĝ_z] = [I −P̂ 0]:
// the reference's noise cancels to first order (P̂ = Ȳ Ū⁻¹ when E = m), and its
// variance is the classical errors-in-variables one of output AND input noise and their
// covariance.  The ratio of noisy means is biased by ≈ −Ĝ·e^{−SNR} (SNR = |V̄|²/N at the
// line), negligible at the lines the rule above finds (SNR >= 100).
//
// BLA over R >= 2 random-phase realisations (P&S §4.3.1, the robust method):
//   Ĝ_BLA = 1/R Σ_r Ĝ_r,
//   σ̂²_BLA = 1/(R(R−1)) Σ_r |Ĝ_r − Ĝ_BLA|²        (total variance of Ĝ_BLA; R−1 dof)
//   σ̂²_n   = 1/R² Σ_r σ̂²_n,r                      (noise variance of Ĝ_BLA; R(P−1) dof)
//   σ̂²_s   = max(σ̂²_BLA − σ̂²_n, 0)                (distortion part of the variance of Ĝ_BLA;
//                                                   R·σ̂²_s is the variance of the stochastic
//                                                   distortion G_s of ONE realisation)
// written to the FrequencyResponse as variance = σ̂²_n + σ̂²_s (= max(σ̂²_BLA, σ̂²_n), what a
// fit weights with) and distortion_variance = σ̂²_s.  With R = 1, variance is the noise
// variance alone and distortion_variance is empty (distortions are then invisible and
// act as a bias).
//
// Output layout (idlib/core/types.h), F = number of excited lines:
//
// | field                   | shape / unit |
// |-------------------------|--------------|
// | frd.omega_rad_s         | F, 2π k / (L Ts) at the excited bins k |
// | frd.response[k]         | outputs × m complex |
// | frd.variance[k]         | outputs × m, E|Ĝ − G|² (total, above) |
// | frd.distortion_variance | R >= 2: outputs × m per line, else empty |
// | frd.flagged             | F entries: Ŝ singular at that line (plant only; the response is then 0) |
#pragma once

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

// A bin is excited when the reference's period-mean power there (summed over inputs and
// blocks) is at least this fraction of the largest such power (lines vs. round-off) ...
inline constexpr double kExcitedLineFraction = 1e-8;
// ... and at least this many times the noise variance of that mean (the larger of the
// bin's own, from the period-to-period scatter, and the median over the bins within
// kLineNoiseHalfWidth, which pools 2·kLineNoiseHalfWidth + 1 bins' degrees of freedom).
// For a bin holding only noise the ratio to the pooled median exceeds 100 with
// probability ≈ e^{−69} (an exponential variate over a median >= 0.69 of its mean); the
// F-16 GVT voltage's lines stand 10⁸–10⁹ above, its other bins at most 30 (measured).
inline constexpr double kExcitedLineSnr = 100.0;
inline constexpr Index kLineNoiseHalfWidth = 8;
// A block's excitation is periodic when the power of its period mean at the excited lines
// is at least this many times the noise power of that mean over every bin (ρ_b above,
// 10 dB).  Not periodic (random noise, a wrong --period-samples): ρ <~ 1.
inline constexpr double kMinExcitationPeriodicity = 10.0;
// ... and its scatter at the lines must be at the noise level of the other bins: the mean
// noise variance N at the lines at most kMaxLineScatterExcess times the median N over the
// bins that are not lines (q_b), unless the lines' SNR Σ|V̄|²/ΣN is at least
// kCoherentLineSnr (then a signal-proportional scatter, e.g. a generator's gain jitter,
// is too small to matter and enters the variance as the reference's noise).  A period
// length off by one to a few samples smears the signal across periods: measured on the
// F-16 GVT voltage (L = 8192): q = 1.1·10⁴–2.8·10⁶ with line SNR 165–233 at L = 8190,
// 8191, 8193 (ρ = 2.4–31 there: ρ alone would pass two of them), against q = 6.8–9.0
// and line SNR 1.5·10⁹–7·10¹⁰ at L = 8192 (levels 1, 2, 7).
inline constexpr double kMaxLineScatterExcess = 300.0;
inline constexpr double kCoherentLineSnr = 1e4;
// A line whose reference SNR |V̄|²/N is below this gets a warning (the ratio's bias
// e^{−SNR} exceeds 4.5e-5 there).
inline constexpr double kLowLineSnr = 10.0;

struct PeriodicLayout {
  Index period_samples = 0;     // L >= 4
  Index periods = 0;            // P >= 2 (the noise variance needs P − 1 >= 1)
  Index transient_periods = 0;  // T >= 0
  Index realisations = 1;       // R >= 1
  Index experiments = 1;        // E >= 1, and >= the number of inputs m

  Index block_samples() const { return (transient_periods + periods) * period_samples; }
  Index total_samples() const { return realisations * experiments * block_samples(); }
  // @throws InputError naming the first broken rule.
  void validate() const;
};

struct PeriodicFrfOptions {
  PeriodicLayout layout;
  double sample_period_s = 0;  // Ts, s; finite and > 0
  // DFT bins (of one L-sample period) to estimate at, 1 <= k < L/2, increasing.
  // Empty: the excited lines found from the reference (see the header comment; DC and
  // Nyquist never).
  std::vector<Index> excited_bins;
  // Refuse a line where the normalised V Vᴴ has a (1-norm) condition above this; flag a
  // plant line where Ŝ's is.  > 1.
  double max_condition = 1e8;

  // @throws InputError naming the first broken rule.
  void validate() const;
};

struct PeriodicFrfResult {
  FrequencyResponse frd;           // see the header comment
  std::vector<Index> bins;         // the excited bin of each line
  // Noise variance of each entry of frd.response per line (σ̂²_n above).
  std::vector<Eigen::MatrixXd> noise_variance;
  // R >= 2: σ̂²_BLA of each entry per line (the realisation scatter), else empty.
  std::vector<Eigen::MatrixXd> scatter_variance;
  // Per measured channel (the columns of `measured`): the noise rms per sample, from
  // the period-to-period scatter in the time domain, all bins (units of the channel).
  Eigen::VectorXd channel_noise_rms;
  // The same for each excitation column (0 for an exact reference).
  Eigen::VectorXd excitation_noise_rms;
  // The smallest ρ_b over the blocks (header comment; +inf for an exact reference).
  double excitation_periodicity = 0;
  // True when the reference has period-to-period scatter: its noise entered the
  // variance (errors in variables).
  bool measured_reference = false;
  Index noise_dof = 0;        // R·E·(P − 1): degrees of freedom behind σ̂²_n (per block P − 1)
  Index realisation_dof = 0;  // R − 1 (0 when R = 1)
  Report report;
};

// Ĝ: v -> y (plant_inputs = 0) or the plant P: u -> y (plant_inputs = m: the last m
// columns of `measured` are the plant inputs u, the others the outputs y), at the
// excited lines.
//
// | argument  | shape |
// |-----------|-------|
// | reference | N × m, the excitation v (periodic; exact or measured with noise) |
// | measured  | N × nz: y (open loop), or [y u] with u the last m columns (plant) |
//
// @throws InputError for: invalid options; N below layout.total_samples(); row counts
//   that differ; a NaN/Inf sample; m > E; plant_inputs not 0 or m, or no output left;
//   no bin where the reference's period mean stands above its scatter (not periodic
//   with L samples); a block whose reference is not periodic (ρ_b below
//   kMinExcitationPeriodicity; names the block); a given bin out of range; a singular V
//   at a line (names the line and realisation: the experiments do not excite the inputs
//   independently there).
PeriodicFrfResult estimate_periodic_frf(const Eigen::MatrixXd& reference, const Eigen::MatrixXd& measured,
                                        Index plant_inputs, const PeriodicFrfOptions& options);

// For the "distortion above noise" test: per line and entry the ratio σ̂²_BLA / σ̂²_n (≈ 1 for a linear system: an F(2(R−1), 2R(P−1)) variate;
// well above 1 where nonlinear distortions dominate).  Empty when R = 1.
std::vector<Eigen::MatrixXd> distortion_to_noise_ratio(const PeriodicFrfResult& result);

// Lines where the distortion stands above the noise, as runs [first, last] of line
// indices.  Test: under "linear" each line's σ̂²_BLA/σ̂²_n (the mean over its entries,
// treated as ONE variate since entries of a line are correlated) is F(d1, d2) with
// d1 = 2(R−1), d2 = 2·noise_dof, mean μ0 = d2/(d2−2) and variance
// σ0² = 2 d2² (d1+d2−2) / (d1 (d2−2)² (d2−4)); a window of kDistortionWindow
// consecutive lines is "distorted" when its mean ratio exceeds
// μ0 + kDistortionSigmas · σ0 / sqrt(window), and the union of such windows is returned.
// Empty when R = 1 or d2 <= 4 (too few degrees of freedom for the moments).
inline constexpr Index kDistortionWindow = 5;
inline constexpr double kDistortionSigmas = 5.0;
std::vector<std::pair<Index, Index>> distortion_bands(const PeriodicFrfResult& result);

}  // namespace lpvid
