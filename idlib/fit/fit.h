// lpvid — fitting the free parameters of a physical model (idlib/physical)
// jointly to frequency responses measured at several beam positions x_b
// (docs/math.md, "Physical fit").
//
// Error.  For data set d at x_b(d), used frequency ω_k and channel (i, j):
//   r = w_ij(ω_k) · (T_ij(θ; x_b, ω_k) − T̂_ij(ω_k)) / s_ij(ω_k),
// complex, split into real and imaginary residuals, where
//   T = P (target plant), G = P (I + C P)⁻¹ (closed loop v → q) or
//       S = (I + C P)⁻¹ (input sensitivity v → u), C the known controller at
//       the same λ (jω, or e^{jωTs} for a discrete controller);
//   P = the model's ZOH response P(e^{jωTs}) when sample_period_s > 0, else P(jω);
//   s_ij(ω) = sqrt(|T̂_ii(ω)| |T̂_jj(ω)|), floored at scale_floor × its largest
//       value over the data set: a relative error per frequency, so that every
//       decade and every channel weighs comparably, and off-diagonal channels
//       are measured against the size of the diagonal ones (they may be ~0);
//   w_ij(ω) = sqrt(γ² / max(1 − γ², 1e-4)) with γ² the coherence when the data
//       carry one (the FRF's variance is ∝ (1 − γ²)/γ²), else 1; flagged
//       frequencies are left out.
// Cost = Σ r².
//
// Parameters: the model's free parameters; one with lower bound > 0 is fitted
// as its logarithm (scale-free steps, positivity kept), the others as they are.
//
// Method.  (1) Global start (optional): NLopt LN_BOBYQA from the start and from
// global_starts − 1 seeded random points in the search box (the bounds
// intersected with [start / global_search_factor, start · global_search_factor]
// for log parameters, start ± (upper − lower) / (2 · global_search_factor) for
// the others), each on a subsample of global_subsample log-spaced used
// frequencies per data set; the best end point wins.  (2) Ceres
// Levenberg–Marquardt with bounds on all data, exact Jacobian (forward-mode
// ceres::Jet through the model matrices and the ZOH exponential, then the
// resolvent identities dP = Y dA X + Y dB + dC X + dD per frequency).
//
// Uncertainty: J the Jacobian of the residuals in natural units at the
// estimate, σ² = cost / (N − p), covariance = σ² (JᵀJ)⁺, standard errors its
// diagonal's roots, correlation its normalisation.  Identifiability: the
// singular values of J with columns scaled by the parameter size (|θ|, or a
// hundredth of the bound range for θ = 0) and then normalised; a singular value
// below singular_value_flag × the largest names the parameter combination (its
// right singular vector); pairs with |corr| > correlation_flag are flagged.
// AIC = N ln(cost/N) + 2p, BIC = N ln(cost/N) + p ln N, N the real residual count.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

enum class FitTarget { kPlant, kClosedLoopOutput, kInputSensitivity };

// "plant", "G", "S".
std::string target_name(FitTarget target);
// @throws InputError  text is none of "plant", "G", "S".
FitTarget parse_target(const std::string& text);

// One measured response at one beam position.
struct FitDataset {
  double beam_position_m = 0.0;
  FrequencyResponse response;  // 3×3 (inputs T_psi T_theta F_z or v, outputs psi theta z or u)
  std::string label;           // e.g. the file name, for messages and reports
};

struct FitOptions {
  FitTarget target = FitTarget::kPlant;
  // The known controller (e = −q → u_c), needed for G and S.
  std::optional<StateSpace> controller;
  // > 0: the model's ZOH response at this period (data identified from sampled
  // data); 0: the continuous response.
  double sample_period_s = 0.0;

  bool global_start = true;
  int global_starts = 8;              // >= 1 (the start itself is the first)
  double global_search_factor = 4.0;  // > 1
  int global_subsample = 30;          // frequencies per data set, >= 2
  int global_max_evaluations = 300;   // per start, >= 10
  unsigned seed = 1;

