// lpvid — the time-domain route of a mechanical base (idlib/physical/mechanical):
// the FORCE-ERROR (inverse-dynamics) fit to a log, and its model-error loop
// (docs/math.md §9b).
//
// A positioning axis, a wafer stage or a gantry logged in closed loop: the log holds
// the base's inputs w (the commanded or measured motor currents or forces) and its
// position outputs y = C_q q.  Every DOF measured (C_q of full column rank, fixed),
// the equation of motion is checked sample by sample:
//
//   r(t) = B_w w(t) − (M q''(t) + D q'(t) + K q(t) + F_c ⊙ sign q'(t) + F_0),
//
// with every term smoothed by one kernel k (a Hann window of W samples): q'' and q'
// are k moved onto central differences (Δ²q/Ts² is the acceleration averaged under a
// ±Ts triangle, as (w(k−1) + w(k))/2 is a held input's force), so that both sides of
// the balance see the same filter.  Every entry of M, D, K, B_w is a linear
// expression of the parameters and the time-only effects (coulomb_friction F_c, force_offset F_0) enter linearly: the
// fit is a LINEAR least-squares problem with bounds (an active set over the normal
// equations, O(N p²) for p free parameters), its optimum global and reproduced
// exactly by the user's refit of diagnose's promise.  No controller model is needed:
// w is logged, so closed loop or open loop is the same computation.
//
// stribeck_friction (F_s, v_s per DOF) adds F_s exp(−(q'/v_s)²) sign q': a friction that
// rises towards standstill above the Coulomb level.  input_saturation (w_max per input)
// replaces w by clip(w, ±w_max): a drive that applies at most its limit while the log
// holds the controller's unlimited command.  position_ripple (a, b, p per DOF) adds
// a sin(2π q/p) + b cos(2π q/p): cogging, a screw's lead error.
//
// sign q' is q'/v_eps clipped to [−1, 1], q' the unsmoothed central difference (the
// smoothed velocity crosses zero late at a reversal), v_eps = 3× its noise: standstill
// does not flip the friction with the noise.  Samples within the kernel's reach of a
// standstill (|q'| < v_eps on some DOF) are left out: at rest the friction holds any
// force up to F_c, which no sign law predicts.
//
// The error figure, per DOF i: 100 rms(r_i)/rms((B_w w)_i) %, the relative error of
// the motor force (the figure published for positioning axes), and one figure over
// the DOFs, sqrt(mean_i e_i²).  The NOISE FLOOR the same figure for the noise alone:
// the position noise σ_q (what a local cubic over the window does not follow, q − h₀∗q,
// its median absolute deviation × 1.4826 / sqrt(1 − h₀(0))) through the kernels' noise
// gains into M q'' + D q' + K q, plus the
// part of w's high-frequency content that the position noise does not explain (a
// current sensor's own noise; the controller's reaction to the position noise is
// force the plant felt, not noise).  A model within 1.5× the floor fits within the
// noise.  The residual is correlated over the window: the effective number of
// samples is n_eff = n Σk², used in BIC and in the standard errors (docs/math.md §9b).
//
// What the data cannot separate is said: a velocity that keeps one sign makes
// Coulomb friction and an offset the same force (diagnose says so and what to
// record), parameters whose regressors are collinear are reported by name, and a
// balance whose every term is free (every mass and the force constant: a uniform
// scaling) is refused.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

// Savitzky–Golay kernels of a local cubic over `window` samples (odd, >= 5): value,
// first and second derivative at the centre per sample (divide by Ts, Ts²).  The route
// uses h₀ for the noise estimates.
// Applied as y(k) = Σ_m h(m) x(k + m), m = −h..h.
struct SavitzkyGolay {
  Eigen::VectorXd h0, h1, h2;
  explicit SavitzkyGolay(Index window);
  Index half() const { return (h0.size() - 1) / 2; }
};

