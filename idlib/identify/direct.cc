#include "idlib/identify/direct.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/core/error.h"
#include "idlib/core/parallel.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {

namespace {

// arx_strictly_proper, with two options for the direct route's friction rungs: `weights`
// (per experiment N_e, each equation weighed by its sample's) and `levels` (per experiment N_e x c, or empty): inputs that enter at lag 1 only — levels
// constant over long stretches (a friction's sign between reversals), whose lags the
// stretches cannot tell apart; their B columns are [β; 0; …] (the first block), after u's.
StateSpace arx_fit(const std::vector<ExperimentView>& experiments, Index order, double sample_period_s,
                   const std::vector<Eigen::VectorXd>& weights = {}, const std::vector<Eigen::MatrixXd>& levels = {}) {
  if (order < 1) throw InputError(fmt::format("ARX order {}: give at least 1", order));
  if (experiments.empty()) throw InputError("ARX: no experiments");
  const Index m = experiments.front().excitation.cols(), p = experiments.front().output.cols();
  const Index E = static_cast<Index>(experiments.size());
  Index rows = 0;
  for (const auto& e : experiments) {
    if (e.excitation.rows() < 4 * (order + 1))
      throw InputError(fmt::format("ARX order {}: a record of {} samples is too short (at least {})", order,
                                   e.excitation.rows(), 4 * (order + 1)));
    rows += e.excitation.rows() - order;
  }
  // Regressors [−q(k−1) … −q(k−n), u(k−1) … u(k−n), one-hot experiment]; every output
  // shares them (one least-squares solve, p right-hand sides).  Columns are scaled to
  // unit RMS for the QR's rank decision.
  const Index c = levels.empty() ? 0 : levels.front().cols();
  const Index cols = order * (p + m) + c + E;
  Eigen::MatrixXd Phi(rows, cols);
  Eigen::MatrixXd Y(rows, p);
  Index row = 0;
  for (Index e = 0; e < E; ++e) {
    const auto& x = experiments[static_cast<std::size_t>(e)];
    const Index n = x.excitation.rows() - order;
    for (Index i = 1; i <= order; ++i) {
      Phi.block(row, (i - 1) * p, n, p) = -x.output.middleRows(order - i, n);
      Phi.block(row, order * p + (i - 1) * m, n, m) = x.excitation.middleRows(order - i, n);
    }
    if (c > 0) Phi.block(row, order * (p + m), n, c) = levels[static_cast<std::size_t>(e)].middleRows(order - 1, n);
    Phi.block(row, order * (p + m) + c, n, E).setZero();
    Phi.block(row, order * (p + m) + c + e, n, 1).setOnes();
    Y.middleRows(row, n) = x.output.bottomRows(n);
    if (!weights.empty()) {  // each equation weighed by its sample's weight
      const auto wt = weights[static_cast<std::size_t>(e)].tail(n).asDiagonal();
      Phi.middleRows(row, n) = wt * Phi.middleRows(row, n);
      Y.middleRows(row, n) = wt * Y.middleRows(row, n);
    }
    row += n;
  }
  Eigen::VectorXd scale = (Phi.colwise().squaredNorm() / static_cast<double>(rows)).cwiseSqrt().transpose();
  for (Index j = 0; j < cols; ++j) scale(j) = scale(j) > 0 ? scale(j) : 1.0;
  const Eigen::MatrixXd Ps = Phi * scale.cwiseInverse().asDiagonal();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Ps);
  qr.setThreshold(1e-12);
  if (qr.rank() < cols) return StateSpace{};
  const Eigen::MatrixXd theta = scale.cwiseInverse().asDiagonal() * qr.solve(Y);  // cols x p
  // Block observer form: x(k+1) = A x(k) + B u(k), q(k) = x_1(k).
  const Index n = order * p;
  StateSpace s;
  s.A = Eigen::MatrixXd::Zero(n, n);
  s.B = Eigen::MatrixXd::Zero(n, m + c);
  s.C = Eigen::MatrixXd::Zero(p, n);
  s.D = Eigen::MatrixXd::Zero(p, m + c);
  s.C.leftCols(p).setIdentity();
  for (Index i = 0; i < order; ++i) {
    s.A.block(i * p, 0, p, p) = -theta.middleRows(i * p, p).transpose();
    if (i + 1 < order) s.A.block(i * p, (i + 1) * p, p, p).setIdentity();
    s.B.block(i * p, 0, p, m) = theta.middleRows(order * p + i * m, m).transpose();
  }
  if (c > 0) s.B.block(0, m, p, c) = theta.middleRows(order * (p + m), c).transpose();
  s.sample_period_s = sample_period_s;
  return s;
}

