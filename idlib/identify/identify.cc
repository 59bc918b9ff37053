#include "idlib/identify/identify.h"
#include "idlib/identify/output_error.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "idlib/closedloop/plant_markov.h"
#include "idlib/core/error.h"
#include "idlib/core/parallel.h"
#include "idlib/identify/response_tail.h"
#include "idlib/lti/analysis.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/lti/interconnect.h"
#include "idlib/signal/noise_spectrum.h"

namespace lpvid {

namespace {

// ---- horizon ----
// The paper recipe's (kEra) default horizon: 2 s covers a slowest closed-loop pole at
// −3 rad/s to 2.5e-3 of its peak (the foundation's choice; kept for that method).
constexpr double kEraDefaultHorizon_s = 2.0;
// kStructured: the first horizon tried is the power of two at or above 1/64 of the
// shortest record (1024 lags for 60 s at 1 kHz, 16384 for 100 s at 10 kHz), at least
// kMinHorizonLags; it is doubled while the response has not ended, up to a quarter of
// the record (each lag then still has 4 record lengths of data behind it).
constexpr Index kHorizonRecordDivisor = 64;
constexpr Index kMinHorizonLags = 256;
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
// Fewest record segments for the replicate covariance of the bands (fewer: the noise
// model's covariance, with a warning in the reason).
constexpr std::size_t kMinReplicates = 8;
// Segments for the replicates: one per horizon L of record, but no more than about this
// many (longer segments leak less and cost less; 64 replicates estimate a variance to
// ±18 %, which the band's radius allows for).
constexpr Index kTargetReplicates = 64;

// ---- starting models and order ----
// ERA on the plant's impulse response p̂ uses a 32 × 32-block Hankel matrix (96 × 96 for
// 3 × 3: orders up to 20 fit, and the SVD costs < 5 ms) over the first Lc lags, Lc from
// {L/32, L/16, L/8, L/4}; the start whose closed loop fits the data best is kept.
constexpr Index kStartBlocks = 32;
constexpr Index kMaxPlantOrder = 20;
// Orders compare by their whitened cost per degree of freedom V/dof (1 at the noise
// floor): a larger order is better only when it lowers V/dof by more than kOrderSigmas
// standard deviations (√(2/dof) relative) — extra states must explain more than noise.
constexpr double kOrderSigmas = 5.0;
// The ladder's noise-floor test allows the noise spectrum estimate this factor of error:
// an order is "at the floor" when V/dof <= kFloorSlack (1 + 5 sqrt(2/dof)).  Measured at the
// first stage on the independent simulator (seed 1, noise x1, 3 positions): the true order
// reached V/dof = 1.10-1.17; one order less stayed at 10^3-10^5.
// Noise-free logs put the first stage's floor higher (the response beyond the horizon is
// the "noise", and its spectrum is estimated roughly): 1.3-1.9 there.  The floor test only
// stops the climb; the next kLadderConfirm orders must still not be better by kOrderSigmas.
constexpr double kFloorSlack = 3.0;
// Orders tried above the first one at the floor before it is chosen, and above the best
// order when none reaches the floor.
constexpr Index kLadderConfirm = 2;
constexpr Index kLadderPlateau = 3;
// An order whose first-stage fit still has V/dof above this many times the noise floor
// after kOrderScreenIterations is not refined further (`screened`).  Measured on the
// independent simulator (seed 1, 3 positions, with and without noise): orders below the
// true one had V/dof of 10^3 to 10^5 after 50 iterations and still after 300; the true
// order's fits from ERA starts reached the floor within 6-10 iterations.
constexpr double kOrderAbandonRatio = 100.0;
// Also the budget of the order above the one at the floor (the confirmation): a state the
// data need lowers the cost within it.
constexpr int kOrderScreenIterations = 15;

// ---- tail rounds ----
// Stop when the plant's response moves by less than this fraction of its own standard
// deviation between rounds (or by less than kTailRelativeFloor of itself, noise-free).
// The rounds contract by ~0.2 per round with the tail's amplitudes refitted (measured,
// noise-free, 10 kHz) and by up to ~0.7 without: the rounds left would move the plant by
// at most 0.7 / 0.3 ≈ 2.3 × the last change, so 1e-5 leaves ≤ ~2.3e-5 of the response,
// 4x under the noise-free error bound of the robustness suite (1e-4; measured ≤ 2e-6).
constexpr double kTailChangeSigmas = 0.1;
constexpr double kTailRelativeFloor = 1e-5;
// Iterations per tail round: the rounds are a fixed-point iteration, so a round need not
// converge (the next continues from it, and the rounds stop only when the plant stops
// moving).  Measured on noise-free logs (independent simulator seed 1, right): rounds of
// 300 iterations took 3.3 s each from the first round's sharper weights; 30 per round
// reached the same plant (error 0.000 %) in 2.7 s in all.
constexpr int kTailRoundIterations = 30;
constexpr Index kChangeGridPoints = 100;

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

std::string order_list(const std::vector<IdentifyChoices::Candidate>& c) {
  std::string s;
  for (const auto& x : c)
    s += fmt::format("{}{} ({:.4g}{})", s.empty() ? "" : ", ", x.order, x.cost / std::max(x.dof, 1.0),
                     x.screened ? ", not refined" : (x.stable ? "" : ", unstable loop"));
  return s;
}

// The kEra chain (the paper's recipe): Markov → ERA → unloop.
IdentifyResult identify_era(const std::vector<ExperimentView>& experiments, double sample_period_s,
                            const StateSpace& controller, const IdentifyOptions& options, Index shortest) {
  IdentifyResult result;
  result.method = IdentifyMethod::kEra;
  result.num_lags = choose_num_lags(options, sample_period_s, shortest);
  MarkovOptions markov_options;
  markov_options.num_lags = result.num_lags;
  markov_options.method = options.markov_method;
  report_progress(options.progress, {"identify", "Markov parameters", 0, 0, fmt::format("{} lags", result.num_lags)});
  result.markov = estimate_markov(experiments, markov_options);
  for (const auto& w : result.markov.report.warnings) result.warnings.push_back("markov: " + w);

  EraOptions era_options;
  era_options.sample_period_s = sample_period_s;
  era_options.order = options.closed_loop_order;
  era_options.max_order = options.max_order;
  era_options.input_scale = result.markov.excitation_rms;
  era_options.output_scale = result.markov.output_rms;
  era_options.markov_noise_std = result.markov.noise_std;
  // A zero-order-hold sampled plant has no direct feedthrough (D_P = 0), so
  // neither has G = P (I + C P)^-1: D_G = D_P (I + D_C D_P)^-1 = 0.
  era_options.estimate_feedthrough = false;
  report_progress(options.progress, {"identify", "realization", 0, 0, ""});
  result.era = realize_era(result.markov.g, era_options);
  for (const auto& w : result.era.report.warnings) result.warnings.push_back("realize: " + w);
  // The experiments ran in a stable closed loop, so an unstable model of it is
  // wrong, and inverting the loop around it would only hide that.
  if (!is_stable(result.era.model)) {
    double radius = 0;
    for (const auto& z : poles(result.era.model)) radius = std::max(radius, std::abs(z));
    throw NumericalError(fmt::format(
        "the realised closed loop (order {}) is unstable (largest pole magnitude {:.6f}) although the loop that ran "
        "was stable; the Markov parameters have not died out within the horizon or the order is wrong: try a longer "
        "--horizon-s, a longer record, --order, or the default --method structured",
        result.era.model.order(), radius));
  }
  UnloopOptions unloop_options;
  unloop_options.plant_order = options.plant_order;
  report_progress(options.progress, {"identify", "unloop", 0, 0, ""});
  result.unloop = plant_from_closed_loop(result.era.model, controller, unloop_options);
  for (const auto& w : result.unloop.report.warnings) result.warnings.push_back("unloop: " + w);
  result.closed_loop = result.era.model;
  result.plant = result.unloop.plant;
  return result;
}

// Largest change of P between two plants over the band, relative to |P| and to P's std.
struct Change {
  double relative = 0, sigmas = 0;
};
Change plant_change(const PlantFitResult& now, const StateSpace& before, const Eigen::VectorXd& grid) {
  const auto a = evaluate_response(now.plant, grid), b = evaluate_response(before, grid);
  const auto var = plant_response_variance(now, grid);
  Change c;
  for (Index k = 0; k < grid.size(); ++k) {
    const double d = (a[static_cast<std::size_t>(k)] - b[static_cast<std::size_t>(k)]).norm();
    c.relative = std::max(c.relative, d / std::max(a[static_cast<std::size_t>(k)].norm(), 1e-300));
    c.sigmas = std::max(c.sigmas, d / std::max(std::sqrt(var[static_cast<std::size_t>(k)].sum()), 1e-300));
  }
  return c;
}

IdentifyResult identify_structured(const std::vector<ExperimentView>& experiments, double Ts,
                                   const StateSpace& controller, const IdentifyOptions& options, Index shortest) {
  IdentifyResult result;
  result.method = IdentifyMethod::kStructured;
  IdentifyChoices& ch = result.choices;
  const Index m = experiments.front().excitation.cols();
  const Index p = experiments.front().output.cols();
  MarkovOptions mo;
  mo.method = options.markov_method;

  // 1. Horizon.
  bool response_beyond = false;  // the response has not ended within the horizon
  const bool given = options.num_lags > 0 || options.markov_horizon_s > 0.0;
  Index L = 0;
  // R_vv and R_qv, computed once for the horizon steps (up to kHorizonCorrelationSteps
  // doublings ahead); R_vv is reused by the tail rounds.
  MarkovCorrelations corr;
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
    L = choose_num_lags(options, Ts, shortest);
    mo.num_lags = L;
    corr.max_lag = L;
    report_progress(options.progress, {"identify", "Markov horizon", 0, 0, fmt::format("{} lags", L)});
    result.markov = estimate_markov(experiments, mo, &corr);
    ch.horizon_reason = fmt::format("{} lags were given", L);
    std::string why;
    response_beyond = !response_ended(scaled_energy(result.markov), L, tail_fraction(), &why);
  } else {
    const Index cap = std::max<Index>(kMinHorizonLags, pow2_at_most(shortest / 4));
    L = std::min(cap, std::max(kMinHorizonLags, pow2_at_least(shortest / kHorizonRecordDivisor)));
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
  const MarkovSequence g0(result.markov.g.begin(), result.markov.g.begin() + L + 1);

  // 2. Noise spectrum and the fit band.
  report_progress(options.progress, {"identify", "noise spectrum", 0, 0, ""});
  const Eigen::MatrixXd R0 = excitation_gram(experiments);
  // A coloured excitation (a reference trajectory, band-limited noise, a sweep): the
  // error of Ĝ_L at bin f is ∝ S_vv(f)⁻¹, not R₀⁻¹, so the fit weighs each bin by the
  // excitation's own spectral density there (MarkovBins::excitation_spectrum).
  const bool coloured = coloured_now();
  ch.excitation_reason =
      coloured ? fmt::format("coloured: its spectral density spans a factor {:.3g} (> {:g}); each bin weighed by the "
                             "excitation's spectrum there (Bartlett window of K/2 lags)",
                             colour_ratio, kWhitenessRatio)
               : fmt::format("white: its spectral density stays within a factor {:.3g} (<= {:g}); R_0 at every bin",
                             colour_ratio, kWhitenessRatio);
  auto with_spectrum = [&](MarkovBins b) {
    if (coloured) {
      const Eigen::VectorXd w = b.omega_rad_s * Ts;
      b.excitation_spectrum = excitation_spectrum_at(corr.vv, b.num_lags / 2, w);
    }
    return b;
  };
  std::vector<Eigen::MatrixXcd> spectrum = fir_residual_spectrum(experiments, g0, L, L / 2 + 1);
  const MarkovBins all = with_spectrum(make_markov_bins(g0, L, L / 2 + 1, spectrum, R0, Ts, kMarkovRelativeAccuracy));
  {
    const Index F = all.num_bins();
    std::vector<double> snr(static_cast<std::size_t>(F)), mag(static_cast<std::size_t>(F));
    for (Index f = 0; f < F; ++f) {
      const Eigen::MatrixXcd& G = all.response[static_cast<std::size_t>(f)];
      const Eigen::MatrixXcd D2 = (coloured ? all.excitation_spectrum[static_cast<std::size_t>(f)]
                                            : Eigen::MatrixXcd(R0.cast<std::complex<double>>())) /
                                  static_cast<double>(L);
      snr[static_cast<std::size_t>(f)] =
          std::sqrt(std::max(0.0, (G.adjoint() * all.noise_inverse[static_cast<std::size_t>(f)] * G * D2).trace().real()) /
                    static_cast<double>(p * m));
      const Eigen::MatrixXcd Gs = result.markov.output_rms.cwiseInverse().asDiagonal() * G *
                                  result.markov.excitation_rms.asDiagonal();
      mag[static_cast<std::size_t>(f)] = Gs.jacobiSvd().singularValues()(0);
    }
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
      F_fit = std::min(F, bins_below(options.fit_band_max_rad_s, L, Ts));
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
  const double omega_fit = ch.fit_band_max_rad_s;
  auto bins_at = [&](const MarkovSequence& g, const std::vector<Eigen::MatrixXcd>& fine, Index K) {
    const Index F = std::max<Index>(std::min(K / 2 + 1, kMinStageBins), bins_below(omega_fit, K, Ts));
    return with_spectrum(make_markov_bins(g, K, F, coarser_spectrum(fine, L, K, F), R0, Ts, kMarkovRelativeAccuracy));
  };
  // Stages: horizons K = L / 2^s, the shortest with at least kMinStageBins bins (at most
  // three halvings); the first fit is the cheapest and the least nonlinear.
  Index K0 = L;
  for (int s = 0; s < 3 && K0 / 2 >= 4 && bins_below(omega_fit, K0 / 2, Ts) >= kMinStageBins; ++s) K0 /= 2;

  PlantFitOptions fo;
  fo.input_scale = result.markov.excitation_rms;
  fo.output_scale = result.markov.output_rms;
  const MarkovBins first = bins_at(g0, spectrum, K0);

  // 3. Starting models: ERA on the plant's impulse response p̂ = Ĝ (I − C Ĝ)⁻¹ over the
  //    first Lc lags for a few Lc, every order from one SVD per Lc; for each order the
  //    start that closes a stable loop and fits the first stage best is kept.
  const Index n_cap = options.plant_order > 0
                          ? options.plant_order
                          : std::min<Index>(kMaxPlantOrder, std::min(options.max_order, kStartBlocks * std::min(p, m) - 1));
  std::vector<Index> start_lags;
  for (Index d : {32, 16, 8, 4})
    if (L / d >= 2 * kStartBlocks + 4) start_lags.push_back(L / d);
  if (start_lags.empty()) start_lags.push_back(L);
  // p̂ is needed only as far as the longest start horizon (its cost grows as its length²).
  const Index start_lags_max = *std::max_element(start_lags.begin(), start_lags.end());
  struct Realised {
    Index lags = 0;
    std::vector<StateSpace> models;  // [n − 1], order 0 where the Hankel matrix cannot hold n
  };
  auto realise_all = [&](const MarkovSequence& phat) {
    std::vector<Realised> out;
    for (const Index Lc : start_lags) {
      EraOptions eo;
      eo.sample_period_s = Ts;
      eo.estimate_feedthrough = false;
      eo.order = 1;
      eo.max_order = n_cap;
      for (Index n = 2; n <= n_cap; ++n) eo.also_orders.push_back(n);
      eo.block_rows = eo.block_cols = kStartBlocks;
      eo.stride = std::max<Index>(1, Lc / (2 * kStartBlocks));
      eo.sum_stride_lags = true;
      const MarkovSequence part(phat.begin(), phat.begin() + std::min<Index>(Lc, L) + 1);
      try {
        EraResult er = realize_era(part, eo);
        Realised r;
        r.lags = Lc;
        r.models.push_back(std::move(er.model));
        for (auto& mdl : er.models_at) r.models.push_back(std::move(mdl));
        out.push_back(std::move(r));
      } catch (const std::runtime_error&) {
        // a Hankel layout these lags cannot hold: no starts from this Lc
      }
    }
    return out;
  };
  struct Start {
    StateSpace model;
    double cost = std::numeric_limits<double>::infinity();
    bool stable = false;
    Index lags = 0;
  };
  // A start that closes a stable loop is preferred to any that does not (the loop that
  // ran was stable, and the fit keeps a stable loop stable); among them the lowest cost.
  auto best_start = [&](const std::vector<const std::vector<Realised>*>& pools, const MarkovBins& data, Index n) {
    Start best;
    for (const auto* pool : pools)
      for (const Realised& r : *pool) {
        const StateSpace& P0 = r.models[static_cast<std::size_t>(n - 1)];
        if (P0.order() != n || !P0.A.allFinite() || !P0.B.allFinite() || !P0.C.allFinite()) continue;
        const bool stable = is_stable(closed_loop_output(P0, controller));
        if (best.stable && !stable) continue;
        const double c = plant_fit_cost(data, controller, P0, fo);
        if (!std::isfinite(c)) continue;
        if ((stable && !best.stable) || c < best.cost) best = {P0, c, stable, r.lags};
      }
    return best;
  };
  auto per_dof = [](const PlantFitResult& f) {
    return f.cost / static_cast<double>(std::max<Index>(1, f.residuals - f.parameters));
  };
  auto sigma_factor = [&](const PlantFitResult& f) {  // 1 + kOrderSigmas standard deviations of V/dof
    return 1.0 + kOrderSigmas * std::sqrt(2.0 / static_cast<double>(std::max<Index>(1, f.residuals - f.parameters)));
  };
  // Order n at the first stage from its best start: kOrderScreenIterations first; a fit
  // still kOrderAbandonRatio above the noise floor (V/dof = 1) then is not refined
  // (`screened`), otherwise it continues up to `budget` iterations in all.
  struct OrderFit {
    PlantFitResult fit;
    Start start;
    bool found = false, screened = false;
  };
  auto fit_order = [&](const std::vector<const std::vector<Realised>*>& pools, const MarkovBins& data, Index n,
                       int budget) {
    OrderFit o;
    o.start = best_start(pools, data, n);
    if (!std::isfinite(o.start.cost)) return o;
    o.found = true;
    PlantFitOptions screen = fo;
    screen.max_iterations = std::min({fo.max_iterations, budget, kOrderScreenIterations});
    o.fit = fit_plant_closed_loop(data, controller, o.start.model, screen);
    if (per_dof(o.fit) > kOrderAbandonRatio) {
      o.screened = true;
      return o;
    }
    if (o.fit.iterations >= screen.max_iterations && budget > o.fit.iterations) {
      PlantFitOptions rest = fo;
      rest.max_iterations = std::max(0, std::min(fo.max_iterations, budget) - o.fit.iterations);
      o.fit = fit_plant_closed_loop(data, controller, o.fit.plant, rest);
    }
    return o;
  };
  auto candidate = [&](Index n, const OrderFit& o) {
    IdentifyChoices::Candidate c;
    c.order = n;
    c.cost = o.fit.cost;
    c.dof = static_cast<double>(std::max<Index>(1, o.fit.residuals - o.fit.parameters));
    c.stable = o.fit.closed_loop_stable;
    c.screened = o.screened;
    return c;
  };

  report_progress(options.progress, {"identify", "starting models", 0, 0, "ERA on the plant's impulse response"});
  const MarkovSequence phat0 = plant_markov_from_closed_loop(g0, controller, start_lags_max);
  const std::vector<Realised> pool0 = realise_all(phat0);
  const bool select_order = options.plant_order == 0;
  PlantFitResult fit;
  if (!select_order) {
    const OrderFit o = fit_order({&pool0}, first, options.plant_order, fo.max_iterations);
    if (!o.found)
      throw NumericalError(fmt::format("no starting model of order {} could be realised from the logs; give another "
                                       "--plant-order or a longer record",
                                       options.plant_order));
    fit = o.fit;
    if (o.screened) fit = fit_plant_closed_loop(first, controller, fit.plant, fo);
    ch.plant_horizon = o.start.lags;
    ch.order_reason = fmt::format("order {} was given", options.plant_order);
  } else {
    // 4. Order: a ladder n = 1, 2, ... at the first stage.  The first order whose whitened
    //    cost per degree of freedom is at the noise floor (≤ kFloorSlack (1 + 5σ): V/dof ≈ 1
    //    when the model explains everything but the noise) is confirmed against the next
    //    order; if that one is not better by more than kOrderSigmas standard deviations, it
    //    is chosen.  When no order reaches the floor, the ladder stops kLadderPlateau orders
    //    above the best one and the smallest order within kOrderSigmas of the best is
    //    chosen (an F-test: extra states must lower the cost by more than noise would).
    std::vector<OrderFit> fits(static_cast<std::size_t>(n_cap + 1));
    Index at_floor = -1, best = -1;
    for (Index n = 1; n <= n_cap; ++n) {
      const bool confirming = at_floor >= 0;
      report_progress(options.progress,
                      {"identify", "plant order", n, 0, fmt::format("up to {}", n_cap)});
      OrderFit o = fit_order({&pool0}, first, n, confirming ? kOrderScreenIterations : fo.max_iterations);
      if (!o.found) continue;
      ch.order_candidates.push_back(candidate(n, o));
      const bool usable = o.fit.closed_loop_stable && !o.screened;
      const double r = per_dof(o.fit);
      fits[static_cast<std::size_t>(n)] = std::move(o);
      if (usable && (best < 0 || r < per_dof(fits[static_cast<std::size_t>(best)].fit))) best = n;
      if (confirming) {
        const PlantFitResult& f0 = fits[static_cast<std::size_t>(at_floor)].fit;
        if (usable && per_dof(f0) > std::max(1.0, r * sigma_factor(fits[static_cast<std::size_t>(n)].fit))) {
          at_floor = -1;  // the next order is significantly better: climb on
        } else if (n >= at_floor + kLadderConfirm) {
          break;
        }
        continue;
      }
      if (usable && r <= kFloorSlack * sigma_factor(fits[static_cast<std::size_t>(n)].fit)) {
        at_floor = n;
        continue;
      }
      if (best >= 0 && n >= best + kLadderPlateau) break;
    }
    // identify_open_loop passes C = 0 (no states, no feedthrough): no loop to speak of.
    const bool open_loop = controller.order() == 0 && controller.D.isZero(0.0);
    Index beyond = -1;  // open loop, nothing near the floor: the best stable order of the ladder
    if (best < 0 && open_loop)
      for (Index n = 1; n <= n_cap; ++n) {
        const OrderFit& o = fits[static_cast<std::size_t>(n)];
        if (o.found && o.fit.closed_loop_stable &&
            (beyond < 0 || per_dof(o.fit) < per_dof(fits[static_cast<std::size_t>(beyond)].fit)))
          beyond = n;
      }
    if (best < 0 && beyond < 0) {
      throw NumericalError(fmt::format(
          "no candidate plant (orders {}) {}", order_list(ch.order_candidates),
          open_loop ? "is stable and fits the open-loop logs to their noise floor; the plant may need an order beyond "
                      "the ladder (give --plant-order) or the route markov + realize"
                    : "closes a stable loop with the controller that fits the logs; check that the controller is the "
                      "one that ran and that the logs are closed-loop data"));
    }
    Index chosen = at_floor;
    std::string why;
    if (best < 0) {
      // A real structure with more modes than the ladder holds (the DaISy steel subframe:
      // every order 1-20 stays above kOrderAbandonRatio times the floor): the open-loop logs
      // still define a best model of each order; take the ladder's best and say why.
      // Why no order was usable: every one still far above the floor (screened), or some
      // came nearer but ended unstable (an open-loop record of a stable plant).
      std::vector<Index> unstable_near;
      for (Index n = 1; n <= n_cap; ++n) {
        const OrderFit& o = fits[static_cast<std::size_t>(n)];
        if (o.found && !o.screened && !o.fit.closed_loop_stable) unstable_near.push_back(n);
      }
      chosen = beyond;
      fits[static_cast<std::size_t>(chosen)].fit =
          fit_plant_closed_loop(first, controller, fits[static_cast<std::size_t>(chosen)].fit.plant, fo);
      const std::string cause =
          unstable_near.empty()
              ? fmt::format("no order up to {} came within {:g} times the noise floor, so the plant holds more "
                            "dynamics than {} states (or the logs more than a linear plant and white noise)",
                            n_cap, kOrderAbandonRatio, n_cap)
              : fmt::format("the orders that came within {:g} times the noise floor ({}) ended unstable, which "
                            "open-loop logs of a running plant do not support, and the others stayed above it",
                            kOrderAbandonRatio, fmt::join(unstable_near, ", "));
      why = fmt::format("{}; {} is the ladder's best stable order (cost per degree of freedom {:.4g} after refitting) "
                        "and is taken -- judge it by the simulation fit below, and give --plant-order above {} to try "
                        "more states",
                        cause, chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), n_cap);
    } else if (chosen >= 0) {
      why = fmt::format("{} is the first order at the noise floor (cost per degree of freedom {:.4g}) and the next "
                        "order is not better by {:g} sigma",
                        chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), kOrderSigmas);
    } else {
      const double ref = per_dof(fits[static_cast<std::size_t>(best)].fit);
      for (Index n = 1; n <= best && chosen < 0; ++n) {
        const OrderFit& o = fits[static_cast<std::size_t>(n)];
        if (o.found && !o.screened && o.fit.closed_loop_stable &&
            per_dof(o.fit) <= std::max(1.0, ref * sigma_factor(o.fit)))
          chosen = n;
      }
      why = fmt::format("no order reached the noise floor; {} is the smallest whose cost per degree of freedom ({:.4g}) "
                        "is within {:g} sigma of the best ({:.4g}, order {})",
                        chosen, per_dof(fits[static_cast<std::size_t>(chosen)].fit), kOrderSigmas, ref, best);
    }
    fit = std::move(fits[static_cast<std::size_t>(chosen)].fit);
    ch.plant_horizon = fits[static_cast<std::size_t>(chosen)].start.lags;
    ch.order_reason = fmt::format("orders tried at the first stage (cost per degree of freedom): {}; {}",
                                  order_list(ch.order_candidates), why);
  }
  ch.start_reason = fmt::format("ERA on the first {} lags of the plant's impulse response P = G (I - C G)^-1 (the best "
                                "closed-loop fit among {} horizons)",
                                ch.plant_horizon, start_lags.size());

