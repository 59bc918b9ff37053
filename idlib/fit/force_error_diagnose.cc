// lpvid — the force-error route's model-error loop (diagnose_force_error) and where a
// force-error fit fails in time (force_error_failing_windows); idlib/fit/force_error.h,
// docs/math.md §9b.  The data and the fit: idlib/fit/force_error.cc.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/fit/force_error.h"
#include "idlib/fit/force_error_detail.h"

namespace lpvid {

namespace {

using Eigen::VectorXd;
using force_error_detail::is_time_effect;
using force_error_detail::rms;
using force_error_detail::time_effect_names;

// Where in speed the residual sits: its rms over the slowest quarter of the samples
// against the fastest half.  Viscous and Coulomb friction leave no speed pattern once
// fitted; a residual that grows towards standstill is a friction the library lacks
// (the Stribeck rise of static friction above the Coulomb level).
// The reading (Stribeck) is offered only for a model that has Coulomb friction: without
// it a viscous term stands in for the missing constant force and leaves a residual that
// grows at low speed by itself (measured: 3.7x on a one-way ramp with Coulomb friction and
// an offset missing).
std::string low_speed_signature(const VectorXd& r, const VectorXd& v, const std::string& dof,
                                const std::string& unit, bool has_coulomb, bool has_stribeck) {
  std::vector<double> speed(static_cast<std::size_t>(v.size()));
  for (Index k = 0; k < v.size(); ++k) speed[static_cast<std::size_t>(k)] = std::abs(v(k));
  std::vector<double> sorted = speed;
  const auto at = [&](double f) {
    const auto k = static_cast<std::ptrdiff_t>(f * static_cast<double>(sorted.size() - 1));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    return sorted[static_cast<std::size_t>(k)];
  };
  const double slow = at(0.25), fast = at(0.5);
  double s2 = 0.0, f2 = 0.0;
  Index ns = 0, nf = 0;
  for (Index k = 0; k < r.size(); ++k) {
    const double a = speed[static_cast<std::size_t>(k)];
    if (a <= slow) s2 += r(k) * r(k), ++ns;
    if (a >= fast) f2 += r(k) * r(k), ++nf;
  }
  if (ns == 0 || nf == 0 || !(f2 > 0.0)) return fmt::format("{}: too few samples to see where in speed the residual sits", dof);
  const double ratio = std::sqrt((s2 / static_cast<double>(ns)) / (f2 / static_cast<double>(nf)));
  return fmt::format("{}: the residual's rms is {:.2f}x as large at low speed (the slowest quarter of the samples, "
                     "|v| < {:.3g} {}/s) as in the fastest half{}",
                     dof, ratio, slow, unit,
                     ratio > 2.0 && has_coulomb
                         ? (has_stribeck ? ": a low-speed effect beyond the model's Stribeck curve, which the library "
                                           "lacks"
                                         : ": a friction that rises towards standstill (stribeck_friction: static "
                                           "friction above the Coulomb level)")
                         : "");
}

// Where in the command's size the residual sits: its rms (each DOF's in units of its own
// rms, summed) over the rows where |w_j| is in its top 2 % against the rest.  A drive that
// saturates applies less than the log's command exactly there.
struct CommandSignature {
  double ratio = 0.0;  // 0: too few samples
  std::string text;
};
CommandSignature command_signature(const Eigen::MatrixXd& residual, const ForceErrorData& d, Index j,
                                   const std::string& input, const std::string& unit, bool has_saturation) {
  const VectorXd a = d.w.col(j).cwiseAbs();
  std::vector<double> sorted(a.data(), a.data() + a.size());
  const auto k = static_cast<std::ptrdiff_t>(0.98 * static_cast<double>(sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
  const double top = sorted[static_cast<std::size_t>(k)];
  double s_top = 0.0, s_rest = 0.0;
  Index n_top = 0, n_rest = 0;
  VectorXd scale(residual.cols());
  for (Index i = 0; i < residual.cols(); ++i) scale(i) = rms(residual.col(i));
  for (Index r = 0; r < residual.rows(); ++r) {
    double e2 = 0.0;
    for (Index i = 0; i < residual.cols(); ++i)
      if (scale(i) > 0.0) e2 += std::pow(residual(r, i) / scale(i), 2);
    if (a(r) > top) s_top += e2, ++n_top;
    else s_rest += e2, ++n_rest;
  }
  if (n_top == 0 || n_rest == 0 || !(s_rest > 0.0)) return {};
  const double ratio = std::sqrt((s_top / static_cast<double>(n_top)) / (s_rest / static_cast<double>(n_rest)));
  return {ratio, fmt::format("{}: the residual's rms is {:.2f}x as large where |{}| is in its top 2 % (> {:.3g} {}) as "
                     "elsewhere{}",
                     input, ratio, input, top, unit,
                     ratio > 3.0 && !has_saturation
                         ? ": the force falls short of the command at its largest (input_saturation: a drive at its "
                           "limit while the log holds the controller's command)"
                         : "")};
}

// input_saturation is judged only where the baseline's residual says a limit could be at
// work: largest where the command is, on some input (its top-2 % ratio at least this).
// A limit fitted to a log without one clips the largest commands to absorb some other
// missing force (measured on the simulated axis with the offset missing: ratio 1.01, the
// clipped fit 4 % of the excess, ΔBIC 50.6; with a drive at its limit: 7.1 from the bare
// base, 13.9 with the friction in the model).
constexpr double kSaturationSignature = 2.0;

// Where in position the residual repeats: the periodogram of DOF i's residual over its
// position (force_error_detail::ripple_periodogram), its highest line against the median
// line.  A ripple makes one line stand out; a residual that does not repeat with position
// spreads over every line.
// The threshold: a residual that does not repeat with position gives lines that are
// about exponentially distributed, the largest of K independent ones (ln K + γ) / ln 2
// times the median; a ripple must stand 1.5x above that, K counted as every line (the
// grid has four per peak width, so fewer are independent, but a residual is not white
// and its lines are not alike: the count errs on the side of silence).  13.7x on the
// realistic axis's 316 lines, where the residual the true model leaves peaks at 8.2x, a
// 0.4 N ripple at 19.4x from the bare base, and the sample's two-sine axis (no ripple, a
// noisy current sensor) at 10.8x.
struct RippleSignature {
  double ratio = 0.0;      // 0: the log leaves no range of periods
  double threshold = 0.0;  // above it, the residual repeats with position
  std::string text;
};
RippleSignature ripple_signature(const VectorXd& residual, const ForceErrorData& d, Index i, const std::string& dof,
                                 const std::string& unit, int ripples);

}  // namespace

namespace {

RippleSignature ripple_signature(const VectorXd& residual, const ForceErrorData& d, Index i, const std::string& dof,
                                 const std::string& unit, int ripples) {
  const force_error_detail::RippleGrid g = force_error_detail::ripple_grid(d, i);
  if (g.lines < 8) return {};
  // The residual's part that no term of the balance's kind explains (a constant, sign(v),
  // v, q'' and q of this DOF removed by least squares): on a motion whose speed repeats
  // with position (a ramp with a sinusoid on it) a missing friction would otherwise read
  // as a ripple (measured on the sample's one-way ramp: 7687x the median line at the
  // speed's period), and on a sinusoidal motion (acceleration −ω² q) a mass misfit would
  // (71x at the longest period on the two-sine log)
  Eigen::MatrixXd X(residual.size(), 5);
  X.col(0).setOnes();
  X.col(1) = d.sign_v.col(i);
  X.col(2) = d.qd.col(i);
  X.col(3) = d.qdd.col(i);
  X.col(4) = d.q.col(i);
  const VectorXd speed_free = residual - X * X.colPivHouseholderQr().solve(residual);
  const VectorXd power = force_error_detail::ripple_periodogram(d, i, speed_free, g);
  const std::vector<Index> peak = force_error_detail::periodogram_peaks(power, 1);
  const double median = force_error_detail::periodogram_median(power);
  if (peak.empty() || !(median > 0.0)) return {};
  const double ratio = power(peak[0]) / median;
  const double threshold =
      1.5 * (std::log(static_cast<double>(g.lines)) + 0.5772156649) / std::log(2.0);
  // (the model's ripples: none, one, or the library's two)
  const char* reading = ratio <= threshold ? ""
                        : ripples == 0
                            ? ": a force that repeats with position (position_ripple: cogging, a screw's lead error)"
                        : ripples == 1 ? ": a force that repeats with position beyond the model's ripple "
                                         "(position_ripple_2: a second period, or a harmonic of the first)"
                                       : ": a force that repeats with position beyond the model's two ripples (a "
                                         "third period or harmonic, which the library lacks)";
  return {ratio, threshold,
          fmt::format("{}: over position (periods {:.3g} to {:.3g} {}), the residual's part that no rigid-body or "
                      "friction term explains peaks at a period of {:.4g} {}: {:.1f} % of it, {:.1f}x the median period ({:.1f}x is "
                      "what a residual that does not repeat reaches, 1.5 times over){}",
                      dof, g.period_min, g.period_max, unit, g.period(peak[0]), unit, 100.0 * power(peak[0]), ratio,
                      threshold, reading)};
}

// A time-only effect acts on every DOF (a drive's limit on every input); on a base with
// several, it may have nothing to explain on some (a load without friction beside a
// carriage with it).  Its parameters there end where the effect is absent: a friction
// force at zero on its bound, a ripple's period on its search range's edge or both its
// amplitudes within 2 standard errors of zero, a limit at the largest command.  Those
// groups are returned (their names; a channel's name to say where) so that the candidate
// is refitted with them held at zero instead of vetoed for a parameter on its bound —
// measured on a two-mass axis with friction on the carriage only: Coulomb friction was
// refused in every round and the loop stopped at 9.91 % where Coulomb friction and a
// ripple reach 0.135 % (floor 0.201 %).  One group, or every group, idle: nothing held
// (the candidate is judged as it is).
struct IdleGroup {
  std::string channel;
  std::vector<std::string> zero, hold;  // parameters set to zero / held where they are
};
std::vector<IdleGroup> idle_groups(const PhysicalModel& m, const std::string& effect, const ForceErrorFit& fit) {
  const BaseInfo& b = m.base_info();
  const std::vector<PhysicalParameter>& own = m.effect_info(effect)->parameters;
  const auto nd = b.dof_names.size(), ni = b.input_names.size();
  auto find = [&](std::size_t k) -> const ForceErrorParameter* {
    for (const auto& q : fit.parameters)
      if (k < own.size() && q.name == own[k].name) return &q;
    return nullptr;
  };
  auto zero_at_bound = [](const ForceErrorParameter* q) { return q != nullptr && q->at_bound && q->value == 0.0; };
  auto within_noise = [](const ForceErrorParameter* q) {
    return q != nullptr && std::isfinite(q->std_error) && std::abs(q->value) <= 2.0 * q->std_error;
  };
  std::vector<IdleGroup> idle;
  std::size_t groups = 0;
  if (effect == "coulomb_friction" || effect == "stribeck_friction") {
    groups = nd;
    for (std::size_t i = 0; i < nd; ++i)
      if (zero_at_bound(find(i))) {
        IdleGroup g{b.dof_names[i], {own[i].name}, {}};
        if (effect == "stribeck_friction") g.hold.push_back(own[nd + i].name);
        idle.push_back(g);
      }
  } else if (effect == "position_ripple" || effect == "position_ripple_2") {
    groups = nd;
    for (std::size_t i = 0; i < nd; ++i) {
      const ForceErrorParameter* period = find(2 * nd + i);
      if ((period != nullptr && period->at_bound) || (within_noise(find(i)) && within_noise(find(nd + i))))
        idle.push_back({b.dof_names[i], {own[i].name, own[nd + i].name}, {own[2 * nd + i].name}});
    }
  } else if (effect == "input_saturation") {
    groups = ni;
    for (std::size_t j = 0; j < ni; ++j)
      for (const std::string& u : fit.unidentifiable)
        if (u.rfind(own[j].name + " ends at the largest command", 0) == 0) idle.push_back({b.input_names[j], {}, {own[j].name}});
  }
  if (groups < 2 || idle.size() >= groups) return {};
  return idle;
}

// What the baseline's residual shows (per DOF, per input), and what this log cannot
// separate; returns whether some DOF's velocity keeps one sign while Coulomb friction
// and an offset are both in play.
bool residual_signatures(const PhysicalModel& model, const ForceErrorData& d, const std::vector<std::string>& names,
                         const std::vector<CommandSignature>& by_input, const std::vector<RippleSignature>& by_dof,
                         ForceErrorDiagnosis& out) {
  const ForceErrorFit& base = out.baseline;
  const BaseInfo& info = model.base_info();
  bool one_sign_on_some_dof = false;
  for (Index i = 0; i < base.residual.cols(); ++i) {
    const VectorXd r = base.residual.col(i);
    const VectorXd s = d.sign_v.col(i);
    const double rr = rms(r), rs = rms(s);
    if (!(rr > 0.0)) continue;
    const double mean = r.mean();
    const double rho = rs > 0.0 ? r.dot(s) / (r.norm() * s.norm()) : 0.0;
    const std::string& dof = info.dof_names[static_cast<std::size_t>(i)];
    out.signatures.push_back(fmt::format(
        "{}: the force residual correlates with sign(velocity) at {:+.2f} (Coulomb friction's signature) and has a "
        "mean of {:+.2f} of its rms (an offset's)",
        dof, rho, mean / rr));
    const std::string unit =
        static_cast<std::size_t>(i) < info.dof_units.size() ? info.dof_units[static_cast<std::size_t>(i)] : "unit";
    out.signatures.push_back(low_speed_signature(r, d.qd.col(i), dof, unit, model.has_effect("coulomb_friction"),
                                                 model.has_effect("stribeck_friction")));
    if (static_cast<std::size_t>(i) < by_dof.size() && !by_dof[static_cast<std::size_t>(i)].text.empty())
      out.signatures.push_back(by_dof[static_cast<std::size_t>(i)].text);
    const double one_sign = rs > 0.0 ? std::abs(s.mean()) / rs : 1.0;
    const bool both = (model.has_effect("coulomb_friction") ||
                       std::find(names.begin(), names.end(), "coulomb_friction") != names.end()) &&
                      (model.has_effect("force_offset") ||
                       std::find(names.begin(), names.end(), "force_offset") != names.end());
    if (both && one_sign > 0.95) one_sign_on_some_dof = true;
    if (both && one_sign > 0.95)
      out.cannot_separate.push_back(fmt::format(
          "on {} the velocity keeps one sign (the mean of sign(velocity) is {:.2f} of its rms): Coulomb friction and "
          "a constant offset are the same force on this log; record a motion that moves both ways to separate them",
          dof, one_sign));
  }
  for (const CommandSignature& s : by_input)
    if (!s.text.empty()) out.signatures.push_back(s.text);
  // An offset named: what it is, the log cannot say.  While the axis moves, a constant
  // force F_0 and a Coulomb friction that differs with direction (F_c + F_0 one way,
  // F_c − F_0 the other) are the same force, and at rest the friction holds any force.
  if (out.named >= 0) {
    const auto& named = out.candidates[static_cast<std::size_t>(out.named)].effects;
    if (std::find(named.begin(), named.end(), "force_offset") != named.end() &&
        (model.has_effect("coulomb_friction") ||
         std::find(named.begin(), named.end(), "coulomb_friction") != named.end()))
      out.cannot_separate.push_back(
          "the offset F_0 is one force on the moving axis whatever its cause: a constant force (gravity on a tilt, a "
          "cable's pull, an amplifier's offset) or a friction that differs with direction (F_c + F_0 one way, F_c - "
          "F_0 the other) fit the log alike; a measurement that changes one and not the other tells them apart (the "
          "axis levelled or tilted, the amplifier's offset read with the motor off, the cable carrier unhooked)");
  }
  return one_sign_on_some_dof;
}

// ForceErrorDiagnosis::summary: nothing missing, what is named, or why nothing is.
void force_error_summary(const PhysicalModel& model, const ForceErrorDiagnoseOptions& options,
                         bool one_sign_on_some_dof, ForceErrorDiagnosis& out) {
  const ForceErrorFit& base = out.baseline;
  if (out.baseline_explained) {
    out.summary = fmt::format("nothing is missing: the error {:.3g} % is within {}x the noise floor {:.3g} %",
                              base.error, kForceErrorExplainedRatio, base.floor);
  } else if (out.named >= 0) {
    const ForceErrorCandidate& c = out.candidates[static_cast<std::size_t>(out.named)];
    out.summary = fmt::format("missing: {} (error {:.3g} % -> {:.3g} %, floor {:.3g} %; {})",
                              fmt::join(c.effects, " + "), base.error, c.fit.error, c.fit.floor, c.verdict);
    if (one_sign_on_some_dof)
      out.summary += "; but this log cannot tell Coulomb friction from an offset (below): either names the same force";
  } else if (model.absent_time_effects().empty()) {
    out.summary = fmt::format("not explained: the model has every time-domain effect of the library and its error "
                              "{:.3g} % is {:.1f}x the noise floor {:.3g} %; what is left is not in the library (the "
                              "residual's signatures are below)",
                              base.error, base.error / std::max(base.floor, 1e-300), base.floor);
  } else {
    // every absent effect of the library tried (no --candidates) and none helps: what is
    // left is not in the library
    out.summary = fmt::format("not explained: no time-domain effect of the library{} lowers the error {:.3g} % "
                              "(floor {:.3g} %) significantly{}; the residual's signatures are below",
                              options.candidates.empty() ? "" : " among the candidates given", base.error, base.floor,
                              options.candidates.empty() ? ": what is left is not in the library" : "");
  }
}

}  // namespace

ForceErrorDiagnosis diagnose_force_error(const PhysicalModel& model, const ForceErrorData& d,
                                         const ForceErrorDiagnoseOptions& options) {
  std::vector<std::string> names = options.candidates;
  if (names.empty()) names = model.absent_time_effects();
  for (const std::string& c : names) {
    const EffectInfo* e = model.effect_info(c);
    if (e == nullptr || !e->time_only || !is_time_effect(c))
      throw InputError(fmt::format("--candidates: '{}' is not a time-domain effect of this base; the force-error "
                                   "route tries {}",
                                   c, fmt::join(time_effect_names(), ", ")));
    if (model.has_effect(c))
      throw InputError(fmt::format("--candidates: the model already has '{}'; name an effect it lacks", c));
  }
  ForceErrorDiagnosis out;
  out.baseline = fit_force_error(model, d);
  const ForceErrorFit& base = out.baseline;
  const BaseInfo& info = model.base_info();
  std::vector<CommandSignature> by_input;
  double largest_ratio = 0.0;
  for (Index j = 0; j < d.w.cols(); ++j) {
    by_input.push_back(command_signature(
        base.residual, d, j, info.input_names[static_cast<std::size_t>(j)],
        static_cast<std::size_t>(j) < info.input_units.size() ? info.input_units[static_cast<std::size_t>(j)] : "",
        model.has_effect("input_saturation")));
    largest_ratio = std::max(largest_ratio, by_input.back().ratio);
  }
  // Not refitted unless asked for (--candidates): a limit where the residual says there
  // is none cannot be significant (below), and its profile search is the costliest
  // candidate (measured: diagnose on 10⁶ samples 7.96 s with it and its pairs, 3.4 s without)
  if (options.candidates.empty() && largest_ratio < kSaturationSignature) {
    const auto it = std::find(names.begin(), names.end(), "input_saturation");
    if (it != names.end()) {
      names.erase(it);
      out.not_tried.push_back(fmt::format(
          "input_saturation (and its pairs): the residual is not largest where the command is ({:.2f}x in its top 2 "
          "%; a drive at its limit makes it at least {}x); try it with --candidates input_saturation",
          largest_ratio, kSaturationSignature));
    }
  }
  // The ripple likewise: tried only where the residual repeats with position on some DOF
  // (its periodogram's peak above its threshold, RippleSignature)
  std::vector<RippleSignature> by_dof;
  double largest_ripple = 0.0, ripple_threshold = 0.0;  // the largest ratio over its threshold; that threshold
  for (Index i = 0; i < base.residual.cols(); ++i) {
    by_dof.push_back(ripple_signature(
        base.residual.col(i), d, i, info.dof_names[static_cast<std::size_t>(i)],
        static_cast<std::size_t>(i) < info.dof_units.size() ? info.dof_units[static_cast<std::size_t>(i)] : "",
        static_cast<int>(model.has_effect("position_ripple")) + static_cast<int>(model.has_effect("position_ripple_2"))));
    const RippleSignature& r = by_dof.back();
    if (r.threshold > 0.0 && (ripple_threshold == 0.0 || r.ratio / r.threshold > largest_ripple / ripple_threshold))
      largest_ripple = r.ratio, ripple_threshold = r.threshold;
  }
  if (options.candidates.empty() && largest_ripple <= ripple_threshold)
    for (const std::string ripple : {"position_ripple", "position_ripple_2"}) {
      const auto it = std::find(names.begin(), names.end(), ripple);
      if (it == names.end()) continue;
      names.erase(it);
      out.not_tried.push_back(fmt::format(
          "{} (and its pairs): the residual does not repeat with position (its periodogram over position peaks at "
          "{:.1f}x the median period's; a ripple makes it more than {:.1f}x); try it with --candidates {}",
          ripple, largest_ripple, ripple_threshold, ripple));
    }
  out.baseline_explained = base.error <= kForceErrorExplainedRatio * base.floor;
  const double excess = base.error * base.error - base.floor * base.floor;
  auto judge = [&](std::vector<std::string> effects) {
    ForceErrorCandidate c;
    c.effects = effects;
    PhysicalModel m = model;
    for (const auto& e : effects) m.add_effect(e);
    c.fit = fit_force_error(m, d);
    // where an effect has nothing to explain (a DOF without friction): held at zero there
    // and refitted, said in the verdict
    std::vector<std::string> idle_text;
    for (const auto& e : effects)
      for (const IdleGroup& g : idle_groups(m, e, c.fit)) {
        for (const std::string& q : g.zero) {
          m.parameter(q).value = 0.0;
          m.parameter(q).free = false;
        }
        for (const std::string& q : g.hold) {
          for (const auto& f : c.fit.parameters)
            if (f.name == q) m.parameter(q).value = f.value;
          m.parameter(q).free = false;
        }
        idle_text.push_back(fmt::format("{} on {}", e, g.channel));
      }
    if (!idle_text.empty()) c.fit = fit_force_error(m, d);
    c.delta_bic = base.bic - c.fit.bic;
    c.excess_share = excess > 0.0 ? (base.error * base.error - c.fit.error * c.fit.error) / excess : 0.0;
    c.explained = c.fit.error <= kForceErrorExplainedRatio * c.fit.floor;
    bool own_at_bound = false;
    for (const auto& q : c.fit.parameters)
      for (const auto& e : effects)
        for (const auto& ep : m.effect_info(e)->parameters)
          if (ep.name == q.name && q.at_bound) own_at_bound = true;
    const bool no_limit_signature =
        std::find(effects.begin(), effects.end(), "input_saturation") != effects.end() &&
        largest_ratio < kSaturationSignature;
    c.significant = !out.baseline_explained && c.delta_bic > options.delta_bic &&
                    c.excess_share >= options.min_excess_share && !own_at_bound && !no_limit_signature;
    if (out.baseline_explained)
      c.verdict = "not needed: the model fits within the noise";
    else if (own_at_bound)
      c.verdict = "not significant: a parameter of its own ends on its bound";
    else if (no_limit_signature)
      c.verdict = fmt::format("not significant: the residual is not largest where the command is ({:.2f}x in its "
                              "top 2 %; a limit makes it so)",
                              largest_ratio);
    else if (!c.significant)
      c.verdict = fmt::format("not significant (ΔBIC {:.1f}, {:.0f} % of the excess)", c.delta_bic,
                              100.0 * c.excess_share);
    else if (c.explained)
      c.verdict = fmt::format("significant: explained (error within {}x the floor)", kForceErrorExplainedRatio);
    else
      c.verdict = fmt::format("significant: explains {:.0f} % of the excess; more is missing", 100.0 * c.excess_share);
    if (!idle_text.empty())
      c.verdict += fmt::format(" [nothing to explain, held at zero: {}]", fmt::join(idle_text, ", "));
    return c;
  };
  std::vector<ForceErrorCandidate> singles, pairs;
  for (const auto& c : names) singles.push_back(judge({c}));
  for (std::size_t a = 0; a < names.size(); ++a)
    for (std::size_t b = a + 1; b < names.size(); ++b) pairs.push_back(judge({names[a], names[b]}));
  auto by_bic = [](const ForceErrorCandidate& x, const ForceErrorCandidate& y) { return x.delta_bic > y.delta_bic; };
  std::sort(singles.begin(), singles.end(), by_bic);
  std::sort(pairs.begin(), pairs.end(), by_bic);
  out.candidates = singles;
  for (auto& c : pairs) {
    // a pair is named only when each member is needed beyond the other alone
    bool each_needed = c.significant;
    for (const auto& s : singles)
      if (std::find(c.effects.begin(), c.effects.end(), s.effects[0]) != c.effects.end() &&
          c.delta_bic - s.delta_bic <= options.delta_bic)
        each_needed = false;
    if (c.significant && !each_needed) c.verdict += " (one member is enough)";
    c.significant = each_needed;
    out.candidates.push_back(c);
  }
  for (Index k = 0; k < static_cast<Index>(out.candidates.size()); ++k)
    if (out.candidates[static_cast<std::size_t>(k)].significant) {
      // a single ahead of any pair (the loop adds one effect at a time when one is enough)
      out.named = k;
      break;
    }

  const bool one_sign_on_some_dof = residual_signatures(model, d, names, by_input, by_dof, out);
  force_error_summary(model, options, one_sign_on_some_dof, out);
  return out;
}

std::vector<ForceErrorWindow> force_error_failing_windows(const ForceErrorFit& f, const ForceErrorData& d,
                                                         double window_s) {
  if (!(window_s > 0.0) || !(d.sample_period_s > 0.0) || f.residual.rows() != d.n() || d.sample.size() != d.n())
    throw InputError("force_error_failing_windows: the fit and the data do not match");
  std::vector<ForceErrorWindow> out;
  const Index nd = f.residual.cols();
  const Index span = std::max<Index>(2, static_cast<Index>(std::llround(window_s / d.sample_period_s)));
  for (Index i = 0; i < nd; ++i) {
    const double scale = rms(f.applied.col(i));
    const double floor = f.floor_per_dof(i) / 100.0 * scale, record = rms(f.residual.col(i));
    const double limit = kForceErrorExplainedRatio * std::max(floor, record);
    // windows by the log's sample numbers (the kept rows are not contiguous), every half window
    Index row = 0;
    const Index last = d.n() > 0 ? d.sample(d.n() - 1) : 0;
    for (Index start = d.n() > 0 ? d.sample(0) : 0; d.n() > 0 && start <= last; start += span / 2) {
      while (row < d.n() && d.sample(row) < start) ++row;
      double s2 = 0.0;
      Index count = 0;
      for (Index k = row; k < d.n() && d.sample(k) < start + span; ++k, ++count) s2 += f.residual(k, i) * f.residual(k, i);
      if (count < span / 4) continue;  // mostly at standstill
      const double w_rms = std::sqrt(s2 / static_cast<double>(count));
      if (!(w_rms > limit)) continue;
      const double t0 = static_cast<double>(start) * d.sample_period_s;
      const double t1 = static_cast<double>(std::min(start + span - 1, last)) * d.sample_period_s;
      if (!out.empty() && out.back().dof == i && t0 <= out.back().t_end_s) {
        out.back().t_end_s = t1;
        out.back().rms = std::max(out.back().rms, w_rms);
      } else {
        out.push_back({i, t0, t1, w_rms});
      }
    }
  }
  return out;
}
}  // namespace lpvid