// The controller with `extra` more outputs, all zero: exogenous plant inputs the loop
// passes through untouched.
StateSpace with_zero_outputs(const StateSpace& c, Index extra) {
  StateSpace k = c;
  k.C.conservativeResize(c.C.rows() + extra, Eigen::NoChange);
  k.C.bottomRows(extra).setZero();
  k.D.conservativeResize(c.D.rows() + extra, Eigen::NoChange);
  k.D.bottomRows(extra).setZero();
  k.output_names.clear();
  return k;
}

// The plant of the first m inputs of `r` (fitted with friction inputs beside them), its
// covariance the matching rows and columns of [vec A; vec B; vec C]; the friction as
// forces at those inputs, by the loop's steady state: a constant force at the plant's
// input moves the loop's output by G_u(1) per unit, a friction input by G_w(1), so the
// force it stands for is F = G_u(1)⁺ G_w(1).  (Not the ratio of the B columns: between
// reversals the signs are constant, so the logs fix only their steady effect, not their
// columns' shape.)
DirectFriction keep_plant_inputs(IdentifyResult& r, Index m, const StateSpace& controller_w) {
  StateSpace& P = r.plant;
  const Index n = P.order(), p = P.num_outputs(), mw = P.num_inputs() - m;
  const StateSpace loop = closed_loop_output(P, controller_w);  // [v, w] -> q, stable
  const Eigen::MatrixXd G1 =
      loop.C * (Eigen::MatrixXd::Identity(loop.order(), loop.order()) - loop.A).partialPivLu().solve(loop.B) + loop.D;
  DirectFriction f;
  const Eigen::MatrixXd F = G1.leftCols(m).colPivHouseholderQr().solve(G1.rightCols(mw));  // m x mw
  f.coulomb = F.leftCols(p);  // [sign (p), constant]: the constant's is not determined (direct.h)
  const Eigen::MatrixXd Bu = P.B.leftCols(m);
  P.B = Bu;
  P.D = P.D.leftCols(m).eval();
  P.input_names.clear();
  r.fit.plant.B = P.B;
  r.fit.plant.D = Eigen::MatrixXd::Zero(p, m);
  r.fit.plant.input_names.clear();
  if (r.fit.covariance.size() > 0) {
    std::vector<Index> keep;
    for (Index i = 0; i < n * n + n * m; ++i) keep.push_back(i);
    for (Index i = n * n + n * (m + mw); i < n * n + n * (m + mw) + p * n; ++i) keep.push_back(i);
    const Eigen::MatrixXd& S = r.fit.covariance;
    Eigen::MatrixXd K(keep.size(), keep.size());
    for (std::size_t i = 0; i < keep.size(); ++i)
      for (std::size_t j = 0; j < keep.size(); ++j) K(static_cast<Index>(i), static_cast<Index>(j)) = S(keep[i], keep[j]);
    r.fit.covariance = std::move(K);
  }
  return f;
}

}  // namespace

StateSpace arx_strictly_proper(const std::vector<ExperimentView>& experiments, Index order, double sample_period_s) {
  return arx_fit(experiments, order, sample_period_s);
}

Eigen::MatrixXd friction_inputs(const Eigen::Ref<const Eigen::MatrixXd>& output) {
  const Index N = output.rows(), p = output.cols(), h = kFrictionHalfWindow;
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(N, p + 1);
  w.col(p).setOnes();
  if (N < 2) return w;
  for (Index j = 0; j < p; ++j) {
    Eigen::VectorXd v(N);
    for (Index k = 0; k < N; ++k) v(k) = output(std::min(N - 1, k + h), j) - output(std::max<Index>(0, k - h), j);
    const double band = kFrictionDeadband * v.cwiseAbs().maxCoeff();
    for (Index k = 0; k < N; ++k) w(k, j) = v(k) > band ? 1.0 : v(k) < -band ? -1.0 : 0.0;
  }
  return w;
}

namespace {

// Friction: the inputs w = [sign, 1] (friction_inputs) beside u.  Where the axis rests
// (every sign 0) a stuck axis's friction holds whatever balances the applied force,
// which neither model follows, and the loop then settles from that mismatch: those
// samples are left out of the criterion (weight 0), the simulation running through
// them — the rests and `settle` samples after each (per rung: five time constants of
// the slowest pole of the ARX start's loop, at most half the median moving stretch).
// The views point into the matrices held here: filled in place, never copied.
struct FrictionData {
  std::vector<Eigen::MatrixXd> x_applied_w, x_loop_w, levels;  // [u, w], [v, w], the signs
  std::vector<ExperimentView> applied_w, loop_w;
  std::vector<Eigen::VectorXd> rests;  // 1 where the axis rests
  Index settle_cap = 0;
  StateSpace controller_w;  // the controller with zero outputs for w
  FrictionData() = default;
  FrictionData(const FrictionData&) = delete;
  FrictionData& operator=(const FrictionData&) = delete;

