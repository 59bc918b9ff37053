#include "idlib/closedloop/unloop.h"
#include "idlib/core/eigen_decompositions.h"
#include "idlib/closedloop/interpolation.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/lti/reduce.h"

namespace lpvid {
namespace {

// Frequencies of the selection score: 200 log-spaced points (enough to resolve
// a resonance with ζ ≥ 0.02 to a few percent) over 6 decades below Nyquist
// (discrete) or around the model's fastest eigenvalue (continuous).
constexpr Index kScoreGridPoints = 200;
constexpr double kScoreGridDecades = 6.0;
// See `better_candidate` below.
constexpr double kUnstableWinFactor = 2.0;
// The refit band starts a decade above the fastest removed mode (as a
// continuous-time rate), where its own response has rolled off to a tail.
constexpr double kRefitBandFactor = 10.0;

double norm2(const Eigen::MatrixXcd& M) {
  if (M.size() == 0) return 0.0;
  return Eigen::JacobiSVD<Eigen::MatrixXcd>(M).singularValues()(0);
}

struct Candidate {
  StateSpace model;
  std::vector<size_t> groups;
  double score = INFINITY;
  bool stable = false;
  bool valid = false;
};

std::string format_poles(const std::vector<Complex>& p) {
  std::string s;
  for (size_t i = 0; i < p.size(); ++i) {
    if (i) s += ", ";
    s += p[i].imag() == 0.0 ? fmt::format("{:.6g}", p[i].real()) : fmt::format("{:.6g}{:+.3g}j", p[i].real(), p[i].imag());
  }
  return s;
}

// The models against each other and the plant order; returns that order.
Index checked_plant_order(const StateSpace& closed_loop, const StateSpace& controller, const UnloopOptions& options) {
  options.validate();
  closed_loop.validate();
  controller.validate();
  const double tg = closed_loop.sample_period_s, tc = controller.sample_period_s;
  if (!(tg == 0.0 && tc == 0.0) &&
      !(tg > 0.0 && tc > 0.0 && std::abs(tg - tc) <= kSamplePeriodRelTolerance * std::max(tg, tc)))
    throw InputError(fmt::format("unloop: the closed loop has ts = {} s but the controller ts = {} s (0 = continuous); "
                                 "identify and control at the same sample period",
                                 tg, tc));
  const Index m = closed_loop.num_inputs(), p = closed_loop.num_outputs();
  if (controller.num_inputs() != p || controller.num_outputs() != m)
    throw InputError(fmt::format("unloop: the controller is {}x{} (outputs x inputs) but the closed loop v → q is {}x{}; "
                                 "give the controller that maps the {} outputs back to the {} inputs",
                                 controller.num_outputs(), controller.num_inputs(), p, m, p, m));
  const Index nG = closed_loop.order(), nC = controller.order(), N = nG + nC;
  const Index target = options.plant_order > 0 ? options.plant_order : nG - nC;
  if (target < 1 || target > N)
    throw InputError(fmt::format("unloop: plant order {} (n_G = {}, n_C = {}); it must be in [1, {}]: set plant_order explicitly",
                                 target, nG, nC, N));
  return target;
}

// The selection score's grid and the full interconnection's response on it.
struct ScoreGrid {
  Eigen::VectorXd grid;
  std::vector<Eigen::MatrixXcd> h_full;
};

ScoreGrid score_grid(const StateSpace& full) {
  ScoreGrid sg;
  Eigen::VectorXd& grid = sg.grid;
  if (full.is_discrete()) {
    const double nyq = M_PI / full.sample_period_s;
    grid = log_frequency_grid(nyq * std::pow(10.0, -kScoreGridDecades), nyq * 0.999, kScoreGridPoints);
  } else {
    const Eigen::VectorXcd ev = poles(full);
    double rho = 1.0;
    for (Index i = 0; i < ev.size(); ++i) rho = std::max(rho, std::abs(ev[i]));
    grid = log_frequency_grid(10.0 * rho * std::pow(10.0, -kScoreGridDecades), 10.0 * rho, kScoreGridPoints);
  }
  try {
    sg.h_full = evaluate_response(full, grid);
  } catch (const InputError&) {
    // A grid point hit a pole exactly (measure zero); shift the grid slightly.
    grid *= 1.0 + 1e-7;
    sg.h_full = evaluate_response(full, grid);
  }
  return sg;
}

// The mean relative change of the response from the full interconnection's (+inf when
// `kept` cannot be evaluated); removed_rel: the peak of that change over the kept peak.
double removal_score(const ScoreGrid& sg, const StateSpace& kept, double* removed_rel) {
  std::vector<Eigen::MatrixXcd> h;
  try {
    h = evaluate_response(kept, sg.grid);
  } catch (const InputError&) {
    return INFINITY;
  }
  double s = 0.0, peak_diff = 0.0, peak_kept = 0.0;
  for (size_t i = 0; i < h.size(); ++i) {
    const double nf = norm2(sg.h_full[i]), nk = norm2(h[i]), nd = norm2(h[i] - sg.h_full[i]);
    s += nd / std::max(nf + nk, 1e-300);
    peak_diff = std::max(peak_diff, nd);
    peak_kept = std::max(peak_kept, nk);
  }
  if (removed_rel) *removed_rel = peak_diff / std::max(peak_kept, 1e-300);
  return s / static_cast<double>(h.size());
}

// Eigenvalue groups (real, or a complex pair with Im > 0 representative) and their states.
struct ModeGroups {
  std::vector<Complex> gval;
  std::vector<Index> gsize;
};

ModeGroups mode_groups(const Eigen::VectorXcd& ev) {
  ModeGroups g;
  for (Index i = 0; i < ev.size(); ++i) {
    if (ev[i].imag() < 0.0) continue;  // EigenSolver gives exact conjugate pairs
    g.gval.push_back(ev[i]);
    g.gsize.push_back(ev[i].imag() > 0.0 ? 2 : 1);
  }
  return g;
}

// The groups nearest the controller poles, nearest first, until they hold `states` states.
std::vector<size_t> groups_near_controller(const ModeGroups& g, const Eigen::VectorXcd& cpoles, Index states) {
  const std::vector<Complex>& gval = g.gval;
  std::vector<double> dist(gval.size());
  for (size_t i = 0; i < gval.size(); ++i) {
    double d = INFINITY;
    for (Index j = 0; j < cpoles.size(); ++j)
      d = std::min({d, std::abs(gval[i] - cpoles[j]), std::abs(std::conj(gval[i]) - cpoles[j])});
    dist[i] = d;
  }
  std::vector<size_t> order(gval.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dist[a] < dist[b]; });
  std::vector<size_t> pool;
  Index pool_states = 0;
  for (size_t i : order) {
    if (pool_states >= states) break;
    pool.push_back(i);
    pool_states += g.gsize[i];
  }
  return pool;
}

// The interconnection without the modes of `groups`, scored.
Candidate evaluate_removal(const StateSpace& full, const ModeGroups& g, const ScoreGrid& sg,
                           const std::vector<size_t>& groups) {
  Candidate c;
  c.groups = groups;
  Index cnt = 0;
  for (size_t gi : groups) cnt += g.gsize[gi];
  Eigen::VectorXcd targets(cnt);
  Index t = 0;
  for (size_t gi : groups) {
    targets[t++] = g.gval[gi];
    if (g.gsize[gi] == 2) targets[t++] = std::conj(g.gval[gi]);
  }
  try {
    c.model = remove_modes(full, targets, cnt);
  } catch (const InputError&) {
    return c;
  }
  c.score = removal_score(sg, c.model, nullptr);
  c.stable = is_stable(c.model);
  c.valid = std::isfinite(c.score);
  return c;
}

bool better_candidate(const Candidate& a, const Candidate& b) {
  if (!a.valid) return false;
  if (!b.valid) return true;
  // A stable candidate wins unless an unstable one changes the response
  // less than half as much: a maglev plant is open-loop unstable, so
  // stability alone must not decide.
  if (a.stable != b.stable) return a.stable ? a.score <= kUnstableWinFactor * b.score : a.score * kUnstableWinFactor < b.score;
  return a.score < b.score;
}

// Count the candidate sets (subsets of pool groups with exactly k_remove states):
// ways[i][s], the subsets of pool[i..] with s states.
std::vector<std::vector<double>> count_candidate_sets(const ModeGroups& g, const std::vector<size_t>& pool,
                                                      Index k_remove) {
  const std::vector<Index>& gsize = g.gsize;
  std::vector<std::vector<double>> ways(pool.size() + 1, std::vector<double>(static_cast<size_t>(k_remove) + 1, 0.0));
  ways[pool.size()][0] = 1.0;
  for (size_t i = pool.size(); i-- > 0;)
    for (Index s = 0; s <= k_remove; ++s)
      ways[i][static_cast<size_t>(s)] =
          ways[i + 1][static_cast<size_t>(s)] + (s >= gsize[pool[i]] ? ways[i + 1][static_cast<size_t>(s - gsize[pool[i]])] : 0.0);
  return ways;
}

// The best of every candidate set (counted by `ways`).
Candidate best_of_all_sets(const StateSpace& full, const ModeGroups& g, const ScoreGrid& sg,
                           const std::vector<size_t>& pool, const std::vector<std::vector<double>>& ways,
                           Index k_remove, Index& evaluated) {
  const std::vector<Index>& gsize = g.gsize;
  Candidate best;
  std::vector<size_t> chosen;
  std::function<void(size_t, Index)> rec = [&](size_t i, Index left) {
    if (left == 0) {
      Candidate c = evaluate_removal(full, g, sg, chosen);
      ++evaluated;
      if (better_candidate(c, best)) best = std::move(c);
      return;
    }
    if (i >= pool.size() || ways[i][static_cast<size_t>(left)] == 0.0) return;
    if (gsize[pool[i]] <= left) {
      chosen.push_back(pool[i]);
      rec(i + 1, left - gsize[pool[i]]);
      chosen.pop_back();
    }
    rec(i + 1, left);
  };
  rec(0, k_remove);
  return best;
}

// Greedy: add the group whose removal (together with those chosen) scores best.
Candidate greedy_removal(const StateSpace& full, const ModeGroups& g, const ScoreGrid& sg,
                         const std::vector<size_t>& pool, Index k_remove, Index& evaluated) {
  const std::vector<Index>& gsize = g.gsize;
  Candidate best;
  std::vector<size_t> chosen;
  Index have = 0;
  while (have < k_remove) {
    Candidate step;
    for (size_t gi : pool) {
      if (std::find(chosen.begin(), chosen.end(), gi) != chosen.end() || have + gsize[gi] > k_remove) continue;
      std::vector<size_t> trial = chosen;
      trial.push_back(gi);
      Candidate c = evaluate_removal(full, g, sg, trial);
      ++evaluated;
      if (better_candidate(c, step)) step = std::move(c);
    }
    if (!step.valid) break;
    chosen = step.groups;
    have = 0;
    for (size_t gi : chosen) have += gsize[gi];
    best = std::move(step);
  }
  return best;
}

// Removes k_remove states of modes near the controller poles from `kept` (the full
// interconnection of N states), choosing among the groups of the nearest pool_states
// states; appends the removed eigenvalues to `removed` and returns how the set was found.
std::string remove_controller_modes(const StateSpace& full, const StateSpace& controller, const ScoreGrid& sg, Index N,
                                    Index k_remove, Index pool_states, StateSpace& kept, std::vector<Complex>& removed) {
  const ModeGroups g = mode_groups(poles(full));
  const std::vector<size_t> pool = groups_near_controller(g, poles(controller), pool_states);
  const std::vector<std::vector<double>> ways = count_candidate_sets(g, pool, k_remove);
  const double num_sets = ways[0][static_cast<size_t>(k_remove)];

  Candidate best;
  Index evaluated = 0;
  std::string how;
  if (num_sets >= 1.0 && num_sets <= static_cast<double>(kMaxCandidateSets)) {
    best = best_of_all_sets(full, g, sg, pool, ways, k_remove, evaluated);
    how = fmt::format("best of {} candidate sets", evaluated);
  } else {
    best = greedy_removal(full, g, sg, pool, k_remove, evaluated);
    how = fmt::format("greedy search, {} evaluations", evaluated);
  }
  if (!best.valid)
    throw NumericalError(fmt::format("unloop: no set of {} modes near the controller poles could be removed from the {}-state "
                                     "interconnection (complex pairs straddle the count); set plant_order explicitly",
                                     k_remove, N));
  kept = best.model;
  for (size_t gi : best.groups) {
    removed.push_back(g.gval[gi]);
    if (g.gsize[gi] == 2) removed.push_back(std::conj(g.gval[gi]));
  }
  return how;
}

// Refit the input matrix of the kept model to P_full above the removed
// cluster: with a noisy G the removed modes' residues do not sum to zero, and
// their tail Σ R_i/(λ − λ_i) is part of the measured response in the band.
// Linear least squares in B (poles, C, D fixed), each frequency weighted by
// 1/‖P_full(ω)‖ (relative fit).  Returns the note for the termination line ("" when
// not refitted).
std::string refit_input_matrix(const StateSpace& full, const ScoreGrid& sg, const std::vector<Complex>& removed,
                               Index p, Index m, StateSpace& kept) {
  const Eigen::VectorXd& grid = sg.grid;
  const std::vector<Eigen::MatrixXcd>& h_full = sg.h_full;
  std::string refit;
  if (!removed.empty() && kept.order() > 0) {
    double s_max = 0.0;
    for (const Complex& z : removed)
      s_max = std::max(s_max, full.is_discrete() ? std::abs(std::log(z)) / full.sample_period_s : std::abs(z));
    const double w_lo = kRefitBandFactor * s_max;
    std::vector<Index> band;
    for (Index k = 0; k < grid.size(); ++k)
      if (grid[k] >= w_lo) band.push_back(k);
    const Index nk = kept.order();
    if (static_cast<Index>(band.size()) * p >= 2 * nk) {
      Eigen::MatrixXd L(2 * p * static_cast<Index>(band.size()), nk);
      Eigen::MatrixXd R(L.rows(), m);
      for (size_t b = 0; b < band.size(); ++b) {
        const Index k = band[b];
        const double w = grid[k];
        const Complex lambda = full.is_discrete() ? std::polar(1.0, w * full.sample_period_s) : Complex(0.0, w);
        Eigen::MatrixXcd M = -kept.A.cast<Complex>();
        M.diagonal().array() += lambda;
        // C (λI − A)⁻¹ = ((λI − A)ᵀ⁻¹ Cᵀ)ᵀ
        const Eigen::MatrixXcd CR = M.transpose().partialPivLu().solve(kept.C.transpose().cast<Complex>()).transpose();
        const double wt = 1.0 / std::max(norm2(h_full[static_cast<size_t>(k)]), 1e-300);
        const Eigen::MatrixXcd rhs = h_full[static_cast<size_t>(k)] - kept.D.cast<Complex>();
        const Index r0 = 2 * p * static_cast<Index>(b);
        L.middleRows(r0, p) = wt * CR.real();
        L.middleRows(r0 + p, p) = wt * CR.imag();
        R.middleRows(r0, p) = wt * rhs.real();
        R.middleRows(r0 + p, p) = wt * rhs.imag();
      }
      StateSpace trial = kept;
      trial.B = L.colPivHouseholderQr().solve(R);
      if (trial.B.allFinite()) {
        kept = trial;
        refit = fmt::format("; input matrix refitted to G(I − CG)⁻¹ above {:.3g} rad/s", w_lo);
      }
    }
  }
  return refit;
}

}  // namespace

