// Frequency response of a state-space model (layout: idlib/core/types.h).
//
//   G(λ) = C (λ I − A)⁻¹ B + D,   λ = jω          (continuous, sample_period_s == 0)
//                                 λ = e^{jω Ts}    (discrete, Ts = sample_period_s)
//
// A is reduced once to upper Hessenberg form H = Qᵀ A Q (orthogonal Q); each
// frequency then costs one Hessenberg LU with adjacent-row pivoting, O(n² m),
// instead of O(n³) for a dense solve.  This is backward stable for any A
// (diagonalisation is not when eigenvectors are ill-conditioned).
//
// | quantity      | shape / unit |
// |---------------|--------------|
// | omega_rad_s   | F, rad/s (any sign; not required to be sorted) |
// | result[k]     | p x m complex, response at omega_rad_s[k] |
//
// @throws InputError  sys invalid (StateSpace::validate); an ω is non-finite;
//                     λ(ω) is exactly an eigenvalue of A (e.g. ω = 0 with an
//                     integrator): the response is infinite there.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

std::vector<Eigen::MatrixXcd> evaluate_response(const StateSpace& sys, const Eigen::VectorXd& omega_rad_s);

// As evaluate_response, packaged as FRD with the model's input/output names
// (coherence and flagged left empty).
FrequencyResponse frequency_response(const StateSpace& sys, const Eigen::VectorXd& omega_rad_s);

// `count` frequencies spaced evenly in log10 from lo_rad_s to hi_rad_s, both
// included (count == 1 gives lo_rad_s).
// @throws InputError  lo_rad_s <= 0, hi_rad_s < lo_rad_s, non-finite bounds, count < 1.
Eigen::VectorXd log_frequency_grid(double lo_rad_s, double hi_rad_s, Index count);

}  // namespace lpvid