  // 0 at rest and for `settle` samples after each rest, else 1.
  std::vector<Eigen::VectorXd> weights(Index settle) const {
    std::vector<Eigen::VectorXd> out;
    for (const Eigen::VectorXd& rest : rests) {
      Eigen::VectorXd wt = Eigen::VectorXd::Ones(rest.size());
      Index since = settle + 1;
      for (Index k = 0; k < rest.size(); ++k) {
        since = rest(k) == 1.0 ? 0 : since + 1;
        if (since <= settle) wt(k) = 0.0;
      }
      out.push_back(std::move(wt));
    }
    return out;
  }
};

void fill_friction_data(FrictionData& fd, const std::vector<ExperimentView>& applied,
                        const std::vector<ExperimentView>& loop, const StateSpace& controller) {
  const Index m = controller.num_outputs(), p = applied.front().output.cols(), mw = p + 1;
  std::vector<Index> stretch_rows;  // the moving stretches' lengths
  for (std::size_t e = 0; e < applied.size(); ++e) {
    const Eigen::MatrixXd w = friction_inputs(applied[e].output);
    const Index N = w.rows();
    Eigen::VectorXd rest(N);
    Index run = 0;
    for (Index k = 0; k < N; ++k) {
      rest(k) = w.row(k).head(p).isZero(0.0) ? 1.0 : 0.0;
      if (rest(k) == 0.0) ++run;
      if ((rest(k) == 1.0 || k + 1 == N) && run > 0) {
        stretch_rows.push_back(run);
        run = 0;
      }
    }
    Eigen::MatrixXd aw(N, m + mw);
    aw << applied[e].excitation, w;
    fd.levels.push_back(w.leftCols(p));
    fd.x_applied_w.push_back(std::move(aw));
    fd.rests.push_back(std::move(rest));
    if (!loop.empty()) {
      Eigen::MatrixXd lw(N, m + mw);
      lw << loop[e].excitation, w;
      fd.x_loop_w.push_back(std::move(lw));
    }
  }
  for (std::size_t e = 0; e < applied.size(); ++e) {
    fd.applied_w.push_back({fd.x_applied_w[e], applied[e].output});
    if (!loop.empty()) fd.loop_w.push_back({fd.x_loop_w[e], loop[e].output});
  }
  fd.controller_w = with_zero_outputs(controller, mw);
  if (!stretch_rows.empty()) {
    std::nth_element(stretch_rows.begin(), stretch_rows.begin() + static_cast<std::ptrdiff_t>(stretch_rows.size() / 2),
                     stretch_rows.end());
    fd.settle_cap = stretch_rows[stretch_rows.size() / 2] / 2;
  }
}

}  // namespace

