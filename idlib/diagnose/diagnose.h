// lpvid — which physical effect is missing?  For a physical model (any base) and
// measured responses at several scheduling values: refit the model as it is (the
// baseline), then for every candidate effect the model lacks (the library's and the
// file's user-defined ones), add it with its defaults, refit everything (global
// start + Levenberg–Marquardt, idlib/fit) and judge it against the measurement's
// NOISE FLOOR (docs/math.md, "Diagnose").
//
// Why not an information criterion alone.  BIC = N ln(cost/N) + p ln N assumes the
// model class contains the truth.  When the base is not exact, any parameter that
// absorbs a little of the mismatch gets a huge negative ΔBIC (N ≈ 10⁴ residuals),
// and "significant" stops meaning "this effect is what is missing".  So a candidate
// is SIGNIFICANT only when, beyond ΔBIC < −significance_delta_bic:
//   - there is something to explain: the baseline error e0 > explained_ratio × f,
//     f = the effective noise floor (the error figure of the noise, σ_eff of
//     idlib/validate/model_error.h: the measurement's noise, never below lpvid's
//     resolution);
//   - it explains at least min_excess_share of the EXCESS error:
//       share = (e0² − e²) / (e0² − f²)     (errors add in quadrature);
//   - it removes at least min_band_share of the points in failing bands (the
//     frequencies beyond the noise);
//   - none of its own parameters ends on a bound (a "lightly damped mode" with its
//     damping pinned at the 0.7 bound, a lag at its largest time constant, is the
//     fit using the effect as a patch, not finding it).
// A structural mode of a base that offers several (a structure described by the user:
// idlib/physical/mechanical) is ONE OF SEVERAL: a structure lacks its modes together
// and no one of them explains half of the excess or removes half of the failing
// points while the others are missing (the F-16, real-data test: the torsion mode,
// ΔBIC −1608, explains 37 % of the excess of a model with none).  Such a mode is
// significant when it passes the other tests and explains at least
// min_mode_excess_share; the verdict says that more is missing, and the loop goes on.
// Candidates are ranked: significant ones first, by ΔBIC, then the rest by the error
// after refitting.  Other significant candidates that also leave only noise are listed
// as indistinguishable from the winner on these data.
// The diagnosis is EXPLAINED when the winner is significant and its error e ≤
// explained_ratio × f: what remains is noise.  Otherwise the winner (if any)
// explains part ("explains 85 % of the excess; still failing: ...").
//
// More than one effect missing: when no single candidate is significant or the best
// leaves an excess, pairs and triples are tried (DiagnoseOptions::combination_pool;
// the search and its judgement live in candidates.h/.cc); a combination wins only
// when it needs every member and beats the single winner by the ΔBIC margin.
//
// Where it fails.  The baseline's model-error model against each data set gives
// the failing bands; they are grouped into PHENOMENA (bands whose largest error sits
// at nearly the same frequency, in whatever channel and data set), so that distinct
// phenomena are each shown.
//
// When nothing in the library explains it: the residual is DESCRIBED by generic
// low-order error models fitted on top of the model (its own parameters held): a
// second-order resonance (pole and zero pair) or a first-order lag on one output row
// or one input column; the best is said in plain words ("a resonance near 850 rad/s,
// ζ ≈ 0.05, in the theta output row only — a sensor or its mount") with the
// user-defined effect that models it (docs/effects.md, "User-defined effects").
//
// Error figure and noise floor: idlib/fit/fit.h (FitResult::error, noise_floor).
#pragma once

#include <string>
#include <vector>

#include "idlib/fit/fit.h"
#include "idlib/physical/physical_model.h"
#include "idlib/validate/model_error.h"

