// lpvid — fitting the free parameters of a physical model (idlib/physical, any
// base) jointly to frequency responses measured at several values of the base's
// scheduling variable (the platform: beam positions x_b) (docs/math.md, "Physical
// fit").
//
// Noise model.  Every measured entry Ĥ_ij(ω_k) gets a standard deviation σ per real
// part, from the data themselves (FitOptions::noise says how):
//   1. the data's variance (FrequencyResponse::variance, E|Ĥ − H|²):  σ² = var/2;
//   2. else coherence γ² with n_d independent averages (the data's `averages`, or
//      FitOptions::noise.averages when the data do not state it) — the random
//      error of an H1 estimate (Bendat & Piersol, eqs 9.52/9.90):
//          σ² = |Ĥ|² (1 − γ²) / (2 n_d γ²);
//   3. else a relative noise level given by the user: E|Ĥ − H|² = (level · s_ij)²;
//   4. else unknown: σ = s_ij/√2 for the weights only (noise_known = false).
// σ is never taken below sigma_floor · s_ij (round-off of exported numbers).
// s_ij(ω) = max(sqrt(|Ĥ_ii(ω)| |Ĥ_jj(ω)|), |Ĥ_ij(ω)|) for square responses (an entry
// larger than its diagonals is measured against itself), else the largest |Ĥ| of row
// i, floored at scale_floor × the largest diagonal scale over the data set
// (response_scales, idlib/core/types.h): the scale that makes channels of different
// units and sizes comparable.  Then s_ij(ω) is never below kLocalLevelRatio (0.1) × the
// largest s_ij within ±kLocalLevelDecades (0.1 decade) of ω: the bottom of a narrow
// notch (a structure's antiresonance, 20 dB and more below its surroundings) is not
// the size of its channel there.  Measured on the F-16 (real-data test): one
// antiresonance line of acc3, |H| at twice its noise, held 5246/267 of the squared
// figure of a model with one of the structure's modes (the others, which cancel there,
// still missing), so that adding the torsion mode (ΔBIC −1608) raised the figure from
// 92 % to 280 %; measured against its surroundings the same mode lowers it from 79 %
// to 63 %.  A smooth response (a rigid body's 1/ω², 10 dB over 0.1 decade) never
// meets the floor.  With measured noise (cases 1 and 2) s_ij is also never below
// kNoiseScaleRatio · √2σ_ij: where an entry sinks into its own noise its relative
// error measures the noise.
inline constexpr double kLocalLevelRatio = 0.1;
// FitOptions::model_error_weighting: reweigh when the error is beyond this many noise
// floors (the figure's "within the noise"), at most this many rounds, until the model
// error moves by less than this fraction of itself.
inline constexpr double kModelErrorRatio = 1.5;
inline constexpr int kModelErrorRounds = 4;
inline constexpr double kModelErrorSettled = 0.1;
inline constexpr double kLocalLevelDecades = 0.1;
inline constexpr double kNoiseScaleRatio = 3.0;
//
// Error.  For data set d, used frequency ω_k and channel (i, j):
//   r = (T_ij(θ; s_d, ω_k) − Ĥ_ij(ω_k)) / σ_ij(ω_k),
// complex, split into real and imaginary residuals, where T = P (target plant),
// G = P (I + C P)⁻¹ (closed loop v → q) or S = (I + C P)⁻¹ (input sensitivity
// v → u), C the known controller at the same λ (jω, or e^{jωTs}), or its measured
// value at the data's line ω_k (FitOptions::measured_controller); P the model's
// exactly sampled response when sample_period_s > 0 (fractional delays included,
// idlib/physical/evaluate.h), else P(jω).  Cost = Σ r² (a χ² when the noise is known).
// Frequencies flagged in the data or outside [band_min, band_max] are left out.
//
// The error figure (one number per model; fit, diagnose and history all use it):
//   error = sqrt(mean_ij e_ij²),  e_ij = sqrt(mean_k |T_ij − Ĥ_ij|² / s_ij²)
// over every used frequency of every data set, and the NOISE FLOOR the same figure
// for the noise alone, floor = sqrt(mean_ij mean_k 2σ_ij²/s_ij²): what an exact model
// would score.  A model within about 1.5× the floor fits within the noise.
//
// Parameters: the model's free parameters; one with lower bound > 0 is fitted as
// its logarithm (scale-free steps, positivity kept), the others as they are.
//
// Method.  (1) Global start (optional): NLopt LN_BOBYQA from the start, from each
// of `extra_starts` (e.g. a resonance frequency read off the failing bands) and
// from global_starts − 1 seeded random points in the search box (the bounds
// intersected with [start / factor, start · factor] for log parameters, start ±
// (upper − lower)/(2 · factor) for the others), each on a subsample of
// global_subsample log-spaced frequencies per data set; the best end point wins.
// (2) Ceres Levenberg–Marquardt with bounds on all data, exact Jacobian (forward-mode
// ceres::Jet through the model matrices, the ZOH exponentials and the fractional
// delay, then the resolvent identities per frequency).
//
// Uncertainty: J the Jacobian of the residuals in natural units at the estimate,
// σ² = cost/(N − p), covariance = σ² (JᵀJ)⁺ (so that a misjudged noise level scales
// out), standard errors its diagonal's roots.  Identifiability: the singular values
// of J with columns scaled by the parameter size, normalised; a singular value below
// singular_value_flag × the largest names the combination the data cannot separate;
// pairs with |corr| > correlation_flag are flagged; every estimate on a bound is
// flagged ("at bound": the data want it beyond its physical range).
// AIC = N ln(cost/N) + 2p, BIC = N ln(cost/N) + p ln N, N the real residual count.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/progress.h"
#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

