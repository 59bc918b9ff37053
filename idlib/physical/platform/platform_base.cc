#include "idlib/physical/platform/platform_base.h"

#include <fmt/format.h>

#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"
#include "idlib/plants/platform/platform.h"

namespace lpvid {
namespace {

PhysicalParameter par(const char* name, const char* unit, double value, double lower, double upper, bool free) {
  return PhysicalParameter{name, unit, value, lower, upper, free};
}

Index at(const PhysicalModel& m, const char* name) { return m.index_of(name); }

}  // namespace

BaseInfo make_platform_base() {
  const PlatformParameters d = PlatformParameters::defaults();
  BaseInfo b;
  b.name = "platform";
  b.description = "the 3-DOF planar actuator with manipulator of seed 000 (eqs 2–8), scheduled by the beam position x_b";
  // Bounds: wide physical ranges around the documented defaults
  // (docs/assumptions.md) so that a start 2x off and the global start's search box
  // lie inside; positive quantities have positive lower bounds (fitted as logs).
  const double r = d.coil_arm_m, c = d.coil_damping_Ns_per_m;
  b.parameters = {
      par("J_psi_kgm2", "kg·m²", d.J_psi_kgm2, 1e-4, 10.0, true),
      par("J_theta_kgm2", "kg·m²", d.J_theta_kgm2, 1e-4, 10.0, true),
      par("platform_mass_kg", "kg", d.platform_mass_kg, 0.1, 100.0, true),
      par("beam_mass_kg", "kg", d.beam_mass_kg, 0.01, 20.0, true),
      par("beam_height_m", "m", d.beam_height_m, -0.5, 0.5, false),
      par("beam_stroke_m", "m", d.beam_stroke_m, 1e-3, 1.0, false),
      // eq 5 with nine equal coil dampers d at arm r_vc: 6 r² d, 6 r² d, 9 d
      par("damping_psi_Nms_per_rad", "N·m·s/rad", 6 * r * r * c, 1e-4, 1e5, true),
      par("damping_theta_Nms_per_rad", "N·m·s/rad", 6 * r * r * c, 1e-4, 1e5, true),
      par("damping_z_Ns_per_m", "N·s/m", 9 * c, 1e-3, 1e6, true),
      // D_ij = rho_ij sqrt(D_ii D_jj): coils of unequal damping couple the DOFs
      // (D = Σ d_i c_i c_iᵀ over the nine coils is a general symmetric matrix)
      par("damping_coupling_psi_theta", "1", 0.0, -0.5, 0.5, true),
      par("damping_coupling_psi_z", "1", 0.0, -0.5, 0.5, true),
      par("damping_coupling_theta_z", "1", 0.0, -0.5, 0.5, true),
      par("k_linear_N_per_m", "N/m", d.k_linear_N_per_m, 1.0, 1e7, true),
      // the rods' designed leaf-spring bending (per rod) and axes: the design, fixed
      par("k_torque_low_Nm_per_rad", "N·m/rad", d.k_torque_low_Nm_per_rad, 1e-3, 1e5, false),
      par("rod_axis_angle_1_rad", "rad", d.rod_axis_angles_rad[0], -7.0, 7.0, false),
      par("rod_axis_angle_2_rad", "rad", d.rod_axis_angles_rad[1], -7.0, 7.0, false),
      par("rod_axis_angle_3_rad", "rad", d.rod_axis_angles_rad[2], -7.0, 7.0, false),
      // the built rods' bending about each tilt axis relative to the design: a
      // factor 2 either way (the leaf springs' tolerance); more is not bending
      par("bending_scale_psi", "1", 1.0, 0.5, 2.0, true),
      par("bending_scale_theta", "1", 1.0, 0.5, 2.0, true),
      par("bending_coupling", "1", 0.0, -0.5, 0.5, true),
  };
  b.design_scales = {{"bending_scale_psi", "k_torque_low_Nm_per_rad"},
                     {"bending_scale_theta", "k_torque_low_Nm_per_rad"}};
  b.input_names = {"T_psi", "T_theta", "F_z"};
  b.input_units = {"N·m", "N·m", "N"};
  b.output_names = {"psi", "theta", "z"};
  b.output_units = {"rad", "rad", "m"};
  b.dof_names = {"psi", "theta", "z"};
  b.dof_units = b.output_units;
  b.schedule_name = "beam position x_b";
  b.schedule_unit = "m";
  b.schedule_symbol = "x_b";
  b.default_effects = {"beam_gravity"};
  b.physics_effects = {
      {"rod_twist", "torsional stiffness of the suspension rods (k_torque_high, Fig. 7), per tilt axis",
       "adds the rods' twist stiffness to the psi and theta diagonals of K (Σ_j k_torque_high s_j s_jᵀ; its two "
       "diagonal entries differ when the rods are not 120° apart or not alike)",
       "tilt resonances too low and the low-frequency tilt gain too high (too soft) beyond what the rods' bending "
       "tolerance allows (bending_scale_psi/theta 0.5-2x the designed k_torque_low; if the rods cannot twist, the "
       "design value is off: set it with model init --set)",
       {par("twist_stiffness_psi_Nm_per_rad", "N·m/rad", 1.5 * d.k_torque_high_Nm_per_rad, 1e-3, 1e5, true),
        par("twist_stiffness_theta_Nm_per_rad", "N·m/rad", 1.5 * d.k_torque_high_Nm_per_rad, 1e-3, 1e5, true)},
       {},
       false,
       // the twist and the bending add on each tilt diagonal: with the twist, the
       // bending is the design's
       {"bending_scale_psi", "bending_scale_theta"}},
      {"com_offset", "platform centre-of-mass and stiffness-centre offsets, product of inertia",
       "M_psi,z = m_p c_y, M_theta,z += m_p c_x, M_psi,theta = J_psitheta; the rods' vertical stiffness acts about "
       "(e_x, e_y): K_psi,z = k_linear e_y, K_theta,z = k_linear e_x (+ k_linear e² on the tilts)",
       "off-diagonal (coupling) errors between the tilts and z (growing with frequency: mass; flat: stiffness) or "
       "between the two tilts",
       {par("com_x_m", "m", 0.0, -0.05, 0.05, true), par("com_y_m", "m", 0.0, -0.05, 0.05, true),
        par("J_psitheta_kgm2", "kg·m²", 0.0, -0.05, 0.05, true),
        par("stiffness_centre_x_m", "m", 0.0, -0.05, 0.05, true),
        par("stiffness_centre_y_m", "m", 0.0, -0.05, 0.05, true)},
       {},
       false,
       {}},
      {"beam_gravity", "gravity stiffness -z_b m_b g of the raised beam (eq 4)",
       "adds -z_b m_b g to the two tilt diagonals of K",
       "a small low-frequency tilt gain error (softer tilts)",
       {par("gravity_m_per_s2", "m/s²", d.gravity_m_per_s2, 0.0, 20.0, false)},
       {},
       false,
       {}},
  };
  b.compile = [](ModelLayout& layout, const PhysicalModel& model) { layout.platform.emplace(model); };
  b.check_schedule = check_platform_beam_position;
  return b;
}

PlatformIndices::PlatformIndices(const PhysicalModel& model) {
  J_psi = at(model, "J_psi_kgm2");
  J_theta = at(model, "J_theta_kgm2");
  m_p = at(model, "platform_mass_kg");
  m_b = at(model, "beam_mass_kg");
  z_b = at(model, "beam_height_m");
  stroke = at(model, "beam_stroke_m");
  d_psi = at(model, "damping_psi_Nms_per_rad");
  d_theta = at(model, "damping_theta_Nms_per_rad");
  d_z = at(model, "damping_z_Ns_per_m");
  rho_pt = at(model, "damping_coupling_psi_theta");
  rho_pz = at(model, "damping_coupling_psi_z");
  rho_tz = at(model, "damping_coupling_theta_z");
  k_lin = at(model, "k_linear_N_per_m");
  k_low = at(model, "k_torque_low_Nm_per_rad");
  rod[0] = at(model, "rod_axis_angle_1_rad");
  rod[1] = at(model, "rod_axis_angle_2_rad");
  rod[2] = at(model, "rod_axis_angle_3_rad");
  s_psi = at(model, "bending_scale_psi");
  s_theta = at(model, "bending_scale_theta");
  s_pt = at(model, "bending_coupling");
  tw_psi = at(model, "twist_stiffness_psi_Nm_per_rad");
  tw_theta = at(model, "twist_stiffness_theta_Nm_per_rad");
  com_x = at(model, "com_x_m");
  com_y = at(model, "com_y_m");
  J_pt = at(model, "J_psitheta_kgm2");
  sc_x = at(model, "stiffness_centre_x_m");
  sc_y = at(model, "stiffness_centre_y_m");
  g = at(model, "gravity_m_per_s2");
  for (Index i : {J_psi, J_theta, m_p, m_b, z_b, stroke, d_psi, d_theta, d_z, rho_pt, rho_pz, rho_tz, k_lin, k_low,
                  rod[0], rod[1], rod[2],
                  s_psi, s_theta, s_pt})
    LPVID_ASSERT(i >= 0);  // validate() guarantees the base's parameters
}

PhysicalModel platform_defaults_model() {
  PhysicalModel m = PhysicalModel::bare("platform");
  m.add_effect("rod_twist");
  m.add_effect("com_offset");
  m.add_effect("beam_gravity");
  m.parameter("J_psitheta_kgm2").value = PlatformParameters::defaults().J_psitheta_kgm2;
  return m;
}

void check_platform_beam_position(const PhysicalModel& model, double beam_position_m) {
  const double stroke = model.parameter("beam_stroke_m").value;
  if (!std::isfinite(beam_position_m) || std::abs(beam_position_m) > stroke)
    throw InputError(fmt::format(
        "beam position x_b = {} m is outside the stroke |x_b| <= beam_stroke_m = {} m; give x_b in metres "
        "(e.g. -0.1, 0, 0.1) or raise beam_stroke_m",
        beam_position_m, stroke));
}

PlatformParameters platform_parameters(const PhysicalModel& model, std::vector<std::string>* blocks_left_out) {
  model.validate();
  if (model.base != "platform")
    throw InputError(fmt::format("the model's base is '{}', not 'platform'; give a platform model", model.base));
  auto v = [&](const char* name) { return model.parameter(name).value; };
  PlatformParameters pp;
  pp.J_psi_kgm2 = v("J_psi_kgm2");
  pp.J_theta_kgm2 = v("J_theta_kgm2");
  pp.platform_mass_kg = v("platform_mass_kg");
  pp.beam_mass_kg = v("beam_mass_kg");
  pp.beam_height_m = v("beam_height_m");
  pp.beam_stroke_m = v("beam_stroke_m");
  pp.k_linear_N_per_m = v("k_linear_N_per_m");
  pp.k_torque_low_Nm_per_rad = v("k_torque_low_Nm_per_rad");
  pp.k_torque_high_Nm_per_rad = 0.0;  // twist, bending tolerance, stiffness centre: in stiffness_extra
  pp.rod_axis_angles_rad = {v("rod_axis_angle_1_rad"), v("rod_axis_angle_2_rad"), v("rod_axis_angle_3_rad")};
  const bool com = model.has_effect("com_offset");
  pp.com_x_m = com ? v("com_x_m") : 0.0;
  pp.com_y_m = com ? v("com_y_m") : 0.0;
  pp.J_psitheta_kgm2 = com ? v("J_psitheta_kgm2") : 0.0;
  pp.gravity_m_per_s2 = model.has_effect("beam_gravity") ? v("gravity_m_per_s2") : 0.0;
  const PlatformIndices L(model);
  const Eigen::VectorXd p = model.values();
  double M[3][3], D[3][3], K[3][3];
  platform_matrices<double>(L, p.data(), 0.0, M, D, K);
  Eigen::Matrix3d Km;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) Km(i, j) = K[i][j];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) pp.damping_override(i, j) = D[i][j];
  pp.stiffness_extra = Km - stiffness_matrix(pp);
  if (blocks_left_out != nullptr) {
    blocks_left_out->clear();
    for (const std::string& e : model.effects)
      if (!model.effect_info(e)->blocks.empty()) blocks_left_out->push_back(e);
  }
  return pp;
}

}  // namespace lpvid
