// lpvid — the direct route for closed-loop logs the loop's response cannot identify
// (issue 24: a positioning axis exercised by point-to-point moves, whose few excited
// frequencies leave the loop's long impulse response undetermined; identify_closed_loop
// then finds no plant).  The plant is fitted where such logs do determine it, in the
// time domain and at low order:
//
//   1. u, the input the loop applied (identify.h applied_plant_input), and q give, for
//      each order n = 1..max_order, an ARX model by least squares,
//        q(k) + A_1 q(k−1) + … + A_n q(k−n) = B_1 u(k−1) + … + B_n u(k−n) + c,
//      strictly proper (a plant inside a sampled loop has no feedthrough, and u holds
//      q's own noise at lag 0: a lag-0 term would fit the controller's inverse), in
//      block observer form (n p states);
//   2. each start refined by output error IN ITS LOOP (output_error.h
//      refine_output_error_closed_loop: the loop simulated from the logged excitation v
//      with the known controller, so the output noise enters only the residual — the
//      direct method's feedback bias does not arise), from rest, then with the loop's
//      initial state where Akaike's criterion says it pays (identify_detail::refine_on_logs);
//   3. the order by BIC on the refined costs, N log(V/N) + P log N, among the orders
//      whose loop with the controller is stable.
//   With `friction`, the plant has friction inputs beside u (friction_inputs: Coulomb
//   friction, a force offset and sticking at rest, as inputs whose B columns are fitted
//   with the plant's) and is the linear part of that model.  The caller decides when:
//   cli/identify.cc reruns the ladder so when the linear plant's residual follows the
//   sign of the velocity (idlib/validate/nonlinearity.h), up to the linear ladder's
//   order.  (BIC between the two was tried and not kept: on a linear axis the columns
//   at rest took the encoder's quantisation, constant over each rest, and won at order
//   4, the plant 7 % off where the linear one is 0.02 %: BIC counts correlated residuals
//   as independent.)  A friction axis fitted linearly gives its best linear
//   approximation, tens of percent off its linear part; with the friction beside it,
//   the linear part.
//
// The returned result is `base` (the caller's Markov estimate and report fields) with
// the chosen plant, its sandwich covariance for the bands, the closed loop and the
// choices replaced; `ladder` says every order's outcome.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/identify/identify.h"
#include "idlib/signal/markov.h"

namespace lpvid {

inline constexpr Index kDirectMaxOrder = 4;

// The strictly proper ARX model of the given order (block observer form, D = 0) fitted
// to u -> q by least squares over every experiment (a constant per output and
// experiment, not kept).  Empty (order 0) when the regression is rank-deficient.
// | experiments: excitation N_e x m (u), output N_e x p (q) |
// @throws InputError  order < 1; records shorter than 4 (order + 1) samples.
StateSpace arx_strictly_proper(const std::vector<ExperimentView>& experiments, Index order, double sample_period_s);

// Friction beside the plant (a positioning axis's Coulomb friction and force offset):
// exogenous plant inputs w = [sign of each output's velocity, 1] (p + 1 columns; where
// every sign is 0 the direct route holds the plant's input at zero: a stuck axis), the
// velocity a central difference over ±kFrictionHalfWindow samples, 0 inside a deadband
// of kFrictionDeadband of its peak (at rest the friction holds whatever balances, not
// ±F_c).  The sign is of the logged output's velocity: a position (an encoder), not a
// velocity or an acceleration, for which the columns mean nothing and BIC drops them.
inline constexpr Index kFrictionHalfWindow = 5;
inline constexpr double kFrictionDeadband = 0.02;
// | output N x p | -> N x (p + 1) |
Eigen::MatrixXd friction_inputs(const Eigen::Ref<const Eigen::MatrixXd>& output);

// The friction the ladder took, as forces at the plant's input (its units): the plant
// sees u + coulomb · sign(velocity) + (a constant) while it moves.  coulomb m x p (a
// Coulomb friction opposes the motion: a negative diagonal), each the constant force that
// moves the loop's output as the friction input does (direct.cc keep_plant_inputs).  The
// constant's force is not given: its steady effect on the loop's output is a constant,
// which each log's free output offset (the encoder's zero) takes as well, so the logs
// do not determine it (measured on the point-to-point friction axis: 0.0236 for a 2.8 N
// offset and 0.0229 for none; on two sines, −377).
struct DirectFriction {
  Eigen::MatrixXd coulomb;
};

struct DirectLadder {
  bool found = false;
  Index order = 0;      // the plant's (states)
  Index arx_order = 0;  // the ARX order n it came from (order = n p)
  std::vector<std::string> rungs;  // one sentence per order tried
  std::string reason;              // why this order (or why none)
  // With `friction`: the friction fitted beside the plant (the plant is the linear
  // part: the columns of u alone).
  std::optional<DirectFriction> friction;
};

// | loop: excitation v N_e x m, output q | applied: u N_e x m, the same q |
// | controller: p -> m, e = −q, u = K e + v |
// Fills `result` (plant, fit.plant, fit.covariance, closed_loop, choices.refinement and
// its reason, choices.order_reason, choices.bands_reason) when an order is found.
// `loop` empty: each start is refined as open-loop data on `applied` instead (the
// logs' "excitation" is the plant's own input; output_error.h refine_output_error),
// still kept only when its loop with the controller is stable.
DirectLadder identify_direct_in_loop(const std::vector<ExperimentView>& loop,
                                     const std::vector<ExperimentView>& applied, double sample_period_s,
                                     const StateSpace& controller, Index max_order, IdentifyResult& result,
                                     bool friction = false);

}  // namespace lpvid
