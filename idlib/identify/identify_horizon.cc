// Stages 1-2 of the kStructured identification (identify_detail.h): the Markov horizon,
// the noise spectrum and the fit band.
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/core/error.h"
#include "idlib/identify/identify_detail.h"
#include "idlib/signal/noise_spectrum.h"

namespace lpvid::identify_detail {

// ---- horizon ----
// (kHorizonRecordDivisor and kMinHorizonLags: identify_detail.h.)
// The response has "ended" at horizon K when the lags (K/2, K] carry less than this
// fraction of the energy of lags 1..K (scaled channels) — what is left beyond K is then
// modelled by the tail rounds — or when their energy is within kHorizonNoiseSigmas
// standard deviations of the estimation noise (the issue's "indistinguishable from the
// noise").  Measured on drawn plants: a horizon of 1 s where 2.8 s held 99 % of the
// energy failed (the first fit landed in a wrong minimum); halves holding ≤ 5 % worked.
constexpr double kHorizonTailEnergyFraction = 0.05;
// The same with a coloured excitation: its regressors are correlated across lags, so the
// response left beyond the horizon biases the last lags of ĝ (not only the tail rounds'
// share); measured on a 5-state plant under low-passed noise (tests/cli/
// open_loop_identify_test.cc): with 0.05 the horizon stopped at 1.0 s with 29 % of a
// mode's amplitude beyond it and the fit failed even without noise (order 2, 70 %).
constexpr double kHorizonTailEnergyFractionColoured = 1e-3;
// The first Markov estimate computes the correlations up to 2^this times its horizon
// (estimate_markov's `reuse`), so that this many doublings need no new correlation pass.
// Measured at 10 kHz (3 x 10^6 samples, one thread): 230 ms up to 16384 lags, ~300 ms up
// to 32768, 800 ms up to 65536 (FFT blocks of 2^18 points and 37 MB of spectral sums
// leave the caches), so one step.
constexpr int kHorizonCorrelationSteps = 1;
constexpr double kHorizonNoiseSigmas = 5.0;

// ---- fit band ----
// The band ends where the (running-median) whitened signal power per bin falls below
// the noise power (E|Ĝ|² = |G|² + noise: SNR² − 1 < 1) — the data carry little more — or where the closed loop's response has
// fallen 60 dB below its peak (noise-free data), whichever is lower.  Measured: upper
// edges of 600, 1000 and 2000 rad/s gave the same plant error within 0.02 % on drawn
// plants; Nyquist (3142 rad/s) was up to 0.6 % worse.
constexpr double kBandMinSnr = 1.0;
constexpr double kBandDynamicRange = 1e-3;
constexpr double kBandInformationTail = 1e-3;
constexpr Index kBandMedianBins = 9;
// Compute bound: at most this many bins in the final fit (a 2048-bin fit costs about
// 15 ms per Jacobian on the reference machine).
constexpr Index kMaxFitBins = 2048;
// Fewer bins than this leave too few residuals per parameter for the first stage.
constexpr Index kMinStageBins = 32;
// Numerical accuracy of ĝ relative to the response (make_markov_bins' noise floor): PCG
// stops at a relative residual of 1e-10 and the normal matrix of white excitation is well
// conditioned; measured noise-free fits agree with the truth to ~1e-8 of the response.
constexpr double kMarkovRelativeAccuracy = 1e-8;

Index pow2_at_least(Index n) {
  Index p = 1;
  while (p < n) p *= 2;
  return p;
}
Index pow2_at_most(Index n) {
  Index p = 1;
  while (2 * p <= n) p *= 2;
  return p;
}

// Energy of ĝ[k] in channels scaled by the signals' spread, and the expected noise energy
// per lag in the same scaling.
struct ScaledEnergy {
  std::vector<double> lag;
  double noise = 0;
};
ScaledEnergy scaled_energy(const MarkovResult& mr) {
  const Eigen::MatrixXd to_s = mr.output_rms.cwiseMax(std::numeric_limits<double>::min()).cwiseInverse() *
                               mr.excitation_rms.transpose();
  ScaledEnergy e;
  for (const auto& g : mr.g) e.lag.push_back(g.cwiseProduct(to_s).squaredNorm());
  e.noise = mr.noise_std.cwiseProduct(to_s).squaredNorm();
  return e;
}

// Whether the response has ended within horizon K (see kHorizonTailEnergyFraction).
bool response_ended(const ScaledEnergy& e, Index K, double fraction, std::string* why) {
  double total = 0.0, tail = 0.0;
  for (Index k = 1; k <= K; ++k) total += e.lag[static_cast<std::size_t>(k)];
  for (Index k = K / 2 + 1; k <= K; ++k) tail += e.lag[static_cast<std::size_t>(k)];
  const double count = static_cast<double>(K - K / 2);
  const bool in_noise = e.noise > 0.0 && tail - count * e.noise <= kHorizonNoiseSigmas * e.noise * std::sqrt(2.0 * count);
  const bool small = tail <= fraction * total;
  if (why != nullptr)
    *why = in_noise ? fmt::format("the lags {}..{} hold {:.3g} of the energy and are within {:g} sigma of the "
                                  "estimation noise",
                                  K / 2 + 1, K, tail / std::max(total, 1e-300), kHorizonNoiseSigmas)
                    : fmt::format("the lags {}..{} hold {:.3g} of the energy (<= {:g}; the rest is left to the tail "
                                  "rounds)",
                                  K / 2 + 1, K, tail / std::max(total, 1e-300), fraction);
  return in_noise || small;
}

// The excitation's spectral density at the bins ω_f = 2π f / K, f < F (m × m, per
// sample, summed over the experiments like R₀):
//   S(ω) = Σ_{|d| < M} (1 − |d|/M) R_vv(d) e^{−jωd},  R_vv(−d) = R_vv(d)ᵀ,
// a Bartlett lag window of M lags (positive semi-definite; M ≤ K/2 does not alias on
// the K-point grid).  vv: R_vv(0..) from MarkovCorrelations.  S(ω) = R₀ for white v.
std::vector<Eigen::MatrixXcd> excitation_spectrum_at(const std::vector<Eigen::MatrixXd>& vv, Index M,
                                                      const Eigen::VectorXd& omega_per_sample) {
  M = std::max<Index>(1, std::min<Index>(M, static_cast<Index>(vv.size())));
  std::vector<Eigen::MatrixXcd> out;
  out.reserve(static_cast<std::size_t>(omega_per_sample.size()));
  for (Index f = 0; f < omega_per_sample.size(); ++f) {
    Eigen::MatrixXcd S = vv.front().cast<std::complex<double>>();
    for (Index d = 1; d < M; ++d) {
      const std::complex<double> e = std::polar(1.0, -omega_per_sample(f) * static_cast<double>(d));
      const double w = 1.0 - static_cast<double>(d) / static_cast<double>(M);
      const Eigen::MatrixXd& R = vv[static_cast<std::size_t>(d)];
      S += w * (e * R.cast<std::complex<double>>() + std::conj(e) * R.transpose().cast<std::complex<double>>());
    }
    out.push_back(0.5 * (S + S.adjoint()));
  }
  return out;
}

// Whether the excitation is coloured: the smallest and largest of each input's spectral
// density (Bartlett window of kWhitenessLags lags, at 64 frequencies over 0..π) differ
// by more than kWhitenessRatio.  A white record's estimate scatters by about
// sqrt(2 M / 3 N) (±15 % for N = 1000), far inside the factor.
constexpr Index kWhitenessLags = 32;
constexpr double kWhitenessRatio = 4.0;
bool excitation_coloured(const std::vector<Eigen::MatrixXd>& vv, double* worst_ratio) {
  Eigen::VectorXd omega = Eigen::VectorXd::LinSpaced(64, 0.0, M_PI);
  const auto S = excitation_spectrum_at(vv, kWhitenessLags, omega);
  const Index m = vv.front().rows();
  double worst = 1.0;
  for (Index j = 0; j < m; ++j) {
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (const auto& s : S) {
      lo = std::min(lo, s(j, j).real());
      hi = std::max(hi, s(j, j).real());
    }
    if (hi <= 0.0) continue;  // an input that is never excited: R₀ says so already
    worst = std::max(worst, lo > 0.0 ? hi / lo : std::numeric_limits<double>::infinity());
  }
  *worst_ratio = worst;
  return worst > kWhitenessRatio;
}

// The noise spectrum at the bins of a K-point transform from one at the L-point bins
// (L/K integer): mean over the L-bins within half a K-bin.
std::vector<Eigen::MatrixXcd> coarser_spectrum(const std::vector<Eigen::MatrixXcd>& fine, Index L, Index K, Index F) {
  const Index r = L / K;
  std::vector<Eigen::MatrixXcd> out;
  for (Index f = 0; f < F; ++f) {
    const Index lo = std::max<Index>(0, f * r - r / 2), hi = std::min<Index>(static_cast<Index>(fine.size()) - 1, f * r + r / 2);
    Eigen::MatrixXcd s = Eigen::MatrixXcd::Zero(fine.front().rows(), fine.front().cols());
    for (Index b = lo; b <= hi; ++b) s += fine[static_cast<std::size_t>(b)];
    out.push_back(s / static_cast<double>(hi - lo + 1));
  }
  return out;
}

Index bins_below(double omega_max, Index K, double Ts) {
  return std::min<Index>(K / 2, static_cast<Index>(std::floor(omega_max * static_cast<double>(K) * Ts / (2.0 * M_PI)))) +
         1;
}

Eigen::MatrixXd excitation_gram(const std::vector<ExperimentView>& experiments) {
  const Index m = experiments.front().excitation.cols();
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, m);
  for (const auto& e : experiments) R.noalias() += e.excitation.transpose() * e.excitation;
  return R;
}

