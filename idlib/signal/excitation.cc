#include "idlib/signal/excitation.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <limits>
#include <cmath>
#include <numbers>
#include <random>

#include "idlib/core/error.h"
#include "idlib/signal/real_fft.h"

namespace lpvid {
namespace {

using signal_detail::RealFft;

constexpr double kPi = std::numbers::pi;

// Feedback taps (1-based, polynomial x^m + ...) of a maximum-length Fibonacci LFSR
// of order m = 2..31; each checked to give period 2^m - 1 (tests/idlib/signal/
// excitation_test.cc runs m = 2..20; m = 2..31 were all run once by brute force
// (period 2^m - 1 exactly), 1 min in total).
// Source: the table of maximal-length taps in Xilinx XAPP 052 / the LFSR article
// tables, reduced to the forms below.
const std::vector<std::vector<int>>& lfsr_taps() {
  static const std::vector<std::vector<int>> taps = {
      {},               {},               {2, 1},           {3, 2},           {4, 3},
      {5, 3},           {6, 5},           {7, 6},           {8, 6, 5, 4},     {9, 5},
      {10, 7},          {11, 9},          {12, 11, 10, 4},  {13, 12, 11, 8},  {14, 13, 12, 2},
      {15, 14},         {16, 15, 13, 4},  {17, 14},         {18, 11},         {19, 18, 17, 14},
      {20, 17},         {21, 19},         {22, 21},         {23, 18},         {24, 23, 22, 17},
      {25, 22},         {26, 25, 24, 20}, {27, 26, 25, 22}, {28, 25},         {29, 27},
      {30, 29, 28, 7},  {31, 28},
  };
  return taps;
}

// splitmix64 (Steele, Lea, Flood 2014): decorrelates the (seed, realisation,
// input) triples before they seed one mt19937_64 each.
std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// A uniform double in [0, 1) from the top 53 bits: the same on every platform
// (std::uniform_real_distribution is not specified bit for bit).
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// The order m with d (2^m - 1) = L, or 0 if there is none.
int prbs_order_for_period(Index period_samples, Index divider) {
  if (divider < 1 || period_samples % divider != 0) return 0;
  const Index levels = period_samples / divider;
  for (int m = 2; m <= 31; ++m)
    if ((Index{1} << m) - 1 == levels) return m;
  return 0;
}

// Nearest valid PRBS periods d (2^m - 1) below and above L, for a message.
std::string prbs_period_hint(Index period_samples, Index divider) {
  Index below = 0, above = 0;
  int m_below = 0, m_above = 0;
  for (int m = 2; m <= 31; ++m) {
    const Index p = divider * ((Index{1} << m) - 1);
    if (p <= period_samples) below = p, m_below = m;
    if (p >= period_samples && above == 0) above = p, m_above = m;
  }
  std::string hint;
  if (below > 0) hint += fmt::format("{} (m = {})", below, m_below);
  if (above > 0) hint += fmt::format("{}{} (m = {})", hint.empty() ? "" : " or ", above, m_above);
  return hint;
}

bool periodic(const ExcitationSpec& s) {
  return s.kind == ExcitationKind::kMultisine || (s.kind == ExcitationKind::kPrbs && s.period_samples > 0);
}

Index experiment_count(const ExcitationSpec& s) {
  switch (s.mimo) {
    case MimoDesign::kOneAtATime: return s.channels;
    case MimoDesign::kHadamard: return static_cast<Index>(std::bit_ceil(static_cast<std::uint64_t>(s.channels)));
    default: return 1;
  }
}

double limit_for(const std::vector<double>& values, Index j) {
  if (values.empty()) return std::numeric_limits<double>::infinity();
  return values.size() == 1 ? values[0] : values[static_cast<std::size_t>(j)];
}

void check_limits(const std::vector<double>& values, const char* what, Index channels) {
  if (!values.empty() && values.size() != 1 && static_cast<Index>(values.size()) != channels)
    throw InputError(fmt::format("{} limit: {} values for {} inputs; give one value (every input) or one per input",
                                 what, values.size(), channels));
  for (double v : values)
    if (!std::isfinite(v) || !(v > 0))
      throw InputError(fmt::format("{} limit: {} is not a positive finite number; give the {} in the input's units",
                                   what, v, what));
}

// Synthesises one period x[0..L) = sum_k A_k cos(2 pi k t / L + phi_k) with one
// inverse real FFT: spectrum[k] = (A_k / 2) e^{i phi_k} on the excited bins.
class PeriodSynth {
 public:
  explicit PeriodSynth(Index L) : fft_(L), spec_(signal_detail::alloc_complex(L / 2 + 1)) {}

