// The time-domain closed-loop identification chain of Gajdušek et al. (seed 000,
// section 4) as one call, by one of two methods:
//
// kStructured (default; docs/math.md §2a): the plant is fitted directly with the KNOWN
//   controller, every setting chosen from the logs:
//     logs (v, q) --markov, horizon from the data--> ĝ[0..L] of G: v → q
//       --noise spectrum of the residual--> weights per frequency bin
//       --P̂ = Ĝ (I − C Ĝ)⁻¹ as an impulse response, ERA at candidate orders--> P₀
//       --frequency-domain output-error fit of G(P) = P (I + C P)⁻¹ to ĝ (plant_fit.h),
//         staged horizons, plant order by BIC--> P
//       --tail rounds: subtract the fitted response beyond the horizon, re-estimate ĝ,
//         refit, until P stops moving--> P with its covariance (bands).
//   It does not need the impulse response to die out within the horizon, never
//   realises the closed loop without the controller's structure, and returns a stable
//   closed loop by construction (steps that destabilise it are rejected).
// kEra (the paper's recipe, as before issue 11):
//     logs --markov (2 s horizon unless given)--> ĝ --ERA (scaled, strided block Hankel,
//     noise-floor order)--> G_n --unloop P = G (I − C G)⁻¹, controller modes removed--> P
//
// Each step is also available alone (idlib/signal/markov.h, idlib/realization/era.h,
// idlib/closedloop/unloop.h, idlib/closedloop/plant_markov.h, plant_fit.h); this file
// fixes the policy that joins them and says in IdentifyChoices what it chose and why.
#pragma once

#include <string>
#include <vector>

#include "idlib/closedloop/unloop.h"
#include "idlib/core/progress.h"
#include "idlib/core/types.h"
#include "idlib/identify/plant_fit.h"
#include "idlib/realization/era.h"
#include "idlib/signal/markov.h"

namespace lpvid {

// The 95 % band of an identified response (bode.png; identify's tests): a disc of radius
// r σ around Ĥ, σ² = E|Ĥ − H|² (the variance in plant_frd.csv), drawn as the magnitude
// envelope |Ĥ| ± r σ.  r = 2: the error of a parametric fit is an elliptical, not
// circular, complex Gaussian, for which a disc of radius r σ holds between 1 − e^{−r²}
// (circular: 98.2 %) and P(|N(0,1)| ≤ r) (all in one direction: 95.4 %); σ itself is
// estimated from ~40 record segments (the replicates), which lowers the coverage by a
// few points.  Measured on the independent simulator (10-12 noise draws of each of 4
// plants, 1-400 rad/s): 89-98 % of the true responses inside, per frequency decade.
inline constexpr double kBandRadiusPerSigma = 2.0;

enum class IdentifyMethod { kStructured, kEra };

struct IdentifyOptions {
  IdentifyMethod method = IdentifyMethod::kStructured;
  // Length of the estimated impulse response.  num_lags > 0 gives L directly;
  // markov_horizon_s > 0 gives L = round(markov_horizon_s / Ts); both 0: from the
  // data (kStructured: see IdentifyChoices::horizon_reason; kEra: 2 s, the paper
  // recipe's default).  Either way at most a quarter of the shortest record.
  double markov_horizon_s = 0.0;
  Index num_lags = 0;
  MarkovOptions::Method markov_method = MarkovOptions::Method::kLeastSquares;
  Index closed_loop_order = 0;  // kEra: 0 = automatic (EraOptions::order)
  Index max_order = 40;         // kEra: largest closed-loop order; kStructured: largest plant order tried
  Index plant_order = 0;        // 0: kEra n_G − n_C; kStructured from the data
  // kStructured: upper edge of the fitted band in rad/s; 0 = from the data.
  double fit_band_max_rad_s = 0.0;
  // kStructured: most tail rounds after the first fit.
  int max_tail_rounds = 6;
  // kStructured: refine the fitted plant by output error on the logs (output_error.h);
  // open loop kept only when stable and better, closed loop (inside the loop with the
  // controller, when its Jacobian holds at most kClosedLoopRefinementEntries) only when the
  // loop is stable and it predicts held-out halves of the logs better (order_held_out.cc).
  bool refine_output_error = true;
  // The refinement's initial states (MATLAB ssest's InitialState): kAuto fits each log's
  // initial state only when Akaike's criterion says the extra values pay (a record that
  // starts from rest is fitted without them); kZero never (the user knows the records
  // start from rest, or wants the model that simulates best from zero state); kEstimate
  // always.
  enum class InitialStates { kAuto, kZero, kEstimate };
  InitialStates initial_states = InitialStates::kAuto;
  // identify_open_loop, kStructured, refined, plant_order 0: check the order the ladder
  // chose on data kept out of the fit (order_held_out.cc) and take another where the
  // held-out data prove it predicts better.
  bool check_order_held_out = true;
  // identify_open_loop: false fixes D = 0 (no lag-0 feedthrough).  The direct route on a
  // closed loop's logs (cli identify) needs it: a plant inside a sampled loop has none,
  // and u computed from the same output holds that output's noise at lag 0, so a free D
  // would fit the controller's inverse instead of the plant.
  bool open_loop_feedthrough = true;
  // Relative tolerance on |Ts_log - Ts_controller| / Ts_controller.
  double sample_period_tolerance = 1e-6;
  // Reports (idlib/core/progress.h), nullptr: none.  Task "identify", one step per
  // stage: kStructured "Markov horizon" (lags), "noise spectrum", "starting models",
  // "plant order" n (of at most n_max), "staged fit" i of n, "tail round" r, "order
  // check" n, "bands" (identify_open_loop also "output-error refinement", "order check on
  // held-out data"); kEra "Markov parameters", "realization", "unloop".
  Progress* progress = nullptr;

