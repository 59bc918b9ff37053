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
//
// The returned result is `base` (the caller's Markov estimate and report fields) with
// the chosen plant, its sandwich covariance for the bands, the closed loop and the
// choices replaced; `ladder` says every order's outcome.
#pragma once

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

struct DirectLadder {
  bool found = false;
  Index order = 0;
  std::vector<std::string> rungs;  // one sentence per order tried
  std::string reason;              // why this order (or why none)
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
                                     const StateSpace& controller, Index max_order, IdentifyResult& result);

}  // namespace lpvid
