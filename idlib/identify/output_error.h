// lpvid — output-error (simulation-error) refinement of an identified open-loop model
// (issue 24: "a prediction-error or output-error refinement of the subspace/ERA model on
// the same data, as ssest/pem refine an n4sid start").
//
// The structured fit (plant_fit.h) is maximum likelihood on the L-lag Markov estimate:
// on a short record the FIR estimate itself is noisy (the DaISy robot arm: 256 lags from
// 1024 samples), and the model inherits that.  This refinement fits the model's
// simulated output to the logs directly:
//
//   V(θ) = Σ_e Σ_t ‖S_y⁻¹ (y_e(t) − ŷ_e(t; θ))‖²,   x_e(t+1) = A x_e(t) + B u_e(t),
//   ŷ_e(t) = C x_e(t) + D u_e(t) + c_e,  x_e(0) a parameter per experiment (or 0),
//
// u as logged and an output offset c_e per experiment (as the Markov estimate's
// intercept), S_y the outputs' RMS (each output counts alike, MATLAB compare's
// normalisation).  θ = [vec A; vec B; vec C; (vec D); x_1(0); ...; c_1; ...], column-major;
// D is free only when the start has a feedthrough.  Levenberg–Marquardt (Ceres, dense QR) with the exact
// Jacobian from forward sensitivities (dx(t+1) = A dx(t) + dA x(t) + dB u(t)); the
// similarity directions stay free (they do not change ŷ; LM's damping holds them).
//
// The result is used only when it is stable (the logs of an open-loop experiment
// ran a stable plant) and lowers V; otherwise the start is kept and `reason` says why.
// The covariance of [vec A; vec B; vec C] is the sandwich B (Σ_s g_s g_sᵀ) B · S/(S − 1),
// B = (JᵀJ)⁺, g_s = J_sᵀ r_s over S record segments: the residuals of an output-error
// model are coloured (no noise model), so σ² (JᵀJ)⁻¹ would claim too little.
//
// Cost: O(N (n² P)) per Jacobian, P = n² + n m + p n (+ p m) + n E parameters; the
// Jacobian is N p × P doubles.  Above kMaxOutputErrorJacobianEntries (many outputs) the
// refinement runs in its separable modal form instead (refine_output_error_modal), and is
// skipped (reason says so) only when that too would exceed it.
#pragma once

#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/signal/markov.h"