  // 5. Staged fit: horizons K0, 2 K0, ..., L.
  ch.stages.push_back({K0, first.num_bins(), fit.iterations, fit.cost});
  Index stage_count = 1;
  for (Index K = 2 * K0; K <= L; K *= 2) ++stage_count;
  for (Index K = 2 * K0; K <= L; K *= 2) {
    report_progress(options.progress, {"identify", "staged fit", static_cast<Index>(ch.stages.size()) + 1, stage_count,
                                       fmt::format("{} lags", K)});
    const MarkovBins stage = bins_at(g0, spectrum, K);
    fit = fit_plant_closed_loop(stage, controller, fit.plant, fo);
    ch.stages.push_back({K, stage.num_bins(), fit.iterations, fit.cost});
  }

  // 6. Tail rounds: subtract the fitted response beyond the horizon, re-estimate ĝ, refit,
  //    until the plant stops moving.  Then the order check on the final data: a smaller
  //    order (from its own ERA starts on the corrected p̂ and on the first p̂) replaces the
  //    model when its first-stage cost per degree of freedom is within kOrderSigmas of the
  //    current one's or at the noise floor; the descent stops at the first order that is
  //    not (the best cost cannot rise with the order, so a smaller one would fail too),
  //    and the tail rounds are rerun from the reduced model.  At the first data the
  //    response beyond the horizon is part of the noise, and an extra state can explain
  //    some of it (measured: orders 7 and 9 kept on drawn plants whose order-6 fit on the
  //    final data is as good).
  const Eigen::VectorXd grid = log_frequency_grid(std::max(all.omega_rad_s(1), 1e-3),
                                                  std::max(omega_fit, 2.0 * all.omega_rad_s(1)), kChangeGridPoints);
  std::vector<Eigen::MatrixXd> corrected(experiments.size());
  MarkovSequence g_final = g0;  // ĝ of the last round's corrected data
  for (int pass = 0; pass < 2; ++pass) {
    ch.tail_rounds.clear();
    ch.tail_reason = fmt::format("no rounds ({} allowed)", options.max_tail_rounds);
    for (int round = 1; round <= options.max_tail_rounds; ++round) {
      report_progress(options.progress, {"identify", "tail round", round, 0,
                                         fmt::format("up to {}{}", options.max_tail_rounds,
                                                     pass == 1 ? ", after the order check" : "")});
      std::vector<ExperimentView> views;
      parallel_for(static_cast<Index>(experiments.size()), [&](Index e) {  // one task per experiment
        const auto& x = experiments[static_cast<std::size_t>(e)];
        corrected[static_cast<std::size_t>(e)] =
            x.output - closed_loop_response_beyond(fit.plant, controller, x.excitation, L);
      });
      for (std::size_t e = 0; e < experiments.size(); ++e) views.push_back({experiments[e].excitation, corrected[e]});
      // Where the response had not ended within the horizon, the slow modes' tail
      // amplitudes from the logs (with the last ĝ), not from the model alone
      // (refit_response_beyond): the plain rounds contract too slowly there (measured
      // ~0.7 per round on a drawn plant with 17 % of the energy beyond; ~0.2 with the refit).
      if (response_beyond) {
        const std::vector<Eigen::MatrixXd> refit = refit_response_beyond(fit.plant, controller, views, g_final, L);
        for (std::size_t e = 0; e < experiments.size(); ++e) corrected[e] -= refit[e];
      }
      mo.num_lags = L;
      mo.initial_guess = g_final;  // the previous round's ĝ: the correction is small
      const MarkovResult mr = estimate_markov(views, mo, &corr);
      if (round == 1 && pass == 0) spectrum = fir_residual_spectrum(views, mr.g, L, L / 2 + 1);
      const MarkovBins data = bins_at(mr.g, spectrum, L);
      g_final = mr.g;
      const StateSpace before = fit.plant;
      PlantFitOptions tail_fo = fo;
      tail_fo.max_iterations = std::min(fo.max_iterations, kTailRoundIterations);
      fit = fit_plant_closed_loop(data, controller, fit.plant, tail_fo);
      const Change c = plant_change(fit, before, grid);
      ch.tail_rounds.push_back({fit.cost, c.relative});
      if (c.sigmas <= kTailChangeSigmas || c.relative <= kTailRelativeFloor) {
        ch.tail_reason = fmt::format("{} round(s): the last moved the plant by {:.3g} of its standard deviation ({:.3g} "
                                     "relative)",
                                     round, c.sigmas, c.relative);
        break;
      }
      ch.tail_reason = fmt::format("stopped after {} rounds; the last still moved the plant by {:.3g} of its standard "
                                   "deviation ({:.3g} relative)",
                                   round, c.sigmas, c.relative);
      if (round == options.max_tail_rounds) result.warnings.push_back("identify: " + ch.tail_reason);
    }
    if (!select_order || pass == 1 || fit.plant.order() == 1) break;
    // The next smaller order is not retried when the first stage found it more than
    // kOrderAbandonRatio times worse per degree of freedom than the chosen one: the
    // response beyond the horizon, which the tail rounds remove, burdens both orders
    // alike at the first stage (it is why an extra state can look useful there), so it
    // cannot hide a gap that large.
    {
      const Index top = fit.plant.order();
      auto at = [&](Index n) {
        return std::find_if(ch.order_candidates.begin(), ch.order_candidates.end(),
                            [&](const IdentifyChoices::Candidate& c) { return c.order == n; });
      };
      const auto chosen = at(top), below = at(top - 1);
      if (chosen != ch.order_candidates.end() && below != ch.order_candidates.end() &&
          below->cost / std::max(below->dof, 1.0) >
              kOrderAbandonRatio * std::max(chosen->cost / std::max(chosen->dof, 1.0), 1.0)) {
        ch.order_reason += fmt::format("; order {} was more than {:g}x worse per degree of freedom at the first "
                                       "stage, so smaller orders were not retried on the final data",
                                       top - 1, kOrderAbandonRatio);
        break;
      }
    }
    const MarkovBins small = bins_at(g_final, spectrum, K0);
    const std::vector<Realised> pool = realise_all(plant_markov_from_closed_loop(g_final, controller, start_lags_max));
    PlantFitResult top_small = fit_plant_closed_loop(small, controller, fit.plant, fo);
    const Index top = fit.plant.order();
    std::string tried;
    PlantFitResult lower_fit;
    Index lower = top;
    for (Index n = top - 1; n >= 1; --n) {
      report_progress(options.progress, {"identify", "order check", n, 0, fmt::format("against order {}", top)});
      OrderFit o = fit_order({&pool, &pool0}, small, n, fo.max_iterations);
      if (!o.found) break;
      const double ref = per_dof(top_small);
      const bool pass_n = o.fit.closed_loop_stable && !o.screened &&
                          per_dof(o.fit) <= std::max(1.0, ref * sigma_factor(o.fit));
      tried += fmt::format("{}{} ({:.4g}{})", tried.empty() ? "" : ", ", n, per_dof(o.fit),
                           o.screened ? ", not refined" : (o.fit.closed_loop_stable ? "" : ", unstable loop"));
      if (!pass_n) break;
      lower = n;
      lower_fit = std::move(o.fit);
    }
    if (lower == top) {
      if (!tried.empty()) ch.order_reason += fmt::format("; on the final data smaller orders fit worse ({})", tried);
      break;
    }
    ch.order_reason += fmt::format("; on the final data order {} was reduced to {}: orders {} (first-stage cost per "
                                   "degree of freedom; {:.4g} at order {}) (tail rounds rerun)",
                                   top, lower, tried, per_dof(top_small), top);
    fit = std::move(lower_fit);
    for (Index K = 2 * K0; K <= L; K *= 2) fit = fit_plant_closed_loop(bins_at(g_final, spectrum, K), controller, fit.plant, fo);
  }
  ch.plant_order = fit.plant.order();
  // 7. Bands: the covariance from replicates of ĝ's error, one per segment of the records
  //    (L samples, longer where that would give more than kTargetReplicates;
  //    markov_error_replicates), propagated through the final fit
  //    (use_replicate_covariance).  Measured: the model's own σ̂² (JᵀJ)⁺ assumes
  //    independent bins and claimed 6-10x too little variance on the independent
  //    simulator (bins' errors correlate over tens to hundreds of bins).
  {
    report_progress(options.progress, {"identify", "bands", 0, 0, "covariance from the record's segments"});
    std::vector<ExperimentView> views;
    for (std::size_t e = 0; e < experiments.size(); ++e) {
      if (corrected[e].size() > 0)
        views.push_back({experiments[e].excitation, corrected[e]});
      else
        views.push_back(experiments[e]);
    }
    const MarkovBins final_data = bins_at(g_final, spectrum, L);
    Index total = 0;
    for (const auto& e : experiments) total += e.excitation.rows();
    const Index segment = std::max(L, (total + kTargetReplicates - 1) / kTargetReplicates);
    auto reps = markov_error_replicates(views, g_final, R0, segment, L, final_data.num_bins());
    // The replicates divide by R₀ (white excitation); a coloured one's LS error at bin f
    // is the segment's cross-spectrum over S_vv(f): δG_s(f) R₀ S_vv(f)⁻¹.
    if (coloured && !final_data.excitation_spectrum.empty()) {
      std::vector<Eigen::MatrixXcd> to_coloured;
      for (const Eigen::MatrixXcd& S : final_data.excitation_spectrum) {
        // A ridge of 1e-12 of the mean power keeps an unexcited bin finite (its variance
        // then says the data hold nothing there).
        Eigen::MatrixXcd Sr = S;
        Sr.diagonal().array() += 1e-12 * std::max(S.trace().real(), 1e-300) / static_cast<double>(S.rows());
        to_coloured.push_back(R0.cast<std::complex<double>>() * Sr.partialPivLu().inverse());
      }
      for (auto& rep : reps)
        for (std::size_t f = 0; f < rep.size(); ++f) rep[f] = rep[f] * to_coloured[f];
    }
    if (reps.size() >= kMinReplicates) {
      use_replicate_covariance(fit, final_data, controller, reps, fo);
      ch.bands_reason = fmt::format("covariance from {} replicates of the Markov estimate's error, one per {}-sample "
                                    "segment of the records",
                                    reps.size(), segment);
    } else {
      ch.bands_reason = fmt::format("covariance of the fit's noise model (only {} record segments of {} samples; {} "
                                    "are needed for replicates): bins assumed independent, likely too narrow",
                                    reps.size(), segment, kMinReplicates);
    }
  }
  if (!fit.closed_loop_stable)
    throw NumericalError("the fitted plant closes an unstable loop with the controller; the logs do not fit this "
                         "controller (check --controller)");
  for (const auto& w : fit.report.warnings) result.warnings.push_back("fit: " + w);
  result.fit = std::move(fit);
  result.plant = result.fit.plant;
  result.closed_loop = closed_loop_output(result.plant, controller);
  return result;
}

}  // namespace

