// lpvid — diagnose's report in words (Diagnosis::summary): what the model misses,
// what explains it, what the data cannot separate and what would, from the outcomes
// diagnose() found (diagnose.cc).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "idlib/diagnose/candidates.h"

namespace lpvid::diagnose_detail {
namespace {

void describe_phenomena(const std::vector<Phenomenon>& phenomena, const std::vector<FitDataset>& data,
                        std::vector<std::string>& lines, std::size_t limit) {
  // as the user reads them: the largest share of the error figure first
  const std::vector<Phenomenon> ranked = ranked_by_error_share(phenomena);
  for (std::size_t k = 0; k < std::min(limit, ranked.size()); ++k) {
    const Phenomenon& ph = ranked[k];
    const FailingBand& b = ph.bands.front();
    std::string at;
    if (ph.data_sets.size() == data.size() && data.size() > 1) {
      at = fmt::format("at all {} data sets", data.size());
    } else {
      std::vector<std::string> xs;
      for (Index d : ph.data_sets) {
        const FitDataset& ds = data[static_cast<std::size_t>(d)];
        // a base without a scheduling variable: the data set's name
        xs.push_back(std::isnan(ds.beam_position_m) ? ds.label : fmt::format("{:g}", ds.beam_position_m));
      }
      at = fmt::format("at {} {}", ph.data_sets.size() == 1 ? "data set" : "data sets", fmt::join(xs, ", "));
    }
    // gain and phase of data over model: none where the model is zero there (a
    // coupling the model lacks)
    const std::string ratio = std::isfinite(b.gain_db_max) && std::isfinite(b.phase_deg_max)
                                  ? fmt::format("{:+.2f} dB, {:+.1f} deg", b.gain_db_max, b.phase_deg_max)
                                  : std::string("the model is 0 there");
    // the size against the error figure's scale, and the share of the figure it holds
    lines.push_back(fmt::format("  {}. near {:.4g} rad/s in {}, {}: {:.2g} % of the error, up to {:.3g} % ({}), "
                                "{:.0f}x the noise; {}",
                                k + 1, ph.omega_rad_s, ph.where, at, 100.0 * ph.error_share, b.scaled_percent_max,
                                ratio, b.max_sigma_ratio, b.hint));
  }
  if (phenomena.size() > limit) lines.push_back(fmt::format("  ... and {} more", phenomena.size() - limit));
}

// The model's error against the floor, and where it fails.
void summary_baseline(Diagnosis& out, const SummaryInputs& in) {
  std::vector<std::string>& s = out.summary;
  const std::vector<FitDataset>& data = in.data;
  const double f = out.effective_floor, e0 = out.baseline_error;
  const std::string floor_text =
      std::isfinite(out.noise_floor)
          ? fmt::format("noise floor {} (from {}{})", percent(out.noise_floor), out.noise_source,
                        f > out.noise_floor * 1.0001 ? fmt::format("; {} with lpvid's resolution", percent(f)) : "")
          : fmt::format("noise floor unknown; lpvid's resolution {}", percent(f));
  s.push_back(fmt::format("model with {} free parameters: error {} (rms over the channels of the relative rms error); "
                          "{}",
                          out.baseline.parameters.size(), percent(e0), floor_text));
  if (std::isfinite(out.noise_weighted_baseline_error))
    s.push_back(fmt::format("weights: weighted by the noise alone this model scores {}, a model error, not noise; "
                            "the error figures here are those of fits with each line weighed by its noise plus a "
                            "model error ({} of the response for this model), as `lpvid fit --weighting auto` "
                            "reaches them; ΔBIC is the noise-weighted fits' (docs/math.md, \"Weights when the "
                            "model fails\")",
                            percent(out.noise_weighted_baseline_error), percent(out.model_error_weight)));
  std::size_t nb = 0;
  for (const auto& set : out.baseline_failures) nb += set.size();
  if (nb == 0) {
    s.push_back("where it fails: nowhere beyond the measurement noise (no failing band)");
  } else {
    s.push_back(fmt::format("where it fails ({} distinct phenomena in {} failing bands, largest share of the error first):",
                            out.phenomena.size(), nb));
    describe_phenomena(out.phenomena, data, s, 5);
  }
}

// A baseline on its bounds: the design values the data want (DesignHint).
void summary_design(Diagnosis& out) {
  std::vector<std::string>& s = out.summary;
  const double e0 = out.baseline_error;
  std::vector<std::string> pinned;
  for (const ParameterEstimate& p : out.baseline.parameters)
    if (p.at_bound)
      pinned.push_back(fmt::format("{} = {:.4g}", p.name, p.estimate));
  s.push_back(fmt::format("the base cannot follow the data within its physical ranges: {} ended on a bound (candidates "
                          "are refitted from the model as given)",
                          fmt::join(pinned, ", ")));
  // what the data want, and which design value to set
  std::vector<std::string> sets;
  for (const DesignHint& h : out.design_hints) {
    if (!std::isfinite(h.wanted)) continue;
    std::string line =
        h.design.empty()
            ? fmt::format("  with its bounds widened tenfold the data want {} = {:.4g} (bounds [{:g}, {:g}]",
                          h.parameter, h.wanted, h.lower, h.upper)
            : fmt::format("  the data want {} × {} = {:.4g} × {:.4g} (the scale's bounds [{:g}, {:g}]", h.design,
                          h.parameter, h.design_value, h.wanted, h.lower, h.upper);
    line += std::isfinite(out.widened_error) ? fmt::format("; error {} -> {})", percent(e0), percent(out.widened_error))
                                             : std::string(")");
    if (!h.design.empty()) {
      line += fmt::format(": the design value {} = {:.4g} is off by {:.3g}x; set {} ≈ {:.4g}", h.design, h.design_value,
                          h.wanted, h.design, h.suggested);
      sets.push_back(fmt::format("{}={:.4g}", h.design, h.suggested));
    }
    if (!h.effects.empty())
      line += fmt::format("{} add {} (it carries what lies beyond the design)", h.design.empty() ? "; or" : ", or",
                          fmt::join(h.effects, " or "));
    s.push_back(line);
  }
  if (!sets.empty()) {
    // several scales of one design value: their geometric mean, the scales take the rest
    std::vector<std::pair<std::string, std::vector<double>>> by_design;
    for (const DesignHint& h : out.design_hints) {
      if (h.design.empty() || !std::isfinite(h.wanted)) continue;
      auto it = std::find_if(by_design.begin(), by_design.end(), [&](const auto& x) { return x.first == h.design; });
      if (it == by_design.end()) by_design.push_back({h.design, {h.suggested}});
      else it->second.push_back(h.suggested);
    }
    std::vector<std::string> lines;
    for (const auto& [design, values] : by_design) {
      double log_sum = 0;
      for (double v : values) log_sum += std::log(v);
      lines.push_back(fmt::format("--set {}={:.4g}", design, std::exp(log_sum / static_cast<double>(values.size()))));
    }
    s.push_back(fmt::format("  to start from the design the data ask for: lpvid model init --out model.json {} (or "
                            "lpvid model set --model MODEL {}), then fit and diagnose again",
                            fmt::join(lines, " "), fmt::join(lines, " ")));
  }
}

// Nothing beyond the noise.
void summary_nothing(Diagnosis& out, const SummaryInputs& in) {
  std::vector<std::string>& s = out.summary;
  const DiagnoseOptions& options = in.options;
  const double f = out.effective_floor, e0 = out.baseline_error;
  s.push_back(fmt::format("nothing to explain: the model fits within the noise (error {} <= {:g} x {}, no failing "
                          "band); no candidate is significant",
                          percent(e0), options.explained_ratio, percent(f)));
  // What these data cannot see (a frequency response alone): an input gain is a
  // scaling of M, D and K; only a known value tells them apart.
  bool any_prior = false;
  for (const PhysicalParameter& q : out.baseline.model.parameters) any_prior = any_prior || q.has_prior();
  // An input gain by what the effect is (every block a gain on the inputs: the library's
  // gain_error, or a user's effect of that kind), not by its name.
  auto input_gain = [&](const std::string& name) {
    const EffectInfo* e = in.model.effect_info(name);
    if (e == nullptr || e->blocks.empty()) return false;
    for (const Block& b : e->blocks)
      if (b.kind != BlockKind::kGain || b.side != BlockSide::kInput) return false;
    return true;
  };
  bool gain_candidate = false;
  for (const CandidateOutcome& c : out.ranked) gain_candidate = gain_candidate || (c.members.size() <= 1 && input_gain(c.effect));
  if (!any_prior && gain_candidate)
    s.push_back("  note: these data cannot tell an input gain from a scaling of the masses, damping and stiffness "
                "(the fit takes the scaling); to test for one, give a known value as a prior (a weighed mass: lpvid "
                "model set --model MODEL --set NAME=VALUE±SIGMA) and diagnose again");
}

// The winner: what it is, what it explains, what ties with it, what is left.
void summary_winner(Diagnosis& out, const SummaryInputs& in) {
  std::vector<std::string>& s = out.summary;
  const DiagnoseOptions& options = in.options;
  const std::vector<FitDataset>& data = in.data;
  const PhysicalModel& model = in.model;
  const CandidateOutcome* winner = in.winner;
  const double f = out.effective_floor, e0 = out.baseline_error;
  const bool combination = winner->members.size() > 1;
  // what each member does alone (combinations)
  auto single = [&](const std::string& name) -> const CandidateOutcome* {
    for (const CandidateOutcome& c : out.ranked)
      if (c.effect == name && c.fitted) return &c;
    return nullptr;
  };
  if (!combination) {
    const EffectInfo* info = model.effect_info(winner->effect);
    s.push_back(fmt::format("missing: {} — {}", winner->effect, info->description));
    s.push_back(fmt::format("  it explains: {}", info->signature));
  } else {
    const bool none_alone = out.ranked.empty() || !out.ranked.front().significant;
    s.push_back(fmt::format("missing: {} effects together — {}", winner->members.size(),
                            none_alone ? "no single one is significant alone"
                                       : fmt::format("{} alone leaves {}", out.ranked.front().effect,
                                                     percent(out.ranked.front().error))));
    for (std::size_t k = 0; k < winner->members.size(); ++k) {
      const EffectInfo* info = model.effect_info(winner->members[k]);
      const CandidateOutcome* alone = single(winner->members[k]);
      const double ew = winner->member_without_error[k];
      s.push_back(fmt::format("  {} — {}", winner->members[k], info->description));
      s.push_back(fmt::format("    without it: error {} ({:.3g}x higher), ΔBIC {:+.1f}{}", percent(ew),
                              winner->error > 0 ? ew / winner->error : INFINITY,
                              winner->member_without_delta_bic[k] - winner->delta_bic,
                              alone != nullptr ? fmt::format("; alone: error {}, {:.0f} % of the excess ({})",
                                                             percent(alone->error), 100.0 * alone->excess_share,
                                                             alone->verdict)
                                               : std::string()));
    }
  }
  s.push_back(fmt::format("  error {} -> {} ({:.1f}x lower): {:.0f} % of the excess above the noise floor, {:.0f} % of "
                          "the failing-band points; ΔBIC {:.1f}",
                          percent(e0), percent(winner->error), winner->error > 0 ? e0 / winner->error : INFINITY,
                          100.0 * winner->excess_share, 100.0 * winner->band_share, winner->delta_bic));
  // what the priors say (a tie the data alone cannot break)
  if (out.baseline.priors_contradicted > 0) {
    // The estimates the fit flagged as pulled beyond kPriorPullFlag sigmas, and where the
    // winner's fit leaves them (its own flag): said as it is, returned or not.
    std::vector<std::string> pulls;
    Index returned = 0;
    for (const ParameterEstimate& b : out.baseline.parameters)
      if (b.prior_contradicted)
        for (const ParameterEstimate& w : winner->fit.parameters)
          if (w.name == b.name) {
            const double pull = w.prior_sigma > 0 ? (w.estimate - w.prior_mean) / w.prior_sigma : 0.0;
            if (!w.prior_contradicted) ++returned;
            pulls.push_back(fmt::format("{} {:.4g} -> {:.4g} ({:+.1f} -> {:+.1f} sigma)", b.name, b.estimate,
                                        w.estimate, (b.estimate - b.prior_mean) / b.prior_sigma, pull));
          }
    const std::string said =
        returned == static_cast<Index>(pulls.size())
            ? std::string("with it the estimates return to their priors")
            : returned == 0 ? fmt::format("with it the estimates stay beyond {:g} sigma of their priors", kPriorPullFlag)
                            : fmt::format("with it {} of the {} estimates beyond {:g} sigma return to their priors",
                                          returned, pulls.size(), kPriorPullFlag);
    s.push_back(fmt::format("  {} ({}; the priors' chi-square {:.1f} -> {:.1f}){}", said, fmt::join(pulls, ", "),
                            out.baseline.prior_cost, winner->fit.prior_cost,
                            winner->error > e0 * 0.99 ? ": the data alone fit both equally; the priors decide" : ""));
  }
  if (!out.separated_by_priors.empty())
    s.push_back(fmt::format("  {} {} the data as well but not the priors (the priors' chi-square more than {:g} above "
                            "the winner's): the priors separate {} from {}",
                            fmt::join(out.separated_by_priors, ", "),
                            out.separated_by_priors.size() == 1 ? "fits" : "fit", options.significance_delta_bic,
                            out.separated_by_priors.size() == 1 ? "it" : "them", winner->effect));
  for (const ParameterEstimate& p : winner->effect_parameters)
    s.push_back(fmt::format("  {} = {:.6g} ± {:.2g} {}", p.name, p.estimate, p.std_error, p.unit));
  if (combination)
    s.push_back(fmt::format("  to add them: lpvid model add {} --model MODEL --from-diagnosis REPORT.json (the values "
                            "above as the start), then lpvid fit",
                            fmt::join(winner->members, ",")));
  const std::vector<CandidateOutcome>& list = combination ? out.combinations : out.ranked;
  const CandidateOutcome* second = nullptr;
  for (const CandidateOutcome& c : list)
    if (&c != winner && c.fitted && second == nullptr) second = &c;
  if (second != nullptr)
    s.push_back(fmt::format("  runner-up: {} (error {}, {:.0f} % of the excess; {})", second->effect,
                            percent(second->error), 100.0 * second->excess_share, second->verdict));
  const auto outcome = [&](const std::string& name) -> const CandidateOutcome* {
    for (const CandidateOutcome& c : list)
      if (c.effect == name) return &c;
    return nullptr;
  };
  if (!out.indistinguishable.empty()) {
    // what would separate them: a prior on a parameter of their own (a datasheet's
    // value can be given before the effect is added) or on a base parameter
    std::vector<std::string> own, gaps;
    for (const ParameterEstimate& p : winner->effect_parameters) own.push_back(p.name);
    for (const std::string& name : out.indistinguishable)
      if (const CandidateOutcome* c = outcome(name)) {
        for (const ParameterEstimate& p : c->effect_parameters)
          if (std::find(own.begin(), own.end(), p.name) == own.end()) own.push_back(p.name);
        gaps.push_back(fmt::format("{:+.1f}", c->fit.bic - winner->fit.bic));
      }
    if (own.size() > 4) own.resize(4);
    s.push_back(fmt::format(
        "  indistinguishable on these data from {}: {} {}, and the data's BIC differs from {}'s by {} (within {:g}). "
        "What would separate them: a prior on a parameter one of them moves (lpvid model set --set NAME=VALUE±SIGMA, "
        "e.g. on {}, from a datasheet, even before the effect is added; or a weighed mass, a datasheet force constant "
        "or stiffness), or another experiment (another operating point, a static test, a longer or less noisy "
        "measurement, a wider band)",
        fmt::join(out.indistinguishable, ", "), out.indistinguishable.size() == 1 ? "it leaves" : "they leave",
        out.explained || outcome(out.indistinguishable.front()) == nullptr
            ? std::string("the error within the noise too")
            : fmt::format("the error at {} against {}", percent(outcome(out.indistinguishable.front())->error),
                          percent(winner->error)),
        winner->effect,
        fmt::join(gaps, ", "), options.significance_delta_bic, fmt::join(own, " or ")));
  }
  if (!out.also_explain.empty()) {
    std::vector<std::string> each;
    for (const std::string& name : out.also_explain)
      if (const CandidateOutcome* c = outcome(name))
        each.push_back(fmt::format("{}{}, ΔBIC {:+.1f} on the data", out.also_explain.size() == 1 ? "" : name + " ",
                                   percent(c->error), c->fit.bic - winner->fit.bic));
    s.push_back(fmt::format("  {} also {} the error within the noise ({}), but the likelihood, line by line, prefers {}: "
                            "the data separate them",
                            fmt::join(out.also_explain, ", "), out.also_explain.size() == 1 ? "brings" : "bring",
                            fmt::join(each, "; "), winner->effect));
  }
  if (out.explained) {
    s.push_back(fmt::format("  explained: with it the error is within the noise ({} <= {:g} x {})",
                            percent(winner->error), options.explained_ratio, percent(f)));
  } else {
    s.push_back(fmt::format("  partly explained: with it the error {} is still above {:g} x the noise floor; still "
                            "failing:",
                            percent(winner->error), options.explained_ratio));
    describe_phenomena(out.remaining_phenomena, data, s, 3);
  }
}

// No candidate significant: the closest ones.
void summary_unexplained(Diagnosis& out, const SummaryInputs& in) {
  std::vector<std::string>& s = out.summary;
  const DiagnoseOptions& options = in.options;
  s.push_back(out.combinations.empty()
                  ? "not explained: no effect the model could add explains the excess error"
                  : fmt::format("not explained: no effect the model could add, nor a pair{} of them, explains the "
                                "excess error",
                                options.max_combination >= 3 ? " or triple" : ""));
  if (!out.ranked.empty() && out.ranked.front().fitted)
    s.push_back(fmt::format("  closest candidate: {} (error {}, {:.0f} % of the excess; {})", out.ranked.front().effect,
                            percent(out.ranked.front().error), 100.0 * out.ranked.front().excess_share,
                            out.ranked.front().verdict));
  if (!out.combinations.empty() && out.combinations.front().fitted)
    s.push_back(fmt::format("  closest combination: {} (error {}, {:.0f} % of the excess; {})",
                            out.combinations.front().effect, percent(out.combinations.front().error),
                            100.0 * out.combinations.front().excess_share, out.combinations.front().verdict));
  // The cost and the figure disagree: a candidate the data's likelihood wants that
  // raises the noise-weighted figure.  Say why, and what judges by the figure.
  if (!options.model_error_weighting) {
    const double e0 = out.baseline_error;
    for (const CandidateOutcome& c : out.ranked)
      if (c.fitted && c.delta_bic < -options.significance_delta_bic && c.error > e0 * 1.001 &&
          e0 > options.explained_ratio * out.effective_floor) {
        s.push_back(fmt::format(
            "  the cost and the error figure disagree: {} lowers the noise-weighted cost (ΔBIC {:.1f}) but raises the "
            "figure from {} to {}; the model fails by far more than the noise, and weighted by the noise alone a fit "
            "spends its freedom on the most precisely measured lines; --weighting auto (here and in fit) judges "
            "every model by the figure a fit with the model error in its weights reaches (docs/math.md, \"Weights "
            "when the model fails\")",
            c.effect, c.delta_bic, percent(e0), percent(c.error)));
        break;
      }
  }
}

// What no library effect explains, as a low-order error model.
void summary_description(Diagnosis& out, const SummaryInputs& in) {
  std::vector<std::string>& s = out.summary;
  const DiagnoseOptions& options = in.options;
  const CandidateOutcome* winner = in.winner;
  const double e0 = out.baseline_error;
  if (!out.descriptions.empty()) {
    const ResidualDescription& r = out.descriptions.front();
    s.push_back(fmt::format("  the residual looks like {}: error {} -> {} ({:.0f} % of the excess)", r.text,
                            percent(winner != nullptr ? winner->error : e0), percent(r.error), 100.0 * r.excess_share));
    s.push_back(fmt::format("  to model it, define a user-defined effect like '{}' (lpvid diagnose --out-effect writes it; "
                            "docs/effects.md)",
                            r.effect.name));
  } else if (options.describe && in.left) {
    s.push_back("  no low-order error model (a resonance or lag in one row or column) describes the residual either");
  }
}

}  // namespace

// Effects of the model the data do not need (Diagnosis::idle_effects).
void summary_idle(Diagnosis& out) {
  for (const IdleEffect& e : out.idle_effects)
    out.summary.push_back(fmt::format(
        "idle: {} adds nothing the data need ({}): refitted without it the error is {} ({} with it), ΔBIC {:+.1f}; "
        "remove it: lpvid model remove {} --model MODEL, then fit",
        e.effect, e.why_tried, percent(e.error_without), percent(out.baseline_error), e.delta_bic, e.effect));
}

void summarise(Diagnosis& out, const SummaryInputs& in) {
  summary_baseline(out, in);
  summary_idle(out);
  if (in.distorted) summary_design(out);
  if (!in.something)
    summary_nothing(out, in);
  else if (in.winner != nullptr)
    summary_winner(out, in);
  else
    summary_unexplained(out, in);
  summary_description(out, in);
}

}  // namespace lpvid::diagnose_detail
