// lpvid — the part of a closed loop's response that lies beyond a Markov horizon.
//
// For the closed loop of plant P and controller C (plant_fit.h: A_cl, B_cl, C_cl) driven
// from rest by the logged excitation v, the output splits at lag L into
//
//   q(t) = Σ_{k=1}^{L} g[k] v(t − k)  +  y_L(t),   y_L(t) = C_cl A_cl^L x(t − L),
//
// x(t+1) = A_cl x(t) + B_cl v(t), x(0) = 0 (y_L = 0 for t < L).  Subtracting a model's
// y_L from the logged outputs before estimating g[1..L] removes the response beyond the
// horizon, which otherwise acts as extra noise on every lag (the "tail rounds" of
// identify.h).  Only modes with |λ|^L above 1e-12 contribute; they are simulated in
// modal coordinates (dense simulation when the eigenvectors are ill-conditioned).
//
// | argument   | shape |
// |------------|-------|
// | plant      | discrete, m inputs, p outputs, D = 0 |
// | controller | discrete, p inputs (e = −q), m outputs |
// | excitation | N × m (v), zero before the record |
// | result     | N × p |
//
// @throws InputError  shapes or sample periods that do not match; lag < 1.
#pragma once

#include <Eigen/Core>

#include "idlib/core/types.h"

namespace lpvid {

Eigen::MatrixXd closed_loop_response_beyond(const StateSpace& plant, const StateSpace& controller,
                                            const Eigen::Ref<const Eigen::MatrixXd>& excitation, Index lag);

}  // namespace lpvid
