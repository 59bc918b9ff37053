#include "idlib/physical/physical_model.h"

#include <fmt/format.h>

#include <cmath>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

PhysicalParameter p(const char* name, const char* unit, double value, double lower, double upper, bool free) {
  return PhysicalParameter{name, unit, value, lower, upper, free};
}

std::vector<PhysicalParameter> make_base() {
  const PlatformParameters d = PlatformParameters::defaults();
  // Bounds: wide physical ranges around the documented defaults
  // (docs/assumptions.md), so that a start 2x off and the global start's
  // search box both lie inside; positive quantities have positive lower bounds
  // (the fit works on their logarithm).
  return {
      p("J_psi_kgm2", "kg·m²", d.J_psi_kgm2, 1e-4, 10.0, true),
      p("J_theta_kgm2", "kg·m²", d.J_theta_kgm2, 1e-4, 10.0, true),
      p("platform_mass_kg", "kg", d.platform_mass_kg, 0.1, 100.0, true),
      p("beam_mass_kg", "kg", d.beam_mass_kg, 0.01, 20.0, true),
      p("beam_height_m", "m", d.beam_height_m, -0.5, 0.5, false),
      p("beam_stroke_m", "m", d.beam_stroke_m, 1e-3, 1.0, false),
      p("coil_arm_m", "m", d.coil_arm_m, 1e-3, 1.0, false),
      p("coil_damping_Ns_per_m", "N·s/m", d.coil_damping_Ns_per_m, 1e-3, 1e4, true),
      p("k_linear_N_per_m", "N/m", d.k_linear_N_per_m, 1.0, 1e7, true),
      p("k_torque_low_Nm_per_rad", "N·m/rad", d.k_torque_low_Nm_per_rad, 0.0, 1e5, false),
      p("rod_axis_angle_1_rad", "rad", d.rod_axis_angles_rad[0], -7.0, 7.0, false),
      p("rod_axis_angle_2_rad", "rad", d.rod_axis_angles_rad[1], -7.0, 7.0, false),
      p("rod_axis_angle_3_rad", "rad", d.rod_axis_angles_rad[2], -7.0, 7.0, false),
  };
}

std::vector<EffectInfo> make_library() {
  const PlatformParameters d = PlatformParameters::defaults();
  return {
      {"structural_mode", "an extra lightly damped (non-rigid) mode above ~400 rad/s",
       "adds phi phiᵀ / (s² + 2 zeta w s + w²) to P (collocated, driven by the same wrench); 2 states",
       "a narrow peak/notch pair in several channels at one frequency, above the rigid-body band",
       {p("mode_frequency_rad_s", "rad/s", 600.0, 300.0, 6000.0, true),
        p("mode_damping", "1", 0.02, 1e-4, 0.7, true),
        p("mode_shape_psi", "1/(kg^0.5·m)", 1.0, -100.0, 100.0, true),
        p("mode_shape_theta", "1/(kg^0.5·m)", 1.0, -100.0, 100.0, true),
        p("mode_shape_z", "1/kg^0.5", 0.3, -100.0, 100.0, true)}},
      {"input_delay", "pure delay tau on all inputs (computation + ZOH half-sample)",
       "multiplies P by exp(-j w tau): magnitude unchanged, phase -w tau",
       "a phase lag growing linearly with frequency in every channel, magnitude fits",
       {p("input_delay_s", "s", 5e-4, 0.0, 0.02, true)}},
      {"actuator_lag", "first-order coil current lag 1/(tau_a s + 1), tau_a = L/R (seed 001 eqs 10–13)",
       "inserts 1/(tau_a s + 1) on each of the three inputs; 3 states",
       "magnitude roll-off and phase lag near and above 1/tau_a in every channel",
       {p("actuator_time_constant_s", "s", 5e-4, 1e-6, 0.1, true)}},
      {"gain_error", "per-DOF actuator gain (e.g. the 1.5 of eq 9's printed z row)",
       "multiplies input j of P by g_j: P -> P diag(g_psi, g_theta, g_z)",
       "a frequency-independent magnitude ratio in the columns of one input",
       {p("gain_psi", "1", 1.0, 0.05, 20.0, true), p("gain_theta", "1", 1.0, 0.05, 20.0, true),
        p("gain_z", "1", 1.0, 0.05, 20.0, true)}},
      {"rod_twist", "torsional stiffness of the suspension rods (k_torque_high, Fig. 7)",
       "adds k_torque_high s_j s_jᵀ per rod to the tilt block of K",
       "a low-frequency gain error and a too-low resonance in the tilt channels",
       {p("k_torque_high_Nm_per_rad", "N·m/rad", d.k_torque_high_Nm_per_rad, 1e-3, 1e5, true)}},
      {"com_offset", "platform centre-of-mass offsets and product of inertia",
       "M(0,2) = m_p c_y, M(1,2) += m_p c_x, M(0,1) = J_psitheta",
       "off-diagonal (coupling) error between the tilts and z, or between the two tilts",
       {p("com_x_m", "m", d.com_x_m, -0.05, 0.05, true), p("com_y_m", "m", d.com_y_m, -0.05, 0.05, true),
        p("J_psitheta_kgm2", "kg·m²", d.J_psitheta_kgm2, -0.05, 0.05, true)}},
      {"beam_gravity", "gravity stiffness -z_b m_b g of the raised beam",
       "adds -z_b m_b g to the two tilt diagonals of K",
       "a small low-frequency tilt gain error (softer tilts)",
       {p("gravity_m_per_s2", "m/s²", d.gravity_m_per_s2, 0.0, 20.0, false)}},
  };
}

