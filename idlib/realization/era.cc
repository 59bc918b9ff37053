#include "idlib/realization/era.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "idlib/realization/hankel.h"

namespace lpvid {

namespace {

// Target size of the smaller side of the Hankel matrix (rows = ceil(600 / p)):
// large enough that noise averages out (signal singular values grow like the
// number of blocks, noise ones like its square root), small enough for a partial
// SVD of ~50 ms (BUILD-NOTES: top-30 of 1500^2 in 0.12 s).
constexpr Index kTargetHankelDim = 600;
// Safety factor between the noise floor and the smallest singular value counted
// as dynamics (see era.h: Weyl bound plus room for a misjudged noise level).
constexpr double kKappa = 3.0;
// Rank tolerance relative to the largest singular value for noise-free data:
// rounding in a Hankel matrix of exact Markov parameters leaves ~1e-15 * s_1.
constexpr double kRelativeRankTolerance = 1e-10;
// The effective length ends where the energy of the remaining tail exceeds its
// expected noise energy N s^2 by less than this many standard deviations
// (s^2 sqrt(2N) for N Gaussian blocks): 5 makes a false detection in pure noise
// rare (~3e-7 per tested length), and a false one only lengthens the span.
constexpr double kEffectiveLengthSigmas = 5.0;
// Noise-free data: the response counts as finished below 1e-9 of its peak.
constexpr double kRelativeLengthTolerance = 1e-9;
// Tail used to estimate the noise when markov_noise_std is empty: the last
// quarter of the lags, at least this many.
constexpr Index kMinTailLags = 16;
// 1.4826 * MAD estimates a Gaussian standard deviation robustly.
constexpr double kMadToStd = 1.4826;
// Balancing passes for derived channel scales; three bring row and column RMS
// within a few per cent of each other for the matrices met here.
constexpr int kBalancingPasses = 3;
// A boundary ratio s_n / s_(n+1) below this is reported as an uncertain order.
constexpr double kClearGapRatio = 2.0;
// Below this ratio of extreme singular values of S = sum_{l<d} A^l the recovery
// of B from the summed lags loses more than ~6 of 16 digits: warn.
constexpr double kMinSumConditioning = 1e-6;
// Named seed of the white-noise Hankel matrix that sets the noise floor.
constexpr std::uint64_t kNoiseFloorSeed = 0x6e6f697365ULL;  // "noise"

void check_sequence(const MarkovSequence& g) {
  if (g.empty()) throw InputError("realize_era: the Markov sequence is empty; pass g[0..L] with L >= 2");
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  if (p == 0 || m == 0)
    throw InputError(fmt::format("realize_era: g[0] is {}x{}; there must be at least one output and one input", p, m));
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (g[k].rows() != p || g[k].cols() != m)
      throw InputError(fmt::format("realize_era: g[{}] is {}x{} but g[0] is {}x{}; every lag must have one shape", k,
                                   g[k].rows(), g[k].cols(), p, m));
    if (!g[k].allFinite())
      throw InputError(fmt::format("realize_era: g[{}] holds NaN or Inf; every Markov parameter must be finite", k));
  }
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  double med = *mid;
  if (v.size() % 2 == 0) med = 0.5 * (med + *std::max_element(v.begin(), mid));
  return med;
}

// Per-entry noise std from the first differences of the tail of g.
Eigen::MatrixXd tail_noise_std(const MarkovSequence& g) {
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  const Index last = static_cast<Index>(g.size()) - 1;
  const Index tail = std::min<Index>(last, std::max<Index>(kMinTailLags, last / 4));
  Eigen::MatrixXd std_dev = Eigen::MatrixXd::Zero(p, m);
  if (tail < 3) return std_dev;
  std::vector<double> diff(static_cast<std::size_t>(tail - 1));
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      for (Index t = 0; t + 1 < tail; ++t) {
        const auto k = static_cast<std::size_t>(last - tail + 1 + t);
        diff[static_cast<std::size_t>(t)] = g[k + 1](i, j) - g[k](i, j);
      }
      const double med = median(diff);
      std::vector<double> dev(diff.size());
      for (std::size_t t = 0; t < diff.size(); ++t) dev[t] = std::abs(diff[t] - med);
      std_dev(i, j) = kMadToStd * median(dev) / std::sqrt(2.0);
    }
  return std_dev;
}

