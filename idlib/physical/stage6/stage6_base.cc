#include "idlib/physical/stage6/stage6_base.h"

#include <fmt/format.h>

#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"
#include "idlib/plants/stage6/stage6.h"

namespace lpvid {
namespace {

PhysicalParameter par(std::string name, const char* unit, double value, double lower, double upper, bool free) {
  return PhysicalParameter{std::move(name), unit, value, lower, upper, free};
}

std::string arm_name(int motor, int axis) { return fmt::format("lever_arm_{}_{}_m", motor + 1, "xyz"[axis]); }

}  // namespace

BaseInfo make_stage6_base() {
  const stage6::StageParameters d;
  BaseInfo b;
  b.name = "stage6";
  b.time_route = BaseInfo::TimeRoute::kStageOutputError;
  b.description =
      "the 6-DOF maglev stage of seed 001 (eqs 1–30) linearised about hover, inputs the commanded body wrench; "
      "scheduled by the hover height above the reference gap";
  b.parameters = {
      // weighed; only H/m and kappa/m are identifiable (header comment)
      par("mass_kg", "kg", d.mass_kg, 0.01, 1e3, false),
      par("inertia_xx_kgm2", "kg·m²", d.inertia_kgm2(0, 0), 1e-6, 1e3, true),
      par("inertia_yy_kgm2", "kg·m²", d.inertia_kgm2(1, 1), 1e-6, 1e3, true),
      par("inertia_zz_kgm2", "kg·m²", d.inertia_kgm2(2, 2), 1e-6, 1e3, true),
      // the true force constant over the one the controller allocates with
      par("force_constant_scale", "1", 1.0, 0.05, 20.0, true),
      par("gravity_m_per_s2", "m/s²", stage6::kGravity_m_per_s2, 0.0, 20.0, false),
      // The attitude the stage hovers at: a controller without integral action
      // (the sliding-mode law) holds it off zero (measured ~1 mrad in pitch); the
      // lift then leaks into the horizontal axes (x ← F_z ∝ theta0).  Identifiable
      // from those couplings; free.
      par("hover_yaw_rad", "rad", 0.0, -0.05, 0.05, true),
      par("hover_pitch_rad", "rad", 0.0, -0.05, 0.05, true),
      par("hover_roll_rad", "rad", 0.0, -0.05, 0.05, true),
  };
  // The designed lever arms (body axes, from the centre of mass to each magnet
  // array's force centre): the geometry the controller allocates with.
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a)
      b.parameters.push_back(par(arm_name(i, a), "m", d.lever_arms_m(a, i), -2.0, 2.0, false));
  // generalised order: input k drives output k (stage6_base.h)
  b.input_names = {"F_x", "F_y", "F_z", "tau_z", "tau_y", "tau_x"};
  b.input_units = {"N", "N", "N", "N·m", "N·m", "N·m"};
  b.output_names = {"x", "y", "z", "psi", "theta", "phi"};
  b.output_units = {"m", "m", "m", "rad", "rad", "rad"};
  b.dof_names = {"x", "y", "z", "psi", "theta", "phi"};
  b.dof_units = b.output_units;
  b.schedule_name = "hover height z_0 above the reference gap";
  b.schedule_unit = "m";
  b.schedule_symbol = "z_0";
  b.default_effects = {};
  b.physics_effects = {
      {"com_offset", "centre-of-mass offset c from the reference point the allocation's arms are measured from and the sensors "
       "look at (body axes)",
       "every true lever arm is r_i − c while the controller allocates with r_i: B_w = G₀ kappa A(r − c) A(r)⁺ "
       "(commanded forces leak into torques and torques into other torques); the sensors see p − R c, so the "
       "rotations appear in the measured translations",
       "off-diagonal errors between the forces and the tilts (and between the tilts), flat in frequency relative to "
       "the diagonal: a wrench channel produces a little of another, and the tilts show in x, y, z",
       {par("com_x_m", "m", 0.0, -0.05, 0.05, true), par("com_y_m", "m", 0.0, -0.05, 0.05, true),
        par("com_z_m", "m", 0.0, -0.05, 0.05, true)},
       {},
       false,
       {}},
      {"gap_dependence", "gap-dependent force constant alpha(z) = exp(−gamma (gap − z_ref)) of the magnet arrays (eq 20)",
       "the hover lift changes with each array's gap: a stiffness G₀ kappa gamma alpha₀ A(r − c) diag(f₀) J on z and "
       "the two tilts (the platen is held towards the reference gap), and the gain alpha₀ = exp(−gamma z₀) away from "
       "it",
       "z and tilt (theta, phi) responses too soft at low frequency: a resonance-like flattening where the model "
       "keeps falling as 1/omega²",
       {par("gap_decay_per_m", "1/m", d.gamma_per_m(), 1.0, 1e4, true)},
       {},
       false,
       {}},
      {"electrical_lag",
       "d-q current loop of the motors (eq 25): first-order lag tau_e = L/(R + k_c) and the back-EMF damping b = "
       "k_f k_e/(R + k_c) it feeds back",
       "inserts 1/(tau_e s + 1) on every input and feeds each magnet array's own velocity (translation plus "
       "omega × arm) back into the current loop (w − F q'): damping of the translations and rotations below "
       "1/tau_e, lag above",
       "translation and rotation responses flattened (damped) at low frequency and all channels lagging near and "
       "above 1/tau_e",
       {par("electrical_time_constant_s", "s", d.electrical_time_constant_s(), 1e-6, 0.1, true),
        par("back_emf_damping_Ns_per_m", "N·s/m",
            d.force_constant_N_per_A * d.force_constant_N_per_A / (d.resistance_ohm + d.current_loop_gain_V_per_A),
            1e-3, 1e5, true)},
       {{BlockKind::kFirstOrder, BlockSide::kInput, {}, {"electrical_time_constant_s"}}},
       false,
       {}},
  };
  b.compile = [](ModelLayout& layout, const PhysicalModel& model) { layout.stage6.emplace(model); };
  b.check_schedule = [](const PhysicalModel&, double z0_m) { check_stage6_hover_height(z0_m); };
  return b;
}