DirectLadder identify_direct_in_loop(const std::vector<ExperimentView>& loop,
                                     const std::vector<ExperimentView>& applied, double sample_period_s,
                                     const StateSpace& controller, Index max_order, IdentifyResult& result,
                                     bool friction) {
  DirectLadder ladder;
  const std::vector<std::string> input_names = result.plant.input_names, output_names = result.plant.output_names;
  const Index m = controller.num_outputs(), p = applied.front().output.cols();

  // One rung: order n, linear or (`friction`) with the friction inputs and their
  // residual weights, on the given data.
  struct Rung {
    std::string text;                       // the sentence of the ladder
    std::optional<IdentifyResult> fit;      // when the rung gave a plant
    std::optional<DirectFriction> friction;
    double bic = std::numeric_limits<double>::infinity();
  };
  const auto rung = [&](Index n, const StateSpace& start, const std::vector<ExperimentView>& on_loop,
                        const std::vector<ExperimentView>& on_applied, const StateSpace& K,
                        const std::vector<Eigen::VectorXd>& weights) {
    const std::string label = friction ? " with friction" : "";
    Rung out;
    IdentifyResult r = result;
    r.plant = start;
    r.fit.plant = start;
    if (!is_stable(closed_loop_output(start, K), 0.0)) {
      out.text = fmt::format("{}{}: the ARX start does not close a stable loop", n, label);
      return out;
    }
    if (loop.empty())
      identify_detail::refine_on_logs(on_applied, nullptr, r, weights);
    else
      identify_detail::refine_on_logs(on_loop, &K, r, weights);
    const auto& f = r.choices.refinement;
    if (!f.kept) {
      out.text = fmt::format("{}{}: the refinement in the loop was not kept ({})", n, label,
                             r.choices.refinement_reason);
      return out;
    }
    if (friction) out.friction = keep_plant_inputs(r, m, K);
    if (loop.empty() && !is_stable(closed_loop_output(r.plant, controller), 0.0)) {
      out.text = fmt::format("{}{}: the refined plant does not close a stable loop", n, label);
      out.friction.reset();
      return out;
    }
    if (friction) r.closed_loop = loop.empty() ? r.plant : closed_loop_output(r.plant, controller);
    const double N = static_cast<double>(f.residuals);
    out.bic = N * std::log(f.cost / N) + static_cast<double>(f.parameters) * std::log(N);
    out.text = fmt::format("{}{}: normalised squared simulation error {:.4g}, BIC {:.6g}", n, label, f.cost, out.bic);
    out.fit = std::move(r);
    return out;
  };

  FrictionData fd;
  if (friction) fill_friction_data(fd, applied, loop, controller);

  // The orders are independent: each on a core of its own (parallel_for; the choice
  // below runs in order, so the result does not depend on the schedule).  Orders 3-4
  // of a 30 000-sample log take most of the ladder's time.
  const auto one_order = [&](Index n) {
    // The ARX start of u alone (the linear rung; with friction, its loop gives the settling time).
    const StateSpace arx = arx_fit(applied, n, sample_period_s);
    if (arx.order() == 0) return Rung{fmt::format("{}: the ARX regression is rank-deficient", n), {}, {}};
    if (!friction) return rung(n, arx, loop, applied, controller, {});
    // The settling time from the linear start's loop; the start with friction: the ARX of
    // u with the signs as levels (arx_fit) on the weighed samples, the constant's column
    // zero (the ARX's offset is its own).
    const Eigen::VectorXd rho = poles(closed_loop_output(arx, controller)).cwiseAbs();
    const double slowest = rho.size() > 0 ? rho.maxCoeff() : 0.0;
    const Index settle =
        slowest > 0.0 && slowest < 1.0
            ? std::min(fd.settle_cap, static_cast<Index>(std::ceil(5.0 / -std::log(slowest))))
            : fd.settle_cap;
    const std::vector<Eigen::VectorXd> weights = fd.weights(settle);
    const StateSpace sw = arx_fit(applied, n, sample_period_s, weights, fd.levels);
    if (sw.order() == 0) return Rung{fmt::format("{} with friction: the ARX regression is rank-deficient", n), {}, {}};
    StateSpace start = sw;
    start.B.conservativeResize(Eigen::NoChange, m + p + 1);
    start.B.rightCols(1).setZero();
    start.D = Eigen::MatrixXd::Zero(sw.C.rows(), m + p + 1);
    Rung out = rung(n, start, fd.loop_w, fd.applied_w, fd.controller_w, weights);
    out.text += fmt::format(" (rests and {} samples after each left out)", settle);
    return out;
  };
  std::vector<Rung> rungs(static_cast<std::size_t>(std::max<Index>(max_order, 0)));
  parallel_for(max_order, [&](Index i) { rungs[static_cast<std::size_t>(i)] = one_order(i + 1); });

  // The order by BIC (the first of equals).
  std::optional<IdentifyResult> best;
  std::optional<DirectFriction> best_friction;
  double best_bic = std::numeric_limits<double>::infinity();
  for (Index i = 0; i < max_order; ++i) {
    Rung& g = rungs[static_cast<std::size_t>(i)];
    ladder.rungs.push_back(g.text);
    if (g.fit && g.bic < best_bic) {
      best_bic = g.bic;
      ladder.order = g.fit->plant.order();
      ladder.arx_order = i + 1;
      best = std::move(g.fit);
      best_friction = g.friction;
    }
  }
  if (!best) {
    ladder.reason = fmt::format("no order 1..{} gave a plant whose loop is stable and fits the logs ({})", max_order,
                                fmt::join(ladder.rungs, "; "));
    return ladder;
  }
  ladder.found = true;
  ladder.friction = best_friction;
  ladder.reason = fmt::format(
      "strictly proper ARX starts on the input the loop applied, each refined by output error in its loop, the order "
      "by BIC: {}; order {}{} taken",
      fmt::join(ladder.rungs, "; "), ladder.order,
      best_friction ? " with friction (its linear part the plant)" : "");
  result = std::move(*best);
  result.plant.input_names = input_names;  // the refinement's model carries none
  result.plant.output_names = output_names;
  if (loop.empty()) result.closed_loop = result.plant;  // open-loop data: what the logs' fit simulates
  result.warnings.clear();  // the unrefined route's (its fit is not the plant's)
  IdentifyChoices& ch = result.choices;
  ch.plant_order = ladder.order;
  ch.order_reason = ladder.reason;
  ch.start_reason = "the direct route: strictly proper ARX models of u -> q (the input the loop applied), orders 1.." +
                    std::to_string(max_order) + " (the Markov estimate above is of u -> q and only reported)";
  ch.tail_reason = "none: the direct route fits the logs in the time domain, with no truncated response";
  const std::string structured = "(the structured fit, from rest)";
  if (const auto at = ch.refinement_reason.find(structured); at != std::string::npos)
    ch.refinement_reason.replace(at, structured.size(), "(the ARX start, from rest)");
  return ladder;
}

}  // namespace lpvid