MarkovBins StructuredRun::with_spectrum(MarkovBins b) const {
  if (coloured) {
    const Eigen::VectorXd w = b.omega_rad_s * Ts;
    b.excitation_spectrum = excitation_spectrum_at(corr.vv, b.num_lags / 2, w);
  }
  return b;
}

MarkovBins StructuredRun::bins_at(const MarkovSequence& g, const std::vector<Eigen::MatrixXcd>& fine, Index K) const {
  const Index F = std::max<Index>(std::min(K / 2 + 1, kMinStageBins), bins_below(omega_fit, K, Ts));
  return with_spectrum(make_markov_bins(g, K, F, coarser_spectrum(fine, L, K, F), R0, Ts, kMarkovRelativeAccuracy));
}

void choose_horizon(StructuredRun& run, IdentifyResult& result) {
  IdentifyChoices& ch = result.choices;
  const IdentifyOptions& options = run.options;
  const std::vector<ExperimentView>& experiments = run.experiments;
  const double Ts = run.Ts;
  MarkovOptions& mo = run.mo;
  MarkovCorrelations& corr = run.corr;
  mo.method = options.markov_method;

  bool response_beyond = false;  // the response has not ended within the horizon
  const bool given = options.num_lags > 0 || options.markov_horizon_s > 0.0;
  Index L = 0;
  // Whether the excitation is coloured, judged once R_vv is known (the first estimate).
  double colour_ratio = 1.0;
  std::optional<bool> coloured_flag;
  auto coloured_now = [&] {
    if (!coloured_flag)
      coloured_flag = corr.vv.size() > 1 && excitation_coloured(corr.vv, &colour_ratio);
    return *coloured_flag;
  };
  auto tail_fraction = [&] { return coloured_now() ? kHorizonTailEnergyFractionColoured : kHorizonTailEnergyFraction; };
  if (given) {
    L = choose_num_lags(options, Ts, run.shortest);
    mo.num_lags = L;
    corr.max_lag = L;
    report_progress(options.progress, {"identify", "Markov horizon", 0, 0, fmt::format("{} lags", L)});
    result.markov = estimate_markov(experiments, mo, &corr);
    ch.horizon_reason = fmt::format("{} lags were given", L);
    std::string why;
    response_beyond = !response_ended(scaled_energy(result.markov), L, tail_fraction(), &why);
  } else {
    const Index cap = std::max<Index>(kMinHorizonLags, pow2_at_most(run.shortest / 4));
    L = std::min(cap, std::max(kMinHorizonLags, pow2_at_least(run.shortest / kHorizonRecordDivisor)));
    corr.max_lag = std::min(cap, L << kHorizonCorrelationSteps);
    std::string why;
    for (;;) {
      mo.num_lags = L;
      report_progress(options.progress, {"identify", "Markov horizon", 0, 0, fmt::format("{} lags", L)});
      result.markov = estimate_markov(experiments, mo, &corr);
      const ScaledEnergy e = scaled_energy(result.markov);
      if (response_ended(e, L, tail_fraction(), &why)) {
        ch.horizon_reason = fmt::format("horizon {} lags ({:.4g} s): {}", L, static_cast<double>(L) * Ts, why);
        break;
      }
      mo.initial_guess = result.markov.g;  // the next horizon starts from this one's estimate
      if (2 * L > cap) {
        ch.horizon_reason = fmt::format("horizon {} lags ({:.4g} s), a quarter of the shortest record: {}; the response "
                                        "beyond is left to the tail rounds",
                                        L, static_cast<double>(L) * Ts, why);
        response_beyond = true;
        break;
      }
      L *= 2;
    }
  }
  ch.num_lags = L;
  result.num_lags = L;
  corr.qv.clear();  // the tail rounds' outputs are corrected ones; R_vv stays
  for (const auto& w : result.markov.report.warnings) result.warnings.push_back("markov: " + w);
  run.L = L;
  run.response_beyond = response_beyond;
  run.g0 = MarkovSequence(result.markov.g.begin(), result.markov.g.begin() + L + 1);
  run.coloured = coloured_now();
  run.colour_ratio = colour_ratio;
}

