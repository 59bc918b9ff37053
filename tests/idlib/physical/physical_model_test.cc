#include "idlib/physical/physical_model.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "idlib/core/error.h"
#include "idlib/physical/platform/platform_base.h"

namespace lpvid {
namespace physical_model_test {

using ::testing::HasSubstr;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string error_of(const PhysicalModel& m) {
  return error_of([&] { m.validate(); });
}

TEST(PhysicalModel, InitialPlatformIsTheBaseWithBeamGravityAndValid) {
  const PhysicalModel m = PhysicalModel::initial("platform");
  EXPECT_NO_THROW(m.validate());
  EXPECT_EQ(m.effects, std::vector<std::string>{"beam_gravity"});
  EXPECT_EQ(m.parameters.size(), base_info("platform").parameters.size() + 1);
}

TEST(PhysicalModel, UnknownBaseIsInputErrorListingTheBases) {
  EXPECT_THAT(error_of([] { PhysicalModel::bare("stage9"); }), HasSubstr("the bases are \"platform\""));
}

TEST(PhysicalModel, LibraryEffectsAreDocumentedWithValidDefaultsAndAllCanBeAddedTogether) {
  PhysicalModel all = PhysicalModel::bare("platform");
  for (const EffectInfo& e : effect_library("platform")) {
    EXPECT_FALSE(e.description.empty()) << e.name;
    EXPECT_FALSE(e.changes.empty()) << e.name;
    EXPECT_FALSE(e.signature.empty()) << e.name;
    EXPECT_FALSE(e.parameters.empty()) << e.name;
    all.add_effect(e.name);
  }
  EXPECT_NO_THROW(all.validate());
  // the library: the platform's physics effects, then the shared block effects
  std::vector<std::string> names;
  for (const EffectInfo& e : effect_library("platform")) names.push_back(e.name);
  EXPECT_EQ(names, (std::vector<std::string>{"rod_twist", "com_offset", "beam_gravity", "structural_mode",
                                             "input_delay", "actuator_lag", "gain_error", "sensor_gain",
                                             "sensor_crosstalk"}));
}

TEST(PhysicalModel, RemoveEffectDropsExactlyItsParameters) {
  PhysicalModel m = PhysicalModel::initial();
  m.add_effect("input_delay");
  m.add_effect("com_offset");
  m.parameter("J_psi_kgm2").value = 0.07;
  m.remove_effect("input_delay");
  EXPECT_EQ(m.effects, (std::vector<std::string>{"beam_gravity", "com_offset"}));
  EXPECT_EQ(m.index_of("input_delay_s"), -1);
  EXPECT_EQ(m.parameter("J_psi_kgm2").value, 0.07);
  EXPECT_NO_THROW(m.validate());
  EXPECT_THAT(error_of([&] { m.remove_effect("input_delay"); }), HasSubstr("no effect 'input_delay' to remove"));
}

// A design value for an effect the model lacks (a datasheet's coil L/R with its
// uncertainty): kept aside, the effect starts from it when added (value, prior,
// free flag), and a removed effect's prior is kept for when it comes back.
TEST(PhysicalModel, ADesignValueOfAnAbsentEffectIsWhereTheEffectStartsAndOutlivesItsRemoval) {
  PhysicalModel m = PhysicalModel::initial();
  PhysicalParameter& tau = m.parameter_or_design_value("actuator_time_constant_s");
  tau.value = tau.prior_mean = 5e-5;
  tau.prior_sigma = 2e-5;
  EXPECT_EQ(m.index_of("actuator_time_constant_s"), -1);
  ASSERT_EQ(m.design_values.size(), 1u);
  EXPECT_NO_THROW(m.validate());
  EXPECT_EQ(&m.parameter_or_design_value("actuator_time_constant_s"), &m.design_values.front());  // not twice
  m.add_effect("actuator_lag");
  EXPECT_TRUE(m.design_values.empty());
  EXPECT_EQ(m.parameter("actuator_time_constant_s").value, 5e-5);
  EXPECT_EQ(m.parameter("actuator_time_constant_s").prior_sigma, 2e-5);
  m.parameter("actuator_time_constant_s").value = 6e-5;  // as a fit leaves it
  m.remove_effect("actuator_lag");
  ASSERT_EQ(m.design_values.size(), 1u);
  EXPECT_EQ(m.design_values.front().prior_mean, 5e-5);
  m.add_effect("actuator_lag");
  EXPECT_EQ(m.parameter("actuator_time_constant_s").value, 6e-5);
  // a removed effect without a prior leaves nothing behind
  m.add_effect("input_delay");
  m.remove_effect("input_delay");
  EXPECT_TRUE(m.design_values.empty());
  // names neither the model nor an absent effect has, and broken rules
  EXPECT_THAT(error_of([&] { m.parameter_or_design_value("no_such_s"); }),
              HasSubstr("no effect it could add has one"));
  PhysicalModel bad = PhysicalModel::initial();
  bad.design_values.push_back(bad.parameter("platform_mass_kg"));
  EXPECT_THAT(error_of([&] { bad.validate(); }), HasSubstr("is a parameter the model has"));
  bad.design_values.clear();
  bad.parameter_or_design_value("input_delay_s").value = 1.0;  // beyond its 0.02 s bound
  EXPECT_THAT(error_of([&] { bad.validate(); }), HasSubstr("outside its bounds"));
  bad.design_values.front().value = 1e-3;
  bad.design_values.push_back(bad.design_values.front());
  EXPECT_THAT(error_of([&] { bad.validate(); }), HasSubstr("given twice"));
}

TEST(PhysicalModel, RodTwistHoldsTheBendingScalesAtTheDesignAndRemovingItFreesThem) {
  PhysicalModel m = PhysicalModel::initial();
  m.parameter("bending_scale_psi").value = 1.7;
  m.add_effect("rod_twist");
  EXPECT_EQ(m.parameter("bending_scale_psi").value, 1.0);
  EXPECT_FALSE(m.parameter("bending_scale_psi").free);
  EXPECT_FALSE(m.parameter("bending_scale_theta").free);
  m.remove_effect("rod_twist");
  EXPECT_TRUE(m.parameter("bending_scale_psi").free);
}

TEST(PhysicalModel, AddingUnknownOrRepeatedEffectIsInputError) {
  PhysicalModel m = PhysicalModel::initial();
  EXPECT_THAT(error_of([&] { m.add_effect("friction"); }), HasSubstr("unknown effect 'friction'"));
  EXPECT_THAT(error_of([&] { m.add_effect("beam_gravity"); }), HasSubstr("already in the model"));
}

TEST(PhysicalModel, ValidateNamesTheBrokenRule) {
  PhysicalModel m = PhysicalModel::initial();
  m.parameter("damping_z_Ns_per_m").lower = 100.0;
  m.parameter("damping_z_Ns_per_m").upper = 10.0;
  EXPECT_THAT(error_of(m), HasSubstr("bounds reversed"));

  m = PhysicalModel::initial();
  m.parameter("bending_scale_psi").value = 3.0;
  EXPECT_THAT(error_of(m), HasSubstr("outside its bounds"));

  m = PhysicalModel::initial();
  m.parameters.push_back({"spring_kN", "N/m", 1, 0, 2, false});
  EXPECT_THAT(error_of(m), HasSubstr("unknown parameter 'spring_kN'"));

  m = PhysicalModel::initial();
  m.parameter("beam_mass_kg").unit = "g";
  EXPECT_THAT(error_of(m), HasSubstr("its unit is 'kg'"));

  m = PhysicalModel::initial();
  m.parameters.erase(m.parameters.begin());
  EXPECT_THAT(error_of(m), HasSubstr("missing parameter 'J_psi_kgm2'"));

  m = PhysicalModel::bare();
  m.parameters.push_back(find_effect("platform", "input_delay")->parameters[0]);
  EXPECT_THAT(error_of(m), HasSubstr("belongs to effect 'input_delay'"));
}

EffectInfo sensor_mount() {
  EffectInfo e;
  e.name = "theta_mount";
  e.description = "a resonance of the theta sensor's mount";
  e.parameters = {{"mount_wp_rad_s", "rad/s", 800, 300, 3000, true},
                  {"mount_zp", "1", 0.05, 1e-3, 0.7, true},
                  {"mount_wz_rad_s", "rad/s", 900, 300, 3000, true},
                  {"mount_zz", "1", 0.1, 1e-3, 0.7, true}};
  e.blocks = {{BlockKind::kResonance, BlockSide::kOutput, {"theta"},
               {"mount_wp_rad_s", "mount_zp", "mount_wz_rad_s", "mount_zz"}}};
  return e;
}

TEST(PhysicalModel, UserDefinedEffectIsDefinedAddedAndRemovedLikeALibraryEffect) {
  PhysicalModel m = PhysicalModel::initial();
  m.define_effect(sensor_mount());
  EXPECT_EQ(m.absent_effects().back(), "theta_mount");
  m.add_effect("theta_mount");
  EXPECT_NO_THROW(m.validate());
  EXPECT_TRUE(m.effect_info("theta_mount")->user_defined);
  EXPECT_EQ(m.parameter("mount_zz").value, 0.1);
  m.remove_effect("theta_mount");
  EXPECT_NO_THROW(m.validate());
}

TEST(PhysicalModel, UserDefinitionsBreakingABlockRuleAreInputErrors) {
  auto define = [](EffectInfo e) {
    return error_of([&] {
      PhysicalModel m = PhysicalModel::initial();
      m.define_effect(e);
    });
  };
  EffectInfo e = sensor_mount();
  e.name = "input_delay";
  EXPECT_THAT(define(e), HasSubstr("the library already has an effect of that name"));
  e = sensor_mount();
  e.blocks[0].channels = {"phi"};
  EXPECT_THAT(define(e), HasSubstr("channel 'phi' is not an output of base 'platform'; its outputs are psi, theta, z"));
  e = sensor_mount();
  e.blocks[0].parameters.pop_back();
  EXPECT_THAT(define(e), HasSubstr("a resonance block takes 4 parameter(s) (rad/s, 1, rad/s, 1), got 3"));
  e = sensor_mount();
  e.parameters[0].unit = "Hz";
  EXPECT_THAT(define(e), HasSubstr("parameter 'mount_wp_rad_s' has unit 'Hz' but its place in the resonance block "
                                   "takes 'rad/s'"));
  e = sensor_mount();
  e.parameters.push_back({"unused", "1", 0, -1, 1, true});
  EXPECT_THAT(define(e), HasSubstr("parameter 'unused' is declared but no block uses it"));
  e = sensor_mount();
  e.blocks[0].kind = BlockKind::kDelay;
  EXPECT_THAT(define(e), HasSubstr("a delay block cannot sit on the output side"));
  e = sensor_mount();
  e.parameters[0].name = "J_psi_kgm2";
  EXPECT_THAT(define(e), HasSubstr("is a parameter of the base"));
}

TEST(PhysicalModel, CouplingBlockUnitIsTheRatioOfItsChannelsUnits) {
  const BaseInfo& b = base_info("platform");
  EXPECT_EQ(block_parameter_units(b, {BlockKind::kCoupling, BlockSide::kOutput, {"psi", "z"}, {"c"}}),
            std::vector<std::string>{"m/rad"});
  EXPECT_EQ(block_parameter_units(b, {BlockKind::kCoupling, BlockSide::kInput, {"T_psi", "T_theta"}, {"c"}}),
            std::vector<std::string>{"1"});
  EXPECT_EQ(block_parameter_units(b, {BlockKind::kMode, BlockSide::kBody, {}, {}}),
            (std::vector<std::string>{"rad/s", "1", "1/(kg^0.5·m)", "1/(kg^0.5·m)", "1/kg^0.5"}));
}

TEST(PhysicalModel, PlatformParametersCarryTheGeneralisedStiffnessAndDamping) {
  PhysicalModel m = PhysicalModel::initial();
  m.add_effect("rod_twist");
  m.parameter("bending_scale_psi").value = 1.5;
  m.parameter("damping_theta_Nms_per_rad").value = 2.5;
  const PlatformParameters pp = platform_parameters(m);
  const Eigen::Matrix3d K = stiffness_matrix(pp), D = damping_matrix(pp);
  EXPECT_EQ(D(0, 1), 0.0);
  // 1.5 × the designed bending (1.5 k_low for rods 120° apart) + twist − gravity
  const double kb = 1.5 * m.parameter("k_torque_low_Nm_per_rad").value;
  const double grav = m.parameter("beam_height_m").value * m.parameter("beam_mass_kg").value * 9.81;
  EXPECT_NEAR(K(0, 0), 1.5 * kb + m.parameter("twist_stiffness_psi_Nm_per_rad").value - grav, 1e-9);
  EXPECT_NEAR(K(1, 1), kb + m.parameter("twist_stiffness_theta_Nm_per_rad").value - grav, 1e-9);
  EXPECT_EQ(D(1, 1), 2.5);
}

}  // namespace physical_model_test
}  // namespace lpvid