namespace lpvid {

inline constexpr double kMaxOutputErrorJacobianEntries = 2.0e7;  // 160 MB of doubles

// identify's closed-loop refinement runs only below this many Jacobian entries (16 MB):
// beyond, the records are long enough for the structured fit's Markov estimate (whose
// noise falls as 1/N) and the refinement would cost more than the fit (lpvid's platform
// logs, 3 x 60 s at 1 kHz, hold 6e7).
inline constexpr double kClosedLoopRefinementEntries = 2.0e6;

struct OutputErrorOptions {
  int max_iterations = 200;
  // refine_output_error_closed_loop: not refined (reason says so) above this many
  // Jacobian entries.  (refine_output_error switches to its modal form above
  // kMaxOutputErrorJacobianEntries instead.)
  double max_jacobian_entries = kMaxOutputErrorJacobianEntries;
  // x_e(0) fitted per experiment (true) or 0 (the record starts from rest).
  bool estimate_initial_states = true;
  // Segments for the sandwich covariance: records cut into pieces of at least this
  // many samples; within that, 10 residual correlation times long and 8-64 pieces in all
  // when the records allow (output_error_detail::sandwich_segment_length).
  Index min_segment_samples = 64;
  // Per experiment (N_e values >= 0), or empty: each sample's residual weighed so (0:
  // left out of the criterion, the simulation running through it) — the direct route
  // leaves out where a friction axis rests and settles after (direct.h).  The full form
  // only: where the modal form would run, the start is kept (reason says so).
  std::vector<Eigen::VectorXd> residual_weights;
  void validate() const;  // @throws InputError
};

struct OutputErrorResult {
  bool accepted = false;  // model is the refinement (else the start)
  std::string reason;     // one sentence: what was done and why it was (not) used
  StateSpace model;
  double start_cost = 0, cost = 0;  // V at the start and at `model`
  int iterations = 0;
  Index parameters = 0, residuals = 0;
  // Sandwich covariance of [vec A; vec B; vec C] of `model` (n² + n m + p n square), and
  // the p × m variances of D's entries (zero when D is fixed); empty when not accepted.
  Eigen::MatrixXd covariance;
  Eigen::MatrixXd feedthrough_variance;
  Index replicates = 0;
  // "full" (θ = vec A, B, C, ...) or "modal" (refine_output_error_modal), and the poles of
  // a modal result that sit on its bound |z| = ρ_max (the logs cannot tell them from
  // undamped or integrating ones).
  std::string form = "full";
  std::string form_reason;  // why the modal form ran (empty for the full form)
  Index poles_on_bound = 0;
};

// | experiments: excitation N_e × m (u), output N_e × p (y) | start: discrete, m → p |
// @throws InputError  shapes that differ; a start that is not discrete.
OutputErrorResult refine_output_error(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                                      const OutputErrorOptions& options = {});

// The same criterion for closed-loop logs: the plant (D = 0) inside its loop with the
// known controller K (e = −q, u = K e + v, the convention of identify_closed_loop), the
// loop simulated from the logged excitation v, q̂ = C x + c_e; the free initial state is
// the loop's [x(0); x_K(0)].  The plant may be unstable; the result is used only when its
// loop with K is stable and V falls.  Full form only: when the Jacobian would exceed
// kMaxOutputErrorJacobianEntries the start is kept (reason says so).
// | experiments: excitation v N_e × m, output q N_e × p | start: discrete plant m → p, D = 0 |
// | controller: discrete p → m at the start's rate |
// @throws InputError  as refine_output_error; a controller of other shape or rate; a start
//                     with a feedthrough.
OutputErrorResult refine_output_error_closed_loop(const std::vector<ExperimentView>& experiments,
                                                  const StateSpace& start, const StateSpace& controller,
                                                  const OutputErrorOptions& options = {});

// The same criterion in the coordinates that keep it small when there are many outputs:
// A in real modal form (n numbers, every pole inside the unit circle by construction),
// C, D and the offsets eliminated by least squares for every θ (variable projection), so
// θ = [modal A; B; x_e(0)], n (1 + m + E) numbers.  The returned model is in the modal
// basis; its covariance is the full problem's sandwich, in the same [vec A; vec B; vec C]
// layout as refine_output_error's.  Not used (reason says so) when the start has nearly
// repeated poles (the modal basis would be ill-conditioned).
// @throws InputError  as refine_output_error.
OutputErrorResult refine_output_error_modal(const std::vector<ExperimentView>& experiments, const StateSpace& start,
                                            const OutputErrorOptions& options = {});

// The model's response to u as logged, corrected by least squares as MATLAB compare
// does: a constant per output (a sensor offset, the Markov estimate's intercept) and,
// with fit_initial_states, the initial state x(0) that fits y best (compare's 'e';
// otherwise x(0) = 0, compare's 'z').  predicted is empty when the response diverges
// (an unstable model, or a free response that overflows).
// | u: N × m | y: N × p | predicted: N × p | offsets: p | initial_state: n |
struct SimulatedOutput {
  Eigen::MatrixXd predicted;
  Eigen::VectorXd offsets, initial_state;
};
// @throws InputError  shapes that differ from the model's; an invalid model.
SimulatedOutput simulate_with_fitted_start(const StateSpace& model, const Eigen::Ref<const Eigen::MatrixXd>& u,
                                           const Eigen::Ref<const Eigen::MatrixXd>& y, bool fit_initial_states);

// MATLAB compare's simulation fit, 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) per output over all
// experiments, ŷ the model's response to u as logged plus a constant per output and
// experiment (the Markov estimate's intercept: a sensor offset), simulated from
// x(0) = 0 (fit_initial_states false: compare's 'z') or from the x_e(0) that fits each
// record best (true: compare's default 'e'); the constants and x_e(0) by linear least
// squares.  Empty when the model diverges on the logs.
// @throws InputError  shapes that differ.
Eigen::VectorXd simulation_fit_percent(const StateSpace& model, const std::vector<ExperimentView>& experiments,
                                       bool fit_initial_states);

}  // namespace lpvid

namespace lpvid {

// A stable model whose impulse response fits the Markov parameters g[0..L] (e.g. an ERA
// model that came out unstable on noisy or regularised estimates): the separable modal
// refinement above (every pole inside the unit circle by construction) on one impulse
// experiment per input — u = a unit impulse at t = 0 on that input, y = g[0..L]'s column,
// from rest (no initial state) — so the criterion is Σ_k ‖S⁻¹(g[k] − ĝ[k])‖² plus a
// constant per experiment and output (the modal form's offsets, here a harmless extra).
// `grows`: the last quarter of the lags carries more energy than the first (a growing
// response — or, in a least-squares estimate from a strongly coloured input, amplified
// noise: so it only informs; the caller judges by the errors, e.g. realize keeps the
// unstable model when the stable one fits the Markov parameters worse).
// | g: L + 1 matrices p × m | start: discrete, m → p |
// @throws InputError  g empty or shapes that differ from the start's.
struct MarkovStableFit {
  OutputErrorResult result;
  bool grows = false;
  double start_error = 0, error = 0;  // ‖g − ĝ‖_F / ‖g‖_F of the start and of the result
};
MarkovStableFit fit_markov_stable(const MarkovSequence& g, const StateSpace& start);

}  // namespace lpvid
