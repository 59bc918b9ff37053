#include "idlib/identify/direct.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/QR>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/core/error.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/interconnect.h"

namespace lpvid {

StateSpace arx_strictly_proper(const std::vector<ExperimentView>& experiments, Index order, double sample_period_s) {
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
  const Index cols = order * (p + m) + E;
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
    Phi.block(row, order * (p + m), n, E).setZero();
    Phi.block(row, order * (p + m) + e, n, 1).setOnes();
    Y.middleRows(row, n) = x.output.bottomRows(n);
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
  s.B = Eigen::MatrixXd::Zero(n, m);
  s.C = Eigen::MatrixXd::Zero(p, n);
  s.D = Eigen::MatrixXd::Zero(p, m);
  s.C.leftCols(p).setIdentity();
  for (Index i = 0; i < order; ++i) {
    s.A.block(i * p, 0, p, p) = -theta.middleRows(i * p, p).transpose();
    if (i + 1 < order) s.A.block(i * p, (i + 1) * p, p, p).setIdentity();
    s.B.middleRows(i * p, p) = theta.middleRows(order * p + i * m, m).transpose();
  }
  s.sample_period_s = sample_period_s;
  return s;
}

DirectLadder identify_direct_in_loop(const std::vector<ExperimentView>& loop,
                                     const std::vector<ExperimentView>& applied, double sample_period_s,
                                     const StateSpace& controller, Index max_order, IdentifyResult& result) {
  DirectLadder ladder;
  const std::vector<std::string> input_names = result.plant.input_names, output_names = result.plant.output_names;
  std::optional<IdentifyResult> best;
  double best_bic = std::numeric_limits<double>::infinity();
  for (Index n = 1; n <= max_order; ++n) {
    const StateSpace start = arx_strictly_proper(applied, n, sample_period_s);
    if (start.order() == 0) {
      ladder.rungs.push_back(fmt::format("{}: the ARX regression is rank-deficient", n));
      continue;
    }
    IdentifyResult r = result;
    r.plant = start;
    r.fit.plant = start;
    if (!is_stable(closed_loop_output(start, controller), 0.0)) {
      ladder.rungs.push_back(fmt::format("{}: the ARX start does not close a stable loop", n));
      continue;
    }
    if (loop.empty())
      identify_detail::refine_on_logs(applied, nullptr, r);
    else
      identify_detail::refine_on_logs(loop, &controller, r);
    const auto& f = r.choices.refinement;
    if (f.kept && loop.empty() && !is_stable(closed_loop_output(r.plant, controller), 0.0)) {
      ladder.rungs.push_back(fmt::format("{}: the refined plant does not close a stable loop", n));
      continue;
    }
    if (!f.kept) {
      ladder.rungs.push_back(fmt::format("{}: the refinement in the loop was not kept ({})", n,
                                         r.choices.refinement_reason));
      continue;
    }
    const double N = static_cast<double>(f.residuals);
    const double bic = N * std::log(f.cost / N) + static_cast<double>(f.parameters) * std::log(N);
    ladder.rungs.push_back(fmt::format("{}: normalised squared simulation error {:.4g}, BIC {:.6g}", n, f.cost, bic));
    if (bic < best_bic) {
      best_bic = bic;
      ladder.order = r.plant.order();
      best = std::move(r);
    }
  }
  if (!best) {
    ladder.reason = fmt::format("no order 1..{} gave a plant whose loop is stable and fits the logs ({})", max_order,
                                fmt::join(ladder.rungs, "; "));
    return ladder;
  }
  ladder.found = true;
  ladder.reason = fmt::format(
      "strictly proper ARX starts on the input the loop applied, each refined by output error in its loop, the order "
      "by BIC: {}; order {} taken",
      fmt::join(ladder.rungs, "; "), ladder.order);
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
