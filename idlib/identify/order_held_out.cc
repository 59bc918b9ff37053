// The plant order of identify_open_loop checked on data kept out of the fit (issue 24:
// "the order chosen on data not used for the fit").
//
// The ladder (identify_order.cc) chooses the order against the noise floor of the Markov
// estimate; the output-error refinement then fits the logs themselves.  Neither sees data
// the fit did not use.  Here the whole procedure (the structured fit at a given order and
// its refinement) is run on the first half of every record and the second half is
// predicted — the model simulated on the held-out input, its initial state fitted by
// least squares as MATLAB compare's 'e' does (the half does not start from rest) — then
// the halves swap.  Orders n − 2 .. n + 2 around the ladder's n are tried.
//
// Which order predicts better is decided against the spread of the held-out errors, not
// a tolerance: the held-out samples are cut into kBlocks contiguous blocks; for two orders
// a and b, the difference of their normalised squared errors is summed per block, and b
// replaces the ladder's a only when the total difference exceeds kSpreads standard errors
// of it (√(B · var of the block sums)): blocks, not samples, because an output-error
// model's residuals are coloured.  Otherwise the ladder's order stays (the data do not
// prove another better), and the table says how close the others came.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <vector>

#include "idlib/core/error.h"
#include "idlib/identify/identify.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/identify/output_error.h"

