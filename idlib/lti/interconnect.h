// Interconnections of state-space models.
//
// Feedback convention of the project (DESIGN.md item 3): the controller C maps
// the error e = −q to u_c; the plant input is u = u_c + v, v the injected
// excitation; q = P u.  Hence
//   closed-loop output      G = P (I + C P)⁻¹ : v → q
//   input sensitivity       S = (I + C P)⁻¹   : v → u
//   plant from the loop     P = G (I − C G)⁻¹  (positive feedback of C around G).
//
// | model       | inputs | outputs | states |
// |-------------|--------|---------|--------|
// | plant P     | m      | p       | n_P    |
// | controller C| p      | m       | n_C    |
// | G, S        | m      | p, m    | n_P + n_C |
//
// State order of every result: [x_first_argument; x_second_argument].  No
// reduction is done: cancelled modes stay (see idlib/lti/reduce.h).
//
// Every function throws InputError when a model is invalid, the sample periods
// differ (the message names both), the dimensions do not chain, or, for the
// feedback loops, I − D_C D_P (resp. I + D_C D_P) is singular: an algebraic loop
// with no causal solution.
#pragma once

#include "idlib/core/types.h"

namespace lpvid {

// Relative tolerance on |Ts1 − Ts2| / max(Ts1, Ts2) for two models to be
// considered sampled at the same rate (periods read from files with ~1e-12
// relative round-off must still match).
inline constexpr double kSamplePeriodRelTolerance = 1e-9;

// y = second(first(u)).  A = [[A1 0]; [B2 C1  A2]], B = [B1; B2 D1],
// C = [D2 C1  C2], D = D2 D1.  Input names from first, output names from second.
StateSpace series(const StateSpace& first, const StateSpace& second);

// G = P (I + C P)⁻¹: v → q (names: plant's inputs and outputs).
StateSpace closed_loop_output(const StateSpace& plant, const StateSpace& controller);

// S = (I + C P)⁻¹: v → u (names: plant's inputs on both sides).
StateSpace closed_loop_input_sensitivity(const StateSpace& plant, const StateSpace& controller);

// P = G (I − C G)⁻¹ = (I − G C)⁻¹ G, i.e. y = G (w + C y); order n_G + n_C, no
// reduction.  With E = (I − D_C D_G)⁻¹:
//   A = [[A_G + B_G E D_C C_G,              B_G E C_C];
//        [B_C (C_G + D_G E D_C C_G),  A_C + B_C D_G E C_C]]
//   B = [B_G E; B_C D_G E],  C = [C_G + D_G E D_C C_G,  D_G E C_C],  D = D_G E.
StateSpace positive_feedback_with(const StateSpace& G, const StateSpace& controller);

}  // namespace lpvid
