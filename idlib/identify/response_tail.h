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
#include <vector>

#include "idlib/core/types.h"
#include "idlib/signal/markov.h"

namespace lpvid {

Eigen::MatrixXd closed_loop_response_beyond(const StateSpace& plant, const StateSpace& controller,
                                            const Eigen::Ref<const Eigen::MatrixXd>& excitation, Index lag);

// The error of a model's response beyond the horizon, refitted to the logs.  The tail
// y_L(t) = Σ_i c_i ξ_i(t − L) is linear in the modal states ξ_i of the closed loop
// (ξ_i(t+1) = λ_i ξ_i(t) + b_iᵀ v(t)); with the poles λ_i of `plant` and `controller`
// fixed, the amplitudes are re-estimated from the data: per slow mode (|λ_i|^L ≥
// kSlowModeTail) and excited input a the regressors Re, Im of ξ_{i,a}(t − L),
// ξ_{i,a}(t+1) = λ_i ξ_{i,a}(t) + v_a(t), centred per experiment, fitted by least squares
// to the residual of g on outputs from which the model's tail was already removed
// (e = corrected − Σ g[k] v(t − k) − mean).  With white excitation these regressors (v
// beyond lag L) are orthogonal to g's (lags ≤ L), so the fit takes the tail's amplitude
// from the logs rather than from the model, whose amplitudes come from g at lags ≤ L
// that the tail itself disturbs (the slow fixed point of the tail rounds).
// Returns Δy per experiment (N_e × p): subtract it too.  All zero when no mode is slow.
// @throws InputError  shapes that do not match; lag < 1.
inline constexpr double kSlowModeTail = 1e-3;
std::vector<Eigen::MatrixXd> refit_response_beyond(const StateSpace& plant, const StateSpace& controller,
                                                   const std::vector<ExperimentView>& corrected,
                                                   const MarkovSequence& g, Index lag);

}  // namespace lpvid