std::string library_names() {
  std::string names;
  for (const auto& e : effect_library()) names += (names.empty() ? "" : ", ") + e.name;
  return names;
}

}  // namespace

const std::vector<PhysicalParameter>& platform_base_parameters() {
  static const std::vector<PhysicalParameter> base = make_base();
  return base;
}

const std::vector<EffectInfo>& effect_library() {
  static const std::vector<EffectInfo> library = make_library();
  return library;
}

const EffectInfo* find_effect(const std::string& name) {
  for (const auto& e : effect_library())
    if (e.name == name) return &e;
  return nullptr;
}

PhysicalModel PhysicalModel::bare_platform() {
  PhysicalModel m;
  m.parameters = platform_base_parameters();
  return m;
}

PhysicalModel PhysicalModel::default_platform() {
  PhysicalModel m = bare_platform();
  m.add_effect("rod_twist");
  m.add_effect("com_offset");
  m.add_effect("beam_gravity");
  return m;
}

void PhysicalModel::add_effect(const std::string& name) {
  const EffectInfo* e = find_effect(name);
  if (e == nullptr)
    throw InputError(fmt::format("unknown effect '{}'; the library has {}", name, library_names()));
  if (has_effect(name))
    throw InputError(fmt::format("effect '{}' is already in the model; each effect can be added once", name));
  effects.push_back(name);
  for (const auto& q : e->parameters) parameters.push_back(q);
}

bool PhysicalModel::has_effect(const std::string& name) const {
  for (const auto& e : effects)
    if (e == name) return true;
  return false;
}

Index PhysicalModel::index_of(const std::string& name) const {
  for (std::size_t i = 0; i < parameters.size(); ++i)
    if (parameters[i].name == name) return static_cast<Index>(i);
  return -1;
}

const PhysicalParameter& PhysicalModel::parameter(const std::string& name) const {
  const Index i = index_of(name);
  if (i < 0) {
    std::string names;
    for (const auto& q : parameters) names += (names.empty() ? "" : ", ") + q.name;
    throw InputError(fmt::format("the model has no parameter '{}'; it has {}", name, names));
  }
  return parameters[static_cast<std::size_t>(i)];
}

PhysicalParameter& PhysicalModel::parameter(const std::string& name) {
  return const_cast<PhysicalParameter&>(static_cast<const PhysicalModel&>(*this).parameter(name));
}

Eigen::VectorXd PhysicalModel::values() const {
  Eigen::VectorXd v(static_cast<Index>(parameters.size()));
  for (std::size_t i = 0; i < parameters.size(); ++i) v(static_cast<Index>(i)) = parameters[i].value;
  return v;
}

std::vector<Index> PhysicalModel::free_indices() const {
  std::vector<Index> out;
  for (std::size_t i = 0; i < parameters.size(); ++i)
    if (parameters[i].free) out.push_back(static_cast<Index>(i));
  return out;
}