  // amplitudes[i]: A of bins[i].
  void synth(const std::vector<Index>& bins, const std::vector<double>& phases, const std::vector<double>& amplitudes,
             double* x) {
    std::fill(spec_.get(), spec_.get() + fft_.bins(), Complex(0.0, 0.0));
    for (std::size_t i = 0; i < bins.size(); ++i) spec_[bins[i]] = std::polar(0.5 * amplitudes[i], phases[i]);
    fft_.inverse(spec_.get(), x);
  }
  // Phases of the DFT of x on the bins (a bin whose value is exactly 0 keeps its phase).
  void phases_of(const double* x, const std::vector<Index>& bins, std::vector<double>& phases) {
    fft_.forward(x, spec_.get());
    for (std::size_t i = 0; i < bins.size(); ++i)
      if (std::abs(spec_[bins[i]]) > 0) phases[i] = std::arg(spec_[bins[i]]);
  }

 private:
  RealFft fft_;
  signal_detail::ComplexArray spec_;
};

double peak_of(const double* x, Index n) {
  double p = 0;
  for (Index t = 0; t < n; ++t) p = std::max(p, std::abs(x[t]));
  return p;
}

double rms_of(const double* x, Index n) {
  double s = 0;
  for (Index t = 0; t < n; ++t) s += x[t] * x[t];
  return std::sqrt(s / static_cast<double>(n));
}

// Van der Ouderaa, Schoukens, Renneboog (1988): alternately clip the period in
// time and restore the amplitude spectrum in frequency; keeps the best phases.
// The clip level is a fixed fraction of the current peak.  Measured on 196 flat
// lines (L = 4096, bins 5..200), mean of 5 random-phase starts of crest factor 3.42,
// after 50 / 200 iterations: 0.8 -> 1.74 / 1.58, 0.85 -> 1.84 / 1.58, 0.9 -> 2.06 /
// 1.64, 0.95 -> 2.65 / 1.90 (1000 iterations at 0.9: 1.48).
constexpr double kClipFraction = 0.85;

void minimise_crest(PeriodSynth& synth, const std::vector<Index>& bins, const std::vector<double>& amplitudes,
                    std::vector<double>& phases, Index L, Index iterations, double* work) {
  std::vector<double> best = phases;
  synth.synth(bins, phases, amplitudes, work);
  double best_cf = peak_of(work, L);  // the rms is fixed by the amplitudes
  for (Index it = 0; it < iterations; ++it) {
    const double level = kClipFraction * peak_of(work, L);
    for (Index t = 0; t < L; ++t) work[t] = std::clamp(work[t], -level, level);
    synth.phases_of(work, bins, phases);
    synth.synth(bins, phases, amplitudes, work);
    const double p = peak_of(work, L);
    if (p < best_cf) best_cf = p, best = phases;
  }
  phases = best;
}

// Places the periods: block (r, e) of (T + P) L rows, input j = coding(e, j) * scale_j * period(r, j).
void assemble(const ExcitationSpec& s, const Eigen::MatrixXd& periods, const Eigen::MatrixXd& coding,
              const Eigen::VectorXd& scale, ExcitationSignal& out) {
  const Index L = s.period_samples, n = s.channels, E = out.experiments;
  const Index per_block = s.transient_periods + s.periods;
  out.block_samples = per_block * L;
  const Index R = periods.cols() / n;
  out.samples.setZero(R * E * out.block_samples, n);
  for (Index r = 0; r < R; ++r)
    for (Index e = 0; e < E; ++e) {
      const Index start = (r * E + e) * out.block_samples;
      for (Index j = 0; j < n; ++j) {
        const double c = coding.size() == 0 ? 1.0 : coding(e, j);
        if (c == 0.0) continue;
        const double w = c * scale(j);
        for (Index p = 0; p < per_block; ++p)
          out.samples.col(j).segment(start + p * L, L) = w * periods.col(r * n + j);
      }
    }
}

// rms over the first active period of each input, peak over everything.
void measure(const ExcitationSpec& s, const Eigen::MatrixXd& coding, ExcitationSignal& out) {
  const Index n = s.channels, L = periodic(s) ? s.period_samples : out.samples.rows();
  out.rms.resize(n);
  out.peak.resize(n);
  out.crest_factor.resize(n);
  for (Index j = 0; j < n; ++j) {
    Index e = 0;
    while (coding.size() != 0 && coding(e, j) == 0.0) ++e;
    const Index start = e * out.block_samples + (periodic(s) ? s.transient_periods * L : 0);
    out.rms(j) = rms_of(out.samples.col(j).data() + start, L);
    out.peak(j) = peak_of(out.samples.col(j).data(), out.samples.rows());
    out.crest_factor(j) = out.peak(j) / out.rms(j);
  }
}

ExcitationSignal generate_multisine(const ExcitationSpec& s) {
  const Index L = s.period_samples, n = s.channels, R = s.realisations;
  ExcitationSignal out;
  const std::vector<Index> grid = multisine_grid(s);
  out.excited_bins.assign(static_cast<std::size_t>(n), grid);
  if (s.mimo == MimoDesign::kZipper)
    for (Index j = 0; j < n; ++j) {
      auto& bins = out.excited_bins[static_cast<std::size_t>(j)];
      bins.clear();
      for (std::size_t i = static_cast<std::size_t>(j); i < grid.size(); i += static_cast<std::size_t>(n))
        bins.push_back(grid[i]);
    }
  Eigen::MatrixXd coding;
  if (s.mimo == MimoDesign::kOneAtATime) coding = Eigen::MatrixXd::Identity(n, n);
  if (s.mimo == MimoDesign::kHadamard) coding = hadamard_coding(n);
  out.coding = coding;
  out.experiments = experiment_count(s);
  // Relative amplitudes per input's bins (1 on every bin without a shape).
  const double resolution = s.sample_rate_hz / static_cast<double>(L);
  std::vector<std::vector<double>> relative;
  for (const auto& bins : out.excited_bins) {
    std::vector<double> f;
    for (Index k : bins) f.push_back(static_cast<double>(k) * resolution);
    relative.push_back(amplitude_shape_at(s.shape_f_hz, s.shape_amplitude, f));
  }
  // rms of sum_k a_k cos over whole periods: sqrt(sum_k a_k^2 / 2) (Parseval).
  auto rms_of_lines = [](const std::vector<double>& a) {
    double sum = 0;
    for (double x : a) sum += 0.5 * x * x;
    return std::sqrt(sum);
  };

  // One period per (realisation, input) at the relative amplitudes; column r n + j.
  Eigen::MatrixXd periods(L, R * n);
  out.crest_factor_initial = Eigen::VectorXd::Zero(n);
  PeriodSynth synth(L);
  signal_detail::RealArray work = signal_detail::alloc_real(L);
  for (Index r = 0; r < R; ++r)
    for (Index j = 0; j < n; ++j) {
      const auto& bins = out.excited_bins[static_cast<std::size_t>(j)];
      const Index K = static_cast<Index>(bins.size());
      std::vector<double> phases;
      if (s.phase == PhaseChoice::kSchroeder) {
        phases = schroeder_phases(K);
      } else {
        std::mt19937_64 rng(mix(mix(s.seed) ^ (static_cast<std::uint64_t>(r) * 0x100000001B3ULL +
                                               static_cast<std::uint64_t>(j))));
        phases.resize(static_cast<std::size_t>(K));
        for (double& p : phases) p = 2 * kPi * uniform01(rng);
      }
      const auto& amplitudes = relative[static_cast<std::size_t>(j)];
      const double rms = rms_of_lines(amplitudes);
      synth.synth(bins, phases, amplitudes, work.get());
      out.crest_factor_initial(j) = std::max(out.crest_factor_initial(j), peak_of(work.get(), L) / rms);
      if (s.minimise_crest) minimise_crest(synth, bins, amplitudes, phases, L, s.crest_iterations, work.get());
      synth.synth(bins, phases, amplitudes, periods.col(r * n + j).data());
    }
  // Scale: the smaller of rms_limit / rms and peak_limit / peak over every realisation.
  Eigen::VectorXd scale(n);
  for (Index j = 0; j < n; ++j) {
    const double rms = rms_of_lines(relative[static_cast<std::size_t>(j)]);
    double peak = 0;
    for (Index r = 0; r < R; ++r) peak = std::max(peak, peak_of(periods.col(r * n + j).data(), L));
    scale(j) = std::min(limit_for(s.rms, j) / rms, limit_for(s.peak, j) / peak);
    out.line_amplitudes.push_back(relative[static_cast<std::size_t>(j)]);
    for (double& a : out.line_amplitudes.back()) a *= scale(j);
  }
  assemble(s, periods, coding, scale, out);
  measure(s, coding, out);
  if (!s.minimise_crest) out.crest_factor_initial = out.crest_factor;
  return out;
}

ExcitationSignal generate_prbs(const ExcitationSpec& s) {
  const Index n = s.channels, d = s.clock_divider;
  ExcitationSignal out;
  const bool is_periodic = s.period_samples > 0;
  int m = 0;
  if (is_periodic) {
    m = prbs_order_for_period(s.period_samples, d);
  } else {
    const Index levels = (s.samples + d - 1) / d;
    m = 2;
    while (m < 31 && (Index{1} << m) - 1 < levels) ++m;
  }
  out.prbs_order = m;
  const std::vector<signed char> seq = mls_sequence(m);
  const Index M = static_cast<Index>(seq.size());
  // Input j: the same sequence shifted by j floor(M / n) levels (shifted m-sequences
  // have a periodic cross-correlation of -1 against M at lag 0).
  const Index shift = M / n;
  const Index length = is_periodic ? s.period_samples : s.samples;
  Eigen::MatrixXd base(length, n);
  for (Index j = 0; j < n; ++j)
    for (Index t = 0; t < length; ++t) base(t, j) = seq[static_cast<std::size_t>((t / d + j * shift) % M)];
  Eigen::VectorXd scale(n);
  for (Index j = 0; j < n; ++j) scale(j) = std::min(limit_for(s.rms, j), limit_for(s.peak, j));  // |u| = 1
  if (is_periodic) {
    Eigen::MatrixXd coding;
    if (s.mimo == MimoDesign::kOneAtATime) coding = Eigen::MatrixXd::Identity(n, n);
    if (s.mimo == MimoDesign::kHadamard) coding = hadamard_coding(n);
    out.coding = coding;
    out.experiments = experiment_count(s);
    // A held m-sequence has DFT S(k mod M) H(k), H zero at the non-zero multiples of M.
    std::vector<Index> bins;
    for (Index k = 1; 2 * k < s.period_samples; ++k)
      if (k % M != 0) bins.push_back(k);
    out.excited_bins.assign(static_cast<std::size_t>(n), bins);
    assemble(s, base, coding, scale, out);
    measure(s, coding, out);
  } else {
    out.experiments = 1;
    out.block_samples = s.samples;
    out.excited_bins.assign(static_cast<std::size_t>(n), {});
    out.samples = base * scale.asDiagonal();
    measure(s, Eigen::MatrixXd(), out);
  }
  out.crest_factor_initial = out.crest_factor;
  return out;
}

ExcitationSignal generate_noise(const ExcitationSpec& s) {
  const Index n = s.channels, N = s.samples;
  ExcitationSignal out;
  out.experiments = 1;
  out.block_samples = N;
  out.excited_bins.assign(static_cast<std::size_t>(n), {});
  out.samples.resize(N, n);
  std::mt19937_64 rng(s.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (Index t = 0; t < N; ++t)  // sample by sample, inputs in order (as the simulators draw)
    for (Index j = 0; j < n; ++j) out.samples(t, j) = normal(rng);
  for (Index j = 0; j < n; ++j) {
    const double rms = rms_of(out.samples.col(j).data(), N), peak = peak_of(out.samples.col(j).data(), N);
    out.samples.col(j) *= std::min(limit_for(s.rms, j) / rms, limit_for(s.peak, j) / peak);
  }
  measure(s, Eigen::MatrixXd(), out);
  out.crest_factor_initial = out.crest_factor;
  return out;
}

}  // namespace

std::string to_string(ExcitationKind kind) {
  switch (kind) {
    case ExcitationKind::kMultisine: return "multisine";
    case ExcitationKind::kPrbs: return "prbs";
    case ExcitationKind::kNoise: return "noise";
  }
  return "?";
}

std::string to_string(MimoDesign mimo) {
  switch (mimo) {
    case MimoDesign::kSingle: return "single";
    case MimoDesign::kOneAtATime: return "one-at-a-time";
    case MimoDesign::kHadamard: return "hadamard";
    case MimoDesign::kZipper: return "zipper";
  }
  return "?";
}

std::string to_string(PhaseChoice phase) { return phase == PhaseChoice::kSchroeder ? "schroeder" : "random"; }

void ExcitationSpec::validate() const {
  if (!std::isfinite(sample_rate_hz) || !(sample_rate_hz > 0))
    throw InputError(fmt::format("sample rate {} Hz: give a positive finite rate", sample_rate_hz));
  if (channels < 1 || channels > 256)
    throw InputError(fmt::format("{} inputs: give 1 to 256", channels));
  if (rms.empty() && peak.empty())
    throw InputError("no amplitude given: give an RMS limit, a peak limit, or both, per input");
  check_limits(rms, "RMS", channels);
  check_limits(peak, "peak", channels);
  const std::string kind_name = to_string(kind);
  if (periods < 1 || transient_periods < 0 || realisations < 1)
    throw InputError(fmt::format("periods {}, transient periods {}, realisations {}: give >= 1, >= 0, >= 1", periods,
                                 transient_periods, realisations));
  if (kind == ExcitationKind::kNoise && period_samples != 0)
    throw InputError("white noise is not periodic: leave the period out and give the number of samples (a duration)");
  if (kind == ExcitationKind::kMultisine && period_samples < 3)
    throw InputError(fmt::format("a multisine needs a period of at least 3 samples (got {}); give the period, e.g. "
                                 "1000 samples for 1 Hz resolution at 1 kHz",
                                 period_samples));
  if (periodic(*this)) {
    if (period_samples < 0) throw InputError("the period must be >= 0 samples");
  } else if (samples < 2) {
    throw InputError(fmt::format("a {} signal needs at least 2 samples (got {}); give a longer duration", kind_name,
                                 samples));
  }
  if (!periodic(*this) && mimo != MimoDesign::kSingle)
    throw InputError(fmt::format("the MIMO design {} needs a periodic signal; a {} excites every input at once "
                                 "(independent per input): use single, or a multisine or periodic PRBS",
                                 to_string(mimo), kind == ExcitationKind::kNoise ? "noise" : "non-periodic PRBS"));
  if (!periodic(*this) && (transient_periods != 0 || periods != 1 || realisations != 1))
    throw InputError(fmt::format("periods, transient periods and realisations apply to periodic signals; a {} has "
                                 "none: leave them out",
                                 kind == ExcitationKind::kNoise ? "noise" : "non-periodic PRBS"));
  if (mimo == MimoDesign::kZipper && kind != ExcitationKind::kMultisine)
    throw InputError("the zipper design interleaves multisine lines; use it with a multisine, or use hadamard or "
                     "one-at-a-time for a PRBS");
  if (kind == ExcitationKind::kPrbs) {
    if (clock_divider < 1 || clock_divider > 1'000'000)
      throw InputError(fmt::format("PRBS clock divider {}: give 1 to 1000000 samples per level", clock_divider));
    if (realisations != 1)
      throw InputError("a PRBS has no random phases to draw again: give 1 realisation (or use a random-phase "
                       "multisine for several)");
    if (period_samples > 0 && prbs_order_for_period(period_samples, clock_divider) == 0)
      throw InputError(fmt::format("a PRBS period is d (2^m - 1) samples (d = {} the clock divider, m = 2..31); "
                                   "{} is not: give {}",
                                   clock_divider, period_samples, prbs_period_hint(period_samples, clock_divider)));
  }
  if (!shape_f_hz.empty() || !shape_amplitude.empty()) {
    if (kind != ExcitationKind::kMultisine)
      throw InputError(fmt::format("an amplitude spectrum shapes the lines of a multisine; a {} has no lines: leave "
                                   "it out or use a multisine",
                                   kind_name));
    if (shape_f_hz.size() != shape_amplitude.size() || shape_f_hz.size() < 2)
      throw InputError(fmt::format("amplitude spectrum: {} frequencies and {} amplitudes; give at least 2 points "
                                   "(f_hz, amplitude)",
                                   shape_f_hz.size(), shape_amplitude.size()));
    for (std::size_t i = 0; i < shape_f_hz.size(); ++i) {
      const double f = shape_f_hz[i], a = shape_amplitude[i];
      if (!std::isfinite(f) || !(f > 0) || (i > 0 && !(f > shape_f_hz[i - 1])))
        throw InputError(fmt::format("amplitude spectrum point {}: frequency {} Hz; give frequencies > 0 in strictly "
                                     "increasing order",
                                     i + 1, f));
      if (!std::isfinite(a) || !(a > 0))
        throw InputError(fmt::format("amplitude spectrum point {}: amplitude {}; give positive finite amplitudes",
                                     i + 1, a));
    }
  }
  if (kind == ExcitationKind::kMultisine) {
    if (crest_iterations < 1 || crest_iterations > 100'000)
      throw InputError(fmt::format("{} crest-factor iterations: give 1 to 100000", crest_iterations));
    if (phase == PhaseChoice::kSchroeder && mimo == MimoDesign::kSingle && channels > 1)
      throw InputError("Schroeder phases with every input excited at once give every input the same signal (the "
                       "FRF matrix cannot be separated): use random phases, or the hadamard, zipper or "
                       "one-at-a-time design");
    const std::vector<Index> grid = multisine_grid(*this);  // throws on band and grid
    if (mimo == MimoDesign::kZipper && static_cast<Index>(grid.size()) < channels)
      throw InputError(fmt::format("the zipper design needs at least one line per input: the grid has {} line{} for "
                                   "{} inputs; widen the band, lengthen the period or use a denser grid",
                                   grid.size(), grid.size() == 1 ? "" : "s", channels));
  }
  const double rows = periodic(*this) ? static_cast<double>(realisations) * static_cast<double>(experiment_count(*this)) *
                                            static_cast<double>(transient_periods + periods) *
                                            static_cast<double>(period_samples)
                                      : static_cast<double>(samples);
  if (rows * static_cast<double>(channels) > kMaxValues)
    throw InputError(fmt::format("the signal would have {:.4g} samples x {} inputs, more than {:.0e} values; shorten "
                                 "the period, the periods or the realisations",
                                 rows, channels, kMaxValues));
}

std::vector<Index> multisine_grid(const ExcitationSpec& s) {
  const double fs = s.sample_rate_hz;
  const Index L = s.period_samples;
  const double resolution = fs / static_cast<double>(L);
  const Index last = (L - 1) / 2;  // largest k with k < L / 2
  Index k_lo = 1, k_hi = last;
  const bool whole = s.band_lo_hz == 0 && s.band_hi_hz == 0;
  if (!whole) {
    const double lo = s.band_lo_hz, hi = s.band_hi_hz;
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo > 0) || !(hi < fs / 2) || !(lo <= hi))
      throw InputError(fmt::format("band {},{} Hz: it must satisfy 0 < low <= high < fs/2 = {} Hz; give a band "
                                   "inside (0, {}) Hz",
                                   lo, hi, fs / 2, fs / 2));
    // Relative slack 1e-9: a band edge typed as k fs / L keeps bin k despite rounding.
    constexpr double kEdgeSlack = 1e-9;
    k_lo = std::max<Index>(1, static_cast<Index>(std::ceil(lo / resolution - kEdgeSlack)));
    k_hi = std::min<Index>(last, static_cast<Index>(std::floor(hi / resolution + kEdgeSlack)));
    if (k_lo > k_hi)
      throw InputError(fmt::format("band {},{} Hz holds no DFT line k fs/L: the resolution fs/L is {} Hz "
                                   "(L = {} samples); widen the band or lengthen the period",
                                   lo, hi, resolution, L));
  } else if (last < 1) {
    throw InputError(fmt::format("a period of {} samples has no line between 0 and fs/2; lengthen the period", L));
  }
  std::vector<Index> bins;
  if (s.grid == LineGrid::kLinear) {
    if (s.every < 1) throw InputError(fmt::format("linear grid: every {} lines; give 1 or more", s.every));
    for (Index k = k_lo; k <= k_hi; k += s.every) bins.push_back(k);
  } else {
    if (!std::isfinite(s.lines_per_decade) || !(s.lines_per_decade > 0) || s.lines_per_decade > 1e6)
      throw InputError(fmt::format("log grid: {} lines per decade; give a number in (0, 1e6], e.g. 20",
                                   s.lines_per_decade));
    const double ratio = std::pow(10.0, 1.0 / s.lines_per_decade);
    for (Index k = k_lo; k <= k_hi;) {
      bins.push_back(k);
      k = std::max<Index>(k + 1, static_cast<Index>(std::llround(static_cast<double>(k) * ratio)));
    }
  }
  return bins;
}

std::vector<double> amplitude_shape_at(const std::vector<double>& shape_f_hz, const std::vector<double>& shape_amplitude,
                                       const std::vector<double>& f_hz) {
  std::vector<double> out(f_hz.size(), 1.0);
  if (shape_f_hz.empty()) return out;
  const std::size_t m = shape_f_hz.size();
  LPVID_ASSERT(m >= 2 && shape_amplitude.size() == m);
  for (std::size_t i = 0; i < f_hz.size(); ++i) {
    const double f = f_hz[i];
    if (!(f > shape_f_hz.front())) {
      out[i] = shape_amplitude.front();
    } else if (!(f < shape_f_hz.back())) {
      out[i] = shape_amplitude.back();
    } else {
      // The segment [f_p, f_{p+1}) holding f.
      const std::size_t p =
          static_cast<std::size_t>(std::upper_bound(shape_f_hz.begin(), shape_f_hz.end(), f) - shape_f_hz.begin()) - 1;
      LPVID_ASSERT(p + 1 < m && shape_f_hz[p] < shape_f_hz[p + 1]);
      const double x = std::log(f / shape_f_hz[p]) / std::log(shape_f_hz[p + 1] / shape_f_hz[p]);
      out[i] = shape_amplitude[p] * std::pow(shape_amplitude[p + 1] / shape_amplitude[p], x);
    }
  }
  return out;
}

Eigen::MatrixXd hadamard_coding(Index n) {
  LPVID_ASSERT(n >= 1);
  const Index ne = static_cast<Index>(std::bit_ceil(static_cast<std::uint64_t>(n)));
  Eigen::MatrixXd H(ne, n);
  // Sylvester: H(i, j) = (-1)^popcount(i & j).
  for (Index i = 0; i < ne; ++i)
    for (Index j = 0; j < n; ++j)
      H(i, j) = std::popcount(static_cast<std::uint64_t>(i & j)) % 2 == 0 ? 1.0 : -1.0;
  return H;
}

std::vector<double> schroeder_phases(Index K) {
  std::vector<double> phases(static_cast<std::size_t>(K));
  for (Index i = 1; i <= K; ++i) {
    // i (i - 1) mod 2K exactly in integers, so that large K keeps full precision.
    const Index q = (i * (i - 1)) % (2 * K);
    phases[static_cast<std::size_t>(i - 1)] = -kPi * static_cast<double>(q) / static_cast<double>(K);
  }
  return phases;
}

std::vector<signed char> mls_sequence(int order) {
  LPVID_ASSERT(order >= 2 && order <= 31);
  const auto& taps = lfsr_taps()[static_cast<std::size_t>(order)];
  const std::uint64_t M = (std::uint64_t{1} << order) - 1;
  std::vector<signed char> out(M);
  std::uint64_t state = M;  // all ones
  for (std::uint64_t t = 0; t < M; ++t) {
    out[t] = (state & 1U) != 0 ? 1 : -1;
    std::uint64_t bit = 0;
    for (int tap : taps) bit ^= state >> (order - tap);
    state = (state >> 1) | ((bit & 1U) << (order - 1));
  }
  return out;
}

double crest_factor(const Eigen::Ref<const Eigen::VectorXd>& x) {
  const double rms = std::sqrt(x.squaredNorm() / static_cast<double>(x.size()));
  LPVID_ASSERT(rms > 0);
  return x.cwiseAbs().maxCoeff() / rms;
}

ExcitationSignal generate_excitation(const ExcitationSpec& spec) {
  spec.validate();
  switch (spec.kind) {
    case ExcitationKind::kMultisine: return generate_multisine(spec);
    case ExcitationKind::kPrbs: return generate_prbs(spec);
    case ExcitationKind::kNoise: return generate_noise(spec);
  }
  LPVID_ASSERT(false);
  return {};
}

}  // namespace lpvid