void IdentifyOptions::validate() const {
  if (markov_horizon_s < 0.0 || !std::isfinite(markov_horizon_s))
    throw InputError(fmt::format("markov horizon {} s: must be a positive number of seconds (or 0 for automatic)",
                                 markov_horizon_s));
  if (num_lags < 0) throw InputError(fmt::format("lags {}: must be positive (or 0 for automatic)", num_lags));
  if (closed_loop_order < 0 || plant_order < 0)
    throw InputError("model orders must be positive (or 0 for automatic)");
  if (max_order < 1) throw InputError(fmt::format("max order {}: must be at least 1", max_order));
  if (fit_band_max_rad_s < 0.0 || !std::isfinite(fit_band_max_rad_s))
    throw InputError(fmt::format("fit band {} rad/s: must be positive (or 0 for automatic)", fit_band_max_rad_s));
  if (max_tail_rounds < 0) throw InputError(fmt::format("tail rounds {}: must be >= 0", max_tail_rounds));
}

Index choose_num_lags(const IdentifyOptions& options, double sample_period_s, Index shortest_record) {
  constexpr Index kMinLags = 10;
  if (options.num_lags > 0) {
    if (options.num_lags < kMinLags)
      throw InputError(fmt::format("--lags {}: give at least {} lags", options.num_lags, kMinLags));
    if (options.num_lags >= shortest_record)
      throw InputError(fmt::format("--lags {} needs records longer than {} samples, but the shortest has {}; give at "
                                   "most {} lags (a quarter of it) or record longer",
                                   options.num_lags, options.num_lags, shortest_record, shortest_record / 4));
    return options.num_lags;
  }
  // A horizon in seconds: it needs a known sample time (a log whose time column is the
  // sample index has Ts = 1 s, and a horizon of a few seconds is then a few lags).
  const bool given = options.markov_horizon_s > 0.0;
  const double horizon_s = given ? options.markov_horizon_s : kEraDefaultHorizon_s;
  const double raw = std::round(horizon_s / sample_period_s);
  if (raw < static_cast<double>(kMinLags))
    throw InputError(fmt::format("{} horizon of {:g} s is only {:g} lag(s) at the logs' sample time {:.6g} s, fewer "
                                 "than {}; give --lags, or a --horizon-s of at least {:.6g} s",
                                 given ? "the" : "the default", horizon_s, raw, sample_period_s, kMinLags,
                                 static_cast<double>(kMinLags) * sample_period_s));
  const Index lags = static_cast<Index>(std::min(raw, static_cast<double>(shortest_record / 4)));
  if (lags < kMinLags)
    throw InputError(fmt::format("a record of {} samples supports at most {} lags (a quarter of it), fewer than {}; "
                                 "record at least {} samples",
                                 shortest_record, shortest_record / 4, kMinLags, 4 * kMinLags));
  return lags;
}

