// An independent simulator of a positioning axis WITH FRICTION for the force-error tests (the
// truth comes from here, not from idlib): a carriage on a ball screw,
//
//   m x'' = k_f i − c x' − F_c sign(x') − F_0   (Coulomb friction; at rest it holds any
//                                             net force up to F_c: the axis sticks),
//
// integrated at 100 substeps per sample (semi-implicit Euler; a velocity that would
// change sign within a substep stops at zero, and the axis starts again only when the
// net force exceeds F_c), in closed loop with a discrete PD
// controller on the quantised encoder (1 kHz, the current held between samples),
// tracking a reference trajectory.  The log holds t, the reference r, the current i
// (the commanded current plus a current sensor's Gaussian noise) and the encoder x.
// Used by tests/idlib/fit/force_error_test.cc and tests/cli/friction_axis_cli_test.cc.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>
#include <fstream>
#include <string>

#include <Eigen/Core>

#include "idlib/physical/mechanical/mechanical_base.h"
#include "tests/support/described_base.h"

namespace lpvid::friction_axis {

struct Truth {
  double m_kg = 4.2, c_Ns_per_m = 35.0, coulomb_N = 6.5, offset_N = 2.8, k_f_N_per_A = 10.0;
  // Effects beyond viscous friction, Coulomb friction and the offset (0: absent), as a real
  // axis shows them (the library has Stribeck friction and two ripples; not a third):
  //  - Stribeck: the friction rises by stribeck_N towards standstill,
  //    (F_c + F_s exp(−(v/v_s)²)) sign v, and at rest holds up to F_c + F_s;
  //  - a force ripple periodic in position (cogging, the screw's lead error):
  //    ripple_N sin(2π x / ripple_period_m).
  double stribeck_N = 0.0, stribeck_v = 0.005, ripple_N = 0.0, ripple_period_m = 0.01;
  //  - a second and a third ripple of other periods (a motor's cogging beside a screw's
  //    lead error): ripple2_N sin(2π x / ripple2_period_m), ripple3_N likewise.
  double ripple2_N = 0.0, ripple2_period_m = 0.007, ripple3_N = 0.0, ripple3_period_m = 0.0043;
};

// Integration substeps per sample (simulate(); linear_sample_map takes the same).
inline constexpr int kSubsteps = 100;

struct Experiment {
  double rate_hz = 1000.0, seconds = 30.0;
  double encoder_m = 1e-6;           // quantisation step
  // > 0: the position sensor's white Gaussian noise (std, m) instead of the quantiser
  // (an interferometer, or an encoder interpolated finely; drawn from seed + 77)
  double white_position_noise_m = 0.0;
  double current_noise_A = 0.005;    // the logged current's sensor noise (std)
  bool both_ways = true;             // false: a ramp that never reverses
  // true: point-to-point moves between fixed positions with rests between them
  // (minimum-jerk profiles of 0.6–1.1 s, rests of 0.25–0.45 s; the cycle of 12.2 s
  // ends where it starts), as an industrial
  // axis is exercised; overrides both_ways.
  bool point_to_point = false;
  // true: a broadband reference instead (overrides the above): white noise low-passed at
  // 20 Hz, 5 mm rms, about a slow 0.3 Hz sine of 20 mm — the random excitation identify
  // needs, with the axis reversing often (for the nonlinearity tests).
  bool random_reference = false;
  // The controller: false a PD on the encoder (the current is the command); true a
  // drive's cascade, a P position loop (5 Hz) around a PI velocity loop (20 Hz) on
  // the differenced, low-passed encoder: the integrator makes the axis hunt through
  // the friction at rest (stick–slip), as a real drive does.
  bool cascade = false;
  // The cascade's gains when a drive's are given (0: the defaults above, from the
  // nominal mass): the position loop's P (1/s), the velocity loop's P (N per m/s) and
  // the integral's corner (Hz; 0 a P velocity loop, as some drives ship).
  double kx_per_s = 0.0, kv_N_per_mps = 0.0, integral_corner_hz = 4.0;
  // The drive's limit on the force it commands (N; 0 none): the logged command is the
  // limited one, as a drive logs the value it applies.
  double saturation_N = 0.0;
  // true: the log holds the controller's command before the limit (a drive logging its
  // set-point, not what it applies); the motor applies the limited one.
  bool log_unlimited = false;
  unsigned seed = 7;
};

struct Log {
  Eigen::VectorXd t, r, i, x;
  // The simulator's own account of the forces the library cannot model (Stribeck and
  // ripple), averaged over each sample, and the motor force k_f i (the command, no
  // sensor noise): the truth a fit of viscous + Coulomb + offset cannot go below.
  Eigen::VectorXd unmodelled_N, motor_N, velocity;
  Eigen::VectorXd ripple_force_N;  // the ripple's part of unmodelled_N (the rest is the Stribeck rise)
};

// A realistic axis (tests of the force-error route on what a real axis has and the
// library lacks): Coulomb 3 N, offset −0.8 N, a Stribeck rise of 1.5 N over 1 cm/s, a
// 0.4 N ripple of period 2 cm; logged under a drive's cascade with point-to-point moves
// on a 0.2 µm encoder for 25 s, the command logged as the drive logs it (no sensor noise).
inline Truth realistic_truth() {
  Truth t;
  t.coulomb_N = 3.0;
  t.offset_N = -0.8;
  t.stribeck_N = 1.5;
  t.stribeck_v = 0.01;
  t.ripple_N = 0.4;
  t.ripple_period_m = 0.02;
  return t;
}
inline Experiment realistic_experiment() {
  Experiment e;
  e.point_to_point = true;
  e.cascade = true;
  e.encoder_m = 0.2e-6;
  e.current_noise_A = 0.0;
  e.seconds = 25.0;
  return e;
}

// The point-to-point reference: minimum-jerk moves between these positions (m).
inline double point_to_point_reference(double t) {
  static const double stops[] = {0.0, 0.15, 0.04, 0.2, 0.1, 0.18, 0.0, 0.12, 0.05, 0.2, 0.0};
  static const double moves[] = {0.8, 0.7, 1.1, 0.6, 0.9, 1.0, 0.75, 0.85, 1.05, 0.95};
  static const double rests[] = {0.3, 0.4, 0.25, 0.45, 0.35, 0.3, 0.4, 0.25, 0.35, 0.45};
  constexpr int kMoves = 10;
  double cycle = 0.0;
  for (int k = 0; k < kMoves; ++k) cycle += moves[k] + rests[k];
  double tau = std::fmod(t, cycle);
  for (int k = 0; k < kMoves; ++k) {
    if (tau < rests[k]) return stops[k];
    tau -= rests[k];
    if (tau < moves[k]) {
      const double s = tau / moves[k];
      return stops[k] + (stops[k + 1] - stops[k]) * s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
    }
    tau -= moves[k];
  }
  return stops[kMoves];
}

inline double reference(const Experiment& e, double t) {
  if (e.point_to_point) return point_to_point_reference(t);
  if (e.both_ways) return 0.1 * std::sin(2.0 * M_PI * 0.4 * t) + 0.03 * std::sin(2.0 * M_PI * 1.3 * t + 1.0);
  return 0.05 * t + 0.01 * std::sin(2.0 * M_PI * 0.7 * t);  // velocity 0.05 ± 0.044 m/s: never reverses
}

// The log as a CSV file: t, r, i, enc (full precision).
inline void write_csv(const Log& log, const std::string& path) {
  std::ofstream f(path);
  f.precision(17);
  f << "t,r,i,enc\n";
  for (Eigen::Index k = 0; k < log.t.size(); ++k) f << log.t(k) << ',' << log.r(k) << ',' << log.i(k) << ',' << log.x(k) << '\n';
}

inline Log simulate(const Truth& p, const Experiment& e) {
  const double ts = 1.0 / e.rate_hz;
  const auto n = static_cast<Eigen::Index>(std::llround(e.seconds * e.rate_hz));
  // PD at 30 Hz bandwidth, ζ 0.7 on the nominal mass; derivative filtered at 300 Hz
  const double wc = 2.0 * M_PI * 30.0, kp = p.m_kg * wc * wc, kd = 2.0 * 0.7 * p.m_kg * wc;
  const double alpha = std::exp(-2.0 * M_PI * 300.0 * ts);
  // cascade: velocity PI at 20 Hz (integral corner 4 Hz), position P at 5 Hz,
  // velocity estimate low-passed at 200 Hz
  const double kv = e.kv_N_per_mps > 0.0 ? e.kv_N_per_mps : p.m_kg * 2.0 * M_PI * 20.0;
  const double ki = kv * 2.0 * M_PI * e.integral_corner_hz;
  const double kx = e.kx_per_s > 0.0 ? e.kx_per_s : 2.0 * M_PI * 5.0;
  const double alpha_v = std::exp(-2.0 * M_PI * 200.0 * ts);
  std::mt19937 rng(e.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::mt19937 position_rng(e.seed + 77);
  std::normal_distribution<double> position_n01(0.0, 1.0);  // its own: a distribution keeps a spare draw
  Log log;
  for (Eigen::VectorXd* v :
       {&log.t, &log.r, &log.i, &log.x, &log.unmodelled_N, &log.motor_N, &log.velocity, &log.ripple_force_N})
    v->resize(n);
  Eigen::VectorXd random_r;
  if (e.random_reference) {
    std::mt19937 rr(e.seed + 1000);
    std::normal_distribution<double> g(0.0, 1.0);
    random_r.resize(n);
    const double a = std::exp(-2.0 * M_PI * 20.0 * ts), gain = std::sqrt(1.0 - a * a);
    double state = 0.0;
    for (Eigen::Index k = 0; k < n; ++k) {
      state = a * state + gain * g(rr);
      random_r(k) = 0.005 * state + 0.02 * std::sin(2.0 * M_PI * 0.3 * static_cast<double>(k) * ts);
    }
  }
  const auto ref = [&](Eigen::Index k) {
    return e.random_reference ? random_r(k) : reference(e, static_cast<double>(k) * ts);
  };
  double x = ref(0), v = 0.0, e_prev = 0.0, d_filt = 0.0, enc_prev = 0.0, v_est = 0.0, integ = 0.0;
  auto stribeck = [&](double speed) { return p.stribeck_N * std::exp(-(speed * speed) / (p.stribeck_v * p.stribeck_v)); };
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * ts;
    const double enc = e.white_position_noise_m > 0.0 ? x + e.white_position_noise_m * position_n01(position_rng)
                                                      : std::round(x / e.encoder_m) * e.encoder_m;
    const double r = ref(k);
    const double err = r - enc;
    double current;
    if (e.cascade) {
      v_est = alpha_v * v_est + (1.0 - alpha_v) * (k == 0 ? 0.0 : (enc - enc_prev) / ts);
      enc_prev = enc;
      const double v_err = kx * err - v_est;
      integ += ki * v_err * ts;
      current = (kv * v_err + integ) / p.k_f_N_per_A;
    } else {
      d_filt = alpha * d_filt + (1.0 - alpha) * (k == 0 ? 0.0 : (err - e_prev) / ts);
      e_prev = err;
      // feedforward of the offset the designer knows roughly (2 N), not exactly
      current = (kp * err + kd * d_filt + 2.0) / p.k_f_N_per_A;
    }
    const double commanded = current;
    if (e.saturation_N > 0.0) {
      const double limit = e.saturation_N / p.k_f_N_per_A;
      current = std::clamp(current, -limit, limit);
      // anti-windup, as a drive has it: the integrator holds while the command is limited
      if (e.cascade && current != commanded) integ -= ki * (kx * err - v_est) * ts;
    }
    log.t(k) = t;
    log.r(k) = r;
    log.i(k) = (e.log_unlimited ? commanded : current) + e.current_noise_A * n01(rng);
    log.x(k) = enc;
    log.motor_N(k) = p.k_f_N_per_A * current;
    log.velocity(k) = v;
    const int sub = kSubsteps;
    const double h = ts / sub;
    double unmodelled = 0.0, rippled = 0.0;
    for (int s = 0; s < sub; ++s) {
      const double ripple = p.ripple_N * std::sin(2.0 * M_PI * x / p.ripple_period_m) +
                            p.ripple2_N * std::sin(2.0 * M_PI * x / p.ripple2_period_m) +
                            p.ripple3_N * std::sin(2.0 * M_PI * x / p.ripple3_period_m);
      const double applied = p.k_f_N_per_A * current - p.c_Ns_per_m * v - p.offset_N - ripple;
      double v_new;
      double friction_extra = 0.0;
      if (v == 0.0) {  // stuck: moves only when the net force beats the static friction
        const double stat = p.coulomb_N + stribeck(0.0);
        v_new = std::abs(applied) <= stat ? 0.0 : h * (applied - std::copysign(stat, applied)) / p.m_kg;
        friction_extra = v_new == 0.0 ? 0.0 : std::copysign(stribeck(0.0), applied);
      } else {
        friction_extra = std::copysign(stribeck(v), v);
        v_new = v + h * (applied - std::copysign(p.coulomb_N, v) - friction_extra) / p.m_kg;
        // the friction stops it within the substep (only where there is friction to do it:
        // without, the clamp would itself be a small loss at every reversal)
        if (v_new * v < 0.0 && p.coulomb_N + p.stribeck_N > 0.0) v_new = 0.0;
      }
      unmodelled += (ripple + friction_extra) / sub;
      rippled += ripple / sub;
      x += 0.5 * h * (v + v_new);
      v = v_new;
    }
    log.unmodelled_N(k) = unmodelled;
    log.ripple_force_N(k) = rippled;
  }
  return log;
}

// The axis's linear part (its mass, viscous friction and force constant) exactly as
// simulate() integrates it: with the current held over a sample, the 100 semi-implicit
// substeps (v' = v + h (k_f i − c v)/m, x' = x + h (v + v')/2) are one linear map per
// sample on [position; velocity], x_{k+1} = A x_k + B i_k, the encoder reading the
// position (before its quantisation).  This, not the exact ZOH of the continuous axis, is
// what a linear fit of the simulator's logs should recover: the two differ by the
// integration's own error (c h / m = 8e-5 per substep; 4.2e-5 measured in the
// response), which a noise-free fit resolves.
struct SampleMap {
  Eigen::Matrix2d A;
  Eigen::Vector2d B;
};
inline SampleMap linear_sample_map(const Truth& p, double rate_hz) {
  const double h = 1.0 / rate_hz / kSubsteps, d = 1.0 - h * p.c_Ns_per_m / p.m_kg, g = h * p.k_f_N_per_A / p.m_kg;
  Eigen::Matrix2d phi;
  phi << 1.0, 0.5 * h * (1.0 + d), 0.0, d;
  const Eigen::Vector2d gamma(0.5 * h * g, g);
  SampleMap m{Eigen::Matrix2d::Identity(), Eigen::Vector2d::Zero()};
  for (int s = 0; s < kSubsteps; ++s) {  // x ← Φ x + Γ i, once per substep
    m.A = phi * m.A;
    m.B = phi * m.B + gamma;
  }
  return m;
}

// The base a user would describe (samples/mechanical/ball_screw_axis.json, built here
// in code: the library tests link no JSON reader): one DOF, mass and viscous friction
// free, the datasheet force constant fixed.
inline MechanicalDescription description() {
  const auto par = described_base::parameter;
  const auto ex = described_base::entry;
  MechanicalDescription d;
  d.name = "ball_screw_axis";
  d.description = "a carriage on a ball screw, motor current in, encoder out";
  d.dofs = {{"x", "m"}};
  d.inputs = {{"i", "A"}};
  d.outputs = {{"enc", "m"}};
  d.parameters = {par("m_kg", "kg", 3.0, 0.1, 100.0, true), par("c_Ns_per_m", "N·s/m", 10.0, 0.0, 1e4, true),
                  par("k_f_N_per_A", "N/A", 10.0, 1.0, 100.0, false)};
  d.mass = {{ex("m_kg")}};
  d.damping = {{ex("c_Ns_per_m")}};
  d.stiffness = {{ex("0")}};
  d.input_map = {{ex("k_f_N_per_A")}};
  d.output_map = {{ex("1")}};
  return d;
}

}  // namespace lpvid::friction_axis
