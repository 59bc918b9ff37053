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
// at the excited bins k (unnormalised DFT; every scale cancels in the ratios).
// Per line k and block: the sample mean Z̄(k) = 1/P Σ_p Z^[p](k) (nz-vector of the
// measured channels) and the sample covariance
//   Ĉ_Z(k) = 1/(P−1) Σ_p (Z^[p] − Z̄)(Z^[p] − Z̄)ᴴ     (nz × nz, P−1 degrees of freedom),
// so that the noise covariance of the mean is Ĉ_Z/P (P&S §2.4).  The
// reference V (m-vector) is the mean over periods as well (it is known exactly).
//
// Per realisation r and line k, with the E experiments side by side
// (V: m × E, Z̄: nz × E; m <= E, V of full row rank):
//   Ĝ_z = Z̄ V⁺,   V⁺ = Vᴴ (V Vᴴ)⁻¹                     (nz × m)
// Open loop / closed-loop map (no plant inputs): Ĝ = Ĝ_z.  Plant (z = [y; u], the last
// m channels the plant inputs u): Ŝ = the last m rows of Ĝ_z (v → u), P̂S = the first
// ny rows (v → y), and P̂ = P̂S Ŝ⁻¹ (the indirect or ratio route).  Linearised noise:
//   δĜ = W δZ̄ M,  W = I (open loop) or [I  −P̂] (plant),  M = V⁺ (or V⁺ Ŝ⁻¹),
//   E|δĜ_ij|² = Σ_e |M_ej|² (W (Ĉ_Z,e / P) Wᴴ)_ii,
// which keeps the joint period-to-period covariance of y and u (their noise is
// correlated in feedback: δP = (δ(PS) − P δS) S⁻¹).
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

// A bin is excited when the reference's power there (summed over inputs and blocks) is
// at least this fraction of the largest such power (multisine lines vs. round-off).
inline constexpr double kExcitedLineFraction = 1e-8;
// The reference must repeat from period to period to this relative accuracy (max |v_p −
// v_0| over max |v|): a wrong period length or layout shows up as a gross violation.
inline constexpr double kPeriodicityTolerance = 1e-6;

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
  // Empty: every bin whose reference power is >= kExcitedLineFraction of the largest
  // (DC and Nyquist never).
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
// | reference | N × m, the excitation v (known exactly, periodic) |
// | measured  | N × nz: y (open loop), or [y u] with u the last m columns (plant) |
//
// @throws InputError for: invalid options; N below layout.total_samples(); row counts
//   that differ; a NaN/Inf sample; m > E; plant_inputs not 0 or m, or no output left;
//   a reference that is not periodic with L samples in some block (names the block);
//   no excited bin (or a given bin out of range); a singular V at a line (names the line
//   and realisation: the experiments do not excite the inputs independently there).
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