void check_controller_matches(const StateSpace& controller, double sample_period_s, Index num_outputs,
                              Index num_excitations, double relative_tolerance) {
  if (!controller.is_discrete())
    throw InputError("controller is continuous (ts = 0); give the discrete controller that ran on the setup");
  if (std::abs(controller.sample_period_s - sample_period_s) > relative_tolerance * controller.sample_period_s)
    throw InputError(fmt::format(
        "mismatched sample rates: the logs are sampled at {:.6g} Hz (ts = {:.6g} s) but the controller has ts = {:.6g} s "
        "({:.6g} Hz); give the controller discretised at the logging rate",
        1.0 / sample_period_s, sample_period_s, controller.sample_period_s, 1.0 / controller.sample_period_s));
  if (controller.num_inputs() != num_outputs || controller.num_outputs() != num_excitations)
    throw InputError(fmt::format(
        "controller has {} inputs and {} outputs, but the loop has {} measured outputs and {} excitations; "
        "give the controller that maps the {} outputs (e = -q) to the {} plant inputs",
        controller.num_inputs(), controller.num_outputs(), num_outputs, num_excitations, num_outputs, num_excitations));
}

IdentifyResult identify_closed_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                    const StateSpace& controller, const IdentifyOptions& options) {
  options.validate();
  if (experiments.empty()) throw InputError("no experiments given; pass at least one log");
  const Index m = experiments.front().excitation.cols();
  const Index p = experiments.front().output.cols();
  controller.validate();
  check_controller_matches(controller, sample_period_s, p, m, options.sample_period_tolerance);
  Index shortest = experiments.front().excitation.rows();
  for (const auto& e : experiments) shortest = std::min<Index>(shortest, e.excitation.rows());
  if (options.method == IdentifyMethod::kEra) return identify_era(experiments, sample_period_s, controller, options, shortest);
  if (4 * kMinHorizonLags > shortest && options.num_lags == 0 && options.markov_horizon_s == 0.0)
    throw InputError(fmt::format("a record of {} samples is too short for the automatic horizon (at least {} lags, 4 x "
                                 "that in samples); record longer or give --lags",
                                 shortest, kMinHorizonLags));
  return identify_structured(experiments, sample_period_s, controller, options, shortest);
}