// Per bin of the L-point grid: the whitened signal-to-noise ratio (1 at the noise floor)
// and the largest singular value of the response in scaled channels.
struct BinLevels {
  std::vector<double> snr, mag;
};
BinLevels bin_levels(const StructuredRun& run, const MarkovBins& all, const MarkovResult& markov) {
  const Index F = all.num_bins(), L = run.L;
  BinLevels lv;
  std::vector<double>& snr = lv.snr;
  std::vector<double>& mag = lv.mag;
  snr.resize(static_cast<std::size_t>(F));
  mag.resize(static_cast<std::size_t>(F));
  for (Index f = 0; f < F; ++f) {
    const Eigen::MatrixXcd& G = all.response[static_cast<std::size_t>(f)];
    const Eigen::MatrixXcd D2 = (run.coloured ? all.excitation_spectrum[static_cast<std::size_t>(f)]
                                              : Eigen::MatrixXcd(run.R0.cast<std::complex<double>>())) /
                                static_cast<double>(L);
    snr[static_cast<std::size_t>(f)] =
        std::sqrt(std::max(0.0, (G.adjoint() * all.noise_inverse[static_cast<std::size_t>(f)] * G * D2).trace().real()) /
                  static_cast<double>(run.p * run.m));
    const Eigen::MatrixXcd Gs = markov.output_rms.cwiseInverse().asDiagonal() * G * markov.excitation_rms.asDiagonal();
    mag[static_cast<std::size_t>(f)] = Gs.jacobiSvd().singularValues()(0);
  }
  return lv;
}