enum class FitTarget { kPlant, kClosedLoopOutput, kInputSensitivity };

// "plant", "G", "S".
std::string target_name(FitTarget target);
// @throws InputError  text is none of "plant", "G", "S".
FitTarget parse_target(const std::string& text);

// One measured response at one value of the scheduling variable.
struct FitDataset {
  double beam_position_m = 0.0;  // the scheduling value (x_b for the platform)
  FrequencyResponse response;    // n_out × n_in of the base (or of S: n_in × n_in)
  std::string label;             // e.g. the file name, for messages and reports
};

// How the noise of the data is known (header comment, "Noise model").
struct NoiseOptions {
  double averages = 0;     // n_d behind coherence when the data do not state it; 0 = none given
  double noise_level = 0;  // relative rms error of an entry (E|Ĥ−H|² = (level s_ij)²) for data
                           // with neither variance nor coherence; 0 = none given
  double sigma_floor = 1e-5;  // σ >= sigma_floor · s_ij; in [0, 1)
  // A relative model error λ the WEIGHTS allow for beside the noise: each entry is
  // weighed by 1/sqrt(σ² + (λ s_ij)²/2) (per real part).  0: the data's noise alone
  // (maximum likelihood when the model can be exact).  The noise floor and the error
  // figure do not change with it.  FitOptions::model_error_weighting sets it.
  double model_error = 0.0;
  // @throws InputError naming the field.
  void validate() const;
};

struct FitOptions {
  FitTarget target = FitTarget::kPlant;
  // The known controller (e = −q → u_c), needed for G and S: a model ...
  std::optional<StateSpace> controller;
  // ... or its MEASURED response (FRD, C(ω_k) = response[k]: as many inputs as the
  // base has outputs, as many outputs as it has inputs) on exactly every data set's
  // frequency lines (check_controller_lines).  At most one of the two.
  std::optional<FrequencyResponse> measured_controller;
  // > 0: the model's sampled response at this period (data identified from
  // sampled data); 0: the continuous response.
  double sample_period_s = 0.0;
  // Frequencies used (rad/s); the rest of the data is left out.
  double band_min_rad_s = 0.0, band_max_rad_s = std::numeric_limits<double>::infinity();
  NoiseOptions noise;

  bool global_start = true;
  int global_starts = 8;              // >= 1 (the start itself is the first)
  double global_search_factor = 4.0;  // > 1
  int global_subsample = 30;          // frequencies per data set, >= 2
  int global_max_evaluations = 300;   // per start, >= 10
  unsigned seed = 1;
  // Further starting points of the global start: each a list of (parameter name,
  // value) overriding the start model (unknown names are an error).
  std::vector<std::vector<std::pair<std::string, double>>> extra_starts;
  // The free parameters the global start searches over (the others stay at the
  // start during it; Levenberg–Marquardt then moves all of them).  Empty: all.
  // diagnose searches an added effect's own parameters this way: the rest was fitted.
  std::vector<std::string> global_parameters;

