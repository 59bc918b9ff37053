// Stages 3-4 of the kStructured identification (identify_detail.h): the starting models
// (ERA on the plant's impulse response), the plant order at the first stage, and the
// order check on the final data.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/closedloop/plant_markov.h"
#include "idlib/core/error.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"

namespace lpvid::identify_detail {

// ---- starting models and order ----
// ERA on the plant's impulse response p̂ uses a 32 × 32-block Hankel matrix (96 × 96 for
// 3 × 3: orders up to 20 fit, and the SVD costs < 5 ms) over the first Lc lags, Lc from
// {L/32, L/16, L/8, L/4}; the start whose closed loop fits the data best is kept.
constexpr Index kStartBlocks = 32;
constexpr Index kMaxPlantOrder = 20;
// Orders compare by their whitened cost per degree of freedom V/dof (1 at the noise
// floor): a larger order is better only when it lowers V/dof by more than kOrderSigmas
// standard deviations (√(2/dof) relative) — extra states must explain more than noise.
constexpr double kOrderSigmas = 5.0;
// The ladder's noise-floor test allows the noise spectrum estimate this factor of error:
// an order is "at the floor" when V/dof <= kFloorSlack (1 + 5 sqrt(2/dof)).  Measured at the
// first stage on the independent simulator (seed 1, noise x1, 3 positions): the true order
// reached V/dof = 1.10-1.17; one order less stayed at 10^3-10^5.
// Noise-free logs put the first stage's floor higher (the response beyond the horizon is
// the "noise", and its spectrum is estimated roughly): 1.3-1.9 there.  The floor test only
// stops the climb; the next kLadderConfirm orders must still not be better by kOrderSigmas.
constexpr double kFloorSlack = 3.0;
// Orders tried above the first one at the floor before it is chosen, and above the best
// order when none reaches the floor.
constexpr Index kLadderConfirm = 2;
constexpr Index kLadderPlateau = 3;
// An order whose first-stage fit still has V/dof above this many times the noise floor
// after kOrderScreenIterations is not refined further (`screened`).  Measured on the
// independent simulator (seed 1, 3 positions, with and without noise): orders below the
// true one had V/dof of 10^3 to 10^5 after 50 iterations and still after 300; the true
// order's fits from ERA starts reached the floor within 6-10 iterations.
constexpr double kOrderAbandonRatio = 100.0;
// Also the budget of the order above the one at the floor (the confirmation): a state the
// data need lowers the cost within it.
constexpr int kOrderScreenIterations = 15;

std::string order_list(const std::vector<IdentifyChoices::Candidate>& c) {
  std::string s;
  for (const auto& x : c)
    s += fmt::format("{}{} ({:.4g}{})", s.empty() ? "" : ", ", x.order, x.cost / std::max(x.dof, 1.0),
                     x.screened ? ", not refined" : (x.stable ? "" : ", unstable loop"));
  return s;
}

void plan_starts(StructuredRun& run) {
  const IdentifyOptions& options = run.options;
  const Index L = run.L, p = run.p, m = run.m;
  run.n_cap = options.plant_order > 0
                  ? options.plant_order
                  : std::min<Index>(kMaxPlantOrder, std::min(options.max_order, kStartBlocks * std::min(p, m) - 1));
  std::vector<Index>& start_lags = run.start_lags;
  for (Index d : {32, 16, 8, 4})
    if (L / d >= 2 * kStartBlocks + 4) start_lags.push_back(L / d);
  if (start_lags.empty()) start_lags.push_back(L);
  // p̂ is needed only as far as the longest start horizon (its cost grows as its length²).
  run.start_lags_max = *std::max_element(start_lags.begin(), start_lags.end());
}

std::vector<Realised> realise_all(const StructuredRun& run, const MarkovSequence& phat) {
  const Index n_cap = run.n_cap;
  std::vector<Realised> out;
  for (const Index Lc : run.start_lags) {
    EraOptions eo;
    eo.sample_period_s = run.Ts;
    eo.estimate_feedthrough = false;
    eo.order = 1;
    eo.max_order = n_cap;
    for (Index n = 2; n <= n_cap; ++n) eo.also_orders.push_back(n);
    eo.block_rows = eo.block_cols = kStartBlocks;
    eo.stride = std::max<Index>(1, Lc / (2 * kStartBlocks));
    eo.sum_stride_lags = true;
    const MarkovSequence part(phat.begin(), phat.begin() + std::min<Index>(Lc, run.L) + 1);
    try {
      EraResult er = realize_era(part, eo);
      Realised r;
      r.lags = Lc;
      r.models.push_back(std::move(er.model));
      for (auto& mdl : er.models_at) r.models.push_back(std::move(mdl));
      out.push_back(std::move(r));
    } catch (const std::runtime_error&) {
      // a Hankel layout these lags cannot hold: no starts from this Lc
    }
  }
  return out;
}

struct Start {
  StateSpace model;
  double cost = std::numeric_limits<double>::infinity();
  bool stable = false;
  Index lags = 0;
};

// A start that closes a stable loop is preferred to any that does not (the loop that
// ran was stable, and the fit keeps a stable loop stable); among them the lowest cost.
Start best_start(const StructuredRun& run, const StartPools& pools, const MarkovBins& data, Index n) {
  Start best;
  for (const auto* pool : pools)
    for (const Realised& r : *pool) {
      const StateSpace& P0 = r.models[static_cast<std::size_t>(n - 1)];
      if (P0.order() != n || !P0.A.allFinite() || !P0.B.allFinite() || !P0.C.allFinite()) continue;
      const bool stable = is_stable(closed_loop_output(P0, run.controller));
      if (best.stable && !stable) continue;
      const double c = plant_fit_cost(data, run.controller, P0, run.fo);
      if (!std::isfinite(c)) continue;
      if ((stable && !best.stable) || c < best.cost) best = {P0, c, stable, r.lags};
    }
  return best;
}

double per_dof(const PlantFitResult& f) {
  return f.cost / static_cast<double>(std::max<Index>(1, f.residuals - f.parameters));
}
double sigma_factor(const PlantFitResult& f) {  // 1 + kOrderSigmas standard deviations of V/dof
  return 1.0 + kOrderSigmas * std::sqrt(2.0 / static_cast<double>(std::max<Index>(1, f.residuals - f.parameters)));
}

// Order n at the first stage from its best start: kOrderScreenIterations first; a fit
// still kOrderAbandonRatio above the noise floor (V/dof = 1) then is not refined
// (`screened`), otherwise it continues up to `budget` iterations in all.
struct OrderFit {
  PlantFitResult fit;
  Start start;
  bool found = false, screened = false;
};
OrderFit fit_order(const StructuredRun& run, const StartPools& pools, const MarkovBins& data, Index n, int budget) {
  const PlantFitOptions& fo = run.fo;
  OrderFit o;
  o.start = best_start(run, pools, data, n);
  if (!std::isfinite(o.start.cost)) return o;
  o.found = true;
  PlantFitOptions screen = fo;
  screen.max_iterations = std::min({fo.max_iterations, budget, kOrderScreenIterations});
  o.fit = fit_plant_closed_loop(data, run.controller, o.start.model, screen);
  if (per_dof(o.fit) > kOrderAbandonRatio) {
    o.screened = true;
    return o;
  }
  if (o.fit.iterations >= screen.max_iterations && budget > o.fit.iterations) {
    PlantFitOptions rest = fo;
    rest.max_iterations = std::max(0, std::min(fo.max_iterations, budget) - o.fit.iterations);
    o.fit = fit_plant_closed_loop(data, run.controller, o.fit.plant, rest);
  }
  return o;
}

IdentifyChoices::Candidate candidate(Index n, const OrderFit& o) {
  IdentifyChoices::Candidate c;
  c.order = n;
  c.cost = o.fit.cost;
  c.dof = static_cast<double>(std::max<Index>(1, o.fit.residuals - o.fit.parameters));
  c.stable = o.fit.closed_loop_stable;
  c.screened = o.screened;
  return c;
}

// The plant of the given order (options.plant_order) at the first stage.
PlantFitResult fit_given_order(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovBins& first,
                               IdentifyChoices& ch) {
  const IdentifyOptions& options = run.options;
  const OrderFit o = fit_order(run, {&pool0}, first, options.plant_order, run.fo.max_iterations);
  if (!o.found)
    throw NumericalError(fmt::format("no starting model of order {} could be realised from the logs; give another "
                                     "--plant-order or a longer record",
                                     options.plant_order));
  PlantFitResult fit = o.fit;
  if (o.screened) fit = fit_plant_closed_loop(first, run.controller, fit.plant, run.fo);
  ch.plant_horizon = o.start.lags;
  ch.order_reason = fmt::format("order {} was given", options.plant_order);
  return fit;
}

// The ladder's fits by order ([n], n = 1..n_cap; `found` false where none was tried or
// realised), the first order at the noise floor (-1: none, or the next was better) and
// the best usable one (-1: none).
struct Ladder {
  std::vector<OrderFit> fits;
  Index at_floor = -1, best = -1;
};

// 4. Order: a ladder n = 1, 2, ... at the first stage.  The first order whose whitened
//    cost per degree of freedom is at the noise floor (≤ kFloorSlack (1 + 5σ): V/dof ≈ 1
//    when the model explains everything but the noise) is confirmed against the next
//    order; if that one is not better by more than kOrderSigmas standard deviations, it
//    is chosen.  When no order reaches the floor, the ladder stops kLadderPlateau orders
//    above the best one and the smallest order within kOrderSigmas of the best is
//    chosen (an F-test: extra states must lower the cost by more than noise would).
Ladder climb_ladder(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovBins& first,
                    IdentifyChoices& ch) {
  const Index n_cap = run.n_cap;
  Ladder ladder;
  std::vector<OrderFit>& fits = ladder.fits;
  Index& at_floor = ladder.at_floor;
  Index& best = ladder.best;
  fits.resize(static_cast<std::size_t>(n_cap + 1));
  for (Index n = 1; n <= n_cap; ++n) {
    const bool confirming = at_floor >= 0;
    report_progress(run.options.progress,
                    {"identify", "plant order", n, 0, fmt::format("up to {}", n_cap)});
    OrderFit o = fit_order(run, {&pool0}, first, n, confirming ? kOrderScreenIterations : run.fo.max_iterations);
    if (!o.found) continue;
    ch.order_candidates.push_back(candidate(n, o));
    const bool usable = o.fit.closed_loop_stable && !o.screened;
    const double r = per_dof(o.fit);
    fits[static_cast<std::size_t>(n)] = std::move(o);
    if (usable && (best < 0 || r < per_dof(fits[static_cast<std::size_t>(best)].fit))) best = n;
    if (confirming) {
      const PlantFitResult& f0 = fits[static_cast<std::size_t>(at_floor)].fit;
      if (usable && per_dof(f0) > std::max(1.0, r * sigma_factor(fits[static_cast<std::size_t>(n)].fit))) {
        at_floor = -1;  // the next order is significantly better: climb on
      } else if (n >= at_floor + kLadderConfirm) {
        break;
      }
      continue;
    }
    if (usable && r <= kFloorSlack * sigma_factor(fits[static_cast<std::size_t>(n)].fit)) {
      at_floor = n;
      continue;
    }
    if (best >= 0 && n >= best + kLadderPlateau) break;
  }
  return ladder;
}

// No order was usable, open loop: a real structure with more modes than the ladder holds
// (the DaISy steel subframe: every order 1-20 stays above kOrderAbandonRatio times the
// floor): the open-loop logs still define a best model of each order; take the ladder's
// best stable order (`beyond`), refitted in full, and say why in `why`.
void take_ladder_best(const StructuredRun& run, const MarkovBins& first, std::vector<OrderFit>& fits, Index beyond,
                      std::string* why) {
  const Index n_cap = run.n_cap;
  // Why no order was usable: every one still far above the floor (screened), or some
  // came nearer but ended unstable (an open-loop record of a stable plant).
  std::vector<Index> unstable_near;
  for (Index n = 1; n <= n_cap; ++n) {
    const OrderFit& o = fits[static_cast<std::size_t>(n)];
    if (o.found && !o.screened && !o.fit.closed_loop_stable) unstable_near.push_back(n);
  }
  const Index chosen = beyond;
  fits[static_cast<std::size_t>(chosen)].fit =
      fit_plant_closed_loop(first, run.controller, fits[static_cast<std::size_t>(chosen)].fit.plant, run.fo);
  const std::string cause =
      unstable_near.empty()
          ? fmt::format("no order up to {} came within {:g} times the noise floor, so the plant holds more "
                        "dynamics than {} states (or the logs more than a linear plant and white noise)",
                        n_cap, kOrderAbandonRatio, n_cap)
          : fmt::format("the orders that came within {:g} times the noise floor ({}) ended unstable, which "
                        "open-loop logs of a running plant do not support, and the others stayed above it",
                        kOrderAbandonRatio, fmt::join(unstable_near, ", "));
  *why = fmt::format("{}; {} is the ladder's best stable order (cost per degree of freedom {:.4g} after refitting) "
                     "and is taken -- judge it by the simulation fit below, and give --plant-order above {} to try "
                     "more states",
                     cause, chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), n_cap);
}