  // Throws InputError naming the option and the rule.
  void validate() const;
};

// What kStructured chose from the data, and why (one sentence each, for the report).
struct IdentifyChoices {
  Index num_lags = 0;
  std::string horizon_reason;
  Index fit_bins = 0;
  double fit_band_max_rad_s = 0;
  std::string band_reason;
  Index plant_horizon = 0;  // lags of p̂ realised for the starting models
  std::string start_reason;
  Index plant_order = 0;
  std::string order_reason;
  struct Candidate {
    Index order = 0;
    double cost = 0, dof = 0;  // whitened cost at the first stage and its degrees of freedom
    bool stable = false;
    bool screened = false;     // left after the screening iterations: far above the noise floor
  };
  std::vector<Candidate> order_candidates;
  struct Stage {
    Index lags = 0, bins = 0;
    int iterations = 0;
    double cost = 0;
  };
  std::vector<Stage> stages;
  struct TailRound {
    double cost = 0;
    double change = 0;  // max over the fit band of |ΔP| / |P| (2-norms) against the round before
  };
  std::vector<TailRound> tail_rounds;
  std::string tail_reason;
  std::string bands_reason;  // where the covariance of the bands comes from
  std::string feedthrough_reason;  // identify_open_loop only: how D was chosen
  std::string excitation_reason;   // white (R₀ at every bin) or coloured (its spectrum per bin), and why
  std::string refinement_reason;   // identify_open_loop: the output-error refinement, and whether it was kept
  // identify_open_loop with refine_output_error: the run whose result was kept (or, when
  // neither was, the run from rest).  `ran` false when it was switched off.  When
  // `kept`, the plant and the bands are this refinement's, not the structured fit's
  // (IdentifyResult::fit keeps the structured fit's cost, residuals and parameters).
  struct Refinement {
    bool ran = false, kept = false;
    bool initial_states_fitted = false;
    double start_cost = 0, cost = 0;  // V at the structured fit and at the result
    int iterations = 0;
    Index parameters = 0, residuals = 0, replicates = 0;
    std::string form = "full";  // OutputErrorResult::form
    Index poles_on_bound = 0;   // OutputErrorResult::poles_on_bound
  } refinement;
  // identify_open_loop: the order checked on data kept out of the fit.  Two folds: the
  // whole procedure (ladder at the given order, refinement) fitted on the first half of
  // every record and the second half predicted (its initial state fitted, compare's
  // 'e'), then the halves swapped.  `ran` false with the reason when it was not run.
  struct HeldOutOrder {
    bool ran = false;
    std::string reason;
    Index ladder_order = 0;  // the order the ladder (against the noise floor) chose
    Index chosen_order = 0;  // the order kept
    struct Row {
      Index order = 0;
      bool ok = false;          // fitted on both halves and stable on the held-out ones
      std::string failure;      // why not, when !ok
      double cost = 0;          // Σ over held-out samples of Σ_i (e_i / rms y_i)²
      double fit_percent = 0;   // held-out simulation fit, mean over outputs
    };
    std::vector<Row> rows;
  } held_out;
};

struct IdentifyResult {
  IdentifyMethod method = IdentifyMethod::kStructured;
  Index num_lags = 0;
  MarkovResult markov;       // of the logs as given (kStructured: before the tail rounds)
  StateSpace closed_loop;    // v → q: kEra the ERA model; kStructured G(P) with the controller
  StateSpace plant;          // u → q
  // kEra only:
  EraResult era;
  UnloopResult unloop;
  // kEra with a controller: the plant judged by the loop it makes with the controller that
  // ran — MATLAB compare's simulation fit on the logs (from zero state) of that loop and
  // of the ERA closed loop it came from, per output (equal when unloop is exact), and the
  // sentence the summary prints.  Empty in open loop.
  Eigen::VectorXd reclosed_fit_percent, era_fit_percent;
  std::string reclosed_reason;
  // kStructured only:
  PlantFitResult fit;        // the final fit (covariance for bands: plant_response_variance)
  IdentifyChoices choices;
  std::vector<std::string> warnings;  // from every step, in order
  // identify_open_loop, kStructured: p × m variance of D's entries (0 where D = 0), to
  // add to plant_response_variance's (the lag-0 estimate's error, independent of the
  // fit's to first order).  Empty otherwise.
  Eigen::MatrixXd feedthrough_variance;
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
// @throws NumericalError  kEra: no model order stands above the noise floor, or the
//                     realised closed loop is unstable.  kStructured: no candidate
//                     plant closes a stable loop (the logs do not fit any).
IdentifyResult identify_closed_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                    const StateSpace& controller, const IdentifyOptions& options);

// Open-loop logs (the excitation IS the plant input u; no controller): the same
// route, defaults, order selection and bands with C = 0, where G(P) = P.  The plant
// may have a direct feedthrough: structured takes D from the lag-0 Markov parameter
// where it stands above kFeedthroughSigmas standard errors (the fit itself uses lags
// 1..L); era keeps ERA's D.  Structured then refines the plant by output error on the
// logs themselves (output_error.h; options.refine_output_error), kept when stable and
// better, with its own sandwich covariance for the bands.  closed_loop is the plant.
// @throws as identify_closed_loop.
inline constexpr double kFeedthroughSigmas = 4.0;
IdentifyResult identify_open_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                  const IdentifyOptions& options);

