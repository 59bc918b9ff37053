// The time-domain closed-loop identification chain of Gajdušek et al.
// (seed 000, eqs 10–14) as one call:
//
//   logs (v, q) --markov (FFT correlation, least squares)--> g[0..L] of G: v -> q
//               --ERA (scaled, strided block Hankel, automatic order)--> G_n
//               --unloop P = G (I - C G)^-1, controller modes removed--> P
//
// Each step is also available alone (idlib/signal/markov.h,
// idlib/realization/era.h, idlib/closedloop/unloop.h); this function fixes the
// policy that joins them: the number of lags, the scaling, and the checks that
// the logs and the controller agree.
#pragma once

#include <string>
#include <vector>

#include "idlib/closedloop/unloop.h"
#include "idlib/core/types.h"
#include "idlib/realization/era.h"
#include "idlib/signal/markov.h"

namespace lpvid {

struct IdentifyOptions {
  // Length of the estimated impulse response, in seconds.  The number of lags is
  // L = round(markov_horizon_s / Ts), at most a quarter of the shortest record
  // (so that at least 4 L samples inform every lag).  The closed loop's impulse
  // response must have died out within the horizon; 2 s covers a slowest
  // closed-loop pole at -3 rad/s to 2.5e-3 of its peak.
  double markov_horizon_s = 2.0;
  Index num_lags = 0;  // > 0 overrides markov_horizon_s
  MarkovOptions::Method markov_method = MarkovOptions::Method::kLeastSquares;
  Index closed_loop_order = 0;  // 0: automatic (EraOptions::order)
  Index max_order = 40;
  Index plant_order = 0;        // 0: closed-loop order minus controller order
  // Relative tolerance on |Ts_log - Ts_controller| / Ts_controller.
  double sample_period_tolerance = 1e-6;

  // Throws InputError naming the option and the rule.
  void validate() const;
};

struct IdentifyResult {
  Index num_lags = 0;
  MarkovResult markov;
  EraResult closed_loop;
  UnloopResult plant;
  std::vector<std::string> warnings;  // from every step, in order
};

// | argument        | shape / meaning |
// |-----------------|-----------------|
// | experiments     | each: excitation N_e x m (v), output N_e x p (q) |
// | sample_period_s | of the logs, > 0 |
// | controller      | discrete, p inputs (e = -q) -> m outputs (u_c), same Ts |
//
// @throws InputError  controller/log sample periods differ; controller shape does
//                     not match the channel counts; a record too short for the
//                     lags (and every InputError of the steps).
// @throws NumericalError  no model order stands above the noise floor; the
//                         realised closed loop is unstable (the loop that ran was
//                         stable, so such a model is wrong).
IdentifyResult identify_closed_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                    const StateSpace& controller, const IdentifyOptions& options);

// The number of lags the chain uses for records of `shortest_record` samples.
Index choose_num_lags(const IdentifyOptions& options, double sample_period_s, Index shortest_record);

// Checks that a discrete controller fits logs with p outputs and m excitations
// sampled at sample_period_s (message names both periods in Hz and seconds).
void check_controller_matches(const StateSpace& controller, double sample_period_s, Index num_outputs,
                              Index num_excitations, double relative_tolerance);

}  // namespace lpvid

namespace lpvid {

// How well a discrete model reproduces estimated Markov parameters, per channel:
// fit(i,j) = 100 (1 - ||g_ij - ĝ_ij|| / ||g_ij||) over lags 1..L, in percent
// (100 = exact; the norm is the 2-norm over lags).  Like MATLAB's compare fit,
// but on the impulse response.  | g: L+1 matrices p x m | result: p x m |
// @throws InputError if the model's shape differs from g's.
Eigen::MatrixXd markov_fit_percent(const StateSpace& model, const MarkovSequence& g);

}  // namespace lpvid