  int max_iterations = 200;              // Ceres LM, >= 1
  double function_tolerance = 1e-12;     // Ceres: relative cost change to stop
  double scale_floor = 1e-6;             // see s_ij above; in (0, 1)
  double correlation_flag = 0.95;        // in (0, 1]
  double singular_value_flag = 1e-3;     // in (0, 1)

  // @throws InputError naming the first field out of range.
  void validate() const;
};

struct ParameterEstimate {
  std::string name, unit;
  double start = 0.0, estimate = 0.0;
  double std_error = 0.0;  // NaN when the data cannot determine it
  bool at_bound = false;   // estimate at (within 1e-9 relative of) a bound
  std::vector<std::string> flags;  // e.g. "corr -0.999 with k_torque_low_Nm_per_rad"
};

// Relative rms error (same scaling as the cost, without coherence weights):
// sqrt(mean_k |T_ij − T̂_ij|² / s_ij²) over the used frequencies.
struct ChannelFit {
  Index output = 0, input = 0;
  double relative_rms_error = 0.0;                 // pooled over the data sets
  std::vector<double> per_dataset;                 // one per data set, in order
};

struct FitResult {
  PhysicalModel model;                       // start with the free values replaced by the estimates
  std::vector<ParameterEstimate> parameters;  // the free ones, in model order
  Eigen::MatrixXd covariance;                 // p × p, natural units
  Eigen::MatrixXd correlation;                // p × p
  Eigen::VectorXd singular_values;            // scaled, normalised Jacobian; relative to the largest
  std::vector<std::string> identifiability;   // one line per problem found (empty: none)
  std::vector<ChannelFit> channels;           // 9 entries, row-major (output, input)
  double cost_start = 0.0, cost_global = 0.0, cost_final = 0.0;  // Σ r²
  Index residual_count = 0;                   // N (real residuals)
  double sigma2 = 0.0, aic = 0.0, bic = 0.0;
  int iterations = 0;
  double seconds = 0.0;
  Report report;
};

// Fits start's free parameters to data.
// @throws InputError  options invalid; start invalid; no free parameter; more
//   than 32 free parameters; data empty, not 3×3, frequencies not > 0 and
//   finite, x_b outside the stroke; G or S without a 3×3 controller; fewer
//   residuals than free parameters after removing flagged frequencies.
// @throws NumericalError  the model cannot be evaluated at the start (M not
//   positive definite) or the solver found no usable point.
FitResult fit_physical_model(const PhysicalModel& start, const std::vector<FitDataset>& data,
                             const FitOptions& options);

// Response of model (target as options.target) with delta-method bands:
//   σ_|T|ij = sqrt(g ᵀ Σ g),  g_k = Re(conj(T_ij) ∂T_ij/∂θ_k) / |T_ij|,
//   σ_∠T ij = sqrt(h ᵀ Σ h),  h_k = Im(conj(T_ij) ∂T_ij/∂θ_k) / |T_ij|²,
// Σ = covariance over the model's free parameters (in model order).
struct ResponseBand {
  FrequencyResponse response;                        // nominal
  std::vector<Eigen::MatrixXd> magnitude_sigma;      // per frequency, 3×3, units of |T|
  std::vector<Eigen::MatrixXd> phase_sigma_rad;      // per frequency, 3×3
};
// @throws InputError  covariance not p × p; as fit_physical_model for x_b and options.
ResponseBand response_band(const PhysicalModel& model, const Eigen::MatrixXd& covariance, double beam_position_m,
                           const Eigen::VectorXd& omega_rad_s, const FitOptions& options);

// The target response of model (no bands).
FrequencyResponse target_response(const PhysicalModel& model, double beam_position_m,
                                  const Eigen::VectorXd& omega_rad_s, const FitOptions& options);

}  // namespace lpvid
