// lpvid — diagnose's combinations of candidates (pairs, triples): see candidates.h.
#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include "idlib/core/progress.h"
#include "idlib/diagnose/candidates.h"

namespace lpvid {
namespace diagnose_detail {

namespace {

std::string joined(const std::vector<std::string>& members) { return fmt::format("{}", fmt::join(members, " + ")); }


// Modes are interchangeable: {structural_mode_2} is the candidate {structural_mode},
// {structural_mode, structural_mode_3} the candidate {structural_mode, structural_mode_2}.
std::vector<std::string> modes_renumbered(const std::vector<std::string>& members) {
  std::vector<std::string> out;
  int modes = 0;
  for (const std::string& m : members)
    if (is_mode_effect(m))
      ++modes;
    else
      out.push_back(m);
  for (int k = 1; k <= modes; ++k) out.push_back(k == 1 ? "structural_mode" : fmt::format("structural_mode_{}", k));
  return out;
}

// The members of a combination but the k-th.
std::vector<std::string> without_member(const std::vector<std::string>& members, std::size_t k) {
  std::vector<std::string> rest;
  for (std::size_t j = 0; j < members.size(); ++j)
    if (j != k) rest.push_back(members[j]);
  return rest;
}

bool same_members(std::vector<std::string> a, std::vector<std::string> b) {
  a = modes_renumbered(a);
  b = modes_renumbered(b);
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b;
}

// Tests every member of a fitted combination against the combination without it
// (found in `smaller`: the singles for a pair, the pairs for a triple); a member is
// needed when removing it raises the error and worsens ΔBIC by more than the
// significance margin.  A significant combination with a member it does not need is
// not significant.
void judge_members(CandidateOutcome& c, const std::vector<const CandidateOutcome*>& smaller,
                   const CandidateContext& ctx) {
  c.member_shares.assign(c.members.size(), 0.0);
  c.member_needed.assign(c.members.size(), false);
  c.member_without_error.assign(c.members.size(), std::numeric_limits<double>::quiet_NaN());
  c.member_without_delta_bic.assign(c.members.size(), std::numeric_limits<double>::quiet_NaN());
  if (!c.fitted) return;
  std::vector<std::string> idle;
  for (std::size_t k = 0; k < c.members.size(); ++k) {
    const std::vector<std::string> rest = without_member(c.members, k);
    const CandidateOutcome* without = nullptr;
    for (const CandidateOutcome* o : smaller)
      if (o->fitted && same_members(o->members, rest)) without = o;
    if (without == nullptr) {
      idle.push_back(fmt::format("{} (the fit without it failed)", c.members[k]));
      continue;
    }
    const double e = c.error, ew = without->error;
    c.member_without_error[k] = ew;
    c.member_without_delta_bic[k] = without->delta_bic;
    c.member_shares[k] = ctx.excess2 > 0 ? (ew * ew - e * e) / ctx.excess2 : 0.0;
    c.member_needed[k] = e < ew && c.delta_bic - without->delta_bic < -ctx.options.significance_delta_bic;
    if (!c.member_needed[k])
      idle.push_back(fmt::format("{} (without it: error {} against {}, ΔBIC {:+.1f})", c.members[k], percent(ew),
                                 percent(e), without->delta_bic - c.delta_bic));
  }
  if (c.significant && !idle.empty()) {
    c.significant = false;
    c.verdict = fmt::format("not significant: it does not need {}", fmt::join(idle, ", "));
  }
}

void rank(std::vector<CandidateOutcome>& v) {
  std::stable_sort(v.begin(), v.end(), [](const CandidateOutcome& a, const CandidateOutcome& b) {
    if (a.fitted != b.fitted) return a.fitted;
    if (a.significant != b.significant) return a.significant;
    if (a.significant) return a.delta_bic < b.delta_bic;
    return a.error < b.error;
  });
}

// The pairs a triple's members are judged against (judge_members) that were never
// fitted: only the anchor's and the pool's pairs are, so a triple grown from the best
// pair may reach the floor without that pair's first member while the pair of its other
// two was never tried (independent plant, delay + mode hidden, a design 0.68x off,
// trial seed 1101: the triple lag + mode + delay 0.133 % against a 0.126 % floor,
// refused for want of mode + delay, and the loop stopped at 7.99 %).  Each is fitted
// from its member with the better ΔBIC (as the pool's pairs), judged against the
// singles and appended to `out`.
void fit_missing_pairs(const std::vector<CandidateOutcome>& triples, const CandidateOutcome& best_pair,
                       const std::vector<const CandidateOutcome*>& fitted_singles, std::vector<CandidateOutcome>& out,
                       const CandidateContext& ctx) {
  auto single = [&](const std::string& name) -> const CandidateOutcome* {
    for (const CandidateOutcome* c : fitted_singles)
      if (c->effect == name) return c;
    return nullptr;
  };
  std::vector<CandidateOutcome> missing;
  std::vector<const CandidateOutcome*> from;
  for (const CandidateOutcome& t : triples) {
    if (!t.fitted || !(t.error < best_pair.error)) continue;
    for (std::size_t k = 0; k < t.members.size(); ++k) {
      const std::vector<std::string> rest = without_member(t.members, k);
      bool have = false;
      for (const CandidateOutcome& c : out) have = have || same_members(c.members, rest);
      for (const CandidateOutcome& c : missing) have = have || same_members(c.members, rest);
      const CandidateOutcome *a = single(rest[0]), *b = rest.size() == 2 ? single(rest[1]) : nullptr;
      if (have || a == nullptr || b == nullptr) continue;
      if (b->delta_bic < a->delta_bic) std::swap(a, b);
      CandidateOutcome c;
      c.members = {a->effect, b->effect};
      c.effect = joined(c.members);
      missing.push_back(std::move(c));
      from.push_back(a);
    }
  }
  if (missing.empty()) return;
  ParallelSteps steps(ctx.options.progress, "diagnose", "pair", static_cast<Index>(missing.size()));
  parallel_for(missing.size(), [&](std::size_t i) {
    steps.start(missing[i].effect);
    evaluate_candidate(missing[i], from[i]->fit.model, from[i]->phenomena, ctx);
    steps.finish(missing[i].effect);
  });
  for (CandidateOutcome& c : missing) {
    judge_members(c, fitted_singles, ctx);
    out.push_back(std::move(c));
  }
}

// A triple that beats the pair of its other two members with a member that ended on
// a bound: that member may be idle, the bound the value where its effect vanishes (a
// delay of 0), and the triple's fit a better basin of that pair than the pair's own
// refit reached.  The pair is refitted locally from the triple's fit with the member
// removed and replaces the pair in `out` when it ends lower (judged against the
// singles), so the triple is then judged against the pair at its best.  Measured on
// the independent platform, rod twist 3.9x / 2.8x the bending and the centre-of-mass
// offset hidden, lpvid's rods (seed 222; bending scales on their bounds): the pair's
// own refits stopped at 18.7 %, rod twist + input delay + com_offset reached 0.0792 %
// for a 0.0778 % floor with the delay at 0, and the pair from there ends at the same.
void pairs_from_idle_members(const std::vector<CandidateOutcome>& triples, const CandidateOutcome& best_pair,
                             const std::vector<const CandidateOutcome*>& fitted_singles,
                             std::vector<CandidateOutcome>& out, const CandidateContext& ctx) {
  std::vector<CandidateOutcome> reduced;
  std::vector<PhysicalModel> starts;
  for (const CandidateOutcome& t : triples) {
    if (!t.fitted || !t.own_parameter_at_bound || !(t.error < best_pair.error)) continue;
    for (std::size_t k = 0; k < t.members.size(); ++k) {
      bool at_bound = false;
      for (const ParameterEstimate& p : t.effect_parameters)
        for (const PhysicalParameter& q : t.fit.model.effect_info(t.members[k])->parameters)
          at_bound = at_bound || (p.name == q.name && p.at_bound);
      if (!at_bound) continue;
      const std::vector<std::string> rest = without_member(t.members, k);
      bool better = true;
      for (const CandidateOutcome& c : out)
        if (c.fitted && same_members(c.members, rest)) better = better && t.error < c.error;
      for (const CandidateOutcome& c : reduced)
        if (same_members(c.members, rest)) better = false;
      if (!better) continue;
      CandidateOutcome c;
      c.members = rest;
      c.effect = joined(rest);
      reduced.push_back(std::move(c));
      starts.push_back(t.fit.model);
      starts.back().remove_effect(t.members[k]);
    }
  }
  if (reduced.empty()) return;
  FitOptions local = ctx.refit;
  local.global_start = false;  // from the triple's fit: a local refit
  local.extra_starts.clear();
  ParallelSteps steps(ctx.options.progress, "diagnose", "pair", static_cast<Index>(reduced.size()));
  parallel_for(reduced.size(), [&](std::size_t i) {
    steps.start(reduced[i].effect);
    try {
      reduced[i].fit = fit_physical_model(starts[i], ctx.data, local);
      reduced[i].fitted = true;
      judge_fitted(reduced[i], local, ctx);
    } catch (const NumericalError&) {
      reduced[i].fitted = false;  // the pair's own fit stands
    }
    steps.finish(reduced[i].effect);
  });
  for (CandidateOutcome& c : reduced) {
    if (!c.fitted) continue;
    judge_members(c, fitted_singles, ctx);
    auto same = std::find_if(out.begin(), out.end(), [&](const CandidateOutcome& o) { return same_members(o.members, c.members); });
    if (same == out.end()) {
      out.push_back(std::move(c));
    } else if (!same->fitted || c.error < same->error) {
      *same = std::move(c);
    }
  }
}

}  // namespace

std::vector<CandidateOutcome> evaluate_combinations(const std::vector<CandidateOutcome>& singles,
                                                    const CandidateContext& ctx) {
  const DiagnoseOptions& o = ctx.options;
  // The pool: the fitted singles that lower the error or BIC by the margin, best
  // ΔBIC first.  By ΔBIC, not by error: an effect whose partner is missing can fit
  // the data better in likelihood while its unweighted error rises (a coil lag
  // beside a missing centre-of-mass offset, seed 221: ΔBIC −2879, error 16.36 % for
  // 16.31 %).
  std::vector<const CandidateOutcome*> pool;
  for (const CandidateOutcome& c : singles)
    if (c.fitted && (c.error < ctx.d.baseline_error || c.delta_bic < -o.significance_delta_bic)) pool.push_back(&c);
  std::stable_sort(pool.begin(), pool.end(),
                   [](const CandidateOutcome* a, const CandidateOutcome* b) { return a->delta_bic < b->delta_bic; });
  if (pool.size() > static_cast<std::size_t>(o.combination_pool)) pool.resize(static_cast<std::size_t>(o.combination_pool));
  // The anchor: the single with the lowest error (the greedy step by the error
  // figure).  It is paired with EVERY other candidate, fitted from its fit: an
  // effect hidden behind a larger one shows only once that one is in (a 0.9-sample
  // delay beside a centre-of-mass offset, seed 221: alone the delay ends at 0).
  const CandidateOutcome* anchor = nullptr;
  for (const CandidateOutcome& c : singles)
    if (c.fitted && c.error < ctx.d.baseline_error && (anchor == nullptr || c.error < anchor->error)) anchor = &c;
  std::vector<CandidateOutcome> pairs;
  std::vector<const CandidateOutcome*> from;
  if (o.max_combination < 2) return pairs;
  auto add_pair = [&](const CandidateOutcome* a, const CandidateOutcome* b) {
    for (const CandidateOutcome& c : pairs)
      if (same_members(c.members, {a->effect, b->effect})) return;
    CandidateOutcome c;
    c.members = {a->effect, b->effect};
    c.effect = joined(c.members);
    pairs.push_back(std::move(c));
    from.push_back(a);
  };
  if (anchor != nullptr)
    for (const CandidateOutcome& c : singles)
      if (c.fitted && &c != anchor) add_pair(anchor, &c);
  // Two modes at once: a structure with several unmodelled modes (a base offering
  // more than one, idlib/physical/mechanical) — the anchor mode and the next one,
  // seeded from what the anchor's fit leaves.
  CandidateOutcome next_mode;
  if (anchor != nullptr && is_mode_effect(anchor->effect)) {
    for (const EffectInfo& e : ctx.given.library())
      if (is_mode_effect(e.name) && e.name != anchor->effect && !ctx.given.has_effect(e.name)) {
        next_mode.effect = e.name;
        next_mode.members = {e.name};
        add_pair(anchor, &next_mode);
        break;
      }
  }
  // the pool's pairs, each from its member with the better ΔBIC (the pool is sorted by it)
  for (std::size_t i = 0; i < pool.size(); ++i)
    for (std::size_t j = i + 1; j < pool.size(); ++j) add_pair(pool[i], pool[j]);
  if (pairs.empty()) return pairs;
  {
    ParallelSteps steps(o.progress, "diagnose", "pair", static_cast<Index>(pairs.size()));
    parallel_for(pairs.size(), [&](std::size_t i) {
      steps.start(pairs[i].effect);
      evaluate_candidate(pairs[i], from[i]->fit.model, from[i]->phenomena, ctx);
      steps.finish(pairs[i].effect);
    });
  }
  std::vector<const CandidateOutcome*> fitted_singles;
  for (const CandidateOutcome& c : singles)
    if (c.fitted) fitted_singles.push_back(&c);
  for (CandidateOutcome& c : pairs) judge_members(c, fitted_singles, ctx);
  rank(pairs);
  std::vector<CandidateOutcome> out = std::move(pairs);
  // Triples: the best significant pair — or, with none significant, the pair with
  // the lowest error when it explains at least min_excess_share (a pair can fail the
  // band test only because a third effect is missing: lpvid's default rods, a
  // centre-of-mass offset and a coil lag, trial seed 1100: com_offset + rod_twist
  // 1.21 % for 19.5 %, 33 % of the bands) — with every other candidate, when it
  // leaves an excess.
  std::size_t pick = 0;
  if (!out.front().significant)
    for (std::size_t i = 1; i < out.size(); ++i)
      if (out[i].fitted && (!out[pick].fitted || out[i].error < out[pick].error)) pick = i;
  const CandidateOutcome& best = out[pick];
  const bool promising = best.significant || best.excess_share >= o.min_excess_share;
  if (o.max_combination >= 3 && best.fitted && promising && !leaves_only_noise(best, ctx)) {
    std::vector<CandidateOutcome> triples;
    for (const CandidateOutcome* third : fitted_singles) {
      if (std::find(best.members.begin(), best.members.end(), third->effect) != best.members.end()) continue;
      CandidateOutcome c;
      c.members = best.members;
      c.members.push_back(third->effect);
      c.effect = joined(c.members);
      triples.push_back(std::move(c));
    }
    const CandidateOutcome best_pair = best;  // out grows below
    ParallelSteps steps(o.progress, "diagnose", "triple", static_cast<Index>(triples.size()));
    parallel_for(triples.size(), [&](std::size_t i) {
      steps.start(triples[i].effect);
      evaluate_candidate(triples[i], best_pair.fit.model, best_pair.phenomena, ctx);
      steps.finish(triples[i].effect);
    });
    fit_missing_pairs(triples, best_pair, fitted_singles, out, ctx);
    pairs_from_idle_members(triples, best_pair, fitted_singles, out, ctx);
    std::vector<const CandidateOutcome*> sub;
    for (const CandidateOutcome& c : out) sub.push_back(&c);
    for (CandidateOutcome& c : triples) judge_members(c, sub, ctx);
    for (CandidateOutcome& c : triples) out.push_back(std::move(c));
    rank(out);
  }
  return out;
}

}  // namespace diagnose_detail
}  // namespace lpvid