  // Rounds from the estimate (the estimate as the new start: global start + LM
  // again), at most this many more, while each lowers the cost by more than a
  // relative 1e-6; the first round that does not, or fails numerically, ends them.
  // A cost that ripples (an undamped resonance moving between FRF lines) can stop
  // one round in a ripple (docs/math.md, "Restarts").  >= 0; `lpvid fit` uses 2.
  int restarts = 0;
  // When the model fails the data beyond kModelErrorRatio × the noise floor (a model
  // error, not noise, dominates the residual), weigh the data by noise + model error
  // (NoiseOptions::model_error = λ, λ² = error² − floor², the model error's own rms)
  // and fit again from the estimate, until λ settles (at most kModelErrorRounds).
  // Why: weighted by the noise alone, a model that cannot follow the data spends its
  // freedom on the lines measured most precisely (the F-16's: a noise-weighted fit of
  // eight modes scores 24.6 % on the error figure where the figure's own weighting
  // reaches 10.5 %, docs/math.md "Weights when the model fails"); with the model
  // error in the weights the fit minimises what the figure measures, so the two
  // agree on which model is better.  The result keeps the better figure of the
  // noise-weighted and the reweighted fits (FitResult::model_error_weight says which).
  bool model_error_weighting = false;
  int max_iterations = 200;              // Ceres LM, >= 1
  double function_tolerance = 1e-12;     // Ceres: relative cost change to stop
  double scale_floor = kDefaultScaleFloor;  // see s_ij above; in (0, 1)
  double correlation_flag = 0.95;        // in (0, 1]
  double singular_value_flag = 1e-3;     // in (0, 1)
  // Reports (idlib/core/progress.h), nullptr: none.  Task "fit" ("fit round R" with
  // restarts), steps "global start i of n" (bar: the starts done) and
  // "Levenberg-Marquardt iteration i" (detail: the cost, Σ r²).
  Progress* progress = nullptr;

  // @throws InputError naming the first field out of range.
  void validate() const;
};

struct ParameterEstimate {
  std::string name, unit;
  double start = 0.0, estimate = 0.0;
  double std_error = 0.0;  // from the pseudo-inverse: not infinite along a direction the data cannot fix (the flags say so)
  double lower = 0.0, upper = 0.0;
  bool at_bound = false;   // estimate at (within 1e-6 of the span of) a bound
  std::vector<std::string> flags;  // e.g. "at upper bound 2", "corr -0.999 with ...", "+4.2 sigma from its prior"
  double prior_mean = 0.0, prior_sigma = 0.0;  // the parameter's prior (sigma 0: none)
  bool prior_contradicted = false;  // further than kPriorPullFlag prior sigmas from its prior (flagged)
};

// An estimate further than this many prior standard deviations from its prior's
// mean is flagged (and warned about): beyond 3σ a Gaussian prior is contradicted at
// the 0.3 % level.
inline constexpr double kPriorPullFlag = 3.0;

// Relative rms error per channel (same scaling as the error figure).
struct ChannelFit {
  Index output = 0, input = 0;
  double relative_rms_error = 0.0;   // pooled over the data sets
  double noise_floor = 0.0;          // the same for the noise (NaN when unknown)
  std::vector<double> per_dataset;   // one per data set, in order
};

struct FitResult {
  PhysicalModel model;                        // start with the free values replaced by the estimates
  std::vector<ParameterEstimate> parameters;  // the free ones, in model order
  Eigen::MatrixXd covariance;                 // p × p, natural units
  Eigen::MatrixXd correlation;                // p × p
  Eigen::VectorXd singular_values;            // scaled, normalised Jacobian; relative to the largest
  std::vector<std::string> identifiability;   // one line per problem found (empty: none)
  std::vector<ChannelFit> channels;           // n_out·n_in entries, row-major (output, input)
  std::vector<std::string> output_names, input_names;  // the data's channel names (else the base's)
  double error = 0.0;        // the error figure (header comment)
  double noise_floor = 0.0;  // its value for the noise alone; NaN when the noise is unknown
  bool noise_known = false;
  std::string noise_source;  // "variance", "coherence (16 averages)", "noise level 1 %" or "unknown"
  double cost_start = 0.0, cost_global = 0.0, cost_final = 0.0;  // Σ r²
  Index residual_count = 0;                   // N (real residuals)
  Index frequencies_used = 0;                 // over all data sets
  double sigma2 = 0.0, aic = 0.0, bic = 0.0;  // the data's alone
  // Σ ((θ − mean) / sigma)² over the free parameters with a prior (0 without): the
  // priors' part of cost_final, −2 log prior up to a constant.  diagnose compares
  // models by bic + prior_cost (the posterior's), so that a prior can break a tie.
  double prior_cost = 0.0;
  // The free parameters further than kPriorPullFlag prior sigmas from their prior.
  Index priors_contradicted = 0;
  int iterations = 0;          // Levenberg–Marquardt's, summed over the rounds kept
  int restarts = 0;            // rounds after the first that lowered the cost (FitOptions::restarts)
  double cost_first_round = 0.0;  // cost_final of the first round (= cost_final without restarts)
  double seconds = 0.0;        // the whole call, every round
  // FitOptions::model_error_weighting: the model error λ the kept fit was weighted
  // with (0: the noise alone, the data's weights), the noise-weighted fit's error
  // figure (NaN when no reweighting was tried), and the reweighting rounds run.
  double model_error_weight = 0.0;
  double noise_weighted_error = std::numeric_limits<double>::quiet_NaN();
  int reweightings = 0;
  Report report;
};