void PhysicalModel::validate() const {
  if (base != kPlatformBase)
    throw InputError(fmt::format("unknown base model '{}'; the only base is \"platform\"", base));
  // The expected parameter list: base, then each effect's.
  std::vector<const PhysicalParameter*> expected;
  for (const auto& q : platform_base_parameters()) expected.push_back(&q);
  for (std::size_t k = 0; k < effects.size(); ++k) {
    const EffectInfo* e = find_effect(effects[k]);
    if (e == nullptr)
      throw InputError(fmt::format("unknown effect '{}'; the library has {}", effects[k], library_names()));
    for (std::size_t j = 0; j < k; ++j)
      if (effects[j] == effects[k])
        throw InputError(fmt::format("effect '{}' is listed twice; list each effect once", effects[k]));
    for (const auto& q : e->parameters) expected.push_back(&q);
  }
  for (const auto& q : parameters) {
    const PhysicalParameter* lib = nullptr;
    for (const auto* x : expected)
      if (x->name == q.name) lib = x;
    if (lib == nullptr) {
      std::string owner;
      for (const auto& e : effect_library())
        for (const auto& x : e.parameters)
          if (x.name == q.name) owner = e.name;
      throw InputError(owner.empty()
                           ? fmt::format("unknown parameter '{}'; see 'lpvid model effects' for the parameter names",
                                         q.name)
                           : fmt::format("parameter '{}' belongs to effect '{}', which the model does not list; add "
                                         "\"{}\" to \"effects\" or remove the parameter",
                                         q.name, owner, owner));
    }
    if (q.unit != lib->unit)
      throw InputError(fmt::format("parameter '{}' has unit '{}'; its unit is '{}'; convert the value and write that "
                                   "unit",
                                   q.name, q.unit, lib->unit));
    if (!std::isfinite(q.value) || !std::isfinite(q.lower) || !std::isfinite(q.upper))
      throw InputError(fmt::format("parameter '{}': value {}, bounds [{}, {}]; all must be finite numbers", q.name,
                                   q.value, q.lower, q.upper));
    if (q.lower > q.upper)
      throw InputError(fmt::format("parameter '{}': bounds reversed, lower {} > upper {}; swap them", q.name, q.lower,
                                   q.upper));
    if (q.value < q.lower || q.value > q.upper)
      throw InputError(fmt::format("parameter '{}': value {} is outside its bounds [{}, {}]; change the value or the "
                                   "bounds",
                                   q.name, q.value, q.lower, q.upper));
  }
  for (const auto* x : expected) {
    int count = 0;
    for (const auto& q : parameters) count += q.name == x->name ? 1 : 0;
    if (count == 0)
      throw InputError(fmt::format("missing parameter '{}' (unit {}); give it, e.g. its default {}", x->name, x->unit,
                                   x->value));
    if (count > 1) throw InputError(fmt::format("parameter '{}' is given {} times; give it once", x->name, count));
  }
}

PlatformParameters to_platform_parameters(const PhysicalModel& model) {
  model.validate();
  auto v = [&](const char* name) { return model.parameter(name).value; };
  PlatformParameters pp;
  pp.J_psi_kgm2 = v("J_psi_kgm2");
  pp.J_theta_kgm2 = v("J_theta_kgm2");
  pp.platform_mass_kg = v("platform_mass_kg");
  pp.beam_mass_kg = v("beam_mass_kg");
  pp.beam_height_m = v("beam_height_m");
  pp.beam_stroke_m = v("beam_stroke_m");
  pp.coil_arm_m = v("coil_arm_m");
  pp.coil_damping_Ns_per_m = v("coil_damping_Ns_per_m");
  pp.k_linear_N_per_m = v("k_linear_N_per_m");
  pp.k_torque_low_Nm_per_rad = v("k_torque_low_Nm_per_rad");
  pp.rod_axis_angles_rad = {v("rod_axis_angle_1_rad"), v("rod_axis_angle_2_rad"), v("rod_axis_angle_3_rad")};
  pp.k_torque_high_Nm_per_rad = model.has_effect("rod_twist") ? v("k_torque_high_Nm_per_rad") : 0.0;
  const bool com = model.has_effect("com_offset");
  pp.com_x_m = com ? v("com_x_m") : 0.0;
  pp.com_y_m = com ? v("com_y_m") : 0.0;
  pp.J_psitheta_kgm2 = com ? v("J_psitheta_kgm2") : 0.0;
  pp.gravity_m_per_s2 = model.has_effect("beam_gravity") ? v("gravity_m_per_s2") : 0.0;
  return pp;
}

}  // namespace lpvid