// The fit band's bins (ch.fit_bins, ch.fit_band_max_rad_s, ch.band_reason): the lowest of
// the signal-to-noise edge, the dynamic range, the information tail and the compute bound
// (see kBandMinSnr), unless given.
void choose_band_edge(const StructuredRun& run, const MarkovBins& all, const BinLevels& lv, IdentifyChoices& ch) {
  const IdentifyOptions& options = run.options;
  const Index F = all.num_bins(), L = run.L;
  const std::vector<double>& snr = lv.snr;
  const std::vector<double>& mag = lv.mag;
  const double peak = *std::max_element(mag.begin(), mag.end());
  Index f_snr = 0, f_dyn = 0;
  for (Index f = 0; f < F; ++f) {
    const Index lo = std::max<Index>(0, f - kBandMedianBins / 2), hi = std::min<Index>(F - 1, f + kBandMedianBins / 2);
    std::vector<double> win(snr.begin() + lo, snr.begin() + hi + 1);
    std::nth_element(win.begin(), win.begin() + static_cast<std::ptrdiff_t>(win.size() / 2), win.end());
    // E|Ĝ|² = |G|² + noise: the signal power is the excess over 1 (whitened units).
    if (win[win.size() / 2] * win[win.size() / 2] - 1.0 >= kBandMinSnr * kBandMinSnr) f_snr = f + 1;
    if (mag[static_cast<std::size_t>(f)] >= kBandDynamicRange * peak) f_dyn = f + 1;
  }
  // Cumulative signal power (a proxy of the information about the response): the bins
  // beyond f_info add less than kBandInformationTail of it.
  double total_power = 0.0;
  std::vector<double> power(static_cast<std::size_t>(F));
  for (Index f = 0; f < F; ++f) {
    const double s2 = snr[static_cast<std::size_t>(f)] * snr[static_cast<std::size_t>(f)] - 1.0;
    power[static_cast<std::size_t>(f)] = (f == 0 || 2 * f == L ? 1.0 : 2.0) * std::max(0.0, s2);
    total_power += power[static_cast<std::size_t>(f)];
  }
  Index f_info = F;
  {
    double acc = 0.0;
    for (Index f = 0; f < F; ++f) {
      acc += power[static_cast<std::size_t>(f)];
      if (acc >= (1.0 - kBandInformationTail) * total_power) {
        f_info = f + 1;
        break;
      }
    }
  }
  Index F_fit = std::min({f_snr, f_dyn, f_info, kMaxFitBins, F});
  std::string reason;
  if (options.fit_band_max_rad_s > 0.0) {
    F_fit = std::min(F, bins_below(options.fit_band_max_rad_s, L, run.Ts));
    reason = fmt::format("up to {:.4g} rad/s as given", options.fit_band_max_rad_s);
  } else if (F_fit == F) {
    reason = "up to the Nyquist frequency: the data carry information at every bin";
  } else if (F_fit == kMaxFitBins) {
    reason = fmt::format("the first {} bins (compute bound)", kMaxFitBins);
  } else if (F_fit == f_info) {
    reason = fmt::format("the bins beyond hold less than {:g} of the signal power", kBandInformationTail);
  } else if (F_fit == f_snr) {
    reason = "up to where the signal power per bin falls below the noise power";
  } else {
    reason = "up to where the closed loop's response is 60 dB below its peak";
  }
  F_fit = std::max(F_fit, std::min(F, kMinStageBins));
  ch.fit_bins = F_fit;
  ch.fit_band_max_rad_s = all.omega_rad_s(F_fit - 1);
  ch.band_reason = fmt::format("{} bins, 0..{:.4g} rad/s: {}", F_fit, ch.fit_band_max_rad_s, reason);
}