namespace lpvid {

struct DiagnoseOptions {
  FitOptions fit;                        // target, controller, Ts, band, noise, global start: as for fit
  ModelErrorOptions model_error;         // significance of the residual per frequency
  std::vector<std::string> candidates;   // effects to try; empty: every effect the model lacks
  double significance_delta_bic = 10.0;  // > 0
  double min_excess_share = 0.5;         // in (0, 1]
  double min_band_share = 0.5;           // in [0, 1]
  double min_mode_excess_share = 0.1;    // one of several modes (above); in (0, 1]
  double explained_ratio = 1.5;          // >= 1
  bool describe = true;                  // describe an unexplained residual with generic error models
  // The error figure when the model fails (docs/math.md, "Weights when the model
  // fails"): with a baseline beyond explained_ratio × the floor, the baseline and
  // every candidate are also refitted locally with the model error in the weights
  // (FitOptions::model_error_weighting), and their error figures (excess shares,
  // "raises the error", "within the noise") are those of these fits, as `fit
  // --weighting auto` reaches them; ΔBIC stays the noise-weighted fits' (the data's
  // likelihood).  On the F-16 the structure's third mode (3.47 Hz) raised the
  // noise-weighted figure from 56.3 % to 99 % and lowers the reweighted one from 54.8 %
  // to 47.2 %.  Off: the noise-weighted figures.
  bool model_error_weighting = false;
  // Every refit stops when the cost changes by less than this relative amount (or
  // fit.function_tolerance, if larger): the criteria above need the cost to ~1e-4
  // (ΔBIC of 10 on N ≈ 10⁴ residuals is a relative cost change of ~1e-3; the shares
  // are compared with 0.5), so 1e-6 leaves a margin of 100.
  double refit_function_tolerance = 1e-6;
  // Levenberg–Marquardt iterations per refit: a candidate the data cannot separate
  // from the base (a gain beside free masses) crawls; 60 is far beyond the ~5–20 a
  // separable one needs.
  int refit_max_iterations = 60;
  // Global starts of a candidate's refit (its own parameters only, beside the starts
  // read off the failing bands): fewer than a first fit needs, the base is fitted.
  int candidate_global_starts = 4;
  // Combinations (issue 25): when no single candidate is significant, or the best
  // leaves more than explained_ratio × the floor, pairs are tried: the single with
  // the lowest error (the anchor) with every other candidate, and the
  // combination_pool singles with the best ΔBIC with each other — each pair
  // refitted from one member's fit (the anchor's, or the better ΔBIC's), the other's
  // parameters searched globally; then the best significant pair (or, with none,
  // the pair with the lowest error if it explains min_excess_share of the excess),
  // if it still leaves an excess, with every other candidate as a third.  A combination is
  // significant when it passes the single test against the baseline AND every
  // member is needed: without it (the combination's other members, fitted) ΔBIC is
  // worse by more than significance_delta_bic and the error higher.  It replaces
  // the single winner only when it beats it by that margin too (the greedy order is
  // kept when one effect suffices).  Cost: at most (n − 1) + C(pool, 2) pair and
  // n − 2 triple refits for n candidates.  max_combination 1: singles only.
  int combination_pool = 4;   // >= 2
  int max_combination = 3;    // 1, 2 or 3
  // Reports (idlib/core/progress.h), nullptr: none; fit.progress is not used (the
  // refits run in parallel).  Task "diagnose baseline, fit" (the baseline's global
  // starts and iterations), then "diagnose: candidate K of n: NAMES" (the candidates
  // running, newest first; bar: the share finished), then the residual's models
  // ("residual model", "residual model refit").  Called from several threads.
  Progress* progress = nullptr;