IdentifyResult identify_open_loop(const std::vector<ExperimentView>& experiments, double sample_period_s,
                                  const IdentifyOptions& options) {
  if (experiments.empty()) throw InputError("no experiments given; pass at least one log");
  const Index m = experiments.front().excitation.cols();
  const Index p = experiments.front().output.cols();
  // No controller: the closed loop with C = 0 is the plant, G(P) = P (I + C P)^-1 = P.
  StateSpace none;
  none.A.resize(0, 0);
  none.B.resize(0, p);
  none.C.resize(m, 0);
  none.D = Eigen::MatrixXd::Zero(m, p);
  none.sample_period_s = sample_period_s;
  IdentifyResult r = identify_closed_loop(experiments, sample_period_s, none, options);
  r.feedthrough_variance = Eigen::MatrixXd::Zero(p, m);
  if (r.method == IdentifyMethod::kEra) {
    r.plant = r.era.model;  // nothing to unloop; ERA's D is ĝ[0]
    r.plant.sample_period_s = sample_period_s;
    r.choices.feedthrough_reason = "ERA's D is the lag-0 Markov parameter";
  } else {
    // The structured fit uses lags 1..L (a sampled plant inside a loop has no
    // feedthrough). Open loop, lag 0 is the plant's direct feedthrough D (an
    // accelerometer's response to a force), estimated by least squares with the other
    // lags: kept where it stands above kFeedthroughSigmas of its standard error.
    const Eigen::MatrixXd& g0 = r.markov.g.front();
    const Eigen::MatrixXd& se = r.markov.noise_std;
    Eigen::MatrixXd D = Eigen::MatrixXd::Zero(p, m);
    Index kept = 0;
    double largest = 0.0;
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) {
        const double z = se(i, j) > 0 ? std::abs(g0(i, j)) / se(i, j) : std::numeric_limits<double>::infinity();
        largest = std::max(largest, std::isfinite(z) ? z : 0.0);
        if (z > kFeedthroughSigmas) {
          D(i, j) = g0(i, j);
          r.feedthrough_variance(i, j) = se(i, j) * se(i, j);
          ++kept;
        }
      }
    r.plant.D = D;
    r.choices.feedthrough_reason =
        kept > 0 ? fmt::format("D from the lag-0 Markov parameter: {} of {} entries above {:g} standard errors (largest "
                               "{:.3g})",
                               kept, p * m, kFeedthroughSigmas, largest)
                 : fmt::format("no feedthrough: the lag-0 Markov parameter is within {:g} standard errors of zero "
                               "(largest {:.3g}), D = 0",
                               kFeedthroughSigmas, largest);
    if (options.refine_output_error) {
      report_progress(options.progress, {"identify", "output-error refinement", 0, 0, ""});
      // From rest (x(0) = 0) first; then with each record's initial state fitted, kept
      // only when Akaike's criterion says the n E extra values earn their place
      // (N p ln(V_rest / V_free) > 2 n E): a record that starts from rest is fitted
      // without them.
      OutputErrorOptions rest;
      rest.estimate_initial_states = false;
      const OutputErrorResult at_rest = refine_output_error(experiments, r.plant, rest);
      const OutputErrorResult free = refine_output_error(experiments, at_rest.accepted ? at_rest.model : r.plant);
      const double extra = 2.0 * static_cast<double>(r.plant.order() * static_cast<Index>(experiments.size()));
      const bool use_free = free.accepted && (!at_rest.accepted || static_cast<double>(free.residuals) *
                                                                          std::log(at_rest.cost / free.cost) >
                                                                      extra);
      OutputErrorResult oe = use_free ? free : at_rest;
      if (oe.accepted)
        oe.reason = fmt::format(
            "output error on the logs (Levenberg-Marquardt, Ceres): the outputs' normalised squared simulation error "
            "{:.4g} (the structured fit, from rest) -> {:.4g} from rest{}; stable{}{}",
            at_rest.start_cost, at_rest.accepted ? at_rest.cost : at_rest.start_cost,
            use_free ? fmt::format(" -> {:.4g} with each log's initial state fitted (kept: Akaike's criterion, a "
                                   "factor {:.4g} for {:g} more values)",
                                   free.cost, at_rest.accepted ? at_rest.cost / free.cost : 0.0, extra / 2)
                     : fmt::format(" (fitting the initial states too{} does not pay by Akaike's criterion)",
                                   free.accepted ? fmt::format(" lowers it by a factor {:.4g} only",
                                                               at_rest.cost / free.cost)
                                                 : std::string("")),
            oe.iterations >= 200 ? "; stopped at the iteration limit" : "",
            oe.form == "modal"
                ? fmt::format("; in modal form with C and D eliminated ({}){}", oe.form_reason,
                              oe.poles_on_bound > 0
                                  ? fmt::format(", {} pole(s) on its stability bound: the logs cannot tell them from "
                                                "undamped or integrating ones (a drift, or a line in the outputs)",
                                                oe.poles_on_bound)
                                  : std::string())
                : std::string());
      r.choices.refinement_reason = oe.reason;
      IdentifyChoices::Refinement& rf = r.choices.refinement;
      rf.ran = true;
      rf.kept = oe.accepted;
      rf.initial_states_fitted = use_free;
      rf.start_cost = at_rest.start_cost;
      rf.cost = oe.accepted ? oe.cost : at_rest.start_cost;
      rf.iterations = use_free ? at_rest.iterations + free.iterations : at_rest.iterations;
      rf.parameters = oe.parameters;
      rf.residuals = oe.residuals;
      rf.replicates = oe.accepted ? oe.replicates : 0;
      rf.form = oe.form;
      rf.poles_on_bound = oe.accepted ? oe.poles_on_bound : 0;
      if (oe.accepted) {
        r.plant = oe.model;
        r.fit.plant = oe.model;
        r.fit.plant.D.setZero();
        r.fit.covariance = oe.covariance;
        r.fit.replicates = oe.replicates;
        if (!r.plant.D.isZero(0.0)) r.feedthrough_variance = oe.feedthrough_variance;
        r.choices.bands_reason = fmt::format("covariance of the output-error refinement: a sandwich over {} record "
                                             "segments",
                                             oe.replicates);
      }
    } else {
      r.choices.refinement_reason = "not refined (switched off)";
    }
  }
  r.closed_loop = r.plant;
  return r;
}

}  // namespace lpvid

