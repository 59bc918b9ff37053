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

#include <cmath>
#include <random>
#include <fstream>
#include <string>

#include <Eigen/Core>

#include "idlib/physical/mechanical/mechanical_base.h"

namespace lpvid::friction_axis {

struct Truth {
  double m_kg = 4.2, c_Ns_per_m = 35.0, coulomb_N = 6.5, offset_N = 2.8, k_f_N_per_A = 10.0;
};

struct Experiment {
  double rate_hz = 1000.0, seconds = 30.0;
  double encoder_m = 1e-6;           // quantisation step
  double current_noise_A = 0.005;    // the logged current's sensor noise (std)
  bool both_ways = true;             // false: a ramp that never reverses
  unsigned seed = 7;
};

struct Log {
  Eigen::VectorXd t, r, i, x;
};

inline double reference(const Experiment& e, double t) {
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
  std::mt19937 rng(e.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Log log;
  log.t.resize(n);
  log.r.resize(n);
  log.i.resize(n);
  log.x.resize(n);
  double x = reference(e, 0.0), v = 0.0, e_prev = 0.0, d_filt = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * ts;
    const double enc = std::round(x / e.encoder_m) * e.encoder_m;
    const double r = reference(e, t);
    const double err = r - enc;
    d_filt = alpha * d_filt + (1.0 - alpha) * (k == 0 ? 0.0 : (err - e_prev) / ts);
    e_prev = err;
    // feedforward of the offset the designer knows roughly (2 N), not exactly
    const double current = (kp * err + kd * d_filt + 2.0) / p.k_f_N_per_A;
    log.t(k) = t;
    log.r(k) = r;
    log.i(k) = current + e.current_noise_A * n01(rng);
    log.x(k) = enc;
    const int sub = 100;
    const double h = ts / sub;
    for (int s = 0; s < sub; ++s) {
      const double applied = p.k_f_N_per_A * current - p.c_Ns_per_m * v - p.offset_N;
      double v_new;
      if (v == 0.0) {  // stuck: moves only when the net force beats the friction
        v_new = std::abs(applied) <= p.coulomb_N
                    ? 0.0
                    : h * (applied - std::copysign(p.coulomb_N, applied)) / p.m_kg;
      } else {
        v_new = v + h * (applied - std::copysign(p.coulomb_N, v)) / p.m_kg;
        if (v_new * v < 0.0) v_new = 0.0;  // the friction stops it within the substep
      }
      x += 0.5 * h * (v + v_new);
      v = v_new;
    }
  }
  return log;
}

// The base a user would describe (samples/mechanical/ball_screw_axis.json, built here
// in code: the library tests link no JSON reader): one DOF, mass and viscous friction
// free, the datasheet force constant fixed.
inline MechanicalDescription description() {
  auto par = [](const char* name, const char* unit, double v, double lo, double hi, bool free) {
    PhysicalParameter p;
    p.name = name;
    p.unit = unit;
    p.value = v;
    p.lower = lo;
    p.upper = hi;
    p.free = free;
    return p;
  };
  auto ex = [](const char* text) { return parse_linear_expression(text); };
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
