// Test support: an INDEPENDENT simulator of the 3-DOF platform of seed 000, written
// from the physics apart from idlib/plants and idlib/physical (it includes neither,
// and shares no code with them), so that tests of identification and of the
// model-error loop are not tests of one model family against itself.
//
// What is independent here, and how it is derived:
// - Geometry at the coil level: nine voice coils (actuators and, collocated, the
//   inductive sensors) on a 3x3 grid at pitch r (coils 1-3 at x = +r with
//   y = +r, 0, -r; 4-6 at x = 0; 7-9 at x = -r: the layout eq 9's rows imply).
//   The controller maps wrench -> coil forces with T^T and sensor readings -> q with
//   T, T = (W_d W_d^T)^-1 W_d from the DESIGNED grid; the physics uses the TRUE
//   positions (they may differ: a sensor/actuator gain nobody modelled).
// - Mass matrix from the kinetic energy of a rigid body in q = [psi theta z] with
//   the velocity of a point (x, y, h): (-h theta', -h psi', z' + y psi' + x theta'):
//   M_zz = m, M_psi,z = m c_y, M_theta,z = m c_x, M_psipsi = J_psi, M_thth = J_theta,
//   M_psi,theta = J_pt (all about the origin), plus the beam as a point mass m_b at
//   (x_b, 0, z_b).
// - Stiffness from the rods: rod j attached at (x_j, y_j) along the horizontal unit
//   vector a_j acts as a vertical spring k_vert,j at its attachment point (so the
//   stiffness centre is the k_vert-weighted centroid of the attachments), a bending
//   spring k_bend,j about b_j = e_z x a_j and a twist spring k_twist,j about a_j;
//   the rotation vector is (psi, -theta, 0).  Plus an optional extra tilt stiffness
//   per axis (cables, a torsion bar) and the raised beam's gravity -m_b g z_b.
// - Damping: each coil is an air damper d_i at its true position.
// - Effects: flexible modes (modal coordinates, shape given at the nine coils,
//   collocated), a fractional input delay, a first-order coil-current lag, a
//   second-order filter on one input or output channel (sensor or amplifier
//   dynamics), all optional.
// - Sampling: the plant's input is held (ZOH) and switches tau after each sample
//   (fractional delay); the one-sample propagators are obtained by integrating the
//   matrix ODE with classical RK4 (substeps of at most Ts/16), not with a matrix
//   exponential.
// - The controller: a PID per axis in q, placed on the diagonal plant at x_b = 0,
//   discretised by the bilinear (Tustin) map.
//
// Only Eigen is used.  Units SI; angles rad; inputs [T_psi T_theta F_z], outputs
// [psi theta z] (the conventions of docs/assumptions.md, which an independent user
// would have to match to use lpvid at all).
#pragma once

#include <Eigen/Dense>
#include <complex>
#include <cstdint>
#include <string>
#include <vector>

namespace indep {

struct Rod {
  double x_m = 0, y_m = 0;  // attachment point on the platform
  double axis_rad = 0;      // direction of the rod in the horizontal plane
  double k_vert_N_per_m = 0, k_bend_Nm_per_rad = 0, k_twist_Nm_per_rad = 0;
};

struct Mode {
  double omega_rad_s = 600, zeta = 0.02;
  Eigen::VectorXd shape;  // 9 values at the coils (1/sqrt(kg)); collocated
};

// A second-order filter H(s) = (b2 s^2 + b1 s + b0) / (s^2 + a1 s + a0) on one
// channel: on input `channel` (kind kInput: between the commanded wrench and the
// coils, e.g. an amplifier) or output `channel` (kind kOutput: on q, e.g. a sensor).
struct ChannelFilter {
  enum Kind { kInput, kOutput } kind = kOutput;
  int channel = 0;
  double b2 = 0, b1 = 0, b0 = 1, a1 = 1, a0 = 1;
};

struct Plant {
  double m_p_kg = 6, J_psi_kgm2 = 0.05, J_theta_kgm2 = 0.06, J_pt_kgm2 = 0, c_x_m = 0, c_y_m = 0;
  double m_b_kg = 1, z_b_m = 0.08;
  bool beam_gravity = true;
  double g_m_per_s2 = 9.81;
  double pitch_m = 0.1, design_pitch_m = 0.1;  // true coil/sensor grid pitch and the one T is built from
  Eigen::VectorXd coil_damping_Ns_per_m = Eigen::VectorXd::Constant(9, 30.0);
  std::vector<Rod> rods;
  double extra_k_psi_Nm_per_rad = 0, extra_k_theta_Nm_per_rad = 0;
  std::vector<Mode> modes;
  double input_delay_s = 0;
  double coil_lag_s = 0;  // 0: none
  double input_gain = 1;  // every coil's force per command (1: as designed)
  std::vector<ChannelFilter> filters;

