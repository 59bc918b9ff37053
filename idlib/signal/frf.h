// lpvid — nonparametric frequency-response estimate (H1, Welch averaging) of the
// map excitation v -> output y from (closed-loop) experiment logs.
//
// Estimator (Bendat & Piersol, Random Data, 4th ed., §7.2 and §9.3 — the MIMO
// "H1" estimate; Welch, IEEE Trans. Audio Electroacoust. 15(2), 1967):
//
//   Ĥ(ω_k) = S_yu(ω_k) S_uu(ω_k)⁻¹,
//   S_yu(ω_k) = Σ_experiments Σ_segments Y_s(k) U_s(k)ᴴ    (p x m)
//   S_uu(ω_k) = Σ_experiments Σ_segments U_s(k) U_s(k)ᴴ    (m x m)
//
// where U_s(k), Y_s(k) are the DFTs (bin k) of the windowed segment s of the
// excitation columns ("u" here = ExperimentView::excitation, i.e. the injected v)
// and of the output columns.  In closed loop, using the injected excitation as the
// reference makes Ĥ an estimate of the closed-loop map v -> y (e.g. the input
// sensitivity S = (I + C P)⁻¹ when y = u, or G = P (I + C P)⁻¹ when y = q) that is
// unbiased by noise on y that is uncorrelated with v.  Common scale factors
// (window power, 1/(N Ts)) cancel in Ĥ and in the coherences, so the spectra are
// left unscaled and are not returned.
//
// Frequencies: the DFT bins k = 1 .. floor(nseg / 2) (DC skipped),
//   ω_k = 2π k / (nseg · Ts)  rad/s,  the last one the Nyquist frequency π / Ts for
//   even nseg.
//
// Segments: each experiment is cut into segments of nseg samples starting at
// 0, step, 2·step, ... with step = nseg − round(overlap · nseg) (>= 1); samples after
// the last full segment are not used.  Experiments are never concatenated.
//
// Output layout (idlib/core/types.h):
//
// | field           | shape / unit |
// |-----------------|--------------|
// | omega_rad_s     | F = floor(nseg/2), rad/s |
// | response[k]     | p x m complex, units of y per unit of v |
// | coherence[k]    | p x m, in [0, 1] (meaning below) |
// | flagged[k]      | F entries |
// | averages        | independent averages behind the coherence (below) |
// | variance[k]     | p x m, mean-square error of each entry: random (coherence) + leakage bias² (frf.cc) |
// | names           | empty (ExperimentView carries none) |
//
// averages: the K segments of a column's experiments overlap, so they are worth
// n_d = K / (1 + 2 Σ_l (1 − l/K) c(l)) independent averages (Welch 1967; c(l) the
// squared correlation of the window with itself shifted by l steps; Hann at 50 %
// overlap: n_d ≈ 0.947 K); the smallest over the columns is returned, so that the
// H1 noise E|Ĥ − H|² = |Ĥ|² (1 − γ²)/(n_d γ²) holds for every entry.
//
// What coherence(i, j) means (decided from the excitation pattern, see
// "experiment classification" below):
//  * single-input design — every experiment excites exactly one input and every
//    input is excited alone by at least one experiment: coherence(i, j) is the
//    ORDINARY coherence between v_j and y_i over the experiments that excite v_j,
//      γ²_ij = |S_yi_vj|² / (S_yiyi · S_vjvj)   (spectra summed over those experiments
//    only).  It is the fraction of the power of y_i in those experiments that is
//    linearly explained by v_j; a small off-diagonal entry (weak coupling) has a
//    low ordinary coherence even when Ĥ(i, j) is accurate in the matrix sense.
//  * any other design (several inputs excited at once in some experiment): the
//    MULTIPLE coherence of output i with all excitations,
//      γ²_i = (Ĥ S_uu Ĥᴴ)_ii / S_yiyi = (S_yu S_uu⁻¹ S_uy)_ii / S_yiyi,
//    over all experiments, replicated across j (every entry of row i is γ²_i).
//  In both cases a noise-free linear system gives 1 (up to leakage), and
//  independent noise on y_i of power N_i against a coherent power C_i gives
//  C_i / (C_i + N_i) (plus a positive bias of about 1 / (number of averaged
//  segments)).
//
// Experiment classification: after mean removal (if enabled), experiment e
// excites input j when RMS(v_j) >= kFrfExcitedFraction · max_a RMS(v_a) in e.
//
// Flags: a frequency is flagged (flagged[k] = true; response[k] and coherence[k]
// are then set to ZERO, never to an unreliable value) when S_uu(ω_k) has a zero
// diagonal entry (an input carries no power at that bin) or when the condition
// number of the normalised matrix D^-½ S_uu D^-½ (D = diag S_uu, so input units do
// not matter) exceeds FrfOptions::max_condition (estimated in the 1-norm by
// Eigen's LLT::rcond; it is within a factor m of the 2-norm condition), e.g. two
// inputs always excited with the same signal, or fewer independent segments than
// inputs.
//
// Cost: O((m + p) · N_total · (1 + overlap_factor) · log nseg) for the FFTs (one
// FFTW r2c plan reused for every segment and channel) plus O((m² + p m) · bins ·
// segments) for the spectra; memory O((m² + p m) · nseg) per experiment group, the
// data are read in place.  Measured: bench/frf_bench.cc.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"
#include "idlib/signal/markov.h"  // ExperimentView