void UnloopOptions::validate() const {
  if (plant_order < 0)
    throw InputError(fmt::format("unloop: plant_order = {}; it must be >= 1, or 0 for n_G − n_C", plant_order));
  if (extra_candidates < 0 || extra_candidates > 20)
    throw InputError(fmt::format("unloop: extra_candidates = {}; it must be in [0, 20]", extra_candidates));
  if (!(removed_gain_warning > 0.0) || !std::isfinite(removed_gain_warning))
    throw InputError(fmt::format("unloop: removed_gain_warning = {}; it must be finite and > 0", removed_gain_warning));
}

UnloopResult plant_from_closed_loop(const StateSpace& closed_loop, const StateSpace& controller, const UnloopOptions& options) {
  const Index target = checked_plant_order(closed_loop, controller, options);
  const Index m = closed_loop.num_inputs(), p = closed_loop.num_outputs();
  const Index nC = controller.order(), N = closed_loop.order() + nC;

  UnloopResult result;
  result.interconnection_order = N;
  // Step 0: make the controller's modes cancel exactly (interpolation.h).
  StateSpace g_used = closed_loop;
  if (options.impose_controller_interpolation) {
    const InterpolationCorrection corr = impose_controller_interpolation(closed_loop, controller);
    g_used = corr.closed_loop;
    result.interpolation_note = corr.note;
    result.interpolation_applied = corr.applied;
  }
  const StateSpace full = positive_feedback_with(g_used, controller);  // throws on algebraic loops
  const Index k_remove = std::min(2 * nC, N - target);
  const ScoreGrid sg = score_grid(full);

  StateSpace kept = full;
  std::vector<Complex> removed;
  std::string how;
  // With the interpolation conditions imposed the controller modes are exact:
  // the k nearest eigenvalues are the ones, no search needed.
  if (k_remove > 0)
    how = remove_controller_modes(full, controller, sg, N, k_remove,
                                  k_remove + (result.interpolation_applied ? 0 : options.extra_candidates), kept, removed);
  const std::string refit = refit_input_matrix(full, sg, removed, p, m, kept);

  std::string tail;
  if (kept.order() > target) {
    if (is_stable(kept)) {
      kept = balanced_truncation(kept, target);
      tail = fmt::format("; balanced truncation to order {}", target);
    } else {
      result.report.warnings.push_back(fmt::format(
          "order {} after removing the controller modes exceeds plant_order {} but the model is unstable: no truncation done",
          kept.order(), target));
    }
  }
  removal_score(sg, kept, &result.removed_relative_gain);

  result.plant = kept;
  result.plant.input_names = closed_loop.input_names;
  result.plant.output_names = closed_loop.output_names;
  result.removed_poles = Eigen::Map<const Eigen::VectorXcd>(removed.data(), static_cast<Index>(removed.size()));
  result.report.termination = fmt::format(
      "plant of order {} from the {}-state interconnection G(I − CG)⁻¹: removed {} modes near the controller poles ({}): {}{}; "
      "removed part peak gain {:.3g} of the plant's",
      kept.order(), N, removed.size(), how.empty() ? "none to remove" : how, format_poles(removed), refit + tail,
      result.removed_relative_gain);
  if (!result.interpolation_note.empty()) result.report.termination += "; " + result.interpolation_note;
  if (result.removed_relative_gain > options.removed_gain_warning)
    result.report.warnings.push_back(fmt::format(
        "the removed modes carried {:.3g} of the plant's peak gain (threshold {:.3g}): the controller modes did not cancel "
        "exactly, so the identified closed loop is inaccurate near the controller poles",
        result.removed_relative_gain, options.removed_gain_warning));
  if (!is_stable(result.plant)) {
    result.report.warnings.push_back(
        "the recovered plant is unstable (a pole on or outside the stability boundary): expected for an open-loop unstable "
        "(e.g. magnetically levitated) plant, otherwise check the closed-loop model and the controller");
  }
  return result;
}

}  // namespace lpvid