// Balances the RMS of rows and columns of g[1..L] (see era.h, step 1).
void derive_scales(const MarkovSequence& g, bool derive_in, bool derive_out, Eigen::VectorXd& in,
                   Eigen::VectorXd& out) {
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  for (int pass = 0; pass < kBalancingPasses; ++pass) {
    if (derive_out) {
      Eigen::VectorXd row_energy = Eigen::VectorXd::Zero(p);
      for (std::size_t k = 1; k < g.size(); ++k) row_energy += (g[k] * in.asDiagonal()).rowwise().squaredNorm();
      for (Index i = 0; i < p; ++i) out(i) = row_energy(i) > 0.0 ? std::sqrt(row_energy(i)) : 1.0;
    }
    if (derive_in) {
      Eigen::VectorXd col_energy = Eigen::VectorXd::Zero(m);
      for (std::size_t k = 1; k < g.size(); ++k)
        col_energy += (out.cwiseInverse().asDiagonal() * g[k] * in.asDiagonal()).colwise().squaredNorm().transpose();
      for (Index j = 0; j < m; ++j)
        if (col_energy(j) > 0.0) in(j) /= std::sqrt(col_energy(j));
    }
    if (!derive_out) break;  // only the columns move: one pass settles them
  }
}

Index ceil_div(Index a, Index b) { return (a + b - 1) / b; }

// Largest singular value of a white-noise Hankel matrix of this layout whose
// block entries have std scaled_std(i, j).
double noise_floor(const Eigen::MatrixXd& scaled_std, Index rows, Index cols) {
  if (!(scaled_std.maxCoeff() > 0.0)) return 0.0;
  std::mt19937_64 rng(kNoiseFloorSeed);
  std::normal_distribution<double> normal(0.0, 1.0);
  MarkovSequence noise(static_cast<std::size_t>(rows + cols - 1));
  for (auto& e : noise) {
    e.resize(scaled_std.rows(), scaled_std.cols());
    for (Index j = 0; j < e.cols(); ++j)
      for (Index i = 0; i < e.rows(); ++i) e(i, j) = scaled_std(i, j) * normal(rng);
  }
  // Distinct (i + j) of a strided Hankel matrix hold distinct lags, so stride 1
  // from lag 0 has the same distribution.
  return leading_svd(block_hankel(noise, rows, cols, 0, 1), 1).singular_values(0);
}

// The options' per-channel sizes against g's shape.
void check_era_channels(const EraOptions& options, Index p, Index m) {
  if (options.input_scale.size() > 0 && options.input_scale.size() != m)
    throw InputError(fmt::format("ERA: input_scale has {} entries for {} inputs; give one per input or none",
                                 options.input_scale.size(), m));
  if (options.output_scale.size() > 0 && options.output_scale.size() != p)
    throw InputError(fmt::format("ERA: output_scale has {} entries for {} outputs; give one per output or none",
                                 options.output_scale.size(), p));
  if (options.markov_noise_std.size() > 0 &&
      (options.markov_noise_std.rows() != p || options.markov_noise_std.cols() != m))
    throw InputError(fmt::format("ERA: markov_noise_std is {}x{} but g is {}x{}; give one std per entry or none",
                                 options.markov_noise_std.rows(), options.markov_noise_std.cols(), p, m));
  if (!options.input_names.empty() && static_cast<Index>(options.input_names.size()) != m)
    throw InputError(fmt::format("ERA: {} input names for {} inputs", options.input_names.size(), m));
  if (!options.output_names.empty() && static_cast<Index>(options.output_names.size()) != p)
    throw InputError(fmt::format("ERA: {} output names for {} outputs", options.output_names.size(), p));
}