  // @throws InputError  a field out of range; fit or model_error options invalid;
  //   the noise of the data unknown (checked by diagnose: data without variance,
  //   coherence or averages and no noise level given).
  void validate() const;
};

struct CandidateOutcome {
  std::string effect;
  bool fitted = false;         // false: the refit failed (failure says why)
  std::string failure;
  FitResult fit;               // valid when fitted
  double error = 0.0;          // error figure after the refit
  // With DiagnoseOptions::model_error_weighting: the noise-weighted refit's figure when
  // the reweighted one (`error`) is lower; NaN otherwise.
  double noise_weighted_error = std::numeric_limits<double>::quiet_NaN();
  double delta_bic = 0.0;      // BIC(candidate) − BIC(baseline); < 0 is better
  double delta_aic = 0.0;      // for reference
  double excess_share = 0.0;   // share of the baseline's excess error it explains (can be < 0)
  double band_share = 0.0;     // share of the failing-band points it removes (can be < 0)
  Index band_points = 0;       // failing-band points left with it
  bool own_parameter_at_bound = false;
  bool significant = false;
  std::string verdict;         // "significant", "not significant: ...", "at bound: ...", "refit failed"
  std::vector<ParameterEstimate> effect_parameters;  // the effect's own estimates (free ones; every member's)
  // A combination's members (a single candidate: {effect}); effect is then "A + B".
  std::vector<std::string> members;
  // Per member, the share of the baseline's excess it adds beyond the other members
  // (e_without² − e²) / (e0² − f²) (combinations only; a single's is excess_share).
  std::vector<double> member_shares;
  // Per member, true when the combination needs it (combinations only), and the
  // error and ΔBIC of the combination without it (its other members, fitted).
  std::vector<bool> member_needed;
  std::vector<double> member_without_error, member_without_delta_bic;
  std::vector<Phenomenon> phenomena;  // where it still fails (its failing bands grouped)
};

// What the significance test of one candidate sees (diagnose's refit of it).
struct CandidateEvidence {
  bool something = false;        // the baseline has something to explain (global excess or failing bands)
  bool global_excess = false;    // the baseline's error > explained_ratio × floor
  bool has_band_points = false;  // the baseline has failing-band points
  double floor = 0.0;            // the effective noise floor, error-figure units
  double baseline_error = 0.0;   // error figure without the candidate
  double error = 0.0;            // error figure with it
  double delta_bic = 0.0;        // BIC(with) − BIC(without)
  double excess_share = 0.0;     // share of the baseline's excess it explains
  double band_share = 0.0;       // share of the failing-band points it removes
  std::vector<std::string> pinned;  // its own parameters on a bound, in words ("tau = 0.01 at its upper bound")
  bool one_of_several = false;      // a mode of a base that offers several (header comment)
};

struct CandidateJudgement {
  bool significant = false;
  std::string verdict;  // "significant" or "not significant: <the first test it fails>"
};

// The significance test, in this order: something to explain; none of its own
// parameters on a bound (a patch); the error figure does not rise (a candidate that
// raises it is never significant, whatever its ΔBIC: the two measures disagree and
// the error figure is what the user compares); ΔBIC < −significance_delta_bic; it
// explains ≥ min_excess_share of a global excess; it removes ≥ min_band_share of the
// failing-band points, unless it brings a global excess to within explained_ratio ×
// the floor (what is left is then noise as a whole: residual points of a near-zero
// entry cannot veto it).  One of several modes: ≥ min_mode_excess_share of the
// excess, and no band test (header comment).
CandidateJudgement judge_candidate(const CandidateEvidence& e, const DiagnoseOptions& options);

// A generic error model fitted to the residual (header comment).
struct ResidualDescription {
  std::string kind;        // "resonance" or "lag"
  std::string side;        // "output" (a row) or "input" (a column)
  std::string channel;     // e.g. "theta"
  double error = 0.0;      // error figure with it
  double excess_share = 0.0;
  bool pinned = false;     // one of its parameters ended on a bound
  std::string text;        // plain words
  EffectInfo effect;       // the user-defined effect that models it, with the fitted values as defaults
};

// When the base cannot follow the data (a parameter of the baseline on a bound): the
// value the data want and, for a scale of a design value (BaseInfo::design_scales),
// the design value it should have — from refits with the design value scanned over
// 1/8 … 8x (the best error wins); for any other parameter, from a refit with its
// bound widened tenfold.
struct DesignHint {
  std::string parameter;     // on its bound in the baseline, e.g. "bending_scale_psi"
  double bound = 0.0;        // the bound it sits on
  double lower = 0.0, upper = 0.0;
  double wanted = 0.0;       // the value the data want, relative to the design for a scale (NaN: none better found)
  std::string design;        // the design value it scales ("" when none)
  double design_value = 0.0;     // as given
  double suggested = 0.0;        // design_value × wanted
  std::vector<std::string> effects;  // library effects that hold it (they carry what lies beyond)
};

// An effect already in the model that the data do not need: refitted without it (from
// the baseline, locally), the error does not rise beyond 0.1 % of the figure and BIC
// does not worsen by the significance margin.  Tried for the effects with a free
// parameter on a bound, or correlated beyond 0.99 with another effect's parameter (an
// effect that stood in for what a later one carries: a coil lag named before the
// delay it approximated at low frequency).
struct IdleEffect {
  std::string effect;
  std::string why_tried;       // "actuator_time_constant_s = 1.45e-06, corr -1.000 with input_delay_s"
  double error_without = 0.0;  // the refit's error figure without it
  double delta_bic = 0.0;      // (BIC + prior cost) without it − with it (< 0: better without)
};

struct Diagnosis {
  FitResult baseline;
  // With DiagnoseOptions::model_error_weighting and a failing baseline: the noise-
  // weighted baseline's figure (baseline.error) when the reweighted one
  // (baseline_error) is lower, and the model error λ of the reweighted fit; NaN and 0
  // otherwise.
  double noise_weighted_baseline_error = std::numeric_limits<double>::quiet_NaN();
  double model_error_weight = 0.0;
  double baseline_error = 0.0;
  double noise_floor = 0.0;       // the measurement's (FitResult::noise_floor; NaN when unknown)
  double effective_floor = 0.0;   // with lpvid's resolution (what "within the noise" is measured against)
  std::string noise_source;
  Index baseline_band_points = 0;
  // Per data set: the baseline's failing bands (after mark_differences_between_data).
  std::vector<std::vector<FailingBand>> baseline_failures;
  std::vector<Phenomenon> phenomena;       // the baseline's, distinct, strongest first
  std::vector<CandidateOutcome> ranked;    // significant first (by ΔBIC), then by error; failed refits last
  // Pairs and triples tried (DiagnoseOptions::combination_pool), ranked as `ranked`;
  // empty when one effect explains it or there is nothing to explain.
  std::vector<CandidateOutcome> combinations;
  bool explained = false;                  // the winner is significant and leaves only noise
  // Other significant candidates (or combinations, when the winner is one) the data
  // do not separate from the winner: their BIC on the data alone within
  // significance_delta_bic of the winner's and, when explained, leaving only noise
  // too (a 0.55 ms delay and a lag on an analyzer's S up to 2 Hz: ΔBIC 3.6 apart).
  std::vector<std::string> indistinguishable;
  // Candidates that would be indistinguishable on the data alone but whose fit pulls
  // the estimates further from their priors (prior chi-square higher by more than
  // significance_delta_bic than the winner's): the priors separate them.
  std::vector<std::string> separated_by_priors;
  // With the winner explained: other significant candidates that leave only noise
  // too by the error figure, but whose likelihood on the data is worse than the
  // winner's by more than significance_delta_bic (the data separate them).
  std::vector<std::string> also_explain;
  std::string missing;                     // the winner when significant ("A + B" for a combination), else ""
  std::vector<std::string> missing_effects;  // its members ({missing} for one effect)
  // The winning outcome (in ranked or combinations), nullptr when none is significant.
  const CandidateOutcome* winner() const;
  // With a significant winner: its failing bands and phenomena (what is still wrong).
  std::vector<std::vector<FailingBand>> remaining_failures;
  std::vector<Phenomenon> remaining_phenomena;
  std::vector<DesignHint> design_hints;           // when the baseline is on bounds (empty otherwise)
  std::vector<IdleEffect> idle_effects;           // effects of the model the data do not need
  double widened_error = 0.0;                     // the best error of those refits (NaN: none better)
  std::vector<ResidualDescription> descriptions;  // best first (empty: nothing to describe)
  std::vector<std::string> summary;               // plain-words lines
};

// @throws InputError  as fit_physical_model; options invalid; a candidate unknown
//   or already in the model; the data's noise unknown.
// @throws NumericalError  the baseline refit failed.
Diagnosis diagnose(const PhysicalModel& model, const std::vector<FitDataset>& data, const DiagnoseOptions& options);

// The model-error models (per data set) of a model against the data, with the noise
// of the fit's noise model; the failing bands per set (marked across sets).
struct ModelErrorSet {
  std::vector<ModelErrorModel> models;
  std::vector<std::vector<FailingBand>> failures;
  Index band_points = 0;           // significant points inside failing bands, over all sets
  double effective_floor = 0.0;    // error figure of σ_eff
};
// @throws InputError  as target_response and model_error.
ModelErrorSet model_errors(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& fit,
                           const ModelErrorOptions& options);

}  // namespace lpvid
