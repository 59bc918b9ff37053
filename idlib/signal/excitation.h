// lpvid — excitation signals for identification experiments: periodic multisines
// (random or Schroeder phases, crest-factor minimisation), PRBS (maximum-length
// LFSR) and white Gaussian noise, for one input or for n inputs with a MIMO
// design (one input at a time, Hadamard-coded, zippered).  Pure numerics: no I/O;
// the file layout is docs/formats.md, "Excitation design line".
//
// Signal layout (the contract with periodic `frf`).  The result holds N x n
// samples (idlib/core/types.h: time along rows, column j = input j).  A periodic
// signal (multisine; PRBS with period_samples > 0) is the concatenation of
// blocks, in this order:
//   for realisation r = 0..R-1, for experiment e = 0..E-1:
//     one block of (T + P) * L samples = T transient periods, then P periods,
//     every period the same L samples;
// so N = R * E * (T + P) * L.  E = n (one-at-a-time), n_e (hadamard), 1 (single,
// zipper).  In block (r, e) input j carries coding(e, j) * u_{r,j}(t), where
// u_{r,j} is the L-periodic signal of input j in realisation r; coding is the
// E x n matrix below (empty = all ones: single, zipper).  A non-periodic signal
// (noise; PRBS with period_samples = 0) is N = samples rows, all inputs at once.
//
// Multisine of input j, realisation r, over one period t = 0..L-1:
//   u(t) = sum_{k in K_j} A_k cos(2 pi k t / L + phi_{r,j,k}),
// K_j the excited DFT bins of input j (frequency k * fs / L), A_k = c_j a(k fs / L):
// a the relative amplitude spectrum (ExcitationSpec::shape_*; 1 when none is given:
// the same amplitude on every bin), c_j the scale that meets the RMS/peak limits;
// its DFT over one period is U(k) = (L/2) A_k e^{i phi} on K_j and 0 elsewhere.
// It is synthesised with one inverse real FFT per period (FFTW, real_fft.h).
//
// References: M. R. Schroeder, "Synthesis of low-peak-factor signals and binary
// sequences with low autocorrelation", IEEE Trans. Inf. Theory 16 (1970) 85–89;
// E. Van der Ouderaa, J. Schoukens, J. Renneboog, "Peak factor minimization using a
// time-frequency domain swapping algorithm", IEEE Trans. Instrum. Meas. 37 (1988)
// 145–147; R. Pintelon, J. Schoukens, System Identification: A Frequency Domain
// Approach, 2nd ed., Wiley 2012, ch. 2 (multisines, orthogonal MIMO designs) and
// ch. 4 (best linear approximation, R realisations).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

enum class ExcitationKind { kMultisine, kPrbs, kNoise };
// kSingle: one experiment, every input excited at once (n = 1: the only choice;
//   n > 1 needs independent random phases and R >= n realisations for an FRF matrix).
// kOneAtATime: n experiments, input e alone in experiment e (seed 000's protocol).
// kHadamard: n_e = smallest power of two >= n experiments; coding(e, j) = H(e, j),
//   H the Sylvester Hadamard matrix of order n_e; per excited line the n x n_e
//   input matrix diag(U_j(k)) H(0..n_e-1, 0..n-1)^T has orthogonal rows.
// kZipper: one experiment; input j excites the lines of the grid whose position i
//   in the grid satisfies i mod n = j (disjoint sets that cover the grid).
enum class MimoDesign { kSingle, kOneAtATime, kHadamard, kZipper };
enum class PhaseChoice { kRandom, kSchroeder };
enum class LineGrid { kLinear, kLog };

// What to generate.  One validate() explains the first broken rule.
struct ExcitationSpec {
  ExcitationKind kind = ExcitationKind::kMultisine;
  double sample_rate_hz = 1000.0;  // fs > 0
  Index channels = 1;              // n >= 1 inputs
  MimoDesign mimo = MimoDesign::kSingle;
  std::uint64_t seed = 1;  // same seed, same samples, bit for bit

  // Amplitude limits per input, each empty, one value (every input) or n values,
  // > 0.  At least one is given; with both, the signal is scaled by the smaller
  // factor so that RMS <= rms and peak <= peak, one of them with equality.
  std::vector<double> rms, peak;

  // Periodic signals: L samples per period (multisine: >= 3; PRBS: d (2^m - 1),
  // 0 = a non-periodic PRBS); P >= 1 periods kept, T >= 0 transient periods before
  // them, R >= 1 realisations (multisine: a new random phase set each).
  Index period_samples = 0;
  Index periods = 1;
  Index transient_periods = 0;
  Index realisations = 1;

