// lpvid — the Local Rational Method (LRM) for FRFs from non-periodic (random)
// excitation: like the LPM (lpm.h) one DFT of each whole record and a local fit over the
// 2n+1 neighbouring bins of bin k, but the FRF and the transient are local *rational*
// functions of the bin offset r with one common denominator per output row i:
//
//   Z_ie(k+r) = [Σ_a N_ia(r) U_ae(k+r) + M_ie(r)] / D_i(r) + V_ie(k+r),   r = −n..n,
//   N_ia(r) = Σ_{s=0}^{Rn} n_{ia,s} ρ^s,  M_ie(r) = Σ_{s=0}^{Rn} t_{ie,s} ρ^s,
//   D_i(r) = 1 + Σ_{s=1}^{Rd} d_{i,s} ρ^s,   ρ = r / n,
//
// (T. McKelvey, G. Guérin, "Non-parametric frequency response estimation using a local
// rational model", 16th IFAC SYSID, 2012; the MISO form — a denominator per output,
// shared by its inputs, its transients and the E experiments — as in their paper and
// Geerardyn et al.; Ĝ_ia(k) = n_{ia,0} since D_i(0) = 1.)  The problem is nonlinear in
// d; it is linearised (Levy): D_i Z_i = Σ_a N_ia U_a + M_i + D_i V_i, linear least
// squares in θ_i = [n; t; d] with −ρ^s Z_i(k+r) as the regressor of d_{i,s}.  Then
// `sk_iterations` Sanathanan–Koerner steps re-solve with every equation divided by
// |D̂_i(r)| of the previous step, so the equation error tends to V_i itself (the
// output-error criterion at convergence) and the residual estimates the noise.
//
// Per output row i and bin, with K̃_i the weighted regressor (p × E(2n+1),
// p = m(Rn+1) + E(Rn+1) + Rd), Q_i = (K̃_i K̃_iᴴ)⁻¹ and A_i = K̃_iᴴ Q_i:
//   θ_i = z̃_i A_i,  ε̃_i = z̃_i − θ_i K̃_i,  ĉ_ij = ε̃_i ε̃_jᴴ / q,  q = E(2n+1) − p,
//   Cov(δθ_i(a), δθ_j(b)) = ĉ_ij (A_jᴴ A_i)(b, a)      (= ĉ_ii Q_i(b, a) for i = j).
// Closed loop (plant_inputs = m): z = [y; u], Ŝ and P̂S from one fit per row and
// P̂ = P̂S Ŝ⁻¹ with E|δP̂_ij|² = Σ_{k,l} W_ik W̄_il ĉ_kl sᴴ M_kl s, W = [I −P̂],
// s = column j of Ŝ⁻¹, M_kl = A_l,Gᴴ A_k,G (the G columns) — the LPM's formula when
// every row has the same regressor.
//
// Bias (be aware): Z_i appears in its own regressor, so with noise the linearised
// estimate is biased (an errors-in-variables bias of order σ²/|Z|², largest where the
// output is small: at anti-resonances and far above the mode); the SK steps do not
// remove it.  The variance is the noise only (neither this bias nor a model error is in
// it).  docs/math.md 4d has the measured size.
//
// Output: as the LPM (bins first_bin, first_bin + stride, ... <= ⌊(N−1)/2⌋; windows
// shifted inside 1..⌊(N−1)/2⌋ near the ends; flagged where a row's normalised K̃ K̃ᴴ
// or Ŝ has a condition above max_condition, response 0 there).
// Cost: one r2c FFT of N points per channel, then O(bins · n_z · (1 + sk_iterations) ·
// p² E(2n+1)).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/progress.h"
#include "idlib/core/types.h"
#include "idlib/signal/lpm.h"     // kLpmMinDof
#include "idlib/signal/markov.h"  // ExperimentView

namespace lpvid {

struct LrmOptions {
  // Rn: degree of the FRF and transient numerators, 0..4.  Rd: degree of the
  // denominator, 1..4.  2 and 2 (McKelvey & Guérin's and Geerardyn et al.'s usual
  // choice): a denominator of degree 2 holds one mode (a pole pair) inside the window.
  int numerator_degree = 2;
  int denominator_degree = 2;
  // n; 0 = automatic: the smallest n with q >= max(kLpmMinDof, n_z) (as the LPM; for
  // SISO, one record and degrees 2/2 that is n = 7: 15 bins, q = 7).
  Index half_width = 0;
  // Sanathanan–Koerner reweighting steps after the linearised solve (0 = Levy only).
  // 1 by default: measured on resonators at 1–20 % output noise (docs/math.md 4d), one
  // step lowers the rms error by up to 10 % against Levy alone and more steps do not
  // lower it further while the variance estimate grows optimistic (mean |e|²/σ̂² from
  // 1.12–1.2 at one step to 1.27–1.40 at five; E F(2, 14) = 1.17).
  int sk_iterations = 1;
  double sample_period_s = 0;
  bool remove_mean = true;
  Index first_bin = 1;  // >= 1
  Index stride = 1;     // >= 1
  double max_condition = 1e10;
  // Reports (idlib/core/progress.h), nullptr: none: task "frf lrm", step "frequency
  // line" i of n, a few hundred times over the run.
  Progress* progress = nullptr;

  // @throws InputError naming the first broken rule.
  void validate() const;
};

using LrmResult = LocalFrfResult;  // lpm.h

// | argument                   | shape |
// |----------------------------|-------|
// | experiments[e].excitation  | N × m: the input (u open loop, the reference v closed loop) |
// | experiments[e].output      | N × nz: y, or [y u] with the plant inputs u last (plant_inputs = m) |
// Every experiment has the same N.
// @throws InputError for invalid options, no experiments, differing N or channel counts,
//   NaN/Inf, plant_inputs not 0 or m (or no output left), or a record too short for
//   2n+1 bins.
LrmResult estimate_lrm_frf(const std::vector<ExperimentView>& experiments, Index plant_inputs,
                           const LrmOptions& options);

}  // namespace lpvid
