// lpvid — Markov parameters of the plant from those of the closed loop and the known
// controller: P = G (I − C G)⁻¹ (DESIGN.md item 3) applied to the FIR estimate ĝ.
//
// In the time domain this is the causal recursion p = g + (g ∗ c) ∗ p (G has no
// feedthrough, so (g ∗ c)[0] = 0); it is evaluated per frequency on the half-bin-shifted
// grid z_f = e^{jπ(2f+1)/M}, f = 0..M−1, which never meets a controller pole at z = ±1
// (an integrator), and transformed back:
//
//   p̂[k] = (1/M) Σ_f P̂(z_f) z_f^k,   P̂(z_f) = Ĝ(z_f) (I − C(z_f) Ĝ(z_f))⁻¹,
//   Ĝ(z) = Σ_{k=0}^{L} ĝ[k] z^{−k},
//
// exact up to time aliasing p̂[k] − p̂[k + M] + …, negligible when p̂ has decayed within
// M (M ≥ 4 (L + 1) here, rounded up to a power of two).  Noise in ĝ is amplified by
// |I + C P| on both sides, i.e. strongly where the loop gain is high (low frequencies):
// p̂ is meant as a starting point for a realisation, not as a final estimate.
//
// | argument / result | shape |
// |-------------------|-------|
// | g                 | L + 1 matrices p × m (closed loop v → q) |
// | controller        | discrete, p inputs (e = −q), m outputs (u_c) |
// | result            | num_lags + 1 matrices p × m (plant u → q) |
//
// @throws InputError  g empty or of mixed shapes; controller invalid, continuous or of
//                     the wrong shape; num_lags < 1.  A frequency where I − C Ĝ is
//                     singular gives NumericalError.
#pragma once

#include "idlib/core/types.h"

namespace lpvid {

MarkovSequence plant_markov_from_closed_loop(const MarkovSequence& g, const StateSpace& controller, Index num_lags);

}  // namespace lpvid
