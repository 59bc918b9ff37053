#include "idlib/diagnose/diagnose.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>

#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/evaluate.h"

namespace lpvid {

namespace {

// Runs f(i) for i in [0, n) on the machine's cores (each call single-threaded;
// results do not depend on the thread count).  The first exception that is not a
// NumericalError is rethrown after all threads end.
void parallel_for(std::size_t n, const std::function<void(std::size_t)>& f) {
  std::atomic<std::size_t> next{0};
  std::mutex m;
  std::exception_ptr first;
  auto worker = [&]() {
    for (std::size_t i = next++; i < n; i = next++) {
      try {
        f(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(m);
        if (!first) first = std::current_exception();
      }
    }
  };
  const std::size_t threads = std::min<std::size_t>(n, std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
  if (first) std::rethrow_exception(first);
}

std::string percent(double x) { return fmt::format("{:.3g} %", 100.0 * x); }

}  // namespace

void DiagnoseOptions::validate() const {
  fit.validate();
  model_error.validate();
  if (!(refit_function_tolerance > 0.0 && refit_function_tolerance < 1.0))
    throw InputError(fmt::format("diagnose: refit_function_tolerance must be in (0, 1), got {}",
                                 refit_function_tolerance));
  if (!(std::isfinite(significance_delta_bic) && significance_delta_bic > 0.0))
    throw InputError(fmt::format("diagnose: the ΔBIC threshold must be finite and > 0 (e.g. 10), got {}",
                                 significance_delta_bic));
  if (!(min_excess_share > 0.0 && min_excess_share <= 1.0))
    throw InputError(fmt::format("diagnose: the share of the excess error a candidate must explain must be in (0, 1] "
                                 "(e.g. 0.5), got {}",
                                 min_excess_share));
  if (!(min_band_share >= 0.0 && min_band_share <= 1.0))
    throw InputError(fmt::format("diagnose: the share of failing-band points a candidate must remove must be in [0, 1] "
                                 "(e.g. 0.5), got {}",
                                 min_band_share));
  if (candidate_global_starts < 1)
    throw InputError(fmt::format("diagnose: candidate_global_starts must be >= 1, got {}", candidate_global_starts));
  if (refit_max_iterations < 1)
    throw InputError(fmt::format("diagnose: refit_max_iterations must be >= 1, got {}", refit_max_iterations));
  if (!(std::isfinite(explained_ratio) && explained_ratio >= 1.0))
    throw InputError(fmt::format("diagnose: explained_ratio must be finite and >= 1 (e.g. 1.5), got {}",
                                 explained_ratio));
}

ModelErrorSet model_errors(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& fit,
                           const ModelErrorOptions& options) {
  ModelErrorSet out;
  double sum = 0.0;
  Index count = 0;
  for (std::size_t d = 0; d < data.size(); ++d) {
    FrequencyResponse r = data[d].response;
    // frequencies outside the fit's band are skipped like flagged ones
    if (r.flagged.empty()) r.flagged.assign(static_cast<std::size_t>(r.num_frequencies()), false);
    for (Index k = 0; k < r.num_frequencies(); ++k)
      if (r.omega_rad_s(k) < fit.band_min_rad_s || r.omega_rad_s(k) > fit.band_max_rad_s)
        r.flagged[static_cast<std::size_t>(k)] = true;
    const std::vector<Eigen::MatrixXd> sigma = data_sigma(data[d].response, fit.noise);
    const FrequencyResponse predicted = target_response(model, data[d].beam_position_m, r.omega_rad_s, fit);
    ModelErrorModel mem = model_error(r, predicted.response, sigma, options);
    out.failures.push_back(failing_bands(mem, options, static_cast<Index>(d)));
    for (std::size_t k = 0; k < mem.sigma.size(); ++k) {
      if (mem.skipped[k]) continue;
      for (Index i = 0; i < mem.sigma[k].rows(); ++i)
        for (Index j = 0; j < mem.sigma[k].cols(); ++j) {
          const double s = mem.scale[k](i, j);
          const double q = mem.sigma[k](i, j) / (s > 0 ? s : 1.0);
          if (std::isfinite(q)) sum += 2.0 * q * q;
          ++count;
        }
    }
    out.models.push_back(std::move(mem));
  }
  mark_differences_between_data(out.failures);
  for (const auto& set : out.failures)
    for (const FailingBand& b : set) out.band_points += b.points;
  out.effective_floor = count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  return out;
}

namespace {

// The plant-domain residual P_data − P_model at the data's frequency index k of set d.
Eigen::MatrixXcd plant_residual(const PhysicalModel& model, const FitDataset& ds, Index k, const FitOptions& fit) {
  const double w = ds.response.omega_rad_s(k);
  Eigen::MatrixXcd H = ds.response.response[static_cast<std::size_t>(k)];
  Eigen::MatrixXcd Pd = H;
  if (fit.target != FitTarget::kPlant) {
    const Eigen::MatrixXcd C = controller_response_at(fit, Eigen::VectorXd::Constant(1, w)).front();
    if (fit.target == FitTarget::kClosedLoopOutput) {
      Pd = H * (Eigen::MatrixXcd::Identity(H.cols(), H.cols()) - C * H).inverse();
    } else {
      Pd = C.fullPivLu().solve(H.inverse() - Eigen::MatrixXcd::Identity(H.rows(), H.cols()));
    }
  }
  const Eigen::MatrixXcd Pm =
      physical_response(model, ds.beam_position_m, Eigen::VectorXd::Constant(1, w), fit.sample_period_s).front();
  return Pd - Pm;
}

// Starting points of the global start for an effect, read off the baseline's
// failing phenomena (a resonance frequency and a mode shape) or spread over the
// range a phenomenon of that kind lives in (delays, lags).
std::vector<std::vector<std::pair<std::string, double>>> seeds_for(const EffectInfo& effect,
                                                                   const PhysicalModel& baseline,
                                                                   const std::vector<Phenomenon>& phenomena,
                                                                   const std::vector<FitDataset>& data,
                                                                   const FitOptions& fit) {
  std::vector<std::vector<std::pair<std::string, double>>> out;
  auto bounds = [&](const std::string& name) {
    for (const PhysicalParameter& q : effect.parameters)
      if (q.name == name) return std::pair<double, double>{q.lower, q.upper};
    return std::pair<double, double>{-INFINITY, INFINITY};
  };
  constexpr std::size_t kPhenomenaSeeded = 3;  // the strongest few phenomena
  constexpr double kSeedDamping = 0.02;       // a lightly damped start
  // the strongest few phenomena whose frequency the parameter's bounds admit
  auto strongest_within = [&](const std::string& frequency_parameter) {
    const auto [lo, hi] = bounds(frequency_parameter);
    std::vector<const Phenomenon*> chosen;
    for (const Phenomenon& ph : phenomena)
      if (chosen.size() < kPhenomenaSeeded && ph.omega_rad_s >= lo && ph.omega_rad_s <= hi) chosen.push_back(&ph);
    return chosen;
  };
  for (const Block& b : effect.blocks) {
    if (b.kind == BlockKind::kMode) {
      for (const Phenomenon* p : strongest_within(b.parameters[0])) {
        const Phenomenon& ph = *p;
        std::vector<std::pair<std::string, double>> seed{{b.parameters[0], ph.omega_rad_s},
                                                         {b.parameters[1], kSeedDamping}};
        // shape: φφᵀ ≈ Re(ΔP · 2jζω²) at the peak (a collocated mode at resonance)
        try {
          const FailingBand& rep = ph.bands.front();
          const FitDataset& ds = data[static_cast<std::size_t>(rep.data_index)];
          Index k = 0;
          for (Index f = 0; f < ds.response.num_frequencies(); ++f)
            if (std::abs(ds.response.omega_rad_s(f) - rep.omega_at_max_rad_s) <
                std::abs(ds.response.omega_rad_s(k) - rep.omega_at_max_rad_s))
              k = f;
          const double w = ds.response.omega_rad_s(k);
          const Eigen::MatrixXcd dP = plant_residual(baseline, ds, k, fit);
          const Index n = static_cast<Index>(b.parameters.size()) - 2;
          if (dP.rows() == n && dP.cols() == n) {
            Eigen::MatrixXd M = (dP * Complex(0.0, 2.0 * kSeedDamping * w * w)).real();
            M = 0.5 * (M + M.transpose()).eval();
            const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
            Index best = 0;
            for (Index i = 1; i < n; ++i)
              if (std::abs(es.eigenvalues()(i)) > std::abs(es.eigenvalues()(best))) best = i;
            const Eigen::VectorXd phi = std::sqrt(std::abs(es.eigenvalues()(best))) * es.eigenvectors().col(best);
            for (Index i = 0; i < n; ++i) {
              const auto [slo, shi] = bounds(b.parameters[static_cast<std::size_t>(2 + i)]);
              seed.emplace_back(b.parameters[static_cast<std::size_t>(2 + i)], std::clamp(phi(i), slo, shi));
            }
          }
        } catch (const std::exception&) {
          // no shape estimate (a singular controller or data): frequency and damping only
        }
        out.push_back(std::move(seed));
      }
    } else if (b.kind == BlockKind::kResonance || b.kind == BlockKind::kSecondOrder) {
      for (const Phenomenon* ph : strongest_within(b.parameters[0])) {
        std::vector<std::pair<std::string, double>> seed{{b.parameters[0], ph->omega_rad_s},
                                                         {b.parameters[1], 0.05}};
        if (b.kind == BlockKind::kResonance) {
          seed.emplace_back(b.parameters[2], ph->omega_rad_s * 1.15);
          seed.emplace_back(b.parameters[3], 0.1);
        }
        out.push_back(std::move(seed));
      }
    } else if (b.kind == BlockKind::kDelay) {
      // a computation delay is a few samples (or a few ms in continuous time)
      const double unit = fit.sample_period_s > 0 ? fit.sample_period_s : 1e-3;
      for (double s : {0.5, 1.5, 2.5, 3.5}) out.push_back({{b.parameters[0], s * unit}});
    } else if (b.kind == BlockKind::kFirstOrder) {
      for (double t : {3e-4, 1e-3, 3e-3}) out.push_back({{b.parameters[0], t}});
    }
  }
  return out;
}

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

// Every FREE parameter's library default (the base's and each effect's; fixed ones
// keep the user's design values).  A model fitted while it lacked an effect can sit,
// bent out of shape, in a basin the effect cannot pull it out of (a rod twist that
// makes the tilts 4x stiffer than the design: the fit without it ran the inertia and
// the bending scales to their bounds); a second refit from the defaults finds it
// (tests/idlib/diagnose, FromTheFittedModel).
std::vector<std::pair<std::string, double>> library_defaults(const PhysicalModel& m) {
  std::vector<std::pair<std::string, double>> out;
  auto add_from = [&](const std::vector<PhysicalParameter>& defaults) {
    for (const PhysicalParameter& d : defaults) {
      const Index i = m.index_of(d.name);
      if (i >= 0 && m.parameters[static_cast<std::size_t>(i)].free) out.emplace_back(d.name, d.value);
    }
  };
  add_from(base_info(m.base).parameters);
  for (const std::string& e : m.effects)
    if (const EffectInfo* info = m.effect_info(e)) add_from(info->parameters);
  return out;
}

void evaluate_candidate(CandidateOutcome& c, const PhysicalModel& baseline_model, const CandidateContext& ctx) {
  // From the fitted baseline, searching globally over the effect's own parameters
  // (the base is fitted already).  A baseline with parameters on bounds is a base
  // bent out of shape by what it lacks: then from the model as given, searching
  // over everything, and once more from the library defaults (the better wins).
  PhysicalModel start = ctx.baseline_distorted ? ctx.given : baseline_model;
  start.add_effect(c.effect);
  FitOptions fo = ctx.refit;
  fo.extra_starts = seeds_for(*start.effect_info(c.effect), baseline_model, ctx.d.phenomena, ctx.data, fo);
  if (!ctx.baseline_distorted) {
    for (const PhysicalParameter& q : start.effect_info(c.effect)->parameters) fo.global_parameters.push_back(q.name);
    fo.global_starts = std::min(fo.global_starts, ctx.options.candidate_global_starts);
  }
  const bool physics = start.effect_info(c.effect)->blocks.empty();
  std::string failure;
  try {
    c.fit = fit_physical_model(start, ctx.data, fo);
    c.fitted = true;
  } catch (const NumericalError& e) {
    failure = e.what();
  }
  if (!ctx.baseline_distorted && physics) {
    // A physics effect of the base (no blocks: its terms enter M, K, B_w) moves the
    // base's own parameters with it (the stage's gap stiffness ∝ m g gamma trades
    // against kappa and the inertias): also search over everything, as `fit` does,
    // and keep the better.  Measured on the independent stage simulator: the search
    // over gamma alone settled at 50 1/m for a true 199 (error 26 %), the whole
    // search reached 6.6 %; on lpvid's own simulator the search over gamma alone is
    // the better one (seed 501: 4.0 % against 6.7 %).
    // With as many global starts as `fit` (the capped count missed the basin on the
    // independent stage's gap seed 102: 23.2 % where `fit` after `model add` reached
    // 5.0 %).  And with fit's restarts (FitOptions::restarts): the gap spring is
    // undamped, its cost ripples in gamma, and one round can stop in a ripple (the
    // stage walkthrough: 4.69 % at gamma 237.5 after one round, 3.21 % at 244.9 with
    // the second, as `fit` after `model add` reaches; docs/math.md, "Restarts").
    FitOptions all = fo;
    all.global_parameters.clear();
    all.global_starts = ctx.refit.global_starts;
    all.restarts = 2;
    try {
      FitResult again = fit_physical_model(start, ctx.data, all);
      if (!c.fitted || again.cost_final < c.fit.cost_final) c.fit = std::move(again);
      c.fitted = true;
    } catch (const NumericalError& e) {
      if (!c.fitted) failure = e.what();
    }
  }
  if (ctx.baseline_distorted) {
    PhysicalModel fresh = start;
    for (const auto& [name, value] : library_defaults(start)) fresh.parameter(name).value = value;
    try {
      FitResult again = fit_physical_model(fresh, ctx.data, fo);
      if (!c.fitted || again.cost_final < c.fit.cost_final) c.fit = std::move(again);
      c.fitted = true;
    } catch (const NumericalError& e) {
      if (!c.fitted) failure = e.what();
    }
  }
  if (!c.fitted) {
    c.failure = failure;
    c.verdict = "refit failed";
    return;
  }
  c.error = c.fit.error;
  c.delta_bic = c.fit.bic - ctx.d.baseline.bic;
  c.delta_aic = c.fit.aic - ctx.d.baseline.aic;
  const ModelErrorSet mes = model_errors(c.fit.model, ctx.data, fo, ctx.options.model_error);
  c.band_points = mes.band_points;
  const double e0 = ctx.d.baseline_error;
  c.excess_share = ctx.excess2 > 0 ? (e0 * e0 - c.error * c.error) / ctx.excess2 : 0.0;
  c.band_share = ctx.d.baseline_band_points > 0
                     ? static_cast<double>(ctx.d.baseline_band_points - c.band_points) /
                           static_cast<double>(ctx.d.baseline_band_points)
                     : 0.0;
  const EffectInfo* info = start.effect_info(c.effect);
  std::vector<std::string> pinned;
  for (const ParameterEstimate& p : c.fit.parameters)
    for (const PhysicalParameter& q : info->parameters)
      if (p.name == q.name) {
        c.effect_parameters.push_back(p);
        if (p.at_bound) {
          c.own_parameter_at_bound = true;
          const bool lower = std::abs(p.estimate - p.lower) <= std::abs(p.upper - p.estimate);
          pinned.push_back(fmt::format("{} = {:.4g} at its {} bound", p.name, p.estimate, lower ? "lower" : "upper"));
        }
      }
  CandidateEvidence ev;
  ev.something = ctx.something;
  ev.global_excess = ctx.global_excess;
  ev.has_band_points = ctx.d.baseline_band_points > 0;
  ev.floor = ctx.floor;
  ev.baseline_error = e0;
  ev.error = c.error;
  ev.delta_bic = c.delta_bic;
  ev.excess_share = c.excess_share;
  ev.band_share = c.band_share;
  ev.pinned = std::move(pinned);
  CandidateJudgement j = judge_candidate(ev, ctx.options);
  c.significant = j.significant;
  c.verdict = std::move(j.verdict);
}

std::string channel_label(const std::vector<std::string>& names, Index i, const char* fallback) {
  return i < static_cast<Index>(names.size()) ? names[static_cast<std::size_t>(i)] : fmt::format("{} {}", fallback, i + 1);
}

void describe_phenomena(const std::vector<Phenomenon>& phenomena, const std::vector<FitDataset>& data,
                        std::vector<std::string>& lines, std::size_t limit) {
  for (std::size_t k = 0; k < std::min(limit, phenomena.size()); ++k) {
    const Phenomenon& ph = phenomena[k];
    const FailingBand& b = ph.bands.front();
    std::string at;
    if (ph.data_sets.size() == data.size() && data.size() > 1) {
      at = fmt::format("at all {} data sets", data.size());
    } else {
      std::vector<std::string> xs;
      for (Index d : ph.data_sets) xs.push_back(fmt::format("{:g}", data[static_cast<std::size_t>(d)].beam_position_m));
      at = fmt::format("at {} {}", ph.data_sets.size() == 1 ? "data set" : "data sets", fmt::join(xs, ", "));
    }
    // gain and phase of data over model: none where the model is zero there (a
    // coupling the model lacks)
    const std::string ratio = std::isfinite(b.gain_db_max) && std::isfinite(b.phase_deg_max)
                                  ? fmt::format("{:+.2f} dB, {:+.1f} deg", b.gain_db_max, b.phase_deg_max)
                                  : std::string("the model is 0 there");
    lines.push_back(fmt::format("  {}. near {:.4g} rad/s in {}, {}: up to {:.3g} % ({}), {:.0f}x the noise; {}", k + 1,
                                ph.omega_rad_s, ph.where, at, b.relative_percent_max, ratio, b.max_sigma_ratio,
                                b.hint));
  }
  if (phenomena.size() > limit) lines.push_back(fmt::format("  ... and {} more", phenomena.size() - limit));
}

// The words for a description, from its effect's (fitted) parameter values.
void describe_in_words(ResidualDescription& r) {
  auto v = [&](std::size_t i) { return r.effect.parameters[i].value; };
  // the plant's channel (the data may be S or G, whose rows and columns are others)
  const std::string place = r.side == "output" ? fmt::format("the plant's {} output row only", r.channel)
                                               : fmt::format("the plant's {} input column only", r.channel);
  const std::string cause = r.side == "output" ? "a sensor, its mount or its filter" : "an actuator, its amplifier or its mount";
  if (r.kind == "resonance") {
    const double wp = v(0), zp = v(1), wz = v(2), zz = v(3);
    // the peak of |H| near wp: |H(j wp)| = (wp²/wz²) |wz² − wp² + 2j zz wz wp| / (2 zp wp²)
    const double peak_db =
        20.0 * std::log10((wp * wp / (wz * wz)) * std::abs(Complex(wz * wz - wp * wp, 2 * zz * wz * wp)) / (2 * zp * wp * wp));
    r.text = fmt::format("a resonance near {:.4g} rad/s (ζ ≈ {:.2g}, {:+.1f} dB) with an anti-resonance near {:.4g} "
                         "rad/s (ζ ≈ {:.2g}), in {} — {}",
                         wp, zp, peak_db, wz, zz, place, cause);
  } else {
    r.text = fmt::format("a first-order lag with its corner at {:.4g} rad/s ({:.3g} ms), in {} — {}", 1.0 / v(0),
                         1e3 * v(0), place, cause);
  }
  if (r.pinned) r.text += " (a parameter ends on its bound: a rough description only)";
  r.effect.description = r.text;
}

// Generic error models on top of `reference` (its parameters held), fitted to the
// residual; the ones that explain something, best first.
std::vector<ResidualDescription> describe_residual(const PhysicalModel& reference, double ref_error,
                                                   const std::vector<Phenomenon>& phenomena,
                                                   const std::vector<FitDataset>& data, const FitOptions& refit,
                                                   double floor, int candidate_starts, Progress* progress) {
  const BaseInfo& base = base_info(reference.base);
  double wmin = INFINITY, wmax = 0;
  for (const FitDataset& ds : data) {
    wmin = std::min(wmin, ds.response.omega_rad_s.minCoeff());
    wmax = std::max(wmax, ds.response.omega_rad_s.maxCoeff());
  }
  wmin = std::max(wmin, refit.band_min_rad_s);
  wmax = std::min(wmax, refit.band_max_rad_s);
  struct Template {
    std::string kind, side, channel;
  };
  std::vector<Template> templates;
  for (const char* kind : {"resonance", "lag"}) {
    for (const std::string& c : base.output_names) templates.push_back({kind, "output", c});
    for (const std::string& c : base.input_names) templates.push_back({kind, "input", c});
  }
  PhysicalModel held = reference;
  for (PhysicalParameter& q : held.parameters) q.free = false;
  std::vector<ResidualDescription> found(templates.size());
  std::vector<bool> ok(templates.size(), false);
  const double excess2 = ref_error * ref_error - floor * floor;
  auto template_name = [&](const Template& tp) { return fmt::format("{} in {} {}", tp.kind, tp.side, tp.channel); };
  ParallelSteps screening(progress, "diagnose", "residual model", static_cast<Index>(templates.size()));
  parallel_for(templates.size(), [&](std::size_t t) {
    const Template& tp = templates[t];
    const std::string name = template_name(tp);
    screening.start(name);
    struct Finish {  // also on the early returns below
      ParallelSteps& steps;
      const std::string& name;
      ~Finish() { steps.finish(name); }
    } finish{screening, name};
    EffectInfo e;
    e.name = fmt::format("residual_{}_{}_{}", tp.kind, tp.side, tp.channel);
    const std::string pre = fmt::format("{}_{}_{}", tp.side == "output" ? "sensor" : "actuator", tp.channel, tp.kind);
    const BlockSide side = tp.side == "output" ? BlockSide::kOutput : BlockSide::kInput;
    if (tp.kind == "resonance") {
      const double mid = std::sqrt(wmin * wmax);
      e.parameters = {{pre + "_pole_rad_s", "rad/s", mid, 0.5 * wmin, 2.0 * wmax, true},
                      {pre + "_pole_damping", "1", 0.05, 1e-3, 0.7, true},
                      {pre + "_zero_rad_s", "rad/s", mid * 1.15, 0.5 * wmin, 2.0 * wmax, true},
                      {pre + "_zero_damping", "1", 0.1, 1e-3, 0.7, true}};
      e.blocks = {{BlockKind::kResonance, side, {tp.channel},
                   {e.parameters[0].name, e.parameters[1].name, e.parameters[2].name, e.parameters[3].name}}};
    } else {
      e.parameters = {{pre + "_time_constant_s", "s", 1e-3, 1e-6, 1.0, true}};
      e.blocks = {{BlockKind::kFirstOrder, side, {tp.channel}, {e.parameters[0].name}}};
    }
    PhysicalModel m = held;
    // the reference may already have user definitions; give this one a fresh name
    m.define_effect(e);
    m.add_effect(e.name);
    FitOptions fo = refit;
    fo.extra_starts = seeds_for(*m.effect_info(e.name), reference, phenomena, data, refit);
    fo.global_starts = std::min(fo.global_starts, candidate_starts);
    FitResult f;
    try {
      f = fit_physical_model(m, data, fo);
    } catch (const NumericalError&) {
      return;
    }
    ResidualDescription r;
    r.kind = tp.kind;
    r.side = tp.side;
    r.channel = tp.channel;
    r.error = f.error;
    r.excess_share = excess2 > 0 ? (ref_error * ref_error - f.error * f.error) / excess2 : 0.0;
    r.pinned = false;
    for (const ParameterEstimate& p : f.parameters) r.pinned = r.pinned || p.at_bound;
    e.name = pre;
    for (PhysicalParameter& q : e.parameters) q.value = f.model.parameter(q.name).value;
    e.changes = "user-defined from lpvid diagnose's description of the residual";
    e.signature = "the residual it was fitted to";
    r.effect = e;
    found[t] = std::move(r);
    ok[t] = true;
  });
  // Screened with the model held; the best few are refitted with everything free
  // (the model may have bent to absorb part of the residual), starting from the
  // screening's values.
  std::vector<std::size_t> order;
  for (std::size_t t = 0; t < found.size(); ++t)
    if (ok[t]) order.push_back(t);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return found[a].error < found[b].error; });
  constexpr std::size_t kRefitted = 2;
  if (order.size() > kRefitted) order.resize(kRefitted);
  std::vector<ResidualDescription> refitted(order.size());
  std::vector<bool> refit_ok(order.size(), false);
  ParallelSteps refits(progress, "diagnose", "residual model refit", static_cast<Index>(order.size()));
  parallel_for(order.size(), [&](std::size_t i) {
    ResidualDescription r = found[order[i]];
    const std::string name = fmt::format("{} in {} {}", r.kind, r.side, r.channel);
    refits.start(name);
    struct Finish {
      ParallelSteps& steps;
      const std::string& name;
      ~Finish() { steps.finish(name); }
    } finish{refits, name};
    PhysicalModel m = reference;
    EffectInfo e = r.effect;
    e.name = "residual_description";
    m.define_effect(e);
    m.add_effect(e.name);
    FitOptions fo = refit;
    fo.global_start = false;
    FitResult f;
    try {
      f = fit_physical_model(m, data, fo);
    } catch (const NumericalError&) {
      return;
    }
    if (!(f.error < r.error)) {
      refitted[i] = std::move(r);
      refit_ok[i] = true;
      return;
    }
    r.error = f.error;
    r.excess_share = excess2 > 0 ? (ref_error * ref_error - f.error * f.error) / excess2 : 0.0;
    for (PhysicalParameter& q : r.effect.parameters) q.value = f.model.parameter(q.name).value;
    r.pinned = false;
    for (const ParameterEstimate& p : f.parameters)
      for (const PhysicalParameter& q : r.effect.parameters) r.pinned = r.pinned || (p.name == q.name && p.at_bound);
    refitted[i] = std::move(r);
    refit_ok[i] = true;
  });
  std::vector<ResidualDescription> out;
  // Kept when it explains a third of what remains above the noise: less is not a description.
  constexpr double kMinShareDescribed = 1.0 / 3.0;
  for (std::size_t i = 0; i < refitted.size(); ++i)
    if (refit_ok[i] && refitted[i].excess_share >= kMinShareDescribed) {
      describe_in_words(refitted[i]);
      out.push_back(std::move(refitted[i]));
    }
  std::sort(out.begin(), out.end(),
            [](const ResidualDescription& a, const ResidualDescription& b) { return a.error < b.error; });
  return out;
}

}  // namespace

CandidateJudgement judge_candidate(const CandidateEvidence& e, const DiagnoseOptions& options) {
  const bool raises = e.error > e.baseline_error;
  const bool bic = e.delta_bic < -options.significance_delta_bic;
  // a localized phenomenon (failing bands, the error as a whole within the floor)
  // is judged by the bands it removes
  const bool excess = !e.global_excess || e.excess_share >= options.min_excess_share;
  const bool to_floor = e.global_excess && e.error <= options.explained_ratio * e.floor;
  const bool bands = !e.has_band_points || to_floor || e.band_share >= options.min_band_share;
  CandidateJudgement j;
  j.significant = e.something && e.pinned.empty() && !raises && bic && excess && bands;
  if (j.significant) {
    j.verdict = "significant";
  } else if (!e.something) {
    j.verdict = "not significant: nothing beyond the noise to explain";
  } else if (!e.pinned.empty()) {
    j.verdict = fmt::format("not significant: {} (used as a patch)", fmt::join(e.pinned, ", "));
  } else if (raises) {
    j.verdict = fmt::format("not significant: it raises the error figure from {} to {} (ΔBIC {:.1f})",
                            percent(e.baseline_error), percent(e.error), e.delta_bic);
  } else if (!bic) {
    j.verdict = fmt::format("not significant: ΔBIC {:.1f} above −{:g}", e.delta_bic, options.significance_delta_bic);
  } else if (!excess) {
    j.verdict = fmt::format("not significant: explains {:.0f} % of the excess (needs {:.0f} %)", 100.0 * e.excess_share,
                            100.0 * options.min_excess_share);
  } else {
    j.verdict = fmt::format("not significant: removes {:.0f} % of the failing-band points (needs {:.0f} %)",
                            100.0 * e.band_share, 100.0 * options.min_band_share);
  }
  return j;
}

Diagnosis diagnose(const PhysicalModel& model, const std::vector<FitDataset>& data, const DiagnoseOptions& options) {
  options.validate();
  model.validate();
  if (data.empty()) throw InputError("diagnose: no data; give at least one measured response");
  std::vector<std::string> candidates = options.candidates;
  if (candidates.empty()) {
    candidates = model.absent_effects();
  } else {
    for (const std::string& c : candidates) {
      if (model.effect_info(c) == nullptr) {
        const auto absent = model.absent_effects();
        throw InputError(fmt::format("diagnose: unknown effect '{}'; the effects the model could add are {}", c,
                                     fmt::join(absent, ", ")));
      }
      if (model.has_effect(c))
        throw InputError(fmt::format("diagnose: the model already has effect '{}'; try the others", c));
    }
  }

  // The significance is measured against the data's noise: it must be known.
  for (const FitDataset& ds : data) {
    bool known = false;
    std::string source;
    data_sigma(ds.response, options.fit.noise, &source, &known);
    if (!known)
      throw InputError(fmt::format(
          "diagnose: {}: the noise of the data is not known ({}); give --averages N (the independent averages behind "
          "the coherence) or --noise-level X (the relative rms error of the measurement, e.g. 0.01), or data that "
          "carry their variance",
          ds.label, source));
  }
  FitOptions refit = options.fit;
  refit.function_tolerance = std::max(refit.function_tolerance, options.refit_function_tolerance);
  refit.max_iterations = std::min(refit.max_iterations, options.refit_max_iterations);
  refit.progress = nullptr;  // the candidates' refits run in parallel: diagnose reports them itself

  Diagnosis out;
  {
    NestedProgress baseline(options.progress, "diagnose baseline");
    FitOptions first = refit;
    first.progress = baseline.get();
    out.baseline = fit_physical_model(model, data, first);
  }
  report_progress(options.progress, {"diagnose", "where the baseline fails", 0, 0, "", -1.0});
  out.baseline_error = out.baseline.error;
  out.noise_floor = out.baseline.noise_floor;
  out.noise_source = out.baseline.noise_source;
  const ModelErrorSet base_mes = model_errors(out.baseline.model, data, refit, options.model_error);
  out.baseline_failures = base_mes.failures;
  out.baseline_band_points = base_mes.band_points;
  out.effective_floor = base_mes.effective_floor;
  out.phenomena = group_phenomena(out.baseline_failures, out.baseline.output_names, out.baseline.input_names);
  const double f = out.effective_floor, e0 = out.baseline_error;
  const double excess2 = std::max(e0 * e0 - f * f, 0.0);
  const bool global_excess = e0 > options.explained_ratio * f;
  const bool something = global_excess || out.baseline_band_points > 0;
  bool distorted = false;
  for (const ParameterEstimate& p : out.baseline.parameters) distorted = distorted || p.at_bound;

  std::vector<CandidateOutcome> outcomes(candidates.size());
  for (std::size_t i = 0; i < candidates.size(); ++i) outcomes[i].effect = candidates[i];
  const CandidateContext ctx{out, data, options, refit, model, distorted, f, excess2, global_excess, something};
  ParallelSteps steps(options.progress, "diagnose", "candidate", static_cast<Index>(outcomes.size()));
  parallel_for(outcomes.size(), [&](std::size_t i) {
    steps.start(outcomes[i].effect);
    evaluate_candidate(outcomes[i], out.baseline.model, ctx);
    steps.finish(outcomes[i].effect);
  });

  std::vector<CandidateOutcome> failed;
  for (CandidateOutcome& c : outcomes) {
    if (c.fitted)
      out.ranked.push_back(std::move(c));
    else
      failed.push_back(std::move(c));
  }
  // Significant ones by ΔBIC (the noise-weighted likelihood: between effects that
  // both pass the criteria it is the better judge than the unweighted error figure,
  // which a few noisy low-frequency lines of an frf estimate can sway), the rest
  // by error.
  std::stable_sort(out.ranked.begin(), out.ranked.end(), [](const CandidateOutcome& a, const CandidateOutcome& b) {
    if (a.significant != b.significant) return a.significant;
    if (a.significant) return a.delta_bic < b.delta_bic;
    return a.error < b.error;
  });
  for (CandidateOutcome& c : failed) out.ranked.push_back(std::move(c));

  const CandidateOutcome* winner = !out.ranked.empty() && out.ranked.front().significant ? &out.ranked.front() : nullptr;
  if (winner != nullptr) {
    out.missing = winner->effect;
    // within the noise, and (nearly) no failing band left: at most kLeftBandShare
    // of the baseline's failing-band points (chance exceedances of the noise)
    constexpr double kLeftBandShare = 0.1;
    out.explained = winner->error <= options.explained_ratio * f &&
                    static_cast<double>(winner->band_points) <=
                        kLeftBandShare * static_cast<double>(out.baseline_band_points);
    // Another significant candidate the data do not separate from the winner: with
    // the winner explained, one that explains too; otherwise one whose ΔBIC is within
    // the significance margin of the winner's (a gain and a uniform scaling of M, D
    // and K are the same plant: rod_twist against gain_error, issue 25).
    for (std::size_t i = 1; i < out.ranked.size(); ++i) {
      const CandidateOutcome& c = out.ranked[i];
      if (!c.significant) continue;
      const bool same = out.explained ? c.error <= options.explained_ratio * f
                                      : c.delta_bic - winner->delta_bic < options.significance_delta_bic;
      if (same) out.indistinguishable.push_back(c.effect);
    }
    report_progress(options.progress, {"diagnose", "where the winner fails", 0, 0, winner->effect, -1.0});
    const ModelErrorSet rest = model_errors(winner->fit.model, data, refit, options.model_error);
    out.remaining_failures = rest.failures;
    out.remaining_phenomena = group_phenomena(rest.failures, out.baseline.output_names, out.baseline.input_names);
  }
  // Describe what no library effect explains (after the winner, if it leaves some).
  const bool left = winner != nullptr ? !out.explained : something;
  if (options.describe && left) {
    const PhysicalModel& ref = winner != nullptr ? winner->fit.model : out.baseline.model;
    const double ref_error = winner != nullptr ? winner->error : e0;
    const auto& ph = winner != nullptr ? out.remaining_phenomena : out.phenomena;
    out.descriptions =
        describe_residual(ref, ref_error, ph, data, refit, f, options.candidate_global_starts, options.progress);
  }

  // ---- the report in words ----
  std::vector<std::string>& s = out.summary;
  const std::string floor_text =
      std::isfinite(out.noise_floor)
          ? fmt::format("noise floor {} (from {}{})", percent(out.noise_floor), out.noise_source,
                        f > out.noise_floor * 1.0001 ? fmt::format("; {} with lpvid's resolution", percent(f)) : "")
          : fmt::format("noise floor unknown; lpvid's resolution {}", percent(f));
  s.push_back(fmt::format("model with {} free parameters: error {} (rms over the channels of the relative rms error); "
                          "{}",
                          out.baseline.parameters.size(), percent(e0), floor_text));
  std::size_t nb = 0;
  for (const auto& set : out.baseline_failures) nb += set.size();
  if (nb == 0) {
    s.push_back("where it fails: nowhere beyond the measurement noise (no failing band)");
  } else {
    s.push_back(fmt::format("where it fails ({} distinct phenomena in {} failing bands, strongest first):",
                            out.phenomena.size(), nb));
    describe_phenomena(out.phenomena, data, s, 5);
  }
  if (distorted) {
    std::vector<std::string> pinned;
    for (const ParameterEstimate& p : out.baseline.parameters)
      if (p.at_bound)
        pinned.push_back(fmt::format("{} = {:.4g}", p.name, p.estimate));
    s.push_back(fmt::format("the base cannot follow the data within its physical ranges: {} ended on a bound (candidates "
                            "are refitted from the model as given)",
                            fmt::join(pinned, ", ")));
  }
  if (!something) {
    s.push_back(fmt::format("nothing to explain: the model fits within the noise (error {} <= {:g} x {}, no failing "
                            "band); no candidate is significant",
                            percent(e0), options.explained_ratio, percent(f)));
  } else if (winner != nullptr) {
    const EffectInfo* info = model.effect_info(winner->effect);
    s.push_back(fmt::format("missing: {} — {}", winner->effect, info->description));
    s.push_back(fmt::format("  it explains: {}", info->signature));
    s.push_back(fmt::format("  error {} -> {} ({:.1f}x lower): {:.0f} % of the excess above the noise floor, {:.0f} % of "
                            "the failing-band points; ΔBIC {:.1f}",
                            percent(e0), percent(winner->error), winner->error > 0 ? e0 / winner->error : INFINITY,
                            100.0 * winner->excess_share, 100.0 * winner->band_share, winner->delta_bic));
    for (const ParameterEstimate& p : winner->effect_parameters)
      s.push_back(fmt::format("  {} = {:.6g} ± {:.2g} {}", p.name, p.estimate, p.std_error, p.unit));
    if (out.ranked.size() > 1 && out.ranked[1].fitted)
      s.push_back(fmt::format("  runner-up: {} (error {}, {:.0f} % of the excess; {})", out.ranked[1].effect,
                              percent(out.ranked[1].error), 100.0 * out.ranked[1].excess_share, out.ranked[1].verdict));
    if (!out.indistinguishable.empty()) {
      const CandidateOutcome& second = out.ranked[1];
      s.push_back(fmt::format(
          "  indistinguishable on these data from {}: {} {}; {} has the better likelihood (ΔBIC {:.1f} against {:.1f}, "
          "within {:g}). What would separate them: a prior on a parameter one of them moves (lpvid model set --set "
          "NAME=VALUE±SIGMA: a weighed mass, a datasheet force constant or stiffness), or another experiment (another "
          "operating point, a static test, a longer or less noisy measurement, a wider band)",
          fmt::join(out.indistinguishable, ", "), out.indistinguishable.size() == 1 ? "it leaves" : "they leave",
          out.explained ? "the error within the noise too"
                        : fmt::format("the error at {} against {}", percent(second.error), percent(winner->error)),
          winner->effect, winner->delta_bic, second.delta_bic, options.significance_delta_bic));
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
  } else {
    s.push_back("not explained: no effect the model could add explains the excess error");
    if (!out.ranked.empty() && out.ranked.front().fitted)
      s.push_back(fmt::format("  closest candidate: {} (error {}, {:.0f} % of the excess; {})", out.ranked.front().effect,
                              percent(out.ranked.front().error), 100.0 * out.ranked.front().excess_share,
                              out.ranked.front().verdict));
  }
  if (!out.descriptions.empty()) {
    const ResidualDescription& r = out.descriptions.front();
    s.push_back(fmt::format("  the residual looks like {}: error {} -> {} ({:.0f} % of the excess)", r.text,
                            percent(winner != nullptr ? winner->error : e0), percent(r.error), 100.0 * r.excess_share));
    s.push_back(fmt::format("  to model it, define a user-defined effect like '{}' (lpvid diagnose --out-effect writes it; "
                            "docs/effects.md)",
                            r.effect.name));
  } else if (options.describe && left) {
    s.push_back("  no low-order error model (a resonance or lag in one row or column) describes the residual either");
  }
  (void)channel_label;
  return out;
}

}  // namespace lpvid
