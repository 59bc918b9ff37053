// Closed-loop excitation experiments on the 3-DOF platform (seed 000, section 4,
// Fig. 8): white noise v injected at the plant input, the loop closed by the
// stabilising controller, the measured outputs logged.
//
//        v ──►(+)── u ──► P ── q_true ──►(+)── q_meas ──┐
//              ▲                          n ─┘           │
//              └──────── u_c ◄── C ◄── e = -q_meas ◄─────┘
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct ExcitationOptions {
  // Record length; the log has N = round(duration_s / sample_period_s) rows,
  // 1 <= N <= kMaxSamples.
  double duration_s = 60.0;
  double sample_period_s = 1e-3;  // must equal the plant's and controller's Ts
  // Which plant input receives the white noise: 0, 1, 2, or -1 for all three at
  // once (mutually independent).  Inputs not excited get v = 0.
  int excited_input = 0;
  // Standard deviation of the white excitation per plant input [T_psi T_theta F_z]
  // in N·m, N·m, N.  Defaults: with the default platform and PI gains the
  // closed-loop responses are ~50 µrad rms in each tilt and ~20 µm rms in z at
  // 1 kHz (~15 µrad and ~6 µm at 10 kHz, where the same per-sample std spreads
  // over a 10× wider band): ≫ the sensor noise below, ≪ the 1 mm air gap, and
  // far inside the ~110 N control budget (docs/assumptions.md).
  Eigen::Vector3d excitation_std{0.05, 0.05, 1.0};
  // Standard deviation of the white measurement noise per output [psi theta z]
  // in rad, rad, m.  Defaults: 0.3 µm rms per inductive sensor; z averages nine
  // sensors (0.3/3 = 0.1 µm); a tilt uses six sensors at arm r_vc = 0.1 m:
  // 0.3 µm / (0.1 m · sqrt 6) ≈ 1.2 µrad.
  Eigen::Vector3d sensor_noise_std{1.2e-6, 1.2e-6, 1.0e-7};
  std::uint64_t seed = 1;
  // A designed excitation (e.g. from lpvid excite), N x 3 in the plant input's
  // units, used sample for sample as v instead of the white noise: when not empty
  // the log has its N rows (duration_s is not used) and excited_input and
  // excitation_std are not used.  The noise draws are unchanged (see
  // simulate_excitation), so the sensor noise is the same as with white v.
  Eigen::MatrixXd excitation_samples;

  // 5e7 samples = 4 GB of log; a larger request is almost surely a unit mistake.
  static constexpr double kMaxSamples = 5e7;

  // @throws InputError naming the field: duration/sample period not finite or
  //   <= 0, or giving N < 1 or N > kMaxSamples; excited_input not in {-1,0,1,2};
  //   a standard deviation negative or not finite; the excited input(s) with a
  //   zero excitation_std (without excitation_samples); excitation_samples not
  //   N x 3, with N > kMaxSamples, or not finite.
  void validate() const;
};

// A simulated log: data is N × 10 (time along rows, idlib/core/types.h) with
// columns names = {"t", "v1","v2","v3", "u1","u2","u3", "q1","q2","q3"}:
// t = k·Ts in s; v the injected excitation, u = u_c + v the plant input (both in
// the plant's input units); q the measured output (plant output units).
struct SimulatedLog {
  std::vector<std::string> names;
  Eigen::MatrixXd data;
};

// Runs one closed-loop excitation experiment from rest (zero plant and
// controller state; v = 0 before the record).  Per sample k = 0..N-1:
//   q_true = C_p x_p;  q_meas = q_true + n;  e = -q_meas;
//   u_c = C_c x_c + D_c e;  u = u_c + v;   log (k·Ts, v, u, q_meas);
//   x_p ← A_p x_p + B_p u;  x_c ← A_c x_c + B_c e.
// v and n are Gaussian, drawn from std::mt19937_64(seed) through
// std::normal_distribution in the order v1 v2 v3 n1 n2 n3 every sample (all
// six are drawn even when a std is zero, so the excitation sequence does not
// depend on the noise settings); with options.excitation_samples, v = its row k
// (the drawn v is discarded).  The same seed gives the same log bit for bit.
//
// | argument   | requirement |
// |------------|-------------|
// | discrete_plant      | discrete, any order n_p, 3 inputs, 3 outputs, D = 0 (strictly proper) |
// | discrete_controller | discrete, any order n_c, 3 inputs (e), 3 outputs (u_c) |
// | both sample periods | equal options.sample_period_s to a relative 1e-9 |
//
// @throws InputError  options invalid (ExcitationOptions::validate); a model
//   invalid (StateSpace::validate), continuous, of the wrong shape, with a
//   non-zero plant D, or with a sample period different from the options'.
SimulatedLog simulate_excitation(const StateSpace& discrete_plant, const StateSpace& discrete_controller,
                                 const ExcitationOptions& options);

}  // namespace lpvid
