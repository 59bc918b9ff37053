// An independent simulator of a TWO-MASS positioning axis for the force-error tests (the
// truth comes from here, not from idlib): a carriage driven on a ball screw and a load
// coupled to it by a spring and a damper, each measured by its own encoder,
//
//   m_c x_c'' = k_f i − c_g x_c' − F_c sign(x_c') − F_0 − R sin(2π x_c / P)
//               − c (x_c' − x_l') − k (x_c − x_l)          (friction on the carriage only:
//                                                          at rest it holds up to F_c)
//   m_l x_l'' = c (x_c' − x_l') + k (x_c − x_l),
//
// integrated at 100 substeps per sample (semi-implicit Euler, the carriage's stick as in
// tests/support/friction_axis.h), in closed loop with a discrete PD controller (8 Hz, on
// the total mass) on the carriage's quantised encoder, tracking a two-sine reference.
// The log holds t, the current i (commanded, plus a current sensor's noise) and the two
// encoders.  Used by tests/idlib/fit/force_error_test.cc.
#pragma once

#include <cmath>
#include <random>

#include <Eigen/Core>

#include "idlib/physical/mechanical/mechanical_base.h"
#include "tests/support/described_base.h"

namespace lpvid::two_mass_friction {

struct Truth {
  double m_c_kg = 2.3, m_l_kg = 4.6, k_N_per_m = 1.8e5, c_Ns_per_m = 35.0, c_guide_Ns_per_m = 30.0;
  double k_f_N_per_A = 12.0;
  double coulomb_N = 4.0, offset_N = 1.5, ripple_N = 0.5, ripple_period_m = 0.01;
};

struct Log {
  Eigen::VectorXd t, i, x_c, x_l;
};

inline Log simulate(const Truth& p, double seconds = 30.0, unsigned seed = 11) {
  const double ts = 1e-3, q = 1e-6;
  const auto n = static_cast<Eigen::Index>(std::llround(seconds / ts));
  const double m = p.m_c_kg + p.m_l_kg, wc = 2.0 * M_PI * 8.0, kp = m * wc * wc, kd = 2.0 * 0.7 * m * wc;
  const double alpha = std::exp(-2.0 * M_PI * 300.0 * ts);
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Log log;
  for (Eigen::VectorXd* v : {&log.t, &log.i, &log.x_c, &log.x_l}) v->resize(n);
  auto reference = [](double t) {
    return 0.1 * std::sin(2.0 * M_PI * 0.4 * t) + 0.03 * std::sin(2.0 * M_PI * 1.3 * t + 1.0);
  };
  double xc = reference(0.0), xl = xc, vc = 0.0, vl = 0.0, e_prev = 0.0, d_filt = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * ts;
    const double enc_c = std::round(xc / q) * q, enc_l = std::round(xl / q) * q;
    const double err = reference(t) - enc_c;
    d_filt = alpha * d_filt + (1.0 - alpha) * (k == 0 ? 0.0 : (err - e_prev) / ts);
    e_prev = err;
    const double current = (kp * err + kd * d_filt) / p.k_f_N_per_A;
    log.t(k) = t;
    log.i(k) = current + 0.005 * n01(rng);
    log.x_c(k) = enc_c;
    log.x_l(k) = enc_l;
    const int sub = 100;
    const double h = ts / sub;
    for (int s = 0; s < sub; ++s) {
      const double coupling = p.c_Ns_per_m * (vc - vl) + p.k_N_per_m * (xc - xl);
      const double applied = p.k_f_N_per_A * current - p.c_guide_Ns_per_m * vc - p.offset_N -
                             p.ripple_N * std::sin(2.0 * M_PI * xc / p.ripple_period_m) - coupling;
      double vc_new;
      if (vc == 0.0) {
        vc_new = std::abs(applied) <= p.coulomb_N ? 0.0 : h * (applied - std::copysign(p.coulomb_N, applied)) / p.m_c_kg;
      } else {
        vc_new = vc + h * (applied - std::copysign(p.coulomb_N, vc)) / p.m_c_kg;
        if (vc_new * vc < 0.0) vc_new = 0.0;
      }
      const double vl_new = vl + h * coupling / p.m_l_kg;
      xc += 0.5 * h * (vc + vc_new);
      xl += 0.5 * h * (vl + vl_new);
      vc = vc_new;
      vl = vl_new;
    }
  }
  return log;
}

// The base a user would describe (as samples/mechanical/two_mass_axis.json, in code):
// both masses, the coupling and the guide's viscous friction free at design values, the
// datasheet force constant fixed.
inline MechanicalDescription description() {
  const auto par = described_base::parameter;
  const auto ex = described_base::entry;
  MechanicalDescription d;
  d.name = "two_mass_axis";
  d.description = "a carriage and a flexibly coupled load, an encoder on each";
  d.dofs = {{"x_c", "m"}, {"x_l", "m"}};
  d.inputs = {{"i", "A"}};
  d.outputs = {{"enc", "m"}, {"load", "m"}};
  d.parameters = {par("m_c_kg", "kg", 2.0, 0.1, 50.0, true),       par("m_l_kg", "kg", 5.0, 0.1, 50.0, true),
                  par("k_N_per_m", "N/m", 2e5, 1e3, 1e8, true),    par("c_Ns_per_m", "N·s/m", 40.0, 0.0, 1e4, true),
                  par("c_guide_Ns_per_m", "N·s/m", 10.0, 0.0, 1e4, true),
                  par("k_f_N_per_A", "N/A", 12.0, 1.0, 100.0, false)};
  d.mass = {{ex("m_c_kg"), ex("0")}, {ex("0"), ex("m_l_kg")}};
  d.damping = {{ex("c_guide_Ns_per_m + c_Ns_per_m"), ex("-c_Ns_per_m")}, {ex("-c_Ns_per_m"), ex("c_Ns_per_m")}};
  d.stiffness = {{ex("k_N_per_m"), ex("-k_N_per_m")}, {ex("-k_N_per_m"), ex("k_N_per_m")}};
  d.input_map = {{ex("k_f_N_per_A")}, {ex("0")}};
  d.output_map = {{ex("1"), ex("0")}, {ex("0"), ex("1")}};
  return d;
}

}  // namespace lpvid::two_mass_friction