// The order the ladder chooses (see climb_ladder), its first-stage fit, and why.
PlantFitResult choose_from_ladder(const StructuredRun& run, const MarkovBins& first, Ladder& ladder,
                                  IdentifyChoices& ch) {
  const Index n_cap = run.n_cap;
  std::vector<OrderFit>& fits = ladder.fits;
  const Index at_floor = ladder.at_floor, best = ladder.best;
  // identify_open_loop passes C = 0 (no states, no feedthrough): no loop to speak of.
  const bool open_loop = run.controller.order() == 0 && run.controller.D.isZero(0.0);
  Index beyond = -1;  // open loop, nothing near the floor: the best stable order of the ladder
  if (best < 0 && open_loop)
    for (Index n = 1; n <= n_cap; ++n) {
      const OrderFit& o = fits[static_cast<std::size_t>(n)];
      if (o.found && o.fit.closed_loop_stable &&
          (beyond < 0 || per_dof(o.fit) < per_dof(fits[static_cast<std::size_t>(beyond)].fit)))
        beyond = n;
    }
  if (best < 0 && beyond < 0) {
    throw NumericalError(fmt::format(
        "no candidate plant (orders {}) {}{}", order_list(ch.order_candidates),
        open_loop ? "is stable and fits the open-loop logs to their noise floor; the plant may need an order beyond "
                    "the ladder (give --plant-order) or the route markov + realize"
                  : "closes a stable loop with the controller that fits the logs; check that the controller is the "
                    "one that ran and that the logs are closed-loop data",
        open_loop || !run.coloured ? std::string()
                                   : fmt::format(
                                         "; or the excitation does not determine the loop's response: its spectral "
                                         "density spans a factor {:.3g} and the information in it ends at {:.4g} "
                                         "rad/s (the fit band), too narrow for the {}-lag response the starting "
                                         "models come from (a few sines or slow point-to-point moves excite a "
                                         "handful of frequencies) — add broadband excitation (noise or a "
                                         "multisine on the reference or the plant input) over the band the plant "
                                         "is wanted in",
                                         run.colour_ratio, ch.fit_band_max_rad_s, run.L)));
  }
  Index chosen = at_floor;
  std::string why;
  if (best < 0) {
    take_ladder_best(run, first, fits, beyond, &why);
    chosen = beyond;
  } else if (chosen >= 0) {
    why = fmt::format("{} is the first order at the noise floor (cost per degree of freedom {:.4g}) and the next "
                      "order is not better by {:g} sigma",
                      chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), kOrderSigmas);
  } else {
    const double ref = per_dof(fits[static_cast<std::size_t>(best)].fit);
    for (Index n = 1; n <= best && chosen < 0; ++n) {
      const OrderFit& o = fits[static_cast<std::size_t>(n)];
      if (o.found && !o.screened && o.fit.closed_loop_stable &&
          per_dof(o.fit) <= std::max(1.0, ref * sigma_factor(o.fit)))
        chosen = n;
    }
    why = fmt::format("no order reached the noise floor; {} is the smallest whose cost per degree of freedom ({:.4g}) "
                      "is within {:g} sigma of the best ({:.4g}, order {})",
                      chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), kOrderSigmas, ref, best);
  }
  PlantFitResult fit = std::move(fits[static_cast<std::size_t>(chosen)].fit);
  ch.plant_horizon = fits[static_cast<std::size_t>(chosen)].start.lags;
  ch.order_reason = fmt::format("orders tried at the first stage (cost per degree of freedom): {}; {}",
                                order_list(ch.order_candidates), why);
  return fit;
}

