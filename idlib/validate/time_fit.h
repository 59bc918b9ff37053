// Time-domain validation of a model against a measurement: the fit figure of
// MATLAB's `compare`, the residual tests of MATLAB's `resid`, and the time
// windows where the model fails.
//
// Signals follow idlib/core/types.h: N × channels, time along rows, row k at
// t_k = start_s + k·Ts.  The residual is e = y - ŷ (measured minus predicted).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct TimeFitOptions {
  // Largest lag of the residual tests, in samples (MATLAB resid's default 25).
  Index max_lag = 25;
  // Confidence of the correlation bounds, in (0, 1).
  double confidence = 0.99;
  // Failing windows: the record is cut into windows of window_s (half
  // overlapping); a window of channel i fails when the rms of e_i in it exceeds
  // both window_threshold_percent of the rms of y_i - mean(y_i) over the whole
  // record and noise_factor times the noise floor σ̂_i = rms(e_i[k] - e_i[k-1])/√2
  // (the sample-to-sample part of the residual: sensor noise, which no model
  // predicts; a model error is smooth and cancels in the difference).
  double window_s = 0.5;
  double window_threshold_percent = 10.0;
  double noise_factor = 3.0;

  // @throws InputError naming the field: max_lag < 1; confidence not in (0, 1);
  //   window_s, the threshold or noise_factor not finite and > 0.
  void validate() const;
};

// NRMSE fit in percent: 100·(1 - ‖y - ŷ‖₂ / ‖y - mean(y)‖₂) per column; 100 is
// perfect, 0 is no better than the mean, negative is worse.  A constant y gives
// -inf unless ŷ = y exactly (then 100).  Shapes: y, ŷ N × p; result p.
// @throws InputError  shapes differ, N < 2, or a value is not finite.
Eigen::VectorXd nrmse_fit_percent(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted);

// One correlation test over lags.  Whiteness (input empty): r(τ) = R_ee(τ)/R_ee(0),
// τ = 1..L.  Cross (residual e_i vs input u_j): r(τ) = R_eu(τ)/sqrt(R_ee(0) R_uu(0)),
// τ = -L..L (R_eu(τ) = Σ_t e(t+τ) u(t): τ > 0 is e after u, the causal side).
// FFT correlation (idlib/signal/correlation.h), means removed first.
//
// Bounds (Ljung, System Identification, 2nd ed., §16.6):
//   whiteness:  |r(τ)| <= z / sqrt(N);
//   cross:      |r(τ)| <= z · sqrt(P / N),  P = Σ_{|k|<=L} r_ee(k) r_uu(k)
//               (P = 1 for white e or white u; a coloured input widens the bound).
// bound_per_lag uses z = Φ⁻¹((1 + confidence)/2) (2.576 at 99 %), the band
// MATLAB's resid draws.  The pass/fail decision uses the family-wise bound
// (Bonferroni over the m lags tested: z = Φ⁻¹(1 - (1 - confidence)/(2m))) so
// that a correct model fails a channel with probability <= 1 - confidence, not
// 1 - confidence^m (22 % for 25 lags at 99 % per lag).
struct CorrelationTest {
  Index channel = 0;
  Index input = -1;                 // -1 for whiteness
  Eigen::VectorXi lags;             // τ tested
  Eigen::VectorXd r;                // normalised correlation at each lag
  double bound_per_lag = 0.0;
  double bound = 0.0;               // the one the decision uses
  double worst_ratio = 0.0;         // max |r| / bound
  int worst_lag = 0;
  Index lags_outside_per_lag_bound = 0;
  bool pass = true;
};

// @throws InputError  e has fewer than max_lag + 2 rows, a non-finite value.
std::vector<CorrelationTest> residual_whiteness(const Eigen::MatrixXd& residual, const TimeFitOptions& options);
// One test per (residual channel, input channel); an input column with zero
// variance is skipped (not excited).
// @throws InputError  row counts differ; as residual_whiteness.
std::vector<CorrelationTest> residual_input_correlation(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& input,
                                                        const TimeFitOptions& options);

// A run of consecutive failing windows of one channel, merged: [t_start_s,
// t_end_s], size_percent = the largest window rms of e over the record rms of
// y - mean(y), in percent.
struct FailingWindow {
  Index channel = 0;
  double t_start_s = 0.0;
  double t_end_s = 0.0;
  double size_percent = 0.0;
};
// Windows of min(N, max(2, round(window_s/Ts))) samples starting every half window; the
// last window ends at the last sample.  Sorted by channel, then time.
// @throws InputError  shapes differ; Ts not finite and > 0; N < 2.
std::vector<FailingWindow> failing_windows(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted,
                                           double start_s, double sample_period_s, const TimeFitOptions& options);

// All of the above in one call.  The residual tests run on
// measured - test_predicted when test_predicted is given (e.g. the open-loop
// prediction from the measured plant input, idlib/sim/moving_beam.h), else on
// measured - predicted.
struct TimeFitResult {
  Eigen::VectorXd fit_percent;   // per output
  Eigen::MatrixXd residual;      // N × p, measured - predicted
  // Noise floor σ̂ = rms(Δe)/√2 of each output's residual, and the fit a perfect
  // model would reach against that noise, 100·(1 - σ̂/rms(y - ȳ)) (the ceiling
  // of fit_percent set by the sensor noise, not by the model).
  Eigen::VectorXd noise_floor;
  Eigen::VectorXd fit_ceiling_percent;
  std::vector<CorrelationTest> whiteness;
  std::vector<CorrelationTest> cross;
  std::vector<FailingWindow> failures;
};
// input may have 0 columns (no cross test).
TimeFitResult time_fit(const Eigen::MatrixXd& measured, const Eigen::MatrixXd& predicted, const Eigen::MatrixXd& input,
                       double start_s, double sample_period_s, const TimeFitOptions& options,
                       const Eigen::MatrixXd& test_predicted = Eigen::MatrixXd());

// Φ⁻¹(p) of the standard normal, p in (0, 1); |error| < 1e-12 (bisection on erfc).
double standard_normal_quantile(double p);

}  // namespace lpvid