struct ForceErrorOptions {
  // The smoothing window in seconds (rounded to an odd number of samples, at least 5);
  // 0 = the default, 20 ms.
  double window_s = 0.0;
  // The input is a command held over each sample (zero-order hold, the default): the
  // force acting around sample k is (w(k−1) + w(k))/2, the hold's half-sample delay.
  // false: the log's w is a measurement of the force's own signal (a current sensor
  // sampled with the position, `--measured-input`), used as it is.
  bool held_input = true;
};
inline constexpr double kForceErrorDefaultWindowS = 0.02;

// The log made ready: samples of [first, N − first) of the original log (2 half-windows
// lost at each end), those near standstill left out, per DOF.
struct ForceErrorData {
  double sample_period_s = 0.0;
  Index window = 0, first = 0;
  double centre_weight = 0.0;            // Σ k² (k the smoothing kernel, Σ k = 1)
  Eigen::MatrixXd q, qd, qdd;            // n × n_dof (C_q⁺ y, smoothed; its derivatives, smoothed)
  Eigen::MatrixXd w;                     // n × n_in, smoothed
  Eigen::MatrixXd sign_v;                // n × n_dof, the smoothed sign of q'
  Eigen::VectorXd q_noise, v_eps;        // per DOF: the position noise σ_q, the velocity scale v_eps
  Eigen::VectorXd w_noise;               // per input: the noise of w not explained by the position noise
  double g0 = 0.0, g1 = 0.0, g2 = 0.0;   // noise gains sqrt(Σh²) of the kernels (per sample)
  // Samples left out near standstill (a DOF slower than v_eps within the kernel's reach):
  // at rest the friction holds any force up to F_c, which no sign law predicts.  The
  // rows above are the samples kept (not contiguous when standstill > 0).
  Index standstill = 0;
  Eigen::Matrix<Index, Eigen::Dynamic, 1> sample;  // each row's sample number in the log (0-based)
  // For terms built at fit time (stribeck_friction's, whose shape depends on a fitted
  // velocity scale): the unsmoothed central-difference velocity per DOF, row j the log's
  // sample kernel_reach + j, and the smoothing kernel k (half-width kernel_reach − 1).
  Eigen::MatrixXd v_raw;
  Eigen::VectorXd kernel;
  Index kernel_reach = 0;
  // For input_saturation: the log's inputs as logged (N × n_in, row k the log's sample
  // k), and whether the route holds them (ForceErrorOptions::held_input).
  Eigen::MatrixXd w_log;
  bool held_input = true;
  // For position_ripple: the DOFs' positions C_q⁺ y as logged (N × n_dof, row k the log's
  // sample k).
  Eigen::MatrixXd q_raw;
  Index n() const { return q.rows(); }
};

// @throws InputError  the model's base is not mechanical; an output measures a velocity
//   or an acceleration; C_q depends on a free parameter or has rank < n_dof (a DOF
//   not measured); the log's shapes; a sample period not > 0; fewer than 4 windows of
//   samples; a value not finite.
ForceErrorData prepare_force_error(const PhysicalModel& model, const Eigen::MatrixXd& inputs,
                                   const Eigen::MatrixXd& outputs, double sample_period_s,
                                   const ForceErrorOptions& options = {});

struct ForceErrorParameter {
  std::string name, unit;
  double value = 0.0, std_error = 0.0;
  bool at_bound = false;
};

struct ForceErrorFit {
  PhysicalModel model;                          // the start with the estimates
  std::vector<ForceErrorParameter> parameters;  // the free ones, in model order
  Eigen::VectorXd error_per_dof, floor_per_dof; // % of rms((B_w w)_i)
  double error = 0.0, floor = 0.0;              // sqrt(mean over DOFs of the squares), %
  double rss = 0.0;                             // Σ over DOFs of rms-normalised squared residuals
  double n_eff = 0.0;                           // effective samples (all DOFs)
  double bic = 0.0;
  Eigen::MatrixXd residual;                     // n × n_dof, in force units
  Eigen::MatrixXd applied;                      // n × n_dof, the actuators' force B_w w (smoothed)
  // Parameters the log cannot separate, one sentence each ("m_kg and k_f_N_per_A
  // move together: ..."); empty when all are determined.
  std::vector<std::string> unidentifiable;
};