Stage6Indices::Stage6Indices(const PhysicalModel& model) {
  mass = model.index_of("mass_kg");
  I_xx = model.index_of("inertia_xx_kgm2");
  I_yy = model.index_of("inertia_yy_kgm2");
  I_zz = model.index_of("inertia_zz_kgm2");
  kappa = model.index_of("force_constant_scale");
  g = model.index_of("gravity_m_per_s2");
  Eigen::Matrix<double, 3, 4> r;
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a) {
      arm[i][a] = model.index_of(arm_name(i, a));
      LPVID_ASSERT(arm[i][a] >= 0);  // validate() guarantees the base's parameters
      r(a, i) = model.parameters[static_cast<std::size_t>(arm[i][a])].value;
    }
  com[0] = model.index_of("com_x_m");
  com[1] = model.index_of("com_y_m");
  com[2] = model.index_of("com_z_m");
  gamma = model.index_of("gap_decay_per_m");
  back_emf = model.index_of("back_emf_damping_Ns_per_m");
  attitude[0] = model.index_of("hover_yaw_rad");
  attitude[1] = model.index_of("hover_pitch_rad");
  attitude[2] = model.index_of("hover_roll_rad");
  for (Index i : {mass, I_xx, I_yy, I_zz, kappa, g, attitude[0], attitude[1], attitude[2]}) LPVID_ASSERT(i >= 0);
  allocation_pinv = stage6::allocation_pseudo_inverse(r);  // @throws InputError: a degenerate geometry
}

PhysicalModel stage6_defaults_model() { return PhysicalModel::bare("stage6"); }

void check_stage6_hover_height(double z0_m) {
  constexpr double kMaxHeight_m = 1e-3;
  if (!std::isfinite(z0_m) || std::abs(z0_m) > kMaxHeight_m)
    throw InputError(fmt::format(
        "hover height z_0 = {} m above the reference gap is outside |z_0| <= {} m; give it in metres (0 = hovering "
        "at the reference gap)",
        z0_m, kMaxHeight_m));
}

}  // namespace lpvid
