// lpvid — diagnose's candidates (internal to idlib/diagnose): the refit of a model
// with one more effect (or a combination of effects), its starting points read off
// the failing bands, and the evidence its significance test sees.  diagnose.h says
// what the criteria are; this is how a candidate is evaluated.
#pragma once

#include <optional>

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "idlib/diagnose/diagnose.h"

namespace lpvid::diagnose_detail {

// Runs f(i) for i in [0, n) on the machine's cores (each call single-threaded;
// results do not depend on the thread count).  The first exception is rethrown
// after all threads end.
void parallel_for(std::size_t n, const std::function<void(std::size_t)>& f);

std::string percent(double x);  // "1.23 %"

// The plant-domain residual P_data − P_model at the data's frequency index k of set d.
Eigen::MatrixXcd plant_residual(const PhysicalModel& model, const FitDataset& ds, Index k, const FitOptions& fit);

// Starting points of the global start for an effect, read off the reference's
// failing phenomena (a resonance frequency and a mode shape) or spread over the
// range a phenomenon of that kind lives in (delays, lags).
std::vector<std::vector<std::pair<std::string, double>>> seeds_for(const EffectInfo& effect,
                                                                   const PhysicalModel& reference,
                                                                   const std::vector<Phenomenon>& phenomena,
                                                                   const std::vector<FitDataset>& data,
                                                                   const FitOptions& fit);

struct CandidateContext {
  const Diagnosis& d;
  const std::vector<FitDataset>& data;
  const DiagnoseOptions& options;
  const FitOptions& refit;
  const PhysicalModel& given;  // the model as the user gave it
  bool baseline_distorted;     // the baseline has parameters on bounds
  double floor;                // effective floor
  double excess2;              // e0² − f² (> 0 when the error as a whole is beyond the floor)
  bool global_excess;          // e0 > explained_ratio × floor
  bool something;              // global excess or failing bands: there is something to explain
};

// Every FREE parameter's library default (the base's and each effect's).
std::vector<std::pair<std::string, double>> library_defaults(const PhysicalModel& m);

// Refits c.members (set by the caller; the last is the one added) and judges the
// result against the baseline (judge_candidate).  `from` is the fitted model that
// holds every member but the last (the baseline for a single candidate, a member's
// or a pair's fit for a combination); `phenomena` are where `from` fails (seeds).
// Fills every field of c but the member_* ones.
void evaluate_candidate(CandidateOutcome& c, const PhysicalModel& from, const std::vector<Phenomenon>& phenomena,
                        const CandidateContext& ctx);

// The judgement half of evaluate_candidate, for c.fit already fitted (c.fitted):
// error, ΔBIC, failing bands and the verdict against the baseline.  `fo` are the
// options the fit ran with.  Fills every field of c but the member_* ones.
void judge_fitted(CandidateOutcome& c, const FitOptions& fo, const CandidateContext& ctx);

// Pairs, then triples, of the singles (DiagnoseOptions::combination_pool, header of
// diagnose.h): each refitted and judged (evaluate_candidate), then every member's
// need tested against the combination without it.  `singles` are the evaluated
// single candidates; returns the combinations tried, significant first by ΔBIC, then
// by error.  Triples only when the best significant pair leaves more than
// explained_ratio × the floor.
std::vector<CandidateOutcome> evaluate_combinations(const std::vector<CandidateOutcome>& singles,
                                                    const CandidateContext& ctx);

// Whether an effect is one of the library's structural modes (structural_mode,
// structural_mode_2, ...): interchangeable members of a combination.
bool is_mode_effect(const std::string& name);

// fo for a local refit from where a model is: no global start (so no extra starts,
// no searched subset), no restarts; with the model error in the weights when asked.
FitOptions local_refit(const FitOptions& fo, bool model_error_weighting);
// `from` refitted locally with the model error in its weights
// (DiagnoseOptions::model_error_weighting: the figure the model can reach, as `fit
// --weighting auto` reaches it); nullopt when the refit fails numerically.
std::optional<FitResult> reweighted_refit(const PhysicalModel& from, const std::vector<FitDataset>& data,
                                          const FitOptions& fo);

// Whether an outcome leaves only noise: error within explained_ratio × the floor and
// at most 10 % of the baseline's failing-band points.
bool leaves_only_noise(const CandidateOutcome& c, const CandidateContext& ctx);

// What diagnose() found, for the report in words (diagnose_summary.cc).
struct SummaryInputs {
  const PhysicalModel& model;  // the model as the user gave it
  const std::vector<FitDataset>& data;
  const DiagnoseOptions& options;
  const CandidateOutcome* winner;  // nullptr: no candidate (nor combination) significant
  bool something;                  // an excess or failing bands: something to explain
  bool distorted;                  // the baseline has parameters on bounds
  bool left;                       // something the winner (or, without one, the model) leaves
};

// Diagnosis::summary, in the order a user reads it: the model's error and where it
// fails, the design values a baseline on its bounds asks for, the verdict (nothing to
// explain, the winner, or the closest candidates), and the residual's description.
void summarise(Diagnosis& out, const SummaryInputs& in);

}  // namespace lpvid::diagnose_detail