// 3. Effective length: the largest K whose tail g~[K..L] still carries more
// energy than its noise, by kEffectiveLengthSigmas standard deviations of the
// noise energy (a slow weak mode is found through its accumulated energy).
Index effective_length_of(const MarkovSequence& gs, const Eigen::MatrixXd& scaled_std) {
  const Index last_lag = static_cast<Index>(gs.size()) - 1;
  std::vector<double> energy(gs.size(), 0.0);
  double peak = 0.0;
  for (Index k = 1; k <= last_lag; ++k) {
    energy[static_cast<std::size_t>(k)] = gs[static_cast<std::size_t>(k)].squaredNorm();
    peak = std::max(peak, energy[static_cast<std::size_t>(k)]);
  }
  double noise_energy = scaled_std.squaredNorm();  // E ||noise block||_F^2
  const Index reference_lags = std::max<Index>(1, last_lag / 4);
  double reference = 0.0;
  for (Index k = last_lag - reference_lags + 1; k <= last_lag; ++k) reference += energy[static_cast<std::size_t>(k)];
  if (noise_energy > 0.0) noise_energy = std::max(noise_energy, reference / static_cast<double>(reference_lags));
  const double floor_energy = kRelativeLengthTolerance * kRelativeLengthTolerance * peak;
  Index effective_length = 2;
  double tail = 0.0;
  for (Index k = last_lag; k >= 1; --k) {
    tail += energy[static_cast<std::size_t>(k)];
    const double count = static_cast<double>(last_lag - k + 1);
    const double excess = tail - count * (noise_energy + floor_energy);
    if (excess > kEffectiveLengthSigmas * noise_energy * std::sqrt(2.0 * count) && excess > 0.0) {
      effective_length = std::max<Index>(k + 1, 2);
      break;
    }
  }
  return effective_length;
}

// Block rows, block columns and stride of the Hankel matrix.
struct HankelLayout {
  Index rows = 0, cols = 0, stride = 0;
};

// 4. Hankel layout.
HankelLayout hankel_layout(const MarkovSequence& g, const EraOptions& options, Index effective_length) {
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  const Index last_lag = static_cast<Index>(g.size()) - 1;
  const Index k_max = std::max(options.order, options.max_order) + 1;
  const Index min_rows = ceil_div(k_max, p);
  const Index min_cols = ceil_div(k_max, m);
  const bool auto_rows = options.block_rows == 0;
  const bool auto_cols = options.block_cols == 0;
  Index rows = auto_rows ? std::max(ceil_div(kTargetHankelDim, p), min_rows) : options.block_rows;
  Index cols = auto_cols ? std::max(ceil_div(kTargetHankelDim, m), min_cols) : options.block_cols;
  // Shrink automatic block counts to the span of the response (lags 1..L_eff-1)
  // and to what g holds (the shifted Hankel reaches lag rows + cols at d = 1).
  const auto shrink_to = [&](Index span) {
    if (rows + cols - 1 <= span) return;
    if (auto_rows && auto_cols) {
      rows = std::max(min_rows, span * rows / (rows + cols));
      cols = std::max(min_cols, span - rows);
    } else if (auto_rows) {
      rows = std::max(min_rows, span - cols);
    } else if (auto_cols) {
      cols = std::max(min_cols, span - rows);
    }
  };
  if (options.stride <= 1) shrink_to(effective_length - 1);
  shrink_to(last_lag - 1);
  Index stride = options.stride;
  if (stride == 0) {
    stride = std::max<Index>(1, ceil_div(effective_length - 1, rows + cols - 1));
    const Index cap = options.sum_stride_lags ? (last_lag - 1) / (rows + cols - 1)
                                              : (rows + cols > 2 ? (last_lag - 2) / (rows + cols - 2) : stride);
    stride = std::max<Index>(1, std::min(stride, cap));
  }
  // Last lag of g read by the shifted Hankel (with sums over d lags: d - 1 more).
  const Index needed_lag = 2 + (rows + cols - 2) * stride + (options.sum_stride_lags ? stride - 1 : 0);
  if (needed_lag > last_lag) {
    const Index least = (auto_rows && auto_cols && options.stride == 0) ? min_rows + min_cols + 1 : needed_lag + 1;
    throw InputError(fmt::format(
        "ERA: g has {} lags (0..{}) but a Hankel matrix of {}x{} blocks with stride {} (and its one-sample shift) "
        "needs {} lags (0..{}); pass at least {} lags, or fewer blocks, a smaller stride or a lower max_order",
        g.size(), last_lag, rows, cols, stride, needed_lag + 1, needed_lag, least));
  }
  const Index hankel_rows = rows * p;
  const Index hankel_cols = cols * m;
  const Index available = std::min(hankel_rows, hankel_cols);
  if (options.order > available)
    throw InputError(fmt::format(
        "ERA: order {} exceeds the {} singular values of the {}x{} Hankel matrix; raise block_rows/block_cols or lower "
        "the order",
        options.order, available, hankel_rows, hankel_cols));
  if (options.order == 0 && available < k_max)
    throw InputError(fmt::format(
        "ERA: the automatic order needs {} singular values (max_order + 1) but the {}x{} Hankel matrix has {}; raise "
        "block_rows/block_cols or lower max_order",
        k_max, hankel_rows, hankel_cols, available));
  return {rows, cols, stride};
}

