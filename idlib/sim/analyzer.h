// A simulated dynamic-signal analyzer (SigLab-style stepped sine) measuring the
// input sensitivity S = (I + C P)⁻¹ : v → u of a discrete closed loop, one
// plant input excited at a time, as in seed 000, section 4 ("the frequency
// responses were measured by the SigLab analyzer ... S measured by injecting v
// into one input at a time").  The loop is that of idlib/sim/platform_sim.h:
//
//        v ──►(+)── u ──► P ── q ──►(+)── q_meas ──┐
//              ▲                     n ─┘           │
//              └──── u_c ◄── C ◄── e = −q_meas ◄────┘
//
// so  u = S v − S C n :  the analyzer's error in S is the SENSOR NOISE n seen
// through the controller, not an error proportional to S.  (Where the loop gain
// is small, S ≈ I and S − I ≈ −C P: the noise −S C n relative to S − I is then
// n / (P v), the output noise-to-signal ratio, which is what limits P = C⁻¹(S⁻¹−I).)
//
// Measurement model, per excited input j and frequency ω_k (z = e^{jω_k Ts}):
//   v_j = a_j cos(ω_k t) (a_j = excitation_amplitude(j)), the other inputs 0; the
//   loop has settled (transients are waited out, not simulated).  The analyzer
//   records `averages` blocks of N_b = round(integration_s / (averages · Ts))
//   samples and correlates every channel x with the reference in each block,
//   X̂ = (2 / N_b) Σ_n x[n] e^{−jω_k n Ts} (the complex amplitude; v̂_j = a_j).  For
//   block b this gives
//     û⁽ᵇ⁾ = S(z) e_j a_j − S(z) C(z) ñ⁽ᵇ⁾,
//   ñ⁽ᵇ⁾ the correlation of the white sensor noise: independent circular complex
//   Gaussian per channel l with E|ñ_l|² = 4 σ_l² / N_b (σ_l = sensor_noise_std(l),
//   the per-sample std of platform_sim.h).  The H1 estimate with the known
//   reference and its ordinary coherence are
//     Ŝ(:, j)    = (1/K) Σ_b û⁽ᵇ⁾ / a_j,          K = averages,
//     γ²(i, j)   = |Σ_b û_i⁽ᵇ⁾|² / (K Σ_b |û_i⁽ᵇ⁾|²)   (1 without noise; 1/K-biased).
//   Neglected (documented, not simulated): leakage of the filtered noise from
//   frequencies within ~1/(N_b Ts) of ω_k (the spectrum of S C n is smooth on that
//   scale except within that distance of a lightly damped closed-loop pole), the
//   analyzer's own input noise and quantisation (u is a signal of the digital
//   controller), and excitation distortion.
//
// "Noise on S" — the number a user quotes — is reported per frequency as
//   ε_S(ω) = sqrt(E‖Ŝ − S‖_F²) / ‖S‖_F
//          = 2 ‖S C diag(σ)‖_F · sqrt(Σ_j 1/a_j²) / (sqrt(N_b K) · ‖S‖_F),
// the expected relative error of the measured matrix (exact for this model), with
// its mean over the grid in AnalyzerMeasurement::mean_relative_noise.
//
// | argument            | requirement |
// |---------------------|-------------|
// | discrete_plant      | discrete, n_p states, m inputs, m outputs (square) |
// | discrete_controller | discrete, same Ts, m inputs (e), m outputs (u_c) |
// | options             | AnalyzerOptions::validate; m = 3 (the vectors below) |
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "idlib/core/types.h"

namespace lpvid {

struct AnalyzerOptions {
  // Frequencies of the sweep in rad/s: finite, > 0, strictly increasing, below
  // the Nyquist frequency π / Ts.  Required (no default grid).
  Eigen::VectorXd omega_rad_s;
  // Sine amplitude a_j per plant input [T_psi T_theta F_z] in N·m, N·m, N, > 0.
  // Defaults: the per-sample std of the time-domain experiments
  // (ExcitationOptions::excitation_std), so one sine carries the power the white
  // noise spreads over the whole band — within the ~110 N control budget.
  Eigen::Vector3d excitation_amplitude{0.05, 0.05, 1.0};
  // Measurement time per frequency and excited input, s (SigLab's "integration
  // time"), split into `averages` blocks.  The error of Ŝ falls as 1/sqrt of it.
  double integration_s = 1.0;
  Index averages = 4;  // K >= 2 (one block has coherence 1 by definition)
  // Per-sample std of the white sensor noise [psi theta z] in rad, rad, m, >= 0
  // (default: ExcitationOptions{}.sensor_noise_std, derived there).
  Eigen::Vector3d sensor_noise_std{1.2e-6, 1.2e-6, 1.0e-7};
  double sample_period_s = 1e-3;  // must equal the models' Ts
  std::uint64_t seed = 1;

  // @throws InputError naming the field and the rule: grid empty, not finite,
  //   not > 0, not strictly increasing or above Nyquist; amplitudes not finite
  //   or <= 0; noise std negative or not finite; integration_s not finite or
  //   <= 0, or giving N_b < 1 sample per block; averages < 2; sample period not
  //   finite or <= 0.
  void validate() const;
};

struct AnalyzerMeasurement {
  // Ŝ with coherence (3 x 3 per frequency, output u_i, input v_j), flagged all
  // false; names: outputs {"u1","u2","u3"}, inputs {"v1","v2","v3"} (the log
  // columns of platform_sim.h).
  FrequencyResponse sensitivity;
  // The exact S(e^{jωTs}) on the same grid and names (the truth).
  FrequencyResponse exact_sensitivity;
  // ε_S(ω_k) (see above), one per frequency, and its mean over the grid.
  Eigen::VectorXd relative_noise;
  double mean_relative_noise = 0.0;
};

// Measures S of the loop (plant, controller) as described above.  Noise draws:
// std::mt19937_64(seed), std::normal_distribution(0, 1), in the order excited
// input j, frequency k, block b, channel l, real part then imaginary part.  The
// same seed gives the same measurement bit for bit.
// @throws InputError  options invalid; a model invalid, continuous, not 3 x 3,
//   or at a sample period other than options.sample_period_s (relative 1e-9).
AnalyzerMeasurement measure_sensitivity(const StateSpace& discrete_plant, const StateSpace& discrete_controller,
                                        const AnalyzerOptions& options);

}  // namespace lpvid
