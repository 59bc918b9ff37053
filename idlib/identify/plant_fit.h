// lpvid — structured closed-loop fit of the plant with the KNOWN controller, in the
// frequency domain of the estimated Markov parameters (issue 11).
//
// Data.  ĝ[1..L] of the closed loop G = P (I + C P)⁻¹ : v → q (idlib/signal/markov.h)
// and its L-point DFT at the first F bins (z_f = e^{j 2π f / L}, ω_f = 2π f / (L Ts)):
//
//   Ĝ_L(z_f) = Σ_{k=1}^{L} ĝ[k] z_f^{−k}.
//
// Model.  P(θ) = (A, B, C_P, D = 0) of order n (a ZOH-sampled plant has no
// feedthrough), closed with the controller K = (A_K, B_K, C_K, D_K), e = −q,
// u = u_c + v:
//
//   A_cl = [A − B D_K C_P,  B C_K;  −B_K C_P,  A_K],  B_cl = [B; 0],  C_cl = [C_P, 0],
//
// and the truncated transform of its impulse response, EXACT for any L (no need for
// the response to have died out within the horizon):
//
//   H_L(z_f; θ) = Σ_{k=1}^{L} C_cl A_cl^{k−1} B_cl z_f^{−k} = C_cl (z_f I − A_cl)⁻¹ (I − A_cl^L) B_cl
//
// (z_f^L = 1).  The fit minimises the whitened least-squares cost
//
//   V(θ) = Σ_f s_f Re tr[(Ĝ_L − H_L)ᴴ Φ_f⁻¹ (Ĝ_L − H_L) R₀ / L],   s_f = 2 (1 at DC/Nyquist),
//
// where Φ_f is the p × p power spectral density of the Markov estimate's residual
// e(t) (noise, disturbances and the part of the response beyond the horizon; two-sided,
// per sample) and R₀ = Σ_t v(t) v(t)ᵀ: for white v the DFT-bin errors of ĝ are
// approximately independent across bins with covariance L R₀⁻¹ ⊗ Φ_f, so V is the
// negative log-likelihood (up to constants) and V ≈ the number of real residuals at
// the truth.  This is Pintelon & Schoukens' frequency-domain output error
// (System Identification: A Frequency Domain Approach, 2nd ed., ch. 9) on the
// Markov-compressed data, with the truncation term in place of their transient.
//
// Solver: Levenberg–Marquardt on θ = [vec A; vec B; vec C_P] (column-major) in the
// orthogonal complement of the similarity (gauge) directions (T A − A T, T B, −C_P T)
// (data-driven local coordinates, McKelvey, Helmersson & Ribarits 2004), so that n(m+p)
// parameters move.  The Jacobian is exact: dH = dC_cl X + Y dA_cl X + Y dB_q,
// X = R (I − A_cl^L) B_cl, Y = C_cl R, R = (zI − A_cl)⁻¹, with d(A_cl^L) from the
// eigendecomposition of A_cl (divided differences of λ^L; block-triangular powers when
// the eigenvectors are ill-conditioned).  Every column of the Jacobian is an outer
// product u vᵀ (or a combination of them), so JᵀJ is accumulated from the Gram matrices
// Uᴴ Φ⁻¹ U and Vᴴ (R₀/L) V per bin, which also makes full output whitening free.
// Steps that would make the closed loop unstable are rejected once it is stable (the
// experiment ran in a stable loop).
//
// | quantity         | shape |
// |------------------|-------|
// | response[f]      | p × m complex (Ĝ_L at bin f) |
// | noise_inverse[f] | p × p complex Hermitian (Φ_f⁻¹) |
// | excitation_gram  | m × m (R₀) |
// | initial          | discrete, n states, m inputs (u), p outputs (q), D = 0 |
// | controller       | discrete, p inputs (e = −q), m outputs (u_c) |
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"