// Sums over d = stride lags, h[k] = sum_{l<d} g~[k+l] = C A^(k-1) B_d, for the lags
// the layout's Hankel matrices read.
MarkovSequence stride_sums(const MarkovSequence& gs, const HankelLayout& lay) {
  const Index p = gs.front().rows();
  const Index m = gs.front().cols();
  const Index stride = lay.stride;
  const Index h_last = 2 + (lay.rows + lay.cols - 2) * stride;
  MarkovSequence hs(static_cast<std::size_t>(h_last + 1), Eigen::MatrixXd::Zero(p, m));
  Eigen::MatrixXd running = Eigen::MatrixXd::Zero(p, m);
  for (Index l = 0; l < stride; ++l) running += gs[static_cast<std::size_t>(1 + l)];
  for (Index k = 1; k <= h_last; ++k) {
    hs[static_cast<std::size_t>(k)] = running;
    running += gs[static_cast<std::size_t>(k + stride)] - gs[static_cast<std::size_t>(k)];
  }
  return hs;
}

// The order from the singular values s against sel.noise_floor (given, or every value
// above the noise threshold up to max_order); fills the rest of `sel`.
void select_era_order(const Eigen::VectorXd& s, const EraOptions& options, OrderSelection& sel, Report& report) {
  sel.threshold = std::max(kKappa * sel.noise_floor, kRelativeRankTolerance * s(0));
  Index above = 0;
  while (above < s.size() && s(above) > sel.threshold) ++above;
  const std::string floor_text =
      sel.noise_floor > 0.0
          ? fmt::format("the noise floor {:.3g} (kappa = {:g}, threshold {:.3g})", sel.noise_floor, kKappa, sel.threshold)
          : fmt::format("the rank tolerance {:.3g} ({:g} of the largest; the noise level is zero)", sel.threshold,
                        kRelativeRankTolerance);
  const auto boundary_ratio = [&](Index n) {
    return n < s.size() ? s(n - 1) / std::max(s(n), std::numeric_limits<double>::min())
                        : std::numeric_limits<double>::infinity();
  };

  Index n = options.order;
  if (n > 0) {
    sel.rule = "given";
    sel.reason = fmt::format("order {} was given; {} singular values stand above {}", n, above, floor_text);
    if (n > above)
      report.warnings.push_back(fmt::format(
          "the given order {} keeps {} singular values below the noise threshold {:.3g}; those modes fit noise", n,
          n - above, sel.threshold));
  } else {
    sel.rule = "noise-floor";
    if (above == 0)
      throw NumericalError(fmt::format(
          "ERA: no singular value stands above the noise floor (largest {:.3g}, threshold {:.3g} = {:g} x floor {:.3g}); "
          "the excitation may be too weak or the record too short",
          s(0), sel.threshold, kKappa, sel.noise_floor));
    n = std::min(above, options.max_order);
    Index best_gap = 1;
    for (Index c = 1; c <= n; ++c)
      if (boundary_ratio(c) > boundary_ratio(best_gap)) best_gap = c;
    sel.reason = fmt::format("{} singular values stand above {}; the ratio s_{}/s_{} at that boundary is {:.3g}", above,
                             floor_text, n, n + 1, boundary_ratio(n));
    if (best_gap != n)
      sel.reason += fmt::format(" (the largest gap among them, {:.3g}, is after {}, but every value above the floor "
                                "is kept)",
                                boundary_ratio(best_gap), best_gap);
    if (above > options.max_order)
      report.warnings.push_back(fmt::format(
          "the order is capped at max_order = {}: more singular values stand above the noise floor; raise max_order "
          "or check the noise level",
          options.max_order));
  }
  sel.order = n;
  if (n < s.size() && boundary_ratio(n) < kClearGapRatio)
    report.warnings.push_back(fmt::format("the order {} is uncertain: s_{}/s_{} = {:.3g} is below {:g}", n, n, n + 1,
                                          boundary_ratio(n), kClearGapRatio));
}

