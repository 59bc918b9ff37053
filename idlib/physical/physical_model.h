// lpvid — physical (grey-box) models: a base model plus a list of effects, each
// effect a small documented unit with named parameters (docs/effects.md).
//
// A PhysicalModel is a flat list of parameters, each {name, unit, value,
// lower, upper, free}: first the base ("platform", seed 000 eqs 2–8), then the
// parameters of each enabled effect in the order the effects were added.  The
// names are globally unique (an effect never reuses a base name), so a
// parameter is addressed by its name alone; its unit is part of its name
// (STYLE.md item 2) and also stored as text for the model file.
//
// Base "platform" parameters (PlatformParameters fields of idlib/models/platform.h):
//   J_psi_kgm2, J_theta_kgm2, platform_mass_kg, beam_mass_kg, beam_height_m,
//   beam_stroke_m, coil_arm_m, coil_damping_Ns_per_m, k_linear_N_per_m,
//   k_torque_low_Nm_per_rad, rod_axis_angle_1_rad .. rod_axis_angle_3_rad.
// The terms of PlatformParameters that belong to an effect are zero while that
// effect is off: k_torque_high (rod_twist), com_x, com_y, J_psitheta
// (com_offset), the gravity stiffness -z_b m_b g (beam_gravity).
//
// Default free set (the parameters plant FRDs at several x_b can separate;
// docs/effects.md, "Identifiability"): J_psi, J_theta, m_p, m_b, d, k_linear,
// and each effect's own parameters except g.  Fixed: z_b (it enters M only as
// J + m_b z_b² and K only as k - z_b m_b g, both inseparable from the inertias
// and stiffnesses), r_vc (the coil pitch is geometry; with d free it is
// separable only through the tilt/z damping ratio), the rod angles, the stroke,
// k_torque_low (the designed leaf-spring bending stiffness; with three rods
// 120° apart only k_torque_low + k_torque_high enters K) and g.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "idlib/core/types.h"
#include "idlib/models/platform.h"

namespace lpvid {

struct PhysicalParameter {
  std::string name;  // unique in a model, unit suffix included (e.g. "coil_damping_Ns_per_m")
  std::string unit;  // as text, e.g. "N·s/m"; "1" for dimensionless
  double value = 0.0;
  double lower = 0.0;  // bounds, lower <= value <= upper, both finite
  double upper = 0.0;
  bool free = false;  // estimated by fit, else held at value
};

// One entry of the effect library.
struct EffectInfo {
  std::string name;         // e.g. "input_delay"
  std::string description;  // one line
  std::string changes;      // how it changes the model (one or two sentences)
  std::string signature;    // the residual signature it explains
  std::vector<PhysicalParameter> parameters;  // with their defaults and bounds
};

// The name of the only base model there is so far.
inline constexpr const char* kPlatformBase = "platform";

// The base parameters with their defaults (PlatformParameters::defaults(),
// docs/assumptions.md), units, bounds and default free flags.
const std::vector<PhysicalParameter>& platform_base_parameters();

// The effect library, in a fixed order: structural_mode, input_delay,
// actuator_lag, gain_error, rod_twist, com_offset, beam_gravity.
const std::vector<EffectInfo>& effect_library();

// The library entry of name, or nullptr.
const EffectInfo* find_effect(const std::string& name);

struct PhysicalModel {
  std::string base = kPlatformBase;
  std::vector<PhysicalParameter> parameters;  // base first, then each effect's
  std::vector<std::string> effects;           // enabled effects, in order

  // The base model alone (no effect).
  static PhysicalModel bare_platform();
  // The base model with rod_twist, com_offset and beam_gravity: the same
  // physics as platform_model(PlatformParameters::defaults(), x_b).
  static PhysicalModel default_platform();

  // Adds the effect with its library defaults.
  // @throws InputError  unknown effect (the message lists the library); already enabled.
  void add_effect(const std::string& name);

  bool has_effect(const std::string& name) const;
  // Index into parameters, or -1.
  Index index_of(const std::string& name) const;
  // @throws InputError  unknown parameter name (the message lists the model's names).
  const PhysicalParameter& parameter(const std::string& name) const;
  PhysicalParameter& parameter(const std::string& name);

  Eigen::VectorXd values() const;
  std::vector<Index> free_indices() const;

  // Every rule a model file can break, as InputError naming the parameter:
  // base is "platform"; effects known and not repeated; the parameter list is
  // exactly the base's plus each effect's (no unknown, none missing, none
  // twice); unit equals the library unit; value and bounds finite;
  // lower <= upper; lower <= value <= upper.
  void validate() const;
};

// The PlatformParameters equivalent of model (effects off -> their terms 0).
// Effects with no PlatformParameters counterpart (structural_mode, input_delay,
// actuator_lag, gain_error) are ignored here.  @throws InputError as validate().
PlatformParameters to_platform_parameters(const PhysicalModel& model);

}  // namespace lpvid