namespace lpvid::identify_detail {

namespace {

constexpr Index kOrdersEachSide = 2;
constexpr Index kBlocks = 16;
constexpr double kSpreads = 2.0;
// Each half must hold enough for the ladder's shortest horizon to be a quarter of it.
constexpr Index kMinHalfSamples = 128;
// The check runs 2 × 5 fits; it is skipped when one fit's Jacobian would exceed this
// share of the refinement's own bound (long or wide records: there the ladder and the
// refinement already have data to spare, and the check would cost ten times the fit).
constexpr double kJacobianShare = 0.1;

struct HeldOutErrors {
  bool ok = false;
  std::string failure;
  std::vector<double> per_sample;  // Σ_i (e_i / rms y_i)² at each held-out sample, in a fixed order
  Eigen::VectorXd err2, ref2;      // per output: Σ e², Σ (y − ȳ)²
};

// Fits order k on `train` and predicts `test`, appending to `out`.
void predict_half(const std::vector<ExperimentView>& train, const std::vector<ExperimentView>& test, double Ts,
                  const IdentifyOptions& options, Index num_lags, Index k, const Eigen::VectorXd& scale, HeldOutErrors& out) {
  IdentifyOptions o = options;
  // The horizon the full records had, within a quarter of the shortest half (the ladder's
  // automatic horizon needs 4 x its 256 lags in samples).
  Index shortest = std::numeric_limits<Index>::max();
  for (const ExperimentView& v : train) shortest = std::min(shortest, v.output.rows());
  o.num_lags = std::max<Index>(1, std::min(num_lags, shortest / 4));
  o.markov_horizon_s = 0.0;
  o.plant_order = k;
  o.check_order_held_out = false;
  o.progress = nullptr;
  IdentifyResult r;
  try {
    r = identify_open_loop(train, Ts, o);
  } catch (const std::exception& e) {
    out.ok = false;
    out.failure = fmt::format("the fit on a half failed: {}", e.what());
    return;
  }
  for (const ExperimentView& v : test) {
    const SimulatedOutput s = simulate_with_fitted_start(r.plant, v.excitation, v.output, true);
    if (s.predicted.size() == 0) {
      out.ok = false;
      out.failure = "diverges on a held-out half";
      return;
    }
    const Eigen::MatrixXd e = v.output - s.predicted;
    for (Index t = 0; t < e.rows(); ++t) out.per_sample.push_back(e.row(t).cwiseQuotient(scale.transpose()).squaredNorm());
    out.err2 += e.colwise().squaredNorm().transpose();
    out.ref2 += (v.output.rowwise() - v.output.colwise().mean()).colwise().squaredNorm().transpose();
  }
}

// Total of a − b and its standard error from kBlocks contiguous block sums.
std::pair<double, double> difference_and_spread(const std::vector<double>& a, const std::vector<double>& b) {
  const Index n = static_cast<Index>(a.size());
  const Index blocks = std::min<Index>(kBlocks, n);
  Eigen::VectorXd sums = Eigen::VectorXd::Zero(blocks);
  for (Index t = 0; t < n; ++t) sums(std::min(blocks - 1, t * blocks / n)) += a[t] - b[t];
  const double total = sums.sum();
  const double var = blocks > 1 ? (sums.array() - sums.mean()).square().sum() / static_cast<double>(blocks - 1) : 0.0;
  return {total, std::sqrt(static_cast<double>(blocks) * var)};
}

}  // namespace

IdentifyChoices::HeldOutOrder check_order_held_out(const std::vector<ExperimentView>& experiments, double Ts,
                                                   const IdentifyOptions& options, const IdentifyResult& ladder) {
  IdentifyChoices::HeldOutOrder h;
  const Index n = ladder.plant.order();
  h.ladder_order = n;
  h.chosen_order = n;
  const Index m = experiments.front().excitation.cols(), p = experiments.front().output.cols();
  Index total = 0, shortest = std::numeric_limits<Index>::max();
  for (const ExperimentView& v : experiments) {
    total += v.output.rows();
    shortest = std::min(shortest, v.output.rows());
  }
  if (shortest / 2 < kMinHalfSamples) {
    h.reason = fmt::format("not checked on held-out data: the shortest record ({} samples) does not split into halves "
                           "of {} samples",
                           shortest, kMinHalfSamples);
    return h;
  }
  const Index top = std::min(n + kOrdersEachSide, options.max_order);
  const Index E = static_cast<Index>(experiments.size());
  const double params = static_cast<double>(top * top + top * m + p * top + p * m + top * E + p * E);
  const double entries = static_cast<double>(total / 2) * static_cast<double>(p) * params;
  if (ladder.choices.refinement.form != "full" || entries > kJacobianShare * kMaxOutputErrorJacobianEntries) {
    h.reason = fmt::format("not checked on held-out data: refitting orders {}..{} on each half would take about ten "
                           "times the fit ({:.3g} Jacobian entries each; {} samples × {} outputs); give --plant-order "
                           "to try another order",
                           std::max<Index>(1, n - kOrdersEachSide), top, entries, total, p);
    return h;
  }

  // The outputs' rms about their means over all records: one scale for every order.
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(p), sum2 = Eigen::VectorXd::Zero(p);
  for (const ExperimentView& v : experiments) {
    sum += v.output.colwise().sum().transpose();
    sum2 += v.output.colwise().squaredNorm().transpose();
  }
  const double N = static_cast<double>(total);
  Eigen::VectorXd scale = (sum2 / N - (sum / N).cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
  for (Index i = 0; i < p; ++i)
    if (!(scale(i) > 0)) scale(i) = 1.0;

  std::vector<ExperimentView> first, second;
  for (const ExperimentView& v : experiments) {
    const Index half = v.output.rows() / 2, rest = v.output.rows() - half;
    first.push_back({v.excitation.topRows(half), v.output.topRows(half)});
    second.push_back({v.excitation.bottomRows(rest), v.output.bottomRows(rest)});
  }

  std::vector<HeldOutErrors> errors;
  for (Index k = std::max<Index>(1, n - kOrdersEachSide); k <= top; ++k) {
    HeldOutErrors he;
    he.ok = true;
    he.err2 = Eigen::VectorXd::Zero(p);
    he.ref2 = Eigen::VectorXd::Zero(p);
    predict_half(first, second, Ts, options, ladder.num_lags, k, scale, he);
    if (he.ok) predict_half(second, first, Ts, options, ladder.num_lags, k, scale, he);
    IdentifyChoices::HeldOutOrder::Row row;
    row.order = k;
    row.ok = he.ok;
    row.failure = he.failure;
    if (he.ok) {
      for (double v : he.per_sample) row.cost += v;
      double fit = 0;
      for (Index i = 0; i < p; ++i) fit += he.ref2(i) > 0 ? 100.0 * (1.0 - std::sqrt(he.err2(i) / he.ref2(i))) : 0.0;
      row.fit_percent = fit / static_cast<double>(p);
    }
    h.rows.push_back(row);
    errors.push_back(std::move(he));
  }
  h.ran = true;

  const auto at = [&](Index k) { return static_cast<std::size_t>(k - h.rows.front().order); };
  std::size_t best = h.rows.size();
  for (std::size_t i = 0; i < h.rows.size(); ++i)
    if (h.rows[i].ok && (best == h.rows.size() || h.rows[i].cost < h.rows[best].cost)) best = i;
  std::string table;
  for (const auto& row : h.rows)
    table += (table.empty() ? "" : ", ") + (row.ok ? fmt::format("{}: {:.1f} %", row.order, row.fit_percent)
                                                   : fmt::format("{}: {}", row.order, row.failure));
  const std::string lead = fmt::format("held-out fit (each half fitted alone, the other predicted with its initial "
                                       "state fitted) by order: {}",
                                       table);
  if (best == h.rows.size()) {
    h.reason = lead + fmt::format("; no order predicts the held-out halves: order {} kept", n);
    return h;
  }
  const IdentifyChoices::HeldOutOrder::Row& ladder_row = h.rows[at(n)];
  const Index b = h.rows[best].order;
  if (b == n) {
    h.reason = lead + fmt::format("; order {} predicts best", n);
    return h;
  }
  if (!ladder_row.ok) {
    h.chosen_order = b;
    h.reason = lead + fmt::format("; order {} {}, order {} taken", n, ladder_row.failure, b);
    return h;
  }
  const auto [diff, spread] = difference_and_spread(errors[at(n)].per_sample, errors[best].per_sample);
  if (diff > kSpreads * spread) {
    h.chosen_order = b;
    h.reason = lead + fmt::format("; order {} predicts better than the ladder's {} by {:.3g} standard errors of the "
                                  "difference ({} blocks): order {} taken",
                                  b, n, spread > 0 ? diff / spread : std::numeric_limits<double>::infinity(),
                                  std::min<Index>(kBlocks, static_cast<Index>(errors[best].per_sample.size())), b);
  } else {
    h.reason = lead + fmt::format("; order {} predicts best but within {:g} standard errors of the ladder's {} "
                                  "({:.2g}): the held-out data do not prove it better, order {} kept",
                                  b, kSpreads, n, spread > 0 ? diff / spread : 0.0, n);
  }
  return h;
}

}  // namespace lpvid::identify_detail