#include "idlib/lti/analysis.h"

namespace lpvid {

Eigen::MatrixXd markov_fit_percent(const StateSpace& model, const MarkovSequence& g) {
  if (g.size() < 2) throw InputError("markov fit needs at least two lags");
  const Index p = g.front().rows(), m = g.front().cols();
  if (model.num_outputs() != p || model.num_inputs() != m)
    throw InputError(fmt::format("model is {}x{} but the Markov parameters are {}x{}", model.num_outputs(),
                                 model.num_inputs(), p, m));
  const MarkovSequence h = markov_parameters(model, static_cast<Index>(g.size()) - 1);
  Eigen::MatrixXd err = Eigen::MatrixXd::Zero(p, m), ref = Eigen::MatrixXd::Zero(p, m);
  for (std::size_t k = 1; k < g.size(); ++k) {
    err += (g[k] - h[k]).cwiseAbs2();
    ref += g[k].cwiseAbs2();
  }
  Eigen::MatrixXd fit(p, m);
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j)
      fit(i, j) = ref(i, j) > 0 ? 100.0 * (1.0 - std::sqrt(err(i, j) / ref(i, j))) : 0.0;
  return fit;
}

Eigen::MatrixXd reference_as_input_excitation(const StateSpace& controller,
                                              const Eigen::Ref<const Eigen::MatrixXd>& reference) {
  controller.validate();
  if (reference.cols() != controller.num_inputs())
    throw InputError(fmt::format("reference excitation: {} reference column(s) for a controller with {} input(s) (one "
                                 "reference per measured output, e = r - q)",
                                 reference.cols(), controller.num_inputs()));
  if (!reference.allFinite()) throw InputError("reference excitation: a reference value is not finite");
  const Eigen::MatrixXd centred = reference.rowwise() - reference.colwise().mean();
  return simulate_discrete(controller, centred);
}

