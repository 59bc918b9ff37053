// Zero-order-hold discretisation, local to the models/sim modules until
// idlib/lti provides the shared one (the lead switches callers over then).
#pragma once

#include "idlib/core/types.h"

namespace lpvid {

// Exact ZOH discretisation of a continuous state-space model:
//   exp([A B; 0 0]·Ts) = [Ad Bd; 0 I],   Cd = C,  Dd = D,
// i.e. Ad = e^{A Ts}, Bd = ∫_0^Ts e^{A s} ds · B (Van Loan's block exponential,
// valid for singular A such as a double integrator).
//
// | matrix | shape | discrete result |
// |--------|-------|-----------------|
// | A      | n×n   | Ad, n×n |
// | B      | n×m   | Bd, n×m |
// | C, D   | p×n, p×m | unchanged |
// Names are copied; the result has sample_period_s = Ts.
// @throws InputError  the model is invalid (StateSpace::validate) or already
//   discrete; sample_period_s not finite or <= 0.
StateSpace discretize_zoh_local(const StateSpace& continuous, double sample_period_s);

}  // namespace lpvid