PlantFitResult fit_first_stage(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovBins& first,
                               IdentifyChoices& ch) {
  const bool select_order = run.options.plant_order == 0;
  PlantFitResult fit;
  if (!select_order) {
    fit = fit_given_order(run, pool0, first, ch);
  } else {
    Ladder ladder = climb_ladder(run, pool0, first, ch);
    fit = choose_from_ladder(run, first, ladder, ch);
  }
  ch.start_reason = fmt::format("ERA on the first {} lags of the plant's impulse response P = G (I - C G)^-1 (the best "
                                "closed-loop fit among {} horizons)",
                                ch.plant_horizon, run.start_lags.size());
  return fit;
}

bool reduce_order(const StructuredRun& run, const std::vector<Realised>& pool0, const MarkovSequence& g_final,
                  PlantFitResult& fit, IdentifyChoices& ch) {
  const PlantFitOptions& fo = run.fo;
  // The next smaller order is not retried when the first stage found it more than
  // kOrderAbandonRatio times worse per degree of freedom than the chosen one: the
  // response beyond the horizon, which the tail rounds remove, burdens both orders
  // alike at the first stage (it is why an extra state can look useful there), so it
  // cannot hide a gap that large.
  {
    const Index top = fit.plant.order();
    auto at = [&](Index n) {
      return std::find_if(ch.order_candidates.begin(), ch.order_candidates.end(),
                          [&](const IdentifyChoices::Candidate& c) { return c.order == n; });
    };
    const auto chosen = at(top), below = at(top - 1);
    if (chosen != ch.order_candidates.end() && below != ch.order_candidates.end() &&
        below->cost / std::max(below->dof, 1.0) >
            kOrderAbandonRatio * std::max(chosen->cost / std::max(chosen->dof, 1.0), 1.0)) {
      ch.order_reason += fmt::format("; order {} was more than {:g}x worse per degree of freedom at the first "
                                     "stage, so smaller orders were not retried on the final data",
                                     top - 1, kOrderAbandonRatio);
      return false;
    }
  }
  const MarkovBins small = run.bins_at(g_final, run.spectrum, run.K0);
  const std::vector<Realised> pool =
      realise_all(run, plant_markov_from_closed_loop(g_final, run.controller, run.start_lags_max));
  PlantFitResult top_small = fit_plant_closed_loop(small, run.controller, fit.plant, fo);
  const Index top = fit.plant.order();
  std::string tried;
  PlantFitResult lower_fit;
  Index lower = top;
  for (Index n = top - 1; n >= 1; --n) {
    report_progress(run.options.progress, {"identify", "order check", n, 0, fmt::format("against order {}", top)});
    OrderFit o = fit_order(run, {&pool, &pool0}, small, n, fo.max_iterations);
    if (!o.found) break;
    const double ref = per_dof(top_small);
    const bool pass_n = o.fit.closed_loop_stable && !o.screened &&
                        per_dof(o.fit) <= std::max(1.0, ref * sigma_factor(o.fit));
    tried += fmt::format("{}{} ({:.4g}{})", tried.empty() ? "" : ", ", n, per_dof(o.fit),
                         o.screened ? ", not refined" : (o.fit.closed_loop_stable ? "" : ", unstable loop"));
    if (!pass_n) break;
    lower = n;
    lower_fit = std::move(o.fit);
  }
  if (lower == top) {
    if (!tried.empty()) ch.order_reason += fmt::format("; on the final data smaller orders fit worse ({})", tried);
    return false;
  }
  ch.order_reason += fmt::format("; on the final data order {} was reduced to {}: orders {} (first-stage cost per "
                                 "degree of freedom; {:.4g} at order {}) (tail rounds rerun)",
                                 top, lower, tried, per_dof(top_small), top);
  fit = std::move(lower_fit);
  for (Index K = 2 * run.K0; K <= run.L; K *= 2)
    fit = fit_plant_closed_loop(run.bins_at(g_final, run.spectrum, K), run.controller, fit.plant, fo);
  return true;
}

}  // namespace lpvid::identify_detail
