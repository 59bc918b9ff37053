// Internal to idlib/identify: the stages of the kStructured identification
// (identify_closed_loop, identify.h), one function per stage, shared by the files that
// hold them:
//   identify_horizon.cc    1-2: the Markov horizon, the noise spectrum and the fit band;
//   identify_order.cc      3-4: the starting models and the plant order (and the order
//                               check on the final data);
//   identify_structured.cc 5-7: the staged fit, the tail rounds and the bands, and the
//                               chain that runs the stages in order;
//   order_held_out.cc      identify_open_loop's order checked on data kept out of the fit.
// Not part of the library's API.  A named namespace, not anonymous ones: the library is
// compiled a few files to a unit (CMake unity build), so file-local names must not clash.
#pragma once

#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/identify/identify.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/signal/markov.h"

namespace lpvid::identify_detail {

// The era route's warning on the plant unloop returns (judge_reclosed_loop, identify.cc):
// closed again with the controller, it misses the logs more than 2x as much as the ERA
// closed loop it came from (in 100 − fit %) AND by more than 1 point of fit — two loops
// that both simulate the logs within a point (99.99 % against 99.97 %: 3x "as much") are
// not set against each other.
bool reclosed_loop_misses_far_more(double era_fit_percent, double reclosed_fit_percent);

// kStructured: the first horizon tried is the power of two at or above 1/64 of the
// shortest record (1024 lags for 60 s at 1 kHz, 16384 for 100 s at 10 kHz), at least
// kMinHorizonLags; it is doubled while the response has not ended, up to a quarter of
// the record (each lag then still has 4 record lengths of data behind it).
constexpr Index kHorizonRecordDivisor = 64;
constexpr Index kMinHorizonLags = 256;

// What the stages of identify_structured share: the inputs, and what the earlier stages
// chose for the later ones.
struct StructuredRun {
  StructuredRun(const std::vector<ExperimentView>& experiments_, double Ts_, const StateSpace& controller_,
                const IdentifyOptions& options_, Index shortest_)
      : experiments(experiments_), Ts(Ts_), controller(controller_), options(options_), shortest(shortest_) {}

  const std::vector<ExperimentView>& experiments;
  const double Ts;
  const StateSpace& controller;
  const IdentifyOptions& options;
  const Index shortest;  // samples in the shortest record
  Index m = 0, p = 0;    // excitations, outputs

  // 1. Horizon (choose_horizon).
  MarkovOptions mo;  // the Markov estimates' options, for the horizon steps and the tail rounds
  // R_vv and R_qv, computed once for the horizon steps (up to kHorizonCorrelationSteps
  // doublings ahead); R_vv is reused by the tail rounds.
  MarkovCorrelations corr;
  Index L = 0;
  bool response_beyond = false;  // the response has not ended within the horizon
  // Whether the excitation is coloured, judged once R_vv is known (the first estimate).
  bool coloured = false;
  double colour_ratio = 1.0;
  MarkovSequence g0;  // ĝ[0..L] of the logs

  // 2. Noise spectrum and the fit band (choose_fit_band).
  Eigen::MatrixXd R0;                      // the excitation's Gram matrix
  std::vector<Eigen::MatrixXcd> spectrum;  // the noise spectrum at the L-point bins
  double lowest_bin_rad_s = 0;             // the first non-zero bin of the L-point grid
  double omega_fit = 0;                    // the fit band's upper edge
  Index K0 = 0;                            // the first stage's horizon

  // 3. Starting models (plan_starts); fo: the fits' options (the channels' scales).
  PlantFitOptions fo;
  Index n_cap = 0;  // the largest plant order tried
  std::vector<Index> start_lags;
  Index start_lags_max = 0;

  // A coloured excitation's spectral density added to bins (MarkovBins::excitation_spectrum).
  MarkovBins with_spectrum(MarkovBins b) const;
  // The data of the fit at horizon K: ĝ's bins up to the fit band (at least kMinStageBins),
  // weighed by the noise spectrum `fine` (L-point bins) averaged onto the K-point ones.
  MarkovBins bins_at(const MarkovSequence& g, const std::vector<Eigen::MatrixXcd>& fine, Index K) const;
};

// ---- stages 1-2 (identify_horizon.cc) ----
// 1. The horizon L and ĝ (run.g0, result.markov); sets run.mo, run.corr, run.coloured.
void choose_horizon(StructuredRun& run, IdentifyResult& result);
// 2. The noise spectrum, the fit band and the first stage's horizon K0.
void choose_fit_band(StructuredRun& run, IdentifyResult& result);

// ---- stages 3-4 (identify_order.cc) ----
// ERA models of the plant from p̂ over the first `lags` lags, every order up to n_cap.
struct Realised {
  Index lags = 0;
  std::vector<StateSpace> models;  // [n − 1], order 0 where the Hankel matrix cannot hold n
};
using StartPools = std::vector<const std::vector<Realised>*>;
// 3. The largest plant order tried and the start horizons (run.n_cap, run.start_lags).
void plan_starts(StructuredRun& run);
std::vector<Realised> realise_all(const StructuredRun& run, const MarkovSequence& phat);
// 4. The plant at the first stage (`first`): of the given order, or of the order the
//    ladder chooses.  Sets the choices' order and start.
PlantFitResult fit_first_stage(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovBins& first,
                               IdentifyChoices& ch);
// The order check on the final data (ĝ g_final): a smaller order replaces `fit` when it
// fits the first stage about as well.  Returns whether it did (`fit` then is the smaller
// order's, refitted at every stage); adds to ch.order_reason either way.
bool reduce_order(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovSequence& g_final,
                  PlantFitResult& fit, IdentifyChoices& ch);

// ---- stages 5-7 and the chain (identify_structured.cc) ----
IdentifyResult identify_structured(const std::vector<ExperimentView>& experiments, double Ts,
                                   const StateSpace& controller, const IdentifyOptions& options, Index shortest);

// identify_open_loop: the ladder's order (of `ladder`, the refined result) checked on
// held-out halves of the records; see order_held_out.cc.
IdentifyChoices::HeldOutOrder check_order_held_out(const std::vector<ExperimentView>& experiments, double Ts,
                                                   const IdentifyOptions& options, const IdentifyResult& ladder);

// The output-error refinement of a structured result `r` on its logs (identify.cc): open
// loop (controller nullptr) or in the loop with the known controller; `residual_weights`
// as OutputErrorOptions's (empty: every sample alike).
// `initial` as IdentifyOptions::initial_states.
void refine_on_logs(const std::vector<ExperimentView>& experiments, const StateSpace* controller, IdentifyResult& r,
                    const std::vector<Eigen::VectorXd>& residual_weights = {},
                    IdentifyOptions::InitialStates initial = IdentifyOptions::InitialStates::kAuto);

// identify_closed_loop: whether the refined plant (r, refinement kept) predicts held-out
// halves of the logs better than the structured fit does, each fitted on the other half
// (order_held_out.cc); `reason` says what was found.
bool refinement_predicts_better(const std::vector<ExperimentView>& experiments, double Ts,
                                const StateSpace& controller, const IdentifyOptions& options, const IdentifyResult& r,
                                std::string& reason);

}  // namespace lpvid::identify_detail