// Realisation (era.h step 5) and unscaling (step 6) at any order from one SVD.
struct EraRealiser {
  const MarkovSequence& g;
  const EraOptions& options;
  const PartialSvd& svd;
  const Eigen::MatrixXd& H1;  // the Hankel matrix shifted by one sample
  const Eigen::VectorXd& in;
  const Eigen::VectorXd& out;
  Index stride;
  bool summed;

  // report: where a poorly conditioned sum over the stride is warned of (none: not).
  StateSpace realise(Index n, Report* report) const {
    const Index p = g.front().rows();
    const Index m = g.front().cols();
    const Eigen::VectorXd& s = svd.singular_values;
    StateSpace model;
    const Eigen::VectorXd sqrt_s = s.head(n).cwiseSqrt();
    const Eigen::VectorXd inv_sqrt_s = sqrt_s.cwiseInverse();
    const Eigen::MatrixXd U = svd.U.leftCols(n);
    const Eigen::MatrixXd V = svd.V.leftCols(n);
    model.A = inv_sqrt_s.asDiagonal() * (U.transpose() * (H1 * V)) * inv_sqrt_s.asDiagonal();
    model.C = out.asDiagonal() * (U.topRows(p) * sqrt_s.asDiagonal());
    Eigen::MatrixXd B_scaled = sqrt_s.asDiagonal() * V.topRows(m).transpose();
    if (summed) {  // B_d = S B with S = sum_{l<d} A^l
      Eigen::MatrixXd S = Eigen::MatrixXd::Identity(n, n);
      Eigen::MatrixXd power = Eigen::MatrixXd::Identity(n, n);
      for (Index l = 1; l < stride; ++l) {
        power = power * model.A;
        S += power;
      }
      const Eigen::VectorXd s_values = Eigen::JacobiSVD<Eigen::MatrixXd>(S).singularValues();
      if (report != nullptr && !(s_values(n - 1) > kMinSumConditioning * s_values(0)))
        report->warnings.push_back(fmt::format(
            "a mode lies near a multiple of fs/{} where the sum over {} lags hides it (conditioning {:.3g}); B is "
            "uncertain: set sum_stride_lags = false or a smaller stride",
            stride, stride, s_values(n - 1) / s_values(0)));
      B_scaled = S.colPivHouseholderQr().solve(B_scaled);
    }
    model.B = B_scaled * in.cwiseInverse().asDiagonal();
    model.D = options.estimate_feedthrough ? g.front() : Eigen::MatrixXd::Zero(p, m);
    model.sample_period_s = options.sample_period_s;
    model.input_names = options.input_names;
    model.output_names = options.output_names;
    return model;
  }
};

}  // namespace

void EraOptions::validate() const {
  if (!(sample_period_s > 0.0) || !std::isfinite(sample_period_s))
    throw InputError(fmt::format("ERA: sample_period_s = {}; it must be a positive, finite sample period in seconds",
                                 sample_period_s));
  if (order < 0) throw InputError(fmt::format("ERA: order = {}; use 0 for automatic or a positive order", order));
  if (max_order < 1) throw InputError(fmt::format("ERA: max_order = {}; it must be at least 1", max_order));
  for (const Index o : also_orders)
    if (o < 1 || o > max_order)
      throw InputError(fmt::format("ERA: also_orders holds {}; each must be 1..max_order ({})", o, max_order));
  if (block_rows < 0 || block_cols < 0 || stride < 0)
    throw InputError(fmt::format("ERA: block_rows = {}, block_cols = {}, stride = {}; use 0 for automatic or a positive "
                                 "number",
                                 block_rows, block_cols, stride));
  if (input_scale.size() > 0 && !(input_scale.allFinite() && input_scale.minCoeff() > 0.0))
    throw InputError("ERA: input_scale holds a value that is zero, negative or not finite; every scale must be > 0");
  if (output_scale.size() > 0 && !(output_scale.allFinite() && output_scale.minCoeff() > 0.0))
    throw InputError("ERA: output_scale holds a value that is zero, negative or not finite; every scale must be > 0");
  if (markov_noise_std.size() > 0 && !(markov_noise_std.allFinite() && markov_noise_std.minCoeff() >= 0.0))
    throw InputError("ERA: markov_noise_std holds a value that is negative or not finite; every std must be >= 0");
}