  // Multisine lines: every DFT bin k with band_lo_hz <= k fs / L <= band_hi_hz and
  // 0 < k < L/2, thinned by the grid: linear takes every `every`-th bin from the
  // lowest; log starts at the lowest and steps k <- max(k + 1, round(k * 10^(1 /
  // lines_per_decade))) (a ratio per step, at least one bin per step, no duplicate).
  double band_lo_hz = 0.0, band_hi_hz = 0.0;  // 0 < lo <= hi < fs / 2
  LineGrid grid = LineGrid::kLinear;
  Index every = 1;                 // linear grid, >= 1
  double lines_per_decade = 0.0;   // log grid, > 0
  PhaseChoice phase = PhaseChoice::kRandom;
  // Relative amplitude spectrum (multisine only; both empty = flat): points
  // (shape_f_hz[i], shape_amplitude[i]), at least 2, f > 0 strictly increasing,
  // amplitudes > 0 and finite, any units (only ratios matter).  The line at f gets
  // a(f), linear in (log f, log a) between neighbouring points and the end point's
  // amplitude beyond either end (constant: no extrapolated slope); the RMS/peak
  // scaling and the crest-factor minimisation come after and keep the ratios.
  std::vector<double> shape_f_hz, shape_amplitude;
  // Crest-factor minimisation (Van der Ouderaa et al. 1988), per input and
  // realisation: clip the period, keep the phases of its DFT on the excited bins,
  // restore the amplitudes (0 elsewhere), repeat `crest_iterations` times; the
  // phases with the lowest crest factor seen are kept.
  bool minimise_crest = false;
  Index crest_iterations = 200;  // 1..100000

  // PRBS: each level is held for clock_divider >= 1 samples.
  Index clock_divider = 1;

  // Non-periodic signals (noise; PRBS with period_samples = 0): N >= 2 rows.
  Index samples = 0;

  // Largest N * n accepted: 10^8 values are 800 MB of samples (the CLI holds a
  // second copy with t); far beyond a lab experiment, so a larger request is a mistake.
  static constexpr double kMaxValues = 1e8;

  // @throws InputError naming the field and the rule: fs, n, limits, L, P, T, R,
  //   band outside (0, fs/2) or with no bin, a grid parameter, a MIMO design that
  //   does not apply to the kind (zipper: multisine only; noise and non-periodic
  //   PRBS: single only), Schroeder phases with kSingle and n > 1 (every input the
  //   same signal), R > 1 for a PRBS, a PRBS period that is not d (2^m - 1), zipper
  //   with fewer lines than inputs, N * n > kMaxValues, an amplitude spectrum that
  //   breaks its rules above or is given for a PRBS or noise.
  void validate() const;
};

// The generated signal and its design.
struct ExcitationSignal {
  Eigen::MatrixXd samples;  // N x n (no time column; t = k / fs)
  Index experiments = 1;    // E
  Index block_samples = 0;  // (T + P) L, or N for a non-periodic signal
  // Excited DFT bins of one period per input (ascending; empty for non-periodic).
  std::vector<std::vector<Index>> excited_bins;
  // Multisine: per input, the amplitude A_k of each excited bin (same order as
  // excited_bins) in the final signal, in the input's units, before the coding
  // weight; empty for a PRBS or noise.
  std::vector<std::vector<double>> line_amplitudes;
  Eigen::MatrixXd coding;  // E x n (one-at-a-time: identity; hadamard: +-1), or 0 x 0
  // Per input, of the final signal: RMS over one active period (equal for every
  // realisation: Parseval), peak = max |u| over the whole signal, crest = peak / rms.
  Eigen::VectorXd rms, peak, crest_factor;
  // Crest factor of the phases before minimisation, scaled the same way (equals
  // crest_factor when minimise_crest is off).
  Eigen::VectorXd crest_factor_initial;
  int prbs_order = 0;  // m of a PRBS (period 2^m - 1 levels), else 0
};

// Generates the signal (ExcitationSpec::validate first).  O(R n L log L) for a
// multisine (+ 2 FFTs per crest iteration), O(N n) for the rest.
// @throws InputError as validate().
ExcitationSignal generate_excitation(const ExcitationSpec& spec);

// The excited bins of the grid before any zipper split (see ExcitationSpec).
// @throws InputError as validate() for the band and grid fields.
std::vector<Index> multisine_grid(const ExcitationSpec& spec);

// The relative amplitude a(f) of the spectrum (shape_f_hz, shape_amplitude) at each
// of the frequencies (Hz), by the rule of ExcitationSpec::shape_*: log-log linear
// inside, constant beyond the ends.  Empty points: 1 everywhere.  The points must
// pass validate()'s rules (asserted: size, order and positivity).
std::vector<double> amplitude_shape_at(const std::vector<double>& shape_f_hz, const std::vector<double>& shape_amplitude,
                                       const std::vector<double>& f_hz);

// Sylvester Hadamard matrix of order n_e = smallest power of two >= n, its first n
// columns: n_e x n, entries +-1, H^T H = n_e I.  n >= 1.
Eigen::MatrixXd hadamard_coding(Index n);

// Schroeder phases for K lines of equal amplitude: phi_i = -pi i (i - 1) / K,
// i = 1..K (line index, not bin), returned for i = 1..K.
std::vector<double> schroeder_phases(Index K);

// One period of the maximum-length sequence of order m (2 <= m <= 31): 2^m - 1
// values +-1 from a Fibonacci LFSR with a primitive feedback polynomial, register
// started at all ones; output bit 1 -> +1, 0 -> -1.
std::vector<signed char> mls_sequence(int order);

// max |x| / rms(x) (rms > 0), the crest factor.
double crest_factor(const Eigen::Ref<const Eigen::VectorXd>& x);

// Names used in files and messages.
std::string to_string(ExcitationKind kind);  // "multisine", "prbs", "noise"
std::string to_string(MimoDesign mimo);      // "single", "one-at-a-time", "hadamard", "zipper"
std::string to_string(PhaseChoice phase);    // "random", "schroeder"

}  // namespace lpvid
