// A two-mass positioning axis described as a "mechanical" base, and its frequency
// response computed independently of the library: P(jw) = C_q (K − w² M + jw D)⁻¹ B_w
// solved in the frequency domain with the 2×2 inverse written out by Cramer's rule
// (the library assembles a state space and evaluates C (jwI − A)⁻¹ B).  Used by the
// physical-model, fit and CLI tests.
#pragma once

#include <Eigen/Core>
#include <complex>
#include <string>

#include "idlib/physical/mechanical/mechanical_base.h"

namespace lpvid::two_mass_axis {

inline PhysicalParameter par(const char* name, const char* unit, double value, double lower, double upper, bool free) {
  return PhysicalParameter{name, unit, value, lower, upper, free};
}

inline LinearExpression ex(const std::string& text) { return parse_linear_expression(text); }

// A ball-screw axis with a flexibly coupled load: carriage x_m (driven by the motor
// current i through k_f, guided with viscous friction c_g) and load x_l (coupled by a
// spring k and damper c); the encoder sees x_m, a load sensor x_l.  No stiffness to
// the ground: a free (double-integrator) rigid-body mode, as a levitated or guided
// stage has.
inline MechanicalDescription axis() {
  MechanicalDescription d;
  d.name = "two_mass_axis";
  d.description = "carriage and flexibly coupled load";
  d.dofs = {{"x_m", "m"}, {"x_l", "m"}};
  d.inputs = {{"i", "A"}};
  d.outputs = {{"enc", "m"}, {"load", "m"}};
  d.parameters = {par("m_carriage_kg", "kg", 2.0, 0.1, 50.0, true), par("m_load_kg", "kg", 5.0, 0.1, 50.0, true),
                  par("k_coupling_N_per_m", "N/m", 2e5, 1e3, 1e8, true),
                  par("c_coupling_Ns_per_m", "N·s/m", 40.0, 0.01, 1e4, true),
                  par("c_guide_Ns_per_m", "N·s/m", 30.0, 0.01, 1e4, true),
                  par("k_f_N_per_A", "N/A", 12.0, 1.0, 100.0, false)};
  d.mass = {{ex("m_carriage_kg"), {}}, {{}, ex("m_load_kg")}};
  d.damping = {{ex("c_guide_Ns_per_m + c_coupling_Ns_per_m"), ex("-c_coupling_Ns_per_m")},
               {ex("-c_coupling_Ns_per_m"), ex("c_coupling_Ns_per_m")}};
  d.stiffness = {{ex("k_coupling_N_per_m"), ex("-k_coupling_N_per_m")},
                 {ex("-1*k_coupling_N_per_m"), ex("k_coupling_N_per_m")}};
  d.input_map = {{ex("k_f_N_per_A")}, {{}}};
  d.output_map = {{ex("1"), {}}, {{}, ex("1")}};
  return d;
}

struct AxisValues {
  double mc, ml, k, c, cg, kf;
};

inline AxisValues values_of(const PhysicalModel& m) {
  return {m.parameter("m_carriage_kg").value, m.parameter("m_load_kg").value, m.parameter("k_coupling_N_per_m").value,
          m.parameter("c_coupling_Ns_per_m").value, m.parameter("c_guide_Ns_per_m").value,
          m.parameter("k_f_N_per_A").value};
}

// The oracle: Z = K − w² M + jw D, q = Z⁻¹ B_w i (Cramer), y = q; optionally a
// collocated mode q += phi eta, eta = phiᵀ B_w i / (wm² − w² + 2j zeta wm w), and a delay.
inline Eigen::Vector2cd oracle(const AxisValues& v, double w, double phi_m = 0, double phi_l = 0, double wm = 1,
                        double zeta = 0, double tau = 0) {
  const std::complex<double> jw(0.0, w);
  const std::complex<double> z11 = v.k - w * w * v.mc + jw * (v.cg + v.c), z12 = -v.k - jw * v.c, z22 = v.k - w * w * v.ml + jw * v.c;
  const std::complex<double> det = z11 * z22 - z12 * z12;
  const std::complex<double> f = v.kf;  // B_w = (k_f, 0)
  Eigen::Vector2cd q(z22 * f / det, -z12 * f / det);
  if (phi_m != 0.0 || phi_l != 0.0) {
    const std::complex<double> eta = (phi_m * f) / (wm * wm - w * w + 2.0 * jw * zeta * wm);
    q(0) += phi_m * eta;
    q(1) += phi_l * eta;
  }
  return q * std::exp(-jw * tau);
}

}  // namespace lpvid::two_mass_axis
