#include "idlib/physical/physical_model.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

using ::testing::HasSubstr;

std::string error_of(const PhysicalModel& m) {
  try {
    m.validate();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(PhysicalModel, DefaultPlatformIsValidAndMatchesPlatformDefaults) {
  const PhysicalModel m = PhysicalModel::default_platform();
  EXPECT_EQ(error_of(m), "");
  const PlatformParameters p = to_platform_parameters(m);
  const PlatformParameters d = PlatformParameters::defaults();
  EXPECT_EQ(p.J_psi_kgm2, d.J_psi_kgm2);
  EXPECT_EQ(p.k_torque_high_Nm_per_rad, d.k_torque_high_Nm_per_rad);
  EXPECT_EQ(p.J_psitheta_kgm2, d.J_psitheta_kgm2);
  EXPECT_EQ(p.gravity_m_per_s2, d.gravity_m_per_s2);
  EXPECT_EQ(p.rod_axis_angles_rad, d.rod_axis_angles_rad);
}

TEST(PhysicalModel, EffectsOffMeanTheirTermsAreZero) {
  const PlatformParameters p = to_platform_parameters(PhysicalModel::bare_platform());
  EXPECT_EQ(p.k_torque_high_Nm_per_rad, 0.0);
  EXPECT_EQ(p.com_x_m, 0.0);
  EXPECT_EQ(p.com_y_m, 0.0);
  EXPECT_EQ(p.J_psitheta_kgm2, 0.0);
  EXPECT_EQ(p.gravity_m_per_s2, 0.0);
}

TEST(PhysicalModel, LibraryHasTheSevenEffectsEachDocumentedWithValidDefaults) {
  const std::vector<std::string> names = {"structural_mode", "input_delay", "actuator_lag", "gain_error",
                                          "rod_twist",       "com_offset",  "beam_gravity"};
  ASSERT_EQ(effect_library().size(), names.size());
  PhysicalModel all = PhysicalModel::bare_platform();
  for (std::size_t i = 0; i < names.size(); ++i) {
    const EffectInfo& e = effect_library()[i];
    EXPECT_EQ(e.name, names[i]);
    EXPECT_FALSE(e.description.empty());
    EXPECT_FALSE(e.changes.empty());
    EXPECT_FALSE(e.signature.empty());
    EXPECT_FALSE(e.parameters.empty());
    all.add_effect(e.name);
  }
  EXPECT_EQ(error_of(all), "");
}

TEST(PhysicalModel, AddingUnknownOrRepeatedEffectIsInputError) {
  PhysicalModel m = PhysicalModel::default_platform();
  EXPECT_THROW(m.add_effect("friction"), InputError);
  EXPECT_THROW(m.add_effect("rod_twist"), InputError);
}

TEST(PhysicalModel, ValidateNamesTheBrokenRule) {
  PhysicalModel m = PhysicalModel::default_platform();
  m.parameter("coil_damping_Ns_per_m").lower = 100.0;
  m.parameter("coil_damping_Ns_per_m").upper = 10.0;
  EXPECT_THAT(error_of(m), HasSubstr("bounds reversed"));

  m = PhysicalModel::default_platform();
  m.parameter("coil_damping_Ns_per_m").value = 1e6;
  EXPECT_THAT(error_of(m), HasSubstr("outside its bounds"));

  m = PhysicalModel::default_platform();
  m.parameters.push_back({"spring_kN", "N/m", 1, 0, 2, false});
  EXPECT_THAT(error_of(m), HasSubstr("unknown parameter 'spring_kN'"));

  m = PhysicalModel::default_platform();
  m.parameter("beam_mass_kg").unit = "g";
  EXPECT_THAT(error_of(m), HasSubstr("its unit is 'kg'"));

  m = PhysicalModel::default_platform();
  m.parameters.erase(m.parameters.begin());
  EXPECT_THAT(error_of(m), HasSubstr("missing parameter 'J_psi_kgm2'"));

  m = PhysicalModel::bare_platform();
  m.parameters.push_back(find_effect("input_delay")->parameters[0]);
  EXPECT_THAT(error_of(m), HasSubstr("belongs to effect 'input_delay'"));
}

}  // namespace
}  // namespace lpvid