BandSupport band_support(const std::vector<Eigen::MatrixXcd>& response, const std::vector<Eigen::MatrixXd>& variance,
                         const Eigen::VectorXd& omega_rad_s, double threshold) {
  const auto F = static_cast<std::size_t>(omega_rad_s.size());
  if (response.size() != F || variance.size() != F)
    throw InputError(fmt::format("band support: {} responses and {} variances for {} frequencies", response.size(),
                                 variance.size(), F));
  if (!(threshold > 0)) throw InputError(fmt::format("band support: threshold {} must be > 0", threshold));
  BandSupport b;
  b.threshold = threshold;
  b.points = omega_rad_s.size();
  for (std::size_t k = 0; k < F; ++k) {
    if (variance[k].rows() != response[k].rows() || variance[k].cols() != response[k].cols())
      throw InputError("band support: a variance's shape differs from its response's");
    const double norm = response[k].norm();
    const double r = norm > 0 ? kBandRadiusPerSigma * std::sqrt(std::max(0.0, variance[k].sum())) / norm
                              : std::numeric_limits<double>::infinity();
    const double w = omega_rad_s(static_cast<Index>(k));
    if (r > b.worst_relative) b.worst_relative = r, b.omega_at_worst_rad_s = w;
    if (r <= threshold) {
      if (b.supported == 0) b.lowest_supported_rad_s = w;
      b.highest_supported_rad_s = w;
      ++b.supported;
    }
  }
  return b;
}

}  // namespace lpvid