// Fits start's free parameters to data.
// @throws InputError  options invalid; start invalid; no free parameter; more than
//   48 free parameters; data empty, of the wrong shape, frequencies not > 0 and
//   finite, a scheduling value outside the base's range; G or S without a
//   controller of the right shape; no frequency left in the band; fewer residuals
//   than free parameters.
// @throws NumericalError  the model cannot be evaluated at the start (mass matrix not
//   positive definite) or the solver found no usable point.
FitResult fit_physical_model(const PhysicalModel& start, const std::vector<FitDataset>& data,
                             const FitOptions& options);

// The error figure, its noise floor and per-channel errors of `model` on data,
// without fitting (the same definitions as FitResult).
struct ModelScore {
  double error = 0.0, noise_floor = 0.0;
  bool noise_known = false;
  std::vector<ChannelFit> channels;
  double cost = 0.0;
  Index residual_count = 0;
};
// @throws as fit_physical_model (except the free-parameter rules).
ModelScore score_model(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options);

// The noise of one data set as the fit sees it: σ per real part (3 cases of the
// header), per used frequency; unused frequencies get +inf.  `source` receives the
// case ("variance", ...); `scales` the s_ij the error figure measures each entry
// against (the header's, floored at the measured noise).  @throws InputError as
// fit_physical_model for one set.
std::vector<Eigen::MatrixXd> data_sigma(const FrequencyResponse& data, const NoiseOptions& noise,
                                        std::string* source = nullptr, bool* known = nullptr,
                                        std::vector<Eigen::MatrixXd>* scales = nullptr);

// Response of model (target as options.target) with delta-method bands:
//   σ_|T|ij = sqrt(g ᵀ Σ g),  g_k = Re(conj(T_ij) ∂T_ij/∂θ_k) / |T_ij|,
//   σ_∠T ij = sqrt(h ᵀ Σ h),  h_k = Im(conj(T_ij) ∂T_ij/∂θ_k) / |T_ij|²,
// Σ = covariance over the model's free parameters (in model order).
struct ResponseBand {
  FrequencyResponse response;                        // nominal
  std::vector<Eigen::MatrixXd> magnitude_sigma;      // per frequency, units of |T|
  std::vector<Eigen::MatrixXd> phase_sigma_rad;      // per frequency
};
// @throws InputError  covariance not p × p; as fit_physical_model for the schedule and options.
ResponseBand response_band(const PhysicalModel& model, const Eigen::MatrixXd& covariance, double beam_position_m,
                           const Eigen::VectorXd& omega_rad_s, const FitOptions& options);

// The target response of model (no bands).  With a measured controller every
// frequency of omega_rad_s must be one of its lines (response_band too).
FrequencyResponse target_response(const PhysicalModel& model, double beam_position_m,
                                  const Eigen::VectorXd& omega_rad_s, const FitOptions& options);

// Relative tolerance |ω_C − ω_data| / ω_data for a measured controller's lines to be
// the data's (the value of idlib/closedloop's kMeasuredControllerFrequencyRelTolerance:
// files written by lpvid and read back agree to ~1e-15).
inline constexpr double kControllerLineRelTolerance = 1e-9;

// A measured controller on the data's lines: as many frequencies as `omega`, each
// equal to relative kControllerLineRelTolerance.
// @throws InputError  naming controller_name, data_name and the first line that
//   differs (or is in one only), and what to do (measure the controller at the data's lines).
void check_controller_lines(const FrequencyResponse& controller, const Eigen::VectorXd& omega,
                            const std::string& controller_name, const std::string& data_name);

// C at each frequency of omega: options.controller evaluated there, or the measured
// controller's value at the line equal to it (relative kControllerLineRelTolerance).
// @throws InputError  no controller; a frequency that is not a line of the measured controller.
std::vector<Eigen::MatrixXcd> controller_response_at(const FitOptions& options, const Eigen::VectorXd& omega_rad_s);

}  // namespace lpvid