namespace lpvid {

struct MarkovBins {
  Index num_lags = 0;           // L (the DFT length)
  double sample_period_s = 0;   // Ts
  Eigen::VectorXd omega_rad_s;  // F: ω_f = 2π f / (L Ts), f = 0..F−1
  std::vector<Eigen::MatrixXcd> response;       // F of p × m
  std::vector<Eigen::MatrixXcd> noise_inverse;  // F of p × p
  Eigen::MatrixXd excitation_gram;              // m × m
  // F of m × m Hermitian: the excitation's spectral density S_vv at each bin, when it is
  // coloured; the fit then weighs bin f by S_vv(f)/L in place of R₀/L (for white v,
  // S_vv ≈ R₀).  Empty: R₀ at every bin.
  std::vector<Eigen::MatrixXcd> excitation_spectrum;
  Index num_bins() const { return omega_rad_s.size(); }
  Index real_residuals() const;  // Σ_f s_f p m (2 per complex entry, 1 at DC / Nyquist)
};

// Ĝ_L at bins 0..num_bins−1 of the L-point DFT of g[1..L] (FFT), with the noise
// spectrum Φ_f given at the same bins (p × p, Hermitian, positive semi-definite).
// Before inversion Φ_f gets a floor that stands for the numerical accuracy of ĝ itself:
// output i's diagonal is raised to at least relative_accuracy² · max_{f,j} |Ĝ_ij(f)|² R₀_jj / L,
// the noise level at which the bins would be known to `relative_accuracy` of the largest
// response (noise-free logs otherwise yield weights that fit round-off and truncation
// as if they were signal).
// @throws InputError  g shorter than L + 1; num_lags < 2; num_bins not in 1..L/2+1;
//                     spectra count/shape mismatch; excitation_gram not m × m;
//                     relative_accuracy not in (0, 1).
MarkovBins make_markov_bins(const MarkovSequence& g, Index num_lags, Index num_bins,
                            const std::vector<Eigen::MatrixXcd>& noise_spectrum, const Eigen::MatrixXd& excitation_gram,
                            double sample_period_s, double relative_accuracy);

struct PlantFitOptions {
  int max_iterations = 300;
  // Stop when an accepted step lowers V by less than max(absolute, relative · V):
  // V is in units of whitened squared residuals, so 1e-3 is far below one standard
  // deviation of V (√(2·#residuals)).
  double cost_tolerance_absolute = 1e-3;
  double cost_tolerance_relative = 1e-12;
  // Channel scales for conditioning (not a weighting: V is invariant to them):
  // u_scale (m) and q_scale (p) > 0, e.g. the RMS of the plant input and output; empty = 1.
  Eigen::VectorXd input_scale, output_scale;
  // @throws InputError naming the field and the rule.
  void validate() const;
};

struct PlantFitResult {
  StateSpace plant;         // order n, D = 0, sample period of the data
  double initial_cost = 0;  // V at the initial plant
  double cost = 0;          // V at the result
  Index residuals = 0;      // real residuals
  Index parameters = 0;     // n (m + p): free parameters after the gauge is removed
  int iterations = 0;
  bool closed_loop_stable = false;
  // σ̂² = V / (residuals − parameters): 1 when Φ was right; scales the covariance.
  double noise_scale = 1;
  // Covariance of θ = [vec A; vec B; vec C_P] of `plant` (its own coordinates),
  // σ̂² (JᵀJ)⁺ restricted to the gauge complement: (n² + n m + p n) square.
  Eigen::MatrixXd covariance;
  // 0: covariance is the model's σ̂² (JᵀJ)⁺; S > 0: the sandwich of S replicates
  // (use_replicate_covariance).
  Index replicates = 0;
  Report report;
};

// @throws InputError  shapes or sample periods that do not match; an initial plant
//                     with feedthrough; options.validate().
// A result whose closed loop is unstable, or whose cost is not finite, has
// report.usable == false.
PlantFitResult fit_plant_closed_loop(const MarkovBins& data, const StateSpace& controller, const StateSpace& initial,
                                     const PlantFitOptions& options);

// V(θ) of `plant` on the data (no fit): for choosing among starting models.
// @throws InputError  as fit_plant_closed_loop.
double plant_fit_cost(const MarkovBins& data, const StateSpace& controller, const StateSpace& plant,
                      const PlantFitOptions& options);

// Replaces fit.covariance by the sandwich B (Σ_s g_s g_sᵀ) B · S/(S − 1), B = (JᵀJ)⁺ on
// the gauge complement, g_s = Jᵀ W δĜ_s the gradient a replicate δĜ_s of the data's
// error adds (J, W at fit.plant on `data`, the data of the fit): the covariance of the
// linearised estimate when the data's error is Σ_s δĜ_s with independent terms,
// however the bins are correlated (Φ's model of independent bins is not used).
// Replicates: markov_error_replicates (signal/noise_spectrum.h), bins as `data`.
// @throws InputError  as fit_plant_closed_loop; fewer than two replicates; a
//                     replicate whose bins do not match the data's.
void use_replicate_covariance(PlantFitResult& fit, const MarkovBins& data, const StateSpace& controller,
                              const std::vector<std::vector<Eigen::MatrixXcd>>& replicates,
                              const PlantFitOptions& options);

// E|P̂_ij(e^{jωTs}) − P_ij|² at each ω (delta method with the fit's covariance: the sum
// of the variances of the real and imaginary parts), p × m per frequency.
// @throws InputError  covariance of the wrong size.
std::vector<Eigen::MatrixXd> plant_response_variance(const PlantFitResult& fit, const Eigen::VectorXd& omega_rad_s);

}  // namespace lpvid