  // Three rods 120 degrees apart at radius 0.12 m, each along its tangent, with
  // the given per-rod stiffnesses.
  static std::vector<Rod> symmetric_rods(double k_vert, double k_bend, double k_twist);
  // A plausible plant (values of the paper's scale, not lpvid's defaults).
  static Plant nominal();
};

// Continuous matrices (no delay): x' = A x + B u_cmd, q_meas = C x.
struct Continuous {
  Eigen::MatrixXd A, B, C;
};
Continuous continuous_plant(const Plant& plant, double x_b_m);

// The 3x3 physical matrices at x_b (for checks and for the controller design).
Eigen::Matrix3d mass_matrix(const Plant& plant, double x_b_m);
Eigen::Matrix3d stiffness_matrix(const Plant& plant);
Eigen::Matrix3d damping_matrix(const Plant& plant);

// A discrete LTI system (D may be nonzero).
struct Discrete {
  Eigen::MatrixXd A, B, C, D;
  double Ts = 0;
  Eigen::MatrixXcd response(double omega_rad_s) const;  // C (zI - A)^-1 B + D, z = e^{j w Ts}
  Eigen::Index order() const { return A.rows(); }
};

// The sampled plant (ZOH input, delay exact including its fractional part).
Discrete sampled_plant(const Plant& plant, double x_b_m, double Ts);

struct PidDesign {
  double bandwidth_rad_s[3] = {40, 40, 25};  // closed-loop natural frequency per axis
  double damping[3] = {0.4, 0.4, 0.5};       // closed-loop damping of the pair
  double integral_time_s[3] = {0.5, 0.5, 0.5};  // time constant of the real closed-loop pole
  double derivative_filter_factor = 8;        // derivative filtered at this multiple of the bandwidth
};
// Discrete PID per axis (3 inputs e = -q, 3 outputs u_c), Tustin at Ts.
Discrete pid_controller(const Plant& plant, const PidDesign& design, double Ts);

// Largest |eigenvalue| of the loop u = C(-q) + v around the strictly proper plant
// (< 1: the loop is stable and an experiment on it exists).
double closed_loop_spectral_radius(const Discrete& plant, const Discrete& controller);

struct Noise {
  double sensor_std_m = 0.3e-6;        // per inductive sensor (9 of them), white
  double force_std[3] = {0, 0, 0};     // white process noise on the wrench (N·m, N·m, N)
};

// One closed-loop experiment: white v (std excitation_std) on input `excited`
// (or all three independently when excited = -1), from rest.  Columns of the
// returned N x 10 matrix: t, v1 v2 v3, u1 u2 u3 (plant input wrench), q1 q2 q3 (measured).
Eigen::MatrixXd simulate_log(const Discrete& plant, const Discrete& controller, const Plant& physical,
                             const Noise& noise, const double excitation_std[3], int excited, Eigen::Index samples,
                             std::uint64_t seed);

// Stepped-sine analyzer measurement of S = (I + C P)^-1 (v -> u) at omega (rad/s),
// one column per excited input, K averages of blocks of block_samples samples; the
// error is the sensor noise through the loop, u = S v - S C n_q.  coherence as H1
// with a noise-free reference.
struct AnalyzerData {
  Eigen::VectorXd omega_rad_s;
  std::vector<Eigen::Matrix3cd> S, truth;
  std::vector<Eigen::Matrix3d> coherence;
  int averages = 0;
};
AnalyzerData analyzer_S(const Discrete& plant, const Discrete& controller, const Plant& physical, const Noise& noise,
                        const Eigen::VectorXd& omega_rad_s, const double amplitude[3], int averages,
                        Eigen::Index block_samples, std::uint64_t seed);

// Writers in lpvid's documented formats (docs/formats.md), by plain fprintf.
void write_log_csv(const std::string& path, const Eigen::MatrixXd& log);
void write_controller_json(const std::string& path, const Discrete& controller);
// One file per excited input j: S_v<j>.csv with columns S_u<i>_v<j>_re/_im and coh;
// write_averages adds the "# averages: K" line.
void write_analyzer_csv(const std::string& dir, const AnalyzerData& data, bool write_averages);
// A discrete system as lpvid state-space JSON (inputs/outputs named).
void write_state_space_json(const std::string& path, const Discrete& sys, const std::vector<std::string>& inputs,
                            const std::vector<std::string>& outputs);

}  // namespace indep
