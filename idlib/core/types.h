// lpvid — the one place where the data layout of idlib is stated.
//
// Signals:    Eigen::MatrixXd, N x channels, time along rows (column j holds
//             channel j; row k is the sample at t = t0 + k * sample_period_s).
// Responses:  MIMO responses are indexed (output, input, frequency): a vector
//             over frequency of (outputs x inputs) complex matrices.
// Markov:     g[k] is the (outputs x inputs) impulse-response matrix at lag k,
//             k = 0..L, for a discrete system G(z) = sum_k g[k] z^-k.
// Units:      SI throughout; angles in rad; frequencies in rad/s unless a name
//             says _hz.
#pragma once

#include <Eigen/Core>
#include <complex>
#include <string>
#include <vector>

namespace lpvid {

using Index = Eigen::Index;
using Complex = std::complex<double>;

// A linear time-invariant state-space model
//   continuous (sample_period_s == 0):  x' = A x + B u,        y = C x + D u
//   discrete   (sample_period_s  > 0):  x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k]
//
// | matrix | shape |
// |--------|-------|
// | A      | n x n |
// | B      | n x m |
// | C      | p x n |
// | D      | p x m |
// input_names has m entries and output_names p entries, or they are empty.
struct StateSpace {
  Eigen::MatrixXd A, B, C, D;
  double sample_period_s = 0.0;  // 0 = continuous time
  std::vector<std::string> input_names;
  std::vector<std::string> output_names;

  Index order() const { return A.rows(); }
  Index num_inputs() const { return D.cols(); }
  Index num_outputs() const { return D.rows(); }
  bool is_discrete() const { return sample_period_s > 0.0; }

  // Throws InputError naming the first broken rule (shapes, non-finite entries,
  // negative sample period, name counts).
  void validate() const;
};

// Frequency-response data (FRD): response[k] is the (outputs x inputs) complex
// matrix at omega_rad_s[k].  coherence, when not empty, has the same layout with
// values in [0, 1].  variance, when not empty, has the same layout: the
// estimator's own noise level E|Ĥ_ij − H_ij|² per entry (the sum of the variances
// of the real and imaginary parts, in the response's units squared), e.g. from
// lpvid frf, the bands of identify/unloop, or per-period averaging.  averages is
// the number of independent averages behind the coherence (n_d of an H1
// estimate, which turns coherence into a variance); 0 = not stated by the data.
// flagged, when not empty, marks frequencies whose values the producer could not
// trust (one entry per frequency).  distortion_variance, when not empty (a Best
// Linear Approximation from several random-phase realisations, periodic_frf.h),
// has the layout of variance and holds the part of variance that the stochastic
// nonlinear distortions explain (E|Ĝ_BLA − G_BLA|² above the measurement noise);
// variance stays the TOTAL (noise + distortion) that fits and bands weight with.
// sample_rate_hz is the rate of the log the response was estimated from (lpvid
// frf): the response then maps held (ZOH) command samples to output samples;
// 0 = not recorded (an analyzer's measurement, a model, an older file).
struct FrequencyResponse {
  Eigen::VectorXd omega_rad_s;
  std::vector<Eigen::MatrixXcd> response;
  std::vector<Eigen::MatrixXd> coherence;
  std::vector<Eigen::MatrixXd> variance;
  std::vector<Eigen::MatrixXd> distortion_variance;
  double averages = 0;
  double sample_rate_hz = 0;
  std::vector<bool> flagged;
  std::vector<std::string> input_names;
  std::vector<std::string> output_names;

  Index num_frequencies() const { return omega_rad_s.size(); }
  Index num_outputs() const { return response.empty() ? 0 : response.front().rows(); }
  Index num_inputs() const { return response.empty() ? 0 : response.front().cols(); }
};

// The size each entry's error is measured against (the error figure of idlib/fit,
// the noise floor and the failing bands of idlib/validate/model_error; docs/math.md,
// "Error figure"), at every frequency of one data set: for a square response
//   s_ij = max(sqrt(|H_ii| |H_jj|), |H_ij|),
// the diagonals' geometric mean, or the entry's own size where it is larger (a
// strong coupling: the 6-DOF stage's tilt-through-gravity coupling g/(J s⁴) is 17x
// the geometric mean at its lowest FRF line, and measured against the diagonals
// alone its relative error there was 99.8 % of the whole figure); for a non-square
// response the largest |H| of row i.  Each is floored at floor × the largest
// diagonal scale (geometric mean, or row maximum) over all the set's frequencies, so
// that no entry is measured against ~0: a diagonal's zero (the ZOH double
// integrator's at the Nyquist frequency) would otherwise let one line own the figure.
inline constexpr double kDefaultScaleFloor = 1e-6;
std::vector<Eigen::MatrixXd> response_scales(const std::vector<Eigen::MatrixXcd>& h,
                                             double floor = kDefaultScaleFloor);

// Markov parameters g[0..L] of a discrete system, each (outputs x inputs).
using MarkovSequence = std::vector<Eigen::MatrixXd>;

}  // namespace lpvid