void choose_fit_band(StructuredRun& run, IdentifyResult& result) {
  IdentifyChoices& ch = result.choices;
  const Index L = run.L;
  const double Ts = run.Ts;
  report_progress(run.options.progress, {"identify", "noise spectrum", 0, 0, ""});
  run.R0 = excitation_gram(run.experiments);
  // A coloured excitation (a reference trajectory, band-limited noise, a sweep): the
  // error of Ĝ_L at bin f is ∝ S_vv(f)⁻¹, not R₀⁻¹, so the fit weighs each bin by the
  // excitation's own spectral density there (MarkovBins::excitation_spectrum,
  // StructuredRun::with_spectrum).
  ch.excitation_reason =
      run.coloured ? fmt::format("coloured: its spectral density spans a factor {:.3g} (> {:g}); each bin weighed by "
                                 "the excitation's spectrum there (Bartlett window of K/2 lags)",
                                 run.colour_ratio, kWhitenessRatio)
                   : fmt::format("white: its spectral density stays within a factor {:.3g} (<= {:g}); R_0 at every bin",
                                 run.colour_ratio, kWhitenessRatio);
  run.spectrum = fir_residual_spectrum(run.experiments, run.g0, L, L / 2 + 1);
  const MarkovBins all =
      run.with_spectrum(make_markov_bins(run.g0, L, L / 2 + 1, run.spectrum, run.R0, Ts, kMarkovRelativeAccuracy));
  choose_band_edge(run, all, bin_levels(run, all, result.markov), ch);
  run.omega_fit = ch.fit_band_max_rad_s;
  run.lowest_bin_rad_s = all.omega_rad_s(1);
  // Stages: horizons K = L / 2^s, the shortest with at least kMinStageBins bins (at most
  // three halvings); the first fit is the cheapest and the least nonlinear.
  Index K0 = L;
  for (int s = 0; s < 3 && K0 / 2 >= 4 && bins_below(run.omega_fit, K0 / 2, Ts) >= kMinStageBins; ++s) K0 /= 2;
  run.K0 = K0;
}

}  // namespace lpvid::identify_detail