namespace lpvid {

// An experiment excites input j when RMS(v_j) is at least this fraction of the
// largest excitation RMS in that experiment (the same 10 % rule as markov.h).
inline constexpr double kFrfExcitedFraction = 0.1;

// Automatic segment length: the largest power of two <= N_min / kFrfAutoSegments
// (N_min = the shortest experiment), at least kFrfMinAutoSegment samples.  With
// 50 % overlap that averages ~2·kFrfAutoSegments − 1 segments per experiment.
inline constexpr Index kFrfAutoSegments = 16;
inline constexpr Index kFrfMinAutoSegment = 256;

struct FrfOptions {
  // Samples per segment (nseg).  0 = automatic (rule above).  Otherwise >= 4 and
  // <= the length of every experiment.
  Index segment_length = 0;
  // Fraction of a segment shared with the next one, in [0, 0.95).
  double overlap = 0.5;
  // kHann: periodic Hann w[n] = 0.5 − 0.5 cos(2π n / nseg) (low leakage; the default).
  // kRectangular: no window (exact for periodic excitation with period nseg, leaks
  //   otherwise).
  enum class Window { kHann, kRectangular } window = Window::kHann;
  // Ts of the logs, s.  Required finite and > 0.
  double sample_period_s = 0;
  // Subtract each channel's mean: over the whole record (per experiment) for the
  // classification of the excitation, and each segment's own mean before its window
  // (scipy's detrend='constant'; frf.cc, segment_mean, says why: line 1 of a Hann
  // window holds the segment's mean).
  bool remove_mean = true;
  // Flag a frequency when the normalised S_uu has a (1-norm) condition number above
  // this.  Must be > 1.
  double max_condition = 1e6;

  // @throws InputError naming the first broken rule.
  void validate() const;
};

// Ĥ: v -> y for all FFT bins 1..nseg/2, with coherence and flags (see the header
// comment).
//
// | argument            | shape |
// |---------------------|-------|
// | experiments[e].excitation | N_e x m (v) |
// | experiments[e].output     | N_e x p (y) |
//
// @throws InputError for: invalid options; no experiments; an experiment whose
//   excitation and output have different N; channel counts that differ between
//   experiments (or are zero); a NaN/Inf sample; an experiment shorter than the
//   segment length (or than kFrfMinAutoSegment when automatic); an experiment whose
//   excitation is constant (zero after mean removal) in every column.
// Frequencies where S_uu is singular or ill-conditioned are flagged, not thrown.
FrequencyResponse estimate_frf(const std::vector<ExperimentView>& experiments, const FrfOptions& options);

}  // namespace lpvid

namespace lpvid {

// The plant P: u -> y from closed-loop experiments, with the injected excitation v
// as the instrument (the "joint input-output" or indirect route: P̂ = Ĝ Ŝ⁻¹ with Ĝ
// the closed loop v -> y and Ŝ the map v -> u; seed 000 Fig. 11, Pintelon &
// Schoukens 2012 §2.6):
//
//   P̂(ω_k) = S_yv S_uv⁻¹,   spectra summed over the Hann-windowed segments of every
//   experiment (as estimate_frf; the experiments' designs need not be single-input).
//
// Noise on y and on u that is uncorrelated with v does not bias P̂ (an H1 from u
// would be biased by the loop), and a nonlinear or time-varying controller does not
// matter: only the plant has to be linear.  Variance of each entry, to first order
// (the residual e = y − P u holds all the noise that reaches y and u):
//
//   E|P̂_ij − P_ij|² = (S_ee,ii / n_d) · [S_uv⁻ᴴ S_vv S_uv⁻¹]_jj · n_d/(n_d − m),
//
// with S_ee = [I −P̂] S_zz [I −P̂]ᴴ from the full cross-spectral matrix of z = [y; u],
// n_d the independent averages (estimate_frf's formula) and the last factor for the
// m columns P̂ took from the same data; plus the same leakage-bias term as
// estimate_frf (the larger of the curvature of P̂ over neighbouring lines and the
// Richardson estimate from a second pass with segments twice as long).  Coherence: the multiple
// coherence of y_i with the excitations (every entry of row i).
//
// experiments[e].excitation is v (N × m); experiments[e].output holds y then u
// (N × (p + m)): the last m columns are the plant's inputs.  Frequencies where S_vv
// or S_uv is ill-conditioned (max_condition) are flagged.
// @throws InputError  as estimate_frf; output with no more columns than excitation
//   columns (no y).
FrequencyResponse estimate_plant_frf(const std::vector<ExperimentView>& experiments, const FrfOptions& options);

}  // namespace lpvid
