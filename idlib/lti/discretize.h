// Zero-order-hold discretisation.
//
//   exp([[A B]; [0 0]] · Ts) = [[Φ Γ]; [0 I]],   A_d = Φ = e^{A Ts},
//   B_d = Γ = ∫₀^Ts e^{A τ} dτ B,   C_d = C,   D_d = D.
//
// Exact for inputs held constant over each sample period (Franklin, Powell &
// Workman, Digital Control of Dynamic Systems, §4.3.3).  The matrix exponential
// is Eigen's scaling-and-squaring Padé (unsupported/MatrixFunctions).
//
// | matrix | shape (in = out) |
// |--------|------------------|
// | A      | n x n |
// | B      | n x m |
// | C, D   | p x n, p x m |
//
// @throws InputError  continuous is invalid or already discrete; sample_period_s
//                     is not finite and > 0.
#pragma once

#include "idlib/core/types.h"

namespace lpvid {

StateSpace discretize_zoh(const StateSpace& continuous, double sample_period_s);

}  // namespace lpvid
