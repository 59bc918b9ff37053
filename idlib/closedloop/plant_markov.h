// lpvid — Markov parameters of the plant from those of the closed loop and the known
// controller: P = G (I − C G)⁻¹ (DESIGN.md item 3) applied to the FIR estimate ĝ.
//
// Evaluated in the time domain as the causal response of the loop to an impulse at
// the plant's input u (e = −q, u = u_c + v, so v = u − u_c): for each input j,
//
//   q[k] = Σ_{i=0}^{L} ĝ[i] v[k − i],   v[k] = δ_j[k] − (C_K x_K[k] + D_K e[k]),  e = −q,
//   x_K[k + 1] = A_K x_K[k] + B_K e[k],
//
// and p̂[k](:, j) = q[k].  The lag-0 term ĝ[0] (an estimate, not exactly 0) closes an
// algebraic loop at each step, solved with (I − D_K ĝ[0]).  This is exact for the FIR
// model ĝ at every lag, whatever the plant: it has no transform length and so no
// time aliasing.  (Before issue 24 it was evaluated on the unit circle and transformed
// back, which is exact only for a plant whose response decays within the transform:
// for a levitated platform — a free rigid body, the beam's gravity making the tilts
// unstable — or a positioning axis with an integrator, p̂ was the stable, two-sided
// sequence with the same spectrum, 60–170 % off the true response at every lag, and
// no starting model closed the loop.)
//
// Cost O(num_lags² p m²) (one (p × m k) · (m k × m) product per lag k): 0.1 s for
// 4096 lags of a 3 × 3 loop.  Noise in ĝ is amplified by |I + C P| on both sides, i.e.
// strongly where the loop gain is high (low frequencies), and grows with an unstable
// plant's modes along the lags: p̂ is meant as a starting point for a realisation, not
// as a final estimate.
//
// | argument / result | shape |
// |-------------------|-------|
// | g                 | L + 1 matrices p × m (closed loop v → q) |
// | controller        | discrete, p inputs (e = −q), m outputs (u_c) |
// | result            | num_lags + 1 matrices p × m (plant u → q); ĝ[i] = 0 for i > L |
//
// @throws InputError  g empty or of mixed shapes; controller invalid, continuous or of
//                     the wrong shape; num_lags < 1.  A singular I − D_K ĝ[0] gives
//                     NumericalError.
#pragma once

#include "idlib/core/types.h"

namespace lpvid {

MarkovSequence plant_markov_from_closed_loop(const MarkovSequence& g, const StateSpace& controller, Index num_lags);

}  // namespace lpvid
