// lpvid — the Local Polynomial Method (LPM) for FRFs from non-periodic (random)
// excitation: one DFT of each whole record, and at every bin k a local least-squares
// fit over the 2n+1 neighbouring bins of both the FRF and the transient (leakage) term
// as polynomials of degree R in the bin offset r:
//
//   Z_e(k+r) = Σ_{s=0}^{R} g_s r^s U_e(k+r) + Σ_{s=0}^{R} t_{e,s} r^s + V_e(k+r),  r = −n..n
//
// (R. Pintelon, J. Schoukens, G. Vandersteen, K. Barbé, "Estimation of nonparametric
// noise and FRF models for multivariable systems — Part I: Theory", Mech. Syst. Signal
// Process. 24(3), 2010; P&S 2012 §7.2.)  Ĝ(k) = g_0; the E experiments share the FRF
// polynomial and have their own transient polynomial.  Per bin, with K the regressor
// ((R+1)(m+E) rows × E(2n+1) columns) and Q = (K Kᴴ)⁻¹:
//   Θ = Z Kᴴ Q,  residual ε = Z − Θ K,  Ĉ_V = ε εᴴ / q,  q = E(2n+1) − (R+1)(m+E)
// (q = the degrees of freedom: 2n+1 − (R+1)(n_u+1) for one experiment), and
//   Cov(δΘ(:,a), δΘ(:,b)) = Q(b, a) Ĉ_V.
// Closed loop (plant_inputs = m): the reference v is the LPM input and z = [y; u];
// Ŝ (v → u) and P̂S (v → y) come from one fit and P̂ = P̂S Ŝ⁻¹ with the linearised
// variance of δP = [I −P̂] δG_z Ŝ⁻¹ (the indirect route, as periodic_frf.h):
//   E|δP̂_ij|² = (sᴴ Q_GG s) ([I −P̂] Ĉ_V [I −P̂]ᴴ)_ii,  s = column j of Ŝ⁻¹.
// The bins near the ends use a window shifted inside 1..⌊(N−1)/2⌋ (offsets r then
// not centred).
//
// Output: frd at bins k = first_bin, first_bin + stride, ... <= ⌊(N−1)/2⌋ (DC and
// Nyquist never), omega = 2π k / (N Ts); response outputs × m; variance = E|Ĝ − G|²
// from Ĉ_V (noise only: the polynomial approximation error is not in it); flagged where
// K Kᴴ (normalised) or Ŝ has a condition above max_condition (response 0 there).
// Cost: one r2c FFT of N points per channel, then O(bins · (R+1)²(m+E)² · E(2n+1)).
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/progress.h"
#include "idlib/core/types.h"
#include "idlib/signal/markov.h"  // ExperimentView

namespace lpvid {

// Default width: the smallest n giving at least this many degrees of freedom (the
// variance estimate then has a relative sd <= 1/sqrt(6) = 41 %) and at least n_z (so
// Ĉ_V is invertible: the literature's minimum, Pintelon et al. 2010).
inline constexpr Index kLpmMinDof = 6;

struct LpmOptions {
  int order = 2;             // R, 0..4 (2 = the usual choice)
  Index half_width = 0;      // n; 0 = automatic (kLpmMinDof)
  double sample_period_s = 0;
  bool remove_mean = true;   // subtract each channel's mean per experiment first
  Index first_bin = 1;       // >= 1
  Index stride = 1;          // >= 1: estimate every stride-th bin
  double max_condition = 1e10;
  // Reports (idlib/core/progress.h), nullptr: none: task "frf lpm", step "frequency
  // line" i of n, a few hundred times over the run.
  Progress* progress = nullptr;

  // @throws InputError naming the first broken rule.
  void validate() const;
};

// The result of a local method (LPM here, LRM in lrm.h): the FRD with its noise
// variance, the estimated bins, the window half-width n and the residual degrees of
// freedom q per window.
struct LocalFrfResult {
  FrequencyResponse frd;
  std::vector<Index> bins;
  Index half_width = 0;
  Index dof = 0;  // q
  Report report;
};
using LpmResult = LocalFrfResult;

// | argument                   | shape |
// |----------------------------|-------|
// | experiments[e].excitation  | N × m: the LPM input (u in open loop, the reference v in closed loop) |
// | experiments[e].output      | N × nz: y, or [y u] with the plant inputs u last (plant_inputs = m) |
// Every experiment has the same N.
// @throws InputError for invalid options, no experiments, differing N or channel counts,
//   NaN/Inf, plant_inputs not 0 or m (or no output left), or a record too short for
//   2n+1 bins.
LpmResult estimate_lpm_frf(const std::vector<ExperimentView>& experiments, Index plant_inputs,
                           const LpmOptions& options);

// Shared by the local methods (lpm.cc, lrm.cc); not a public interface.
namespace signal_detail {
// The records checked (messages name `method`) and their DFTs at bins 0..kmax = ⌊(N−1)/2⌋
// (U[e]: (kmax+1) × m, Z[e]: (kmax+1) × nz), each channel's mean removed if asked.
struct LocalDfts {
  Index N = 0, m = 0, nz = 0, ny = 0, E = 0, kmax = 0;
  std::vector<Eigen::MatrixXcd> U, Z;
};
LocalDfts local_dfts(const std::vector<ExperimentView>& experiments, Index plant_inputs, bool remove_mean,
                     const char* method);
// n: `given`, or (0) the smallest with q = E(2n+1) − npar >= max(kLpmMinDof, nz).
// @throws InputError when q < 1 or the record has fewer bins than the window.
Index local_half_width(Index given, Index npar, Index nz, const LocalDfts& dft, const char* method);
// The output bins first_bin, first_bin + stride, ... <= kmax, their ω = 2π k / (N Ts), and
// frd sized for them (ny × m zeros, nothing flagged).
void local_output_grid(const LocalDfts& dft, Index first_bin, Index stride, double sample_period_s,
                       std::vector<Index>& bins, FrequencyResponse& frd);
// From the fitted z-responses Gz (nz × m): open loop G = Gz, W = I, Ŝ⁻¹ = I; closed loop
// G = Gz_y Ŝ⁻¹ with Ŝ = Gz_u and W = [I −G].  False when Ŝ's condition > max_condition.
bool plant_from_local_fit(const Eigen::MatrixXcd& Gz, Index plant_inputs, double max_condition, Eigen::MatrixXcd& G,
                          Eigen::MatrixXcd& W, Eigen::MatrixXcd& Sinv);
}  // namespace signal_detail

}  // namespace lpvid