EraResult realize_era(const MarkovSequence& g, const EraOptions& options) {
  options.validate();
  check_sequence(g);
  const Index p = g.front().rows();
  const Index m = g.front().cols();
  const Index last_lag = static_cast<Index>(g.size()) - 1;
  check_era_channels(options, p, m);

  EraResult result;
  Report& report = result.report;

  // 1. Scaling.
  Eigen::VectorXd in = options.input_scale.size() > 0 ? options.input_scale : Eigen::VectorXd::Ones(m);
  Eigen::VectorXd out = options.output_scale.size() > 0 ? options.output_scale : Eigen::VectorXd::Ones(p);
  derive_scales(g, options.input_scale.size() == 0, options.output_scale.size() == 0, in, out);
  result.input_scale = in;
  result.output_scale = out;
  const Eigen::MatrixXd to_scaled = out.cwiseInverse() * in.transpose();  // p x m factors
  MarkovSequence gs(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) gs[k] = g[k].cwiseProduct(to_scaled);

  // 2. Noise level.
  result.markov_noise_std = options.markov_noise_std.size() > 0 ? options.markov_noise_std : tail_noise_std(g);
  const Eigen::MatrixXd scaled_std = result.markov_noise_std.cwiseProduct(to_scaled);

  const Index effective_length = effective_length_of(gs, scaled_std);
  result.effective_length = effective_length;
  const HankelLayout lay = hankel_layout(g, options, effective_length);
  const Index rows = lay.rows, cols = lay.cols, stride = lay.stride;
  const Index k_max = std::max(options.order, options.max_order) + 1;
  const Index hankel_rows = rows * p;
  const Index hankel_cols = cols * m;
  const Index available = std::min(hankel_rows, hankel_cols);
  result.block_rows = rows;
  result.block_cols = cols;
  result.stride = stride;

  // 5. Sums over d lags (h[k] = sum_{l<d} g~[k+l] = C A^(k-1) B_d), then the
  // leading singular triplets.
  const bool summed = options.sum_stride_lags && stride > 1;
  const MarkovSequence hs = summed ? stride_sums(gs, lay) : MarkovSequence();
  const MarkovSequence& hankel_source = summed ? hs : gs;
  const Eigen::MatrixXd H = block_hankel(hankel_source, rows, cols, 1, stride);
  const PartialSvd svd = leading_svd(H, std::min(k_max, available));
  const Eigen::VectorXd& s = svd.singular_values;

  OrderSelection& sel = result.selection;
  sel.singular_values = s;
  // Sums of d independent lags: std grows by sqrt(d); entries d apart stay independent.
  sel.noise_floor = noise_floor(scaled_std * std::sqrt(summed ? static_cast<double>(stride) : 1.0), rows, cols);
  select_era_order(s, options, sel, report);
  const Index n = sel.order;

  // Realisation (era.h step 5) and unscaling (step 6), at n and at every also_orders.
  const Eigen::MatrixXd H1 = block_hankel(hankel_source, rows, cols, 2, stride);
  const EraRealiser realiser{g, options, svd, H1, in, out, stride, summed};
  result.model = realiser.realise(n, &report);
  const StateSpace& model = result.model;
  for (const Index extra : options.also_orders)
    result.models_at.push_back(extra <= s.size() ? realiser.realise(extra, nullptr) : StateSpace{});

  const double spectral_radius = Eigen::EigenSolver<Eigen::MatrixXd>(model.A, false).eigenvalues().cwiseAbs().maxCoeff();
  if (spectral_radius >= 1.0)
    report.warnings.push_back(fmt::format(
        "the realised model is unstable: its largest pole has |z| = {:.6g} >= 1; check the order and the noise level",
        spectral_radius));
  report.termination = fmt::format(
      "ERA order {} ({}) from a {}x{} Hankel matrix ({}x{} blocks, stride {}, lags 1..{} of 0..{}, effective length {})",
      n, sel.rule, hankel_rows, hankel_cols, rows, cols, stride, 2 + (rows + cols - 2) * stride, last_lag,
      effective_length);
  return result;
}

}  // namespace lpvid