// Reference excitation (issue 24: a positioning axis excited through its setpoint).
// With e = r − q the loop applies u = C(r − q) = C(−q) + C r: the references act as the
// plant-input excitation v = C r of identify_closed_loop's loop (u = u_c + v), exactly
// and for any controller.  Returns v = C (r − r°) from the controller's zero state: the
// experiment is taken as deviations about the setpoint r° at which the loop stood still
// before the log — r(0) when every reference holds it (within 1e-6 of its range) over
// the first max(kReferenceAtRestSamples, N/200) samples (a log that starts at rest before
// its moves), else each reference's mean (a zero-mean excitation about the operating
// point); the constant this leaves in v and q is removed with their means downstream.
// A controller state at the first sample that differs from this (a move in progress)
// leaves its decaying response in the output as an unmodelled disturbance.
// | controller: p inputs (e) -> m outputs | reference: N x p | result: N x m |
// @throws InputError  reference's columns differ from the controller's inputs; a
//                     non-finite reference.
inline constexpr Index kReferenceAtRestSamples = 10;
Eigen::MatrixXd reference_as_input_excitation(const StateSpace& controller,
                                              const Eigen::Ref<const Eigen::MatrixXd>& reference);

// The plant input a loop applied, for the direct route (identify a closed loop's plant
// from u and q as open-loop data, when the route through the loop's response finds no
// plant): u = v + C(e − e(0)) with e = r − q, filtered from the controller's zero state
// — e(0) taken as the loop's standing error (a loop at rest tracks its setpoint; filtering
// the raw error would add the controller's step response to it, a kick the loop never
// applied).  `added` is the excitation added to the controller's output (N x m, or empty:
// none), `reference` the setpoints (N x p, or empty: a constant setpoint).
// | controller: p inputs (e) -> m outputs | output: N x p | result: N x m |
// @throws InputError  shapes that differ from the controller's; non-finite values.
Eigen::MatrixXd applied_plant_input(const StateSpace& controller, const Eigen::Ref<const Eigen::MatrixXd>& added,
                                    const Eigen::Ref<const Eigen::MatrixXd>& reference,
                                    const Eigen::Ref<const Eigen::MatrixXd>& output);