// Fits the model's free parameters (base and time-only effects; priors honoured).
// Linear in every parameter but the shape parameters, stribeck_friction's velocity
// scales v_s, input_saturation's limits w_max and position_ripple's periods p: each free
// one is found by a profile search (the linear fit at each trial value; a log-spaced
// grid — for p the periodogram of the residual without the ripple over position, its
// three highest peaks — then golden section; in turn, twice) over its range — v_s from
// 2 v_eps to the median moving speed, w_max from the median |w| to the largest, p from
// one kernel length at the median speed to a third of the travel — its standard error from the profile's
// curvature; a value on the range's edge is reported on its bound (a limit at the
// largest command: the log shows no saturation) (docs/math.md §9b).
// @throws InputError  the model has a block effect (delay, lag, gain, mode: those
//   are the frequency route's; remove them) or no free parameter.
ForceErrorFit fit_force_error(const PhysicalModel& start, const ForceErrorData& data);

// The force error of the model as given, nothing estimated: a model fitted on one log
// checked on another (`compare --log`).  parameters: the model's free ones at their
// values, std_error NaN; rss, n_eff and bic as a fit's (no parameter counted).
// @throws InputError  as fit_force_error for a block effect.
ForceErrorFit evaluate_force_error(const PhysicalModel& model, const ForceErrorData& data);

struct ForceErrorCandidate {
  std::vector<std::string> effects;  // one, or a pair
  ForceErrorFit fit;
  double delta_bic = 0.0;            // baseline − candidate (positive: better)
  double excess_share = 0.0;         // of the baseline's excess error² over the floor²
  bool significant = false;
  bool explained = false;            // within 1.5× the floor
  std::string verdict;
};

struct ForceErrorDiagnosis {
  ForceErrorFit baseline;
  std::vector<ForceErrorCandidate> candidates;  // singles, then pairs; by BIC within each
  Index named = -1;                  // the candidate diagnose names, or -1
  bool baseline_explained = false;   // the model is within 1.5× the floor already
  std::vector<std::string> signatures;   // what the baseline's residual shows (one line each)
  std::vector<std::string> cannot_separate;  // what this log cannot decide, and what would
  std::vector<std::string> not_tried;        // candidates left out, and why (one line each)
  std::string summary;               // one sentence
};

struct ForceErrorDiagnoseOptions {
  std::vector<std::string> candidates;  // empty: every time-only effect the model lacks
  double delta_bic = 10.0;
  double min_excess_share = 0.1;        // of the excess a candidate must explain
};

// The loop's step: refits with each candidate (and each pair), names the best
// significant one (ΔBIC > delta_bic and at least min_excess_share of the excess), says
// "explained" when it reaches 1.5× the floor and "more is missing" when not.
// @throws InputError  a candidate unknown, not time-only or already in the model.
ForceErrorDiagnosis diagnose_force_error(const PhysicalModel& model, const ForceErrorData& data,
                                         const ForceErrorDiagnoseOptions& options = {});

inline constexpr double kForceErrorExplainedRatio = 1.5;

// Where in time the fit fails: windows of window_s (every half window, by the log's
// sample numbers; a window mostly at standstill is skipped) whose residual rms exceeds
// 1.5× the larger of the noise floor's force and the record's own residual rms — the
// places where the model fails more than it does on average (a model failing evenly
// everywhere marks nothing: its residual panel shows the shape).  Merged when they
// overlap; t from the log's first sample.
struct ForceErrorWindow {
  Index dof = 0;
  double t_start_s = 0.0, t_end_s = 0.0;
  double rms = 0.0;  // the worst window's residual rms, in force units
};
// @throws InputError  the fit is not of these data; window_s not > 0.
std::vector<ForceErrorWindow> force_error_failing_windows(const ForceErrorFit& f, const ForceErrorData& d,
                                                         double window_s = 0.25);

}  // namespace lpvid
