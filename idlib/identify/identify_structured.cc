// Stages 5-7 of the kStructured identification (identify_detail.h) — the staged fit, the
// tail rounds and the bands — and the chain that runs all the stages in order.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "idlib/closedloop/plant_markov.h"
#include "idlib/core/eigen_decompositions.h"
#include "idlib/core/error.h"
#include "idlib/core/parallel.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/identify/response_tail.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/signal/noise_spectrum.h"

namespace lpvid::identify_detail {

// Fewest record segments for the replicate covariance of the bands (fewer: the noise
// model's covariance, with a warning in the reason).
constexpr std::size_t kMinReplicates = 8;
// Segments for the replicates: one per horizon L of record, but no more than about this
// many (longer segments leak less and cost less; 64 replicates estimate a variance to
// ±18 %, which the band's radius allows for).
constexpr Index kTargetReplicates = 64;

// ---- tail rounds ----
// Stop when the plant's response moves by less than this fraction of its own standard
// deviation between rounds (or by less than kTailRelativeFloor of itself, noise-free).
// The rounds contract by ~0.2 per round with the tail's amplitudes refitted (measured,
// noise-free, 10 kHz) and by up to ~0.7 without: the rounds left would move the plant by
// at most 0.7 / 0.3 ≈ 2.3 × the last change, so 1e-5 leaves ≤ ~2.3e-5 of the response,
// 4x under the noise-free error bound of the robustness suite (1e-4; measured ≤ 2e-6).
constexpr double kTailChangeSigmas = 0.1;
constexpr double kTailRelativeFloor = 1e-5;
// Iterations per tail round: the rounds are a fixed-point iteration, so a round need not
// converge (the next continues from it, and the rounds stop only when the plant stops
// moving).  Measured on noise-free logs (independent simulator seed 1, right): rounds of
// 300 iterations took 3.3 s each from the first round's sharper weights; 30 per round
// reached the same plant (error 0.000 %) in 2.7 s in all.
constexpr int kTailRoundIterations = 30;
constexpr Index kChangeGridPoints = 100;

// Largest change of P between two plants over the band, relative to |P| and to P's std.
struct Change {
  double relative = 0, sigmas = 0;
};
Change plant_change(const PlantFitResult& now, const StateSpace& before, const Eigen::VectorXd& grid) {
  const auto a = evaluate_response(now.plant, grid), b = evaluate_response(before, grid);
  const auto var = plant_response_variance(now, grid);
  Change c;
  for (Index k = 0; k < grid.size(); ++k) {
    const double d = (a[static_cast<std::size_t>(k)] - b[static_cast<std::size_t>(k)]).norm();
    c.relative = std::max(c.relative, d / std::max(a[static_cast<std::size_t>(k)].norm(), 1e-300));
    c.sigmas = std::max(c.sigmas, d / std::max(std::sqrt(var[static_cast<std::size_t>(k)].sum()), 1e-300));
  }
  return c;
}


// 5. Staged fit: horizons K0, 2 K0, ..., L, each from the last one's plant.
void staged_fit(const StructuredRun& run, const MarkovBins& first, PlantFitResult& fit, IdentifyChoices& ch) {
  const Index K0 = run.K0, L = run.L;
  ch.stages.push_back({K0, first.num_bins(), fit.iterations, fit.cost});
  Index stage_count = 1;
  for (Index K = 2 * K0; K <= L; K *= 2) ++stage_count;
  for (Index K = 2 * K0; K <= L; K *= 2) {
    report_progress(run.options.progress, {"identify", "staged fit", static_cast<Index>(ch.stages.size()) + 1,
                                           stage_count, fmt::format("{} lags", K)});
    const MarkovBins stage = run.bins_at(run.g0, run.spectrum, K);
    fit = fit_plant_closed_loop(stage, run.controller, fit.plant, run.fo);
    ch.stages.push_back({K, stage.num_bins(), fit.iterations, fit.cost});
  }
}

// The tail rounds of one pass (see identify_structured, 6.): each corrects the outputs
// (`corrected`, per experiment) by the fitted response beyond the horizon, re-estimates ĝ
// (g_final) and refits `fit`, until the plant stops moving on `grid`.
void tail_rounds(StructuredRun& run, int pass, const Eigen::VectorXd& grid, PlantFitResult& fit,
                 std::vector<Eigen::MatrixXd>& corrected, MarkovSequence& g_final, IdentifyResult& result) {
  IdentifyChoices& ch = result.choices;
  const IdentifyOptions& options = run.options;
  const std::vector<ExperimentView>& experiments = run.experiments;
  const StateSpace& controller = run.controller;
  const Index L = run.L;
  ch.tail_rounds.clear();
  ch.tail_reason = fmt::format("no rounds ({} allowed)", options.max_tail_rounds);
  for (int round = 1; round <= options.max_tail_rounds; ++round) {
    report_progress(options.progress, {"identify", "tail round", round, 0,
                                       fmt::format("up to {}{}", options.max_tail_rounds,
                                                   pass == 1 ? ", after the order check" : "")});
    // This round's corrected outputs; they replace `corrected` only when finite, so that
    // a round that overflows leaves the bands stage the round before's.
    std::vector<Eigen::MatrixXd> next(experiments.size());
    std::vector<ExperimentView> views;
    parallel_for(static_cast<Index>(experiments.size()), [&](Index e) {  // one task per experiment
      const auto& x = experiments[static_cast<std::size_t>(e)];
      next[static_cast<std::size_t>(e)] = x.output - closed_loop_response_beyond(fit.plant, controller, x.excitation, L);
    });
    for (std::size_t e = 0; e < experiments.size(); ++e) views.push_back({experiments[e].excitation, next[e]});
    // Where the response had not ended within the horizon, the slow modes' tail
    // amplitudes from the logs (with the last ĝ), not from the model alone
    // (refit_response_beyond): the plain rounds contract too slowly there (measured
    // ~0.7 per round on a drawn plant with 17 % of the energy beyond; ~0.2 with the refit).
    if (run.response_beyond) {
      const std::vector<Eigen::MatrixXd> refit = refit_response_beyond(fit.plant, controller, views, g_final, L);
      for (std::size_t e = 0; e < experiments.size(); ++e) next[e] -= refit[e];
    }
    // A round's plant whose loop with the controller is unstable has a tail that grows
    // without bound over the record: its correction overflows.  The rounds end with the
    // fit before it (found on a linear axis's half-log at a forced order 4: the overflow
    // reached estimate_markov as a log to "rescale", or one with an infinite sample, and
    // the held-out check of the refinement failed with it).  Finite when squared and
    // summed, as estimate_markov needs it.  `corrected` and g_final then stay the round
    // before's, which the bands stage reads (the raw outputs and the first ĝ at round 1).
    bool finite = true;
    for (const Eigen::MatrixXd& c : next) finite = finite && std::isfinite(c.squaredNorm());
    if (!finite) {
      ch.tail_reason = fmt::format("stopped at round {}: the plant of the round before closes a loop with the "
                                   "controller whose response beyond the horizon grows without bound over the record "
                                   "(an unstable loop), so its tail cannot correct the logs; the rounds end with that "
                                   "plant",
                                   round);
      result.warnings.push_back("identify: tail rounds " + ch.tail_reason);
      break;
    }
    corrected = std::move(next);
    run.mo.num_lags = L;
    run.mo.initial_guess = g_final;  // the previous round's ĝ: the correction is small
    const MarkovResult mr = estimate_markov(views, run.mo, &run.corr);
    if (round == 1 && pass == 0) run.spectrum = fir_residual_spectrum(views, mr.g, L, L / 2 + 1);
    const MarkovBins data = run.bins_at(mr.g, run.spectrum, L);
    g_final = mr.g;
    const StateSpace before = fit.plant;
    PlantFitOptions tail_fo = run.fo;
    tail_fo.max_iterations = std::min(run.fo.max_iterations, kTailRoundIterations);
    fit = fit_plant_closed_loop(data, controller, fit.plant, tail_fo);
    const Change c = plant_change(fit, before, grid);
    ch.tail_rounds.push_back({fit.cost, c.relative});
    if (c.sigmas <= kTailChangeSigmas || c.relative <= kTailRelativeFloor) {
      ch.tail_reason = fmt::format("{} round(s): the last moved the plant by {:.3g} of its standard deviation ({:.3g} "
                                   "relative)",
                                   round, c.sigmas, c.relative);
      break;
    }
    ch.tail_reason = fmt::format("stopped after {} rounds; the last still moved the plant by {:.3g} of its standard "
                                 "deviation ({:.3g} relative)",
                                 round, c.sigmas, c.relative);
    if (round == options.max_tail_rounds) result.warnings.push_back("identify: " + ch.tail_reason);
  }
}

// 7. Bands: the covariance from replicates of ĝ's error, one per segment of the records
//    (L samples, longer where that would give more than kTargetReplicates;
//    markov_error_replicates), propagated through the final fit
//    (use_replicate_covariance).  Measured: the model's own σ̂² (JᵀJ)⁺ assumes
//    independent bins and claimed 6-10x too little variance on the independent
//    simulator (bins' errors correlate over tens to hundreds of bins).
void estimate_bands(const StructuredRun& run, const std::vector<Eigen::MatrixXd>& corrected,
                    const MarkovSequence& g_final, PlantFitResult& fit, IdentifyChoices& ch) {
  const std::vector<ExperimentView>& experiments = run.experiments;
  const Index L = run.L;
  const Eigen::MatrixXd& R0 = run.R0;
  report_progress(run.options.progress, {"identify", "bands", 0, 0, "covariance from the record's segments"});
  std::vector<ExperimentView> views;
  for (std::size_t e = 0; e < experiments.size(); ++e) {
    if (corrected[e].size() > 0)
      views.push_back({experiments[e].excitation, corrected[e]});
    else
      views.push_back(experiments[e]);
  }
  const MarkovBins final_data = run.bins_at(g_final, run.spectrum, L);
  Index total = 0;
  for (const auto& e : experiments) total += e.excitation.rows();
  const Index segment = std::max(L, (total + kTargetReplicates - 1) / kTargetReplicates);
  auto reps = markov_error_replicates(views, g_final, R0, segment, L, final_data.num_bins());
  // The replicates divide by R₀ (white excitation); a coloured one's LS error at bin f
  // is the segment's cross-spectrum over S_vv(f): δG_s(f) R₀ S_vv(f)⁻¹.
  if (run.coloured && !final_data.excitation_spectrum.empty()) {
    std::vector<Eigen::MatrixXcd> to_coloured;
    for (const Eigen::MatrixXcd& S : final_data.excitation_spectrum) {
      // A ridge of 1e-12 of the mean power keeps an unexcited bin finite (its variance
      // then says the data hold nothing there).
      Eigen::MatrixXcd Sr = S;
      Sr.diagonal().array() += 1e-12 * std::max(S.trace().real(), 1e-300) / static_cast<double>(S.rows());
      to_coloured.push_back(R0.cast<std::complex<double>>() * Sr.partialPivLu().inverse());
    }
    for (auto& rep : reps)
      for (std::size_t f = 0; f < rep.size(); ++f) rep[f] = rep[f] * to_coloured[f];
  }
  // A replicate with a non-finite bin (the logs' correction by a tail that overflowed
  // partway, or an unexcited bin's ridge overwhelmed) carries no spread to use.
  bool finite = true;
  for (const auto& rep : reps)
    for (const Eigen::MatrixXcd& b : rep) finite = finite && b.allFinite();
  if (!finite) {
    ch.bands_reason = "covariance of the fit's noise model (the Markov estimate's error replicates hold non-finite "
                      "bins): bins assumed independent, likely too narrow";
  } else if (reps.size() >= kMinReplicates) {
    use_replicate_covariance(fit, final_data, run.controller, reps, run.fo);
    ch.bands_reason = fmt::format("covariance from {} replicates of the Markov estimate's error, one per {}-sample "
                                  "segment of the records",
                                  reps.size(), segment);
  } else {
    ch.bands_reason = fmt::format("covariance of the fit's noise model (only {} record segments of {} samples; {} "
                                  "are needed for replicates): bins assumed independent, likely too narrow",
                                  reps.size(), segment, kMinReplicates);
  }
}

IdentifyResult identify_structured(const std::vector<ExperimentView>& experiments, double Ts,
                                   const StateSpace& controller, const IdentifyOptions& options, Index shortest) {
  IdentifyResult result;
  result.method = IdentifyMethod::kStructured;
  IdentifyChoices& ch = result.choices;
  StructuredRun run(experiments, Ts, controller, options, shortest);
  run.m = experiments.front().excitation.cols();
  run.p = experiments.front().output.cols();

  // 1. Horizon.
  choose_horizon(run, result);

  // 2. Noise spectrum and the fit band.
  choose_fit_band(run, result);

  run.fo.input_scale = result.markov.excitation_rms;
  run.fo.output_scale = result.markov.output_rms;
  const MarkovBins first = run.bins_at(run.g0, run.spectrum, run.K0);

  // 3. Starting models: ERA on the plant's impulse response p̂ = Ĝ (I − C Ĝ)⁻¹ over the
  //    first Lc lags for a few Lc, every order from one SVD per Lc; for each order the
  //    start that closes a stable loop and fits the first stage best is kept.
  plan_starts(run);
  report_progress(options.progress, {"identify", "starting models", 0, 0, "ERA on the plant's impulse response"});
  const MarkovSequence phat0 = plant_markov_from_closed_loop(run.g0, controller, run.start_lags_max);
  const std::vector<Realised> pool0 = realise_all(run, phat0);
  // 4. Order (given, or from a ladder at the first stage: climb_ladder).
  PlantFitResult fit = fit_first_stage(run, pool0, first, ch);

  // 5. Staged fit: horizons K0, 2 K0, ..., L.
  staged_fit(run, first, fit, ch);

  // 6. Tail rounds: subtract the fitted response beyond the horizon, re-estimate ĝ, refit,
  //    until the plant stops moving.  Then the order check on the final data: a smaller
  //    order (from its own ERA starts on the corrected p̂ and on the first p̂) replaces the
  //    model when its first-stage cost per degree of freedom is within kOrderSigmas of the
  //    current one's or at the noise floor; the descent stops at the first order that is
  //    not (the best cost cannot rise with the order, so a smaller one would fail too),
  //    and the tail rounds are rerun from the reduced model.  At the first data the
  //    response beyond the horizon is part of the noise, and an extra state can explain
  //    some of it (measured: orders 7 and 9 kept on drawn plants whose order-6 fit on the
  //    final data is as good).
  const double lowest = run.lowest_bin_rad_s;
  const Eigen::VectorXd grid =
      log_frequency_grid(std::max(lowest, 1e-3), std::max(run.omega_fit, 2.0 * lowest), kChangeGridPoints);
  std::vector<Eigen::MatrixXd> corrected(experiments.size());
  MarkovSequence g_final = run.g0;  // ĝ of the last round's corrected data
  const bool select_order = options.plant_order == 0;
  for (int pass = 0; pass < 2; ++pass) {
    tail_rounds(run, pass, grid, fit, corrected, g_final, result);
    if (!select_order || pass == 1 || fit.plant.order() == 1) break;
    if (!reduce_order(run, pool0, g_final, fit, ch)) break;
  }
  ch.plant_order = fit.plant.order();

  // 7. Bands (estimate_bands).
  estimate_bands(run, corrected, g_final, fit, ch);
  if (!fit.closed_loop_stable)
    throw NumericalError(controller.order() == 0 && controller.D.isZero(0.0)
                             ? fmt::format("the fitted plant of order {} is unstable, and an open-loop record ran a "
                                           "stable plant; try another --plant-order",
                                           fit.plant.order())
                             : std::string("the fitted plant closes an unstable loop with the controller; the logs do "
                                           "not fit this controller (check --controller)"));
  for (const auto& w : fit.report.warnings) result.warnings.push_back("fit: " + w);
  result.fit = std::move(fit);
  result.plant = result.fit.plant;
  result.closed_loop = closed_loop_output(result.plant, controller);
  return result;
}

}  // namespace lpvid::identify_detail
