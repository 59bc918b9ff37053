// lpvid — periodic FRF, closed-loop ratio and BLA (periodic_frf.h; docs/math.md).
#include "idlib/signal/periodic_frf.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "idlib/signal/real_fft.h"

namespace lpvid {

using signal_detail::alloc_complex;
using signal_detail::alloc_real;
using signal_detail::RealFft;

void PeriodicLayout::validate() const {
  if (period_samples < 4)
    throw InputError(fmt::format("period length {} samples is below 4; give the samples per period of the excitation",
                                 period_samples));
  if (periods < 2)
    throw InputError(fmt::format("{} measured period(s) per block: the noise variance needs at least 2; measure more "
                                 "periods",
                                 periods));
  if (transient_periods < 0)
    throw InputError(fmt::format("{} transient periods is negative; give 0 or more", transient_periods));
  if (realisations < 1) throw InputError(fmt::format("{} realisations: give at least 1", realisations));
  if (experiments < 1) throw InputError(fmt::format("{} experiments per realisation: give at least 1", experiments));
  const double total = static_cast<double>(realisations) * static_cast<double>(experiments) *
                       static_cast<double>(transient_periods + periods) * static_cast<double>(period_samples);
  if (total > 4e12) throw InputError(fmt::format("the layout holds {:.3g} samples: too many; check its numbers", total));
}

void PeriodicFrfOptions::validate() const {
  layout.validate();
  if (!(std::isfinite(sample_period_s) && sample_period_s > 0))
    throw InputError(fmt::format("sample period {} s: give a finite sample period > 0", sample_period_s));
  if (!(max_condition > 1)) throw InputError(fmt::format("max_condition {} must be > 1", max_condition));
  for (size_t i = 0; i < excited_bins.size(); ++i) {
    const Index k = excited_bins[i];
    if (k < 1 || 2 * k >= layout.period_samples)
      throw InputError(fmt::format("excited bin {} is outside 1..{} (DC and Nyquist excluded) for a period of {} "
                                   "samples; give bins of one period's DFT",
                                   k, (layout.period_samples - 1) / 2, layout.period_samples));
    if (i > 0 && k <= excited_bins[i - 1])
      throw InputError(fmt::format("excited bins must increase: {} follows {}", k, excited_bins[i - 1]));
  }
}

namespace {

void check_finite(const Eigen::MatrixXd& x, Index rows, const char* what) {
  for (Index c = 0; c < x.cols(); ++c)
    for (Index t = 0; t < rows; ++t)
      if (!std::isfinite(x(t, c)))
        throw InputError(fmt::format("{} column {} sample {} is {}; give finite samples", what, c + 1, t + 1, x(t, c)));
}

// Condition number (1-norm estimate) of a Hermitian positive matrix after scaling to a
// unit diagonal; +inf when it is not positive definite.
double normalised_condition(const Eigen::MatrixXcd& A) {
  const Eigen::VectorXd d = A.diagonal().real();
  if ((d.array() <= 0).any()) return INFINITY;
  const Eigen::VectorXd s = d.cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXcd N = s.asDiagonal() * A * s.asDiagonal();
  Eigen::LLT<Eigen::MatrixXcd> llt(N);
  if (llt.info() != Eigen::Success) return INFINITY;
  const double rc = llt.rcond();
  return rc > 0 ? 1.0 / rc : INFINITY;
}

// The frequency of DFT bin `bin` of one period.
double periodic_bin_hz(Index bin, Index L, double sample_period_s) {
  return static_cast<double>(bin) / (static_cast<double>(L) * sample_period_s);
}

// The shapes of the logs against the layout, and their samples finite.
void check_periodic_logs(const Eigen::MatrixXd& reference, const Eigen::MatrixXd& measured, Index plant_inputs,
                         const PeriodicLayout& lay) {
  const Index L = lay.period_samples, P = lay.periods, T = lay.transient_periods, R = lay.realisations,
              E = lay.experiments;
  const Index m = reference.cols(), nz = measured.cols();
  if (m < 1) throw InputError("no excitation column; give at least one");
  if (reference.rows() != measured.rows())
    throw InputError(fmt::format("the excitation has {} samples but the measured channels {}; give equally long columns",
                                 reference.rows(), measured.rows()));
  if (plant_inputs != 0 && plant_inputs != m)
    throw InputError(fmt::format("{} plant input columns for {} excitation columns; give one plant input per excitation",
                                 plant_inputs, m));
  const Index ny = nz - plant_inputs;
  if (ny < 1) throw InputError("no output column besides the plant inputs; give at least one output");
  if (m > E)
    throw InputError(fmt::format("{} inputs but {} experiment(s) per realisation: the periodic MIMO estimate needs at "
                                 "least as many experiments as inputs (--experiments)",
                                 m, E));
  const Index needed = lay.total_samples();
  if (reference.rows() < needed)
    throw InputError(fmt::format("the log has {} samples but the layout needs R·E·(T+P)·L = {}·{}·({}+{})·{} = {}; "
                                 "check --period-samples, --periods, --transient-periods, --realisations, --experiments",
                                 reference.rows(), R, E, T, P, L, needed));
  check_finite(reference, needed, "excitation");
  check_finite(measured, needed, "measured");
}

// One period's transform: `fft` of L samples with its aligned buffers (real_fft.h).
struct PeriodTransform {
  const RealFft& fft;
  double* in;
  Complex* out;
};

// Stage 1's reference: per block the DFT of the period mean (nb × m) and the noise
// variance of that mean; its scatter's energy per column; over the blocks, the power of
// the mean and of the noise per bin.
struct PeriodicReference {
  std::vector<Eigen::MatrixXcd> vspec;
  std::vector<Eigen::MatrixXd> vnoise;
  Eigen::VectorXd reference_ss;
  Eigen::VectorXd power, scatter;
};

PeriodicReference periodic_reference_spectra(const Eigen::MatrixXd& reference, const PeriodicLayout& lay,
                                             const PeriodTransform& ft) {
  const Index L = lay.period_samples, P = lay.periods, T = lay.transient_periods;
  const Index m = reference.cols(), block = lay.block_samples(), blocks = lay.realisations * lay.experiments;
  const Index nb = L / 2 + 1;
  double* in = ft.in;
  Complex* out = ft.out;
  // 1. The reference: per block and column the DFT of the period mean and the noise
  //    variance of that mean from the period-to-period scatter (header comment).  A
  //    period that repeats the mean exactly costs no transform.
  PeriodicReference ref;
  ref.vspec.assign(static_cast<size_t>(blocks), Eigen::MatrixXcd(nb, m));
  ref.vnoise.assign(static_cast<size_t>(blocks), Eigen::MatrixXd::Zero(nb, m));
  ref.reference_ss = Eigen::VectorXd::Zero(m);
  Eigen::VectorXd mean(L);
  for (Index b = 0; b < blocks; ++b) {
    const Index start = b * block + T * L;
    for (Index j = 0; j < m; ++j) {
      const double* x = reference.col(j).data() + start;
      for (Index t = 0; t < L; ++t) in[t] = 0;
      for (Index p = 0; p < P; ++p)
        for (Index t = 0; t < L; ++t) in[t] += x[p * L + t] / static_cast<double>(P);
      for (Index t = 0; t < L; ++t) mean(t) = in[t];
      ft.fft.forward(in, out);
      for (Index k = 0; k < nb; ++k) ref.vspec[static_cast<size_t>(b)](k, j) = out[k];
      Eigen::MatrixXd& noise = ref.vnoise[static_cast<size_t>(b)];
      for (Index p = 0; p < P; ++p) {
        double ss = 0;
        for (Index t = 0; t < L; ++t) {
          const double d = x[p * L + t] - mean(t);
          in[t] = d;
          ss += d * d;
        }
        if (ss == 0) continue;
        ref.reference_ss(j) += ss;
        ft.fft.forward(in, out);
        for (Index k = 0; k < nb; ++k) noise(k, j) += std::norm(out[k]);
      }
      noise.col(j) /= static_cast<double>((P - 1) * P);
    }
  }
  ref.power = Eigen::VectorXd::Zero(nb);
  ref.scatter = Eigen::VectorXd::Zero(nb);
  for (Index b = 0; b < blocks; ++b) {
    ref.power += ref.vspec[static_cast<size_t>(b)].rowwise().squaredNorm();
    ref.scatter += ref.vnoise[static_cast<size_t>(b)].rowwise().sum();
  }
  return ref;
}

// 2. The excited bins: power above round-off and, for a measured reference, far above
//    the noise of the period mean (its own and its neighbours' median).
std::vector<Index> detect_excited_bins(const PeriodicReference& ref, bool measured_reference, Index L) {
  const Index kmax = (L - 1) / 2;  // the largest bin below Nyquist
  const Eigen::VectorXd& power = ref.power;
  const Eigen::VectorXd& scatter = ref.scatter;
  std::vector<Index> bins;
  double top = 0;
  for (Index k = 1; k <= kmax; ++k) top = std::max(top, power(k));
  if (!(top > 0)) throw InputError("the excitation carries no power at any bin 1..L/2−1; excite the system");
  Eigen::VectorXd floor = scatter;
  if (measured_reference) {
    std::vector<double> window;
    for (Index k = 1; k <= kmax; ++k) {
      window.assign(scatter.data() + std::max<Index>(1, k - kLineNoiseHalfWidth),
                    scatter.data() + std::min(kmax, k + kLineNoiseHalfWidth) + 1);
      auto mid = window.begin() + static_cast<std::ptrdiff_t>(window.size() / 2);
      std::nth_element(window.begin(), mid, window.end());
      floor(k) = std::max(scatter(k), *mid);
    }
  }
  double best = 0;  // the largest power-to-floor ratio, for the message
  for (Index k = 1; k <= kmax; ++k) {
    if (!(power(k) >= kExcitedLineFraction * top)) continue;
    best = std::max(best, floor(k) > 0 ? power(k) / floor(k) : INFINITY);
    if (power(k) >= kExcitedLineSnr * floor(k)) bins.push_back(k);
  }
  if (bins.empty())
    throw InputError(fmt::format(
        "the excitation does not repeat with {} samples: at no bin does its period mean stand {:g}× above the noise "
        "of its period-to-period scatter (at most {:.3g}×); check --period-samples (the generator's samples per "
        "period) and --transient-periods, or use --method lpm for an excitation that is not periodic",
        L, kExcitedLineSnr, best));
  return bins;
}

// 3. Periodicity of every block's reference (header comment): ρ_b, the power of its
//    period mean at the lines over the noise power of that mean at every bin; and the
//    scatter at the lines against the other bins' (q_b), where the line SNR is modest.
//    Returns the smallest ρ_b (+inf when every block's reference is exact).
double check_reference_periodicity(const PeriodicReference& ref, const std::vector<Index>& bins,
                                   const PeriodicLayout& lay) {
  const Index L = lay.period_samples, E = lay.experiments, blocks = lay.realisations * lay.experiments;
  const Index nb = L / 2 + 1, kmax = (L - 1) / 2, K = static_cast<Index>(bins.size());
  double periodicity = INFINITY;
  std::vector<bool> is_line(static_cast<size_t>(nb), false);
  for (Index k : bins) is_line[static_cast<size_t>(k)] = true;
  std::vector<double> other;
  for (Index b = 0; b < blocks; ++b) {
    const Eigen::MatrixXcd& Vb = ref.vspec[static_cast<size_t>(b)];
    const Eigen::VectorXd Nb = ref.vnoise[static_cast<size_t>(b)].rowwise().sum();
    double line_power = 0, line_noise = 0;
    for (Index k : bins) {
      line_power += Vb.row(k).squaredNorm();
      line_noise += Nb(k);
    }
    const double noise_power = Nb.segment(1, kmax).sum();
    if (!(noise_power > 0)) continue;  // an exact reference in this block
    const double rho = line_power / noise_power;
    periodicity = std::min(periodicity, rho);
    const std::string where = fmt::format("the excitation is not periodic with {} samples in block {} (realisation {}, "
                                          "experiment {}): at its {} excited line(s)",
                                          L, b + 1, b / E + 1, b % E + 1, K);
    const std::string fix = "check --period-samples (the generator's samples per period), --transient-periods and the "
                            "block layout, or use --method lpm for an excitation that is not periodic";
    if (!(rho >= kMinExcitationPeriodicity))
      throw InputError(fmt::format("{} its period mean carries only {:.3g} times the noise power of its "
                                   "period-to-period scatter (at least {:g} needed; a repeating generator signal gives "
                                   "far more); {}",
                                   where, rho, kMinExcitationPeriodicity, fix));
    other.clear();
    for (Index k = 1; k <= kmax; ++k)
      if (!is_line[static_cast<size_t>(k)]) other.push_back(Nb(k));
    if (other.empty() || !(line_noise > 0)) continue;  // every bin excited: no noise floor to compare with
    auto mid = other.begin() + static_cast<std::ptrdiff_t>(other.size() / 2);
    std::nth_element(other.begin(), mid, other.end());
    if (!(*mid > 0)) continue;
    const double excess = line_noise / static_cast<double>(K) / *mid, line_snr = line_power / line_noise;
    if (excess > kMaxLineScatterExcess && line_snr < kCoherentLineSnr)
      throw InputError(fmt::format("{} its period-to-period scatter is {:.3g}× the noise of the other bins and only "
                                   "{:.3g}× below its period mean: the signal drifts from period to period (a period "
                                   "length off by a few samples, or a generator not synchronised with the "
                                   "acquisition); {}",
                                   where, excess, line_snr, fix));
  }
  return periodicity;
}

// A measured reference's lines whose period mean is not far above its noise (stage 3).
void warn_low_line_snr(const PeriodicReference& ref, const std::vector<Index>& bins, Index L, double sample_period_s,
                       std::vector<std::string>& warnings) {
  const Eigen::VectorXd& power = ref.power;
  const Eigen::VectorXd& scatter = ref.scatter;
  Index low = 0, worst = -1;
  for (Index k : bins)
    if (scatter(k) > 0 && power(k) < kLowLineSnr * scatter(k)) {
      ++low;
      if (worst < 0 || power(k) / scatter(k) < power(worst) / scatter(worst)) worst = k;
    }
  if (low > 0)
    warnings.push_back(fmt::format(
        "{} excited line(s) where the excitation's period mean is less than {:g}× the noise of its scatter (worst "
        "{:.6g} Hz, bin {}: {:.3g}×): the ratio of noisy means is biased there by up to e^-SNR",
        low, kLowLineSnr, periodic_bin_hz(worst, L, sample_period_s), worst, power(worst) / scatter(worst)));
}

// Stage 4's measured channels (and the measured reference after them, nw columns): per
// block the period mean at the K lines (K × nw) and its covariance per line (nw × nw);
// the scatter's energy per measured channel.
struct PeriodicMeasuredLines {
  std::vector<Eigen::MatrixXcd> zbar;
  std::vector<std::vector<Eigen::MatrixXcd>> zcov;
  Eigen::VectorXd noise_ss;
};

// 4. The measured channels, and the reference when it is measured (errors in
//    variables): per block the period mean at the bins and the joint covariance.
PeriodicMeasuredLines periodic_line_means(const Eigen::MatrixXd& reference, const Eigen::MatrixXd& measured,
                                          const std::vector<Index>& bins, bool measured_reference,
                                          const PeriodicLayout& lay, const PeriodTransform& ft) {
  const Index L = lay.period_samples, P = lay.periods, T = lay.transient_periods;
  const Index m = reference.cols(), nz = measured.cols(), block = lay.block_samples(),
              blocks = lay.realisations * lay.experiments, K = static_cast<Index>(bins.size());
  double* in = ft.in;
  Complex* out = ft.out;
  const Index nw = nz + (measured_reference ? m : 0);
  PeriodicMeasuredLines lines;
  lines.zbar.assign(static_cast<size_t>(blocks), Eigen::MatrixXcd(K, nw));
  lines.zcov.assign(static_cast<size_t>(blocks), std::vector<Eigen::MatrixXcd>(static_cast<size_t>(K)));
  lines.noise_ss = Eigen::VectorXd::Zero(nz);
  Eigen::VectorXd mean(L);
  std::vector<Eigen::MatrixXcd> periods(static_cast<size_t>(P), Eigen::MatrixXcd(K, nw));
  for (Index b = 0; b < blocks; ++b) {
    const Index start = b * block + T * L;
    for (Index c = 0; c < nw; ++c) {
      const double* x = c < nz ? measured.col(c).data() + start : reference.col(c - nz).data() + start;
      mean.setZero();
      for (Index p = 0; p < P; ++p) {
        std::copy(x + p * L, x + (p + 1) * L, in);
        ft.fft.forward(in, out);
        for (Index k = 0; k < K; ++k) periods[static_cast<size_t>(p)](k, c) = out[bins[static_cast<size_t>(k)]];
        for (Index t = 0; t < L; ++t) mean(t) += x[p * L + t];
      }
      if (c >= nz) continue;
      mean /= static_cast<double>(P);
      double ss = 0;
      for (Index p = 0; p < P; ++p)
        for (Index t = 0; t < L; ++t) {
          const double d = x[p * L + t] - mean(t);
          ss += d * d;
        }
      lines.noise_ss(c) += ss;
    }
    Eigen::MatrixXcd& zb = lines.zbar[static_cast<size_t>(b)];
    zb.setZero();
    for (const auto& Z : periods) zb += Z;
    zb /= static_cast<double>(P);
    for (Index k = 0; k < K; ++k) {
      Eigen::MatrixXcd C = Eigen::MatrixXcd::Zero(nw, nw);
      for (const auto& Z : periods) {
        const Eigen::VectorXcd d = (Z.row(k) - zb.row(k)).transpose();
        C.noalias() += d * d.adjoint();
      }
      // Covariance of the mean over P periods: Ĉ / P with Ĉ = Σ d dᴴ / (P − 1).
      lines.zcov[static_cast<size_t>(b)][static_cast<size_t>(k)] = C / static_cast<double>((P - 1) * P);
    }
  }
  return lines;
}

// Stage 4's ratios per realisation r and line k: G[r][k] (ny × m), its linearised noise
// variance varn[r][k], and the lines where Ŝ is singular in some realisation.
struct PeriodicRatios {
  std::vector<std::vector<Eigen::MatrixXcd>> G;
  std::vector<std::vector<Eigen::MatrixXd>> varn;
  std::vector<bool> flagged;
};

// 4. Per realisation and line: Ĝ_z = Z̄ V⁺, the plant ratio, the linearised noise.
PeriodicRatios periodic_ratios(const PeriodicReference& ref, const PeriodicMeasuredLines& lines,
                               const std::vector<Index>& bins, Index m, Index nz, Index plant_inputs,
                               bool measured_reference, const PeriodicFrfOptions& options) {
  const PeriodicLayout& lay = options.layout;
  const Index L = lay.period_samples, R = lay.realisations, E = lay.experiments, K = static_cast<Index>(bins.size());
  const Index ny = nz - plant_inputs, nw = nz + (measured_reference ? m : 0);
  PeriodicRatios out;
  auto& G = out.G;
  auto& varn = out.varn;
  G.assign(static_cast<size_t>(R), std::vector<Eigen::MatrixXcd>(static_cast<size_t>(K)));
  varn.assign(static_cast<size_t>(R), std::vector<Eigen::MatrixXd>(static_cast<size_t>(K)));
  out.flagged.assign(static_cast<size_t>(K), false);
  for (Index r = 0; r < R; ++r)
    for (Index k = 0; k < K; ++k) {
      const Index bin = bins[static_cast<size_t>(k)];
      Eigen::MatrixXcd V(m, E), Z(nz, E);
      for (Index e = 0; e < E; ++e) {
        V.col(e) = ref.vspec[static_cast<size_t>(r * E + e)].row(bin).transpose();
        Z.col(e) = lines.zbar[static_cast<size_t>(r * E + e)].row(k).head(nz).transpose();
      }
      const Eigen::MatrixXcd gram = V * V.adjoint();
      const double cond = normalised_condition(gram);
      if (!(cond <= options.max_condition))
        throw InputError(fmt::format("the excitation matrix V ({}×{}) at {:.6g} Hz (bin {}) of realisation {} is singular "
                                     "(condition {:.3g}): the experiments do not excite the inputs independently at "
                                     "that line; use a design whose experiment matrix is invertible at every excited "
                                     "line, or restrict the excited bins",
                                     m, E, periodic_bin_hz(bin, L, options.sample_period_s), bin, r + 1, cond));
      const Eigen::MatrixXcd Vp = V.adjoint() * gram.inverse();  // E × m
      const Eigen::MatrixXcd Gz = Z * Vp;                        // nz × m
      Eigen::MatrixXcd Gk, W, M;
      if (plant_inputs == 0) {
        Gk = Gz;
        W = Eigen::MatrixXcd::Identity(nz, nz);
        M = Vp;
      } else {
        const Eigen::MatrixXcd S = Gz.bottomRows(m);
        Eigen::PartialPivLU<Eigen::MatrixXcd> lu(S);
        const double rc = lu.rcond();
        if (!(rc > 0) || 1.0 / rc > options.max_condition) {
          out.flagged[static_cast<size_t>(k)] = true;
          G[static_cast<size_t>(r)][static_cast<size_t>(k)] = Eigen::MatrixXcd::Zero(ny, m);
          varn[static_cast<size_t>(r)][static_cast<size_t>(k)] = Eigen::MatrixXd::Zero(ny, m);
          continue;
        }
        const Eigen::MatrixXcd Sinv = lu.inverse();
        Gk = Gz.topRows(ny) * Sinv;
        W.resize(ny, nz);
        W << Eigen::MatrixXcd::Identity(ny, ny), -Gk;
        M = Vp * Sinv;
      }
      if (measured_reference) {  // errors in variables: δĜ_z = [I  −Ĝ_z] δW̄ V̄⁺
        Eigen::MatrixXcd We(W.rows(), nw);
        We.leftCols(nz) = W;
        We.rightCols(m) = -W * Gz;
        W = We;
      }
      Eigen::MatrixXd var = Eigen::MatrixXd::Zero(ny, m);
      for (Index e = 0; e < E; ++e) {
        const Eigen::VectorXd wcw =
            (W * lines.zcov[static_cast<size_t>(r * E + e)][static_cast<size_t>(k)] * W.adjoint()).diagonal().real();
        for (Index j = 0; j < m; ++j) var.col(j) += std::norm(M(e, j)) * wcw;
      }
      G[static_cast<size_t>(r)][static_cast<size_t>(k)] = Gk;
      varn[static_cast<size_t>(r)][static_cast<size_t>(k)] = var;
    }
  return out;
}

// 5. Over the realisations: the BLA, its noise and its distortion variance.
void average_realisations(const PeriodicRatios& ratios, const std::vector<Index>& bins, Index ny, Index m,
                          const PeriodicFrfOptions& options, PeriodicFrfResult& result) {
  const Index L = options.layout.period_samples, R = options.layout.realisations, K = static_cast<Index>(bins.size());
  const auto& G = ratios.G;
  const auto& varn = ratios.varn;
  FrequencyResponse& frd = result.frd;
  frd.omega_rad_s.resize(K);
  frd.response.resize(static_cast<size_t>(K));
  frd.variance.resize(static_cast<size_t>(K));
  result.noise_variance.resize(static_cast<size_t>(K));
  if (R >= 2) {
    frd.distortion_variance.resize(static_cast<size_t>(K));
    result.scatter_variance.resize(static_cast<size_t>(K));
  }
  for (Index k = 0; k < K; ++k) {
    const size_t kk = static_cast<size_t>(k);
    frd.omega_rad_s(k) = 2.0 * std::numbers::pi * periodic_bin_hz(bins[kk], L, options.sample_period_s);
    Eigen::MatrixXcd mean_g = Eigen::MatrixXcd::Zero(ny, m);
    Eigen::MatrixXd noise = Eigen::MatrixXd::Zero(ny, m);
    for (Index r = 0; r < R; ++r) {
      mean_g += G[static_cast<size_t>(r)][kk];
      noise += varn[static_cast<size_t>(r)][kk];
    }
    mean_g /= static_cast<double>(R);
    noise /= static_cast<double>(R * R);
    frd.response[kk] = mean_g;
    result.noise_variance[kk] = noise;
    if (R >= 2) {
      Eigen::MatrixXd scatter = Eigen::MatrixXd::Zero(ny, m);
      for (Index r = 0; r < R; ++r) scatter += (G[static_cast<size_t>(r)][kk] - mean_g).cwiseAbs2();
      scatter /= static_cast<double>(R * (R - 1));
      result.scatter_variance[kk] = scatter;
      frd.distortion_variance[kk] = (scatter - noise).cwiseMax(0.0);
      frd.variance[kk] = noise + frd.distortion_variance[kk];
    } else {
      frd.variance[kk] = noise;
    }
    if (ratios.flagged[kk]) {  // Ŝ singular in some realisation: no value, never an unreliable one
      frd.response[kk].setZero();
      frd.variance[kk].setZero();
      result.noise_variance[kk].setZero();
      if (R >= 2) {
        frd.distortion_variance[kk].setZero();
        result.scatter_variance[kk].setZero();
      }
    }
  }
}

}  // namespace

PeriodicFrfResult estimate_periodic_frf(const Eigen::MatrixXd& reference, const Eigen::MatrixXd& measured,
                                        Index plant_inputs, const PeriodicFrfOptions& options) {
  options.validate();
  const PeriodicLayout& lay = options.layout;
  const Index L = lay.period_samples, P = lay.periods, R = lay.realisations, E = lay.experiments;
  check_periodic_logs(reference, measured, plant_inputs, lay);
  const Index m = reference.cols(), nz = measured.cols(), ny = nz - plant_inputs;
  const Index blocks = R * E, needed = lay.total_samples();

  PeriodicFrfResult result;
  if (reference.rows() > needed)
    result.report.warnings.push_back(fmt::format("{} samples after the layout's {} were ignored",
                                                 reference.rows() - needed, needed));
  const Index nb = L / 2 + 1;
  RealFft fft(L);
  auto in = alloc_real(L);
  auto out = alloc_complex(nb);
  const PeriodTransform ft{fft, in.get(), out.get()};

  const PeriodicReference ref = periodic_reference_spectra(reference, lay, ft);
  const bool measured_reference = ref.reference_ss.sum() > 0;
  result.measured_reference = measured_reference;
  result.excitation_noise_rms = (ref.reference_ss / static_cast<double>(blocks * L * (P - 1))).cwiseSqrt();

  std::vector<Index> bins =
      options.excited_bins.empty() ? detect_excited_bins(ref, measured_reference, L) : options.excited_bins;
  const Index K = static_cast<Index>(bins.size());

  result.excitation_periodicity = check_reference_periodicity(ref, bins, lay);
  if (measured_reference) warn_low_line_snr(ref, bins, L, options.sample_period_s, result.report.warnings);

  const PeriodicMeasuredLines lines = periodic_line_means(reference, measured, bins, measured_reference, lay, ft);
  result.channel_noise_rms = (lines.noise_ss / static_cast<double>(blocks * L * (P - 1))).cwiseSqrt();

  const PeriodicRatios ratios =
      periodic_ratios(ref, lines, bins, m, nz, plant_inputs, measured_reference, options);
  average_realisations(ratios, bins, ny, m, options, result);

  const std::vector<bool>& flagged = ratios.flagged;
  if (plant_inputs != 0) result.frd.flagged = flagged;
  result.bins = std::move(bins);
  result.noise_dof = R * E * (P - 1);
  result.realisation_dof = R - 1;
  const Index nflag = static_cast<Index>(std::count(flagged.begin(), flagged.end(), true));
  if (nflag > 0)
    result.report.warnings.push_back(
        fmt::format("{} line(s) flagged: the estimated S is singular there (condition above {:.3g})", nflag,
                    options.max_condition));
  result.report.termination =
      fmt::format("{} excited lines, {} realisation(s) × {} experiment(s) × {} periods (noise dof {}){}", K, R, E, P,
                  result.noise_dof,
                  measured_reference
                      ? fmt::format("; measured excitation, periodic to {:.3g}× its scatter noise (errors in "
                                    "variables)",
                                    result.excitation_periodicity)
                      : std::string());
  return result;
}

std::vector<Eigen::MatrixXd> distortion_to_noise_ratio(const PeriodicFrfResult& result) {
  std::vector<Eigen::MatrixXd> ratio;
  for (size_t k = 0; k < result.scatter_variance.size(); ++k) {
    const Eigen::MatrixXd& s = result.scatter_variance[k];
    const Eigen::MatrixXd& n = result.noise_variance[k];
    Eigen::MatrixXd q(s.rows(), s.cols());
    for (Index i = 0; i < s.size(); ++i) q(i) = n(i) > 0 ? s(i) / n(i) : (s(i) > 0 ? INFINITY : 1.0);
    ratio.push_back(q);
  }
  return ratio;
}

std::vector<std::pair<Index, Index>> distortion_bands(const PeriodicFrfResult& result) {
  std::vector<std::pair<Index, Index>> bands;
  const auto ratio = distortion_to_noise_ratio(result);
  const double d1 = 2.0 * static_cast<double>(result.realisation_dof), d2 = 2.0 * static_cast<double>(result.noise_dof);
  const Index F = static_cast<Index>(ratio.size());
  if (F == 0 || d1 < 2 || d2 <= 4) return bands;
  const double mu0 = d2 / (d2 - 2);
  const double sd0 = std::sqrt(2 * d2 * d2 * (d1 + d2 - 2) / (d1 * (d2 - 2) * (d2 - 2) * (d2 - 4)));
  const Index W = std::min(kDistortionWindow, F);
  const double threshold = mu0 + kDistortionSigmas * sd0 / std::sqrt(static_cast<double>(W));
  std::vector<bool> hit(static_cast<size_t>(F), false);
  for (Index s = 0; s + W <= F; ++s) {
    double mean = 0;
    for (Index k = s; k < s + W; ++k) mean += ratio[static_cast<size_t>(k)].mean();
    if (mean / static_cast<double>(W) > threshold)
      for (Index k = s; k < s + W; ++k) hit[static_cast<size_t>(k)] = true;
  }
  for (Index k = 0; k < F; ++k) {
    if (!hit[static_cast<size_t>(k)]) continue;
    if (!bands.empty() && bands.back().second == k - 1)
      bands.back().second = k;
    else
      bands.emplace_back(k, k);
  }
  return bands;
}

}  // namespace lpvid