// Where the data pin the plant down (issue 24: "say what the data cannot support"): the
// relative width of the 95 % band, r(ω) = kBandRadiusPerSigma √(Σ_ij var_ij) / ‖P̂‖_F,
// against `threshold` at each frequency.  In a closed loop the plant reaches the logs
// through the sensitivity, so where the loop gain is high (a PID's low frequencies,
// most of all on a levitated plant) r grows: the plant there is extrapolated by the
// model, not measured.
struct BandSupport {
  double threshold = 0.1;
  Index points = 0, supported = 0;  // frequencies given; those with r ≤ threshold
  double lowest_supported_rad_s = 0, highest_supported_rad_s = 0;  // 0 when none
  double worst_relative = 0, omega_at_worst_rad_s = 0;             // the largest r and where
};
// | response, variance: F of p × m | omega: F, rad/s |
// @throws InputError  counts or shapes that differ; threshold ≤ 0.
BandSupport band_support(const std::vector<Eigen::MatrixXcd>& response, const std::vector<Eigen::MatrixXd>& variance,
                         const Eigen::VectorXd& omega_rad_s, double threshold);

// Whether the logs prove a plant's instability.  A pole outside the stability boundary
// that grows at a rate a (ln|z|/Ts discrete, Re s continuous) changes the response at ω
// by about a/ω relative to the same pole on the boundary (an integrator); where the logs
// support the plant (BandSupport: its band within ±threshold) that change is below the
// band when a ≤ threshold · lowest_supported_rad_s, so those logs cannot tell the pole
// from an integrator and do not prove instability (`proven` false).  A stable plant, or no
// support: proven as the poles say.
struct InstabilityEvidence {
  Index unstable_poles = 0;         // poles with |z| > 1 (Re s > 0)
  double growth_rate_rad_s = 0.0;   // the fastest of them
  double largest_magnitude = 0.0;   // max |z| (discrete) or max Re s (continuous)
  bool proven = false;              // the logs show the instability (false for a stable plant)
};
InstabilityEvidence instability_evidence(const StateSpace& plant, const BandSupport* support);

// The number of lags for records of `shortest_record` samples when the horizon is
// given (num_lags or markov_horizon_s > 0; kEra also with both 0: 2 s).
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
