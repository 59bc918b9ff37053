// lpvid — which physical effect is missing?  For a physical model and measured
// responses at several beam positions: refit the model as it is (the
// baseline), then for every candidate effect of the library that the model
// lacks, add it with its library defaults, refit everything (global start +
// Levenberg–Marquardt, idlib/fit) and rank the candidates by the Bayesian
// information criterion (docs/math.md, "Diagnose").
//
// Why BIC.  Adding an effect never raises the least-squares cost, so the cost
// alone always prefers the larger model.  BIC = N ln(cost/N) + p ln N charges
// ln N per extra parameter (N = the number of real residuals, thousands here),
// against AIC's 2: with this much data AIC lets an effect with 1–3 parameters in
// whenever it lowers the cost by ~0.1–0.3 %, which noise alone does about one
// time in six; BIC is consistent (the probability of choosing a superfluous
// effect falls to zero as N grows) and its difference approximates twice the log
// Bayes factor, for which Kass & Raftery (JASA 1995) call a difference above 10
// "very strong" evidence.  A candidate is SIGNIFICANT when
//     ΔBIC = BIC(candidate) − BIC(baseline) < −significance_delta_bic  (10).
// The significance test assumes the residuals are independent with a common
// variance after the fit's weighting (coherence weights for H1 data); smooth
// systematic errors (e.g. a plant recovered from an identified state-space model
// rather than measured per frequency) break that assumption and make ΔBIC
// overconfident — diagnose is meant for measured FRDs (analyzer data, lpvid frf).
//
// Error figure.  "error" below is the root mean square over the nine channels of
// the fit's per-channel relative rms error (FitResult::channels, pooled over the
// data sets): sqrt(mean_ij e_ij²), e_ij = sqrt(mean_k |T_ij − T̂_ij|² / s_ij²).
//
// Where it fails.  The baseline's model-error model against each data set
// (idlib/validate/model_error.h) gives the failing bands (channel, band, size,
// signature); the same for the winning candidate shows what remains.
#pragma once

#include <string>
#include <vector>

#include "idlib/fit/fit.h"
#include "idlib/physical/physical_model.h"
#include "idlib/validate/model_error.h"

namespace lpvid {

struct DiagnoseOptions {
  FitOptions fit;                       // target, controller, Ts, global start: as for fit
  ModelErrorOptions model_error;        // significance of the residual per frequency
  std::vector<std::string> candidates;  // effects to try; empty: every library effect the model lacks
  double significance_delta_bic = 10.0; // > 0, see above
  // Every refit stops when the cost changes by less than this relative amount (or
  // fit.function_tolerance, if larger).  ΔBIC needs the cost only to ~1e-9: its
  // error is then N·1e-9 ≈ 3e-5 for N ≈ 3·10⁴ residuals, against the threshold of 10;
  // Levenberg–Marquardt spends most of its time creeping from 1e-9 to fit's 1e-12
  // (the benchmark runs 3.3× faster).  In (0, 1).
  double refit_function_tolerance = 1e-9;

  // @throws InputError  a field out of range; fit or model_error options invalid.
  void validate() const;
};

struct CandidateOutcome {
  std::string effect;
  bool fitted = false;         // false: the refit failed (failure says why)
  std::string failure;
  FitResult fit;               // valid when fitted
  double error = 0.0;          // error figure after the refit
  double delta_bic = 0.0;      // BIC(candidate) − BIC(baseline); < 0 is better
  double delta_aic = 0.0;      // for reference
  bool significant = false;    // delta_bic < −significance_delta_bic
  std::vector<ParameterEstimate> effect_parameters;  // the effect's own estimates (free ones)
};

struct Diagnosis {
  FitResult baseline;
  double baseline_error = 0.0;
  // Per data set: the baseline's failing bands (after mark_differences_between_data).
  std::vector<std::vector<FailingBand>> baseline_failures;
  std::vector<CandidateOutcome> ranked;  // fitted ones by ΔBIC ascending, then the failed ones
  bool explained = false;                // the first ranked candidate is significant
  // With explained: the winner's failing bands (what is still wrong after adding it).
  std::vector<std::vector<FailingBand>> remaining_failures;
  std::vector<std::string> summary;      // plain-words lines (what is missing, where, before/after)
};

// The error figure of a fit (see the header comment).
double fit_error(const FitResult& fit);

// @throws InputError  as fit_physical_model; options invalid; a candidate unknown
//   or already in the model.
// @throws NumericalError  the baseline refit failed.
Diagnosis diagnose(const PhysicalModel& model, const std::vector<FitDataset>& data, const DiagnoseOptions& options);

// The same model without effect `name` (its parameters dropped, everything else
// kept with its value, bounds and free flag).
// @throws InputError  the model does not have the effect.
PhysicalModel without_effect(const PhysicalModel& model, const std::string& name);

}  // namespace lpvid
