// The stage6 model <-> time-domain fit mapping (idlib/stage6/stage6_time.h).
#include "idlib/stage6/stage6_time.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "idlib/core/error.h"

namespace lpvid {
namespace stage6_time_test {

using ::testing::HasSubstr;

std::string message_of(const PhysicalModel& m) {
  try {
    stage6_time_setup(m);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Stage6Time, SetupTakesTheModelsValuesAndEffects) {
  PhysicalModel m = PhysicalModel::bare("stage6");
  m.add_effect("gap_dependence");
  m.add_effect("com_offset");
  m.parameter("inertia_yy_kgm2").value = 0.031;
  m.parameter("gap_decay_per_m").value = 300.0;
  const Stage6TimeSetup s = stage6_time_setup(m);
  EXPECT_TRUE(s.fix_mass);
  EXPECT_TRUE(s.model.gap_dependence);
  EXPECT_TRUE(s.model.com_offset);
  EXPECT_FALSE(s.model.electrical_lag);
  EXPECT_DOUBLE_EQ(s.nominal.inertia_kgm2(1, 1), 0.031);
  EXPECT_NEAR(s.nominal.gamma_per_m(), 300.0, 1e-12);
  // The designed arms of the file (the base's defaults = the simulator's, docs/assumptions.md).
  EXPECT_EQ(s.nominal.lever_arms_m, stage6::StageParameters::default_lever_arms());
}

TEST(Stage6Time, SetupRefusesWhatTheTimeRouteCannotFit) {
  PhysicalModel delay = PhysicalModel::bare("stage6");
  delay.add_effect("input_delay");
  EXPECT_THAT(message_of(delay), HasSubstr("effect input_delay of the model has no time-domain form"));
  PhysicalModel both = PhysicalModel::bare("stage6");
  both.parameter("mass_kg").free = true;
  EXPECT_THAT(message_of(both), HasSubstr("mass_kg and force_constant_scale are both free"));
  PhysicalModel held = PhysicalModel::bare("stage6");
  held.parameter("inertia_zz_kgm2").free = false;
  EXPECT_THAT(message_of(held), HasSubstr("inertia_zz_kgm2 is held"));
  EXPECT_THAT(message_of(PhysicalModel::bare("platform")), HasSubstr("this model's base is 'platform'"));
}

TEST(Stage6Time, FittedValuesGoToTheFreeParametersOnlyAndStayInTheirBounds) {
  PhysicalModel m = stage6_model_of(stage6::StageFitModel{true, true, false}, /*fix_mass=*/true);
  ASSERT_TRUE(m.has_effect("com_offset") && m.has_effect("gap_dependence") && !m.has_effect("electrical_lag"));
  Eigen::Matrix<double, stage6::kStageThetaSize, 1> theta = stage6_time_theta(m);
  EXPECT_DOUBLE_EQ(theta(0), m.parameter("mass_kg").value);
  theta(0) = 9.0;    // the mass is held: not written
  theta(1) = 0.033;  // written
  theta(5) = 0.2;    // com_x beyond its bound 0.05: clamped, with a warning
  theta(8) = 250.0;
  std::vector<std::string> warnings;
  const PhysicalModel f = stage6_apply_time_fit(m, theta, &warnings);
  EXPECT_DOUBLE_EQ(f.parameter("mass_kg").value, m.parameter("mass_kg").value);
  EXPECT_DOUBLE_EQ(f.parameter("inertia_xx_kgm2").value, 0.033);
  EXPECT_DOUBLE_EQ(f.parameter("com_x_m").value, 0.05);
  EXPECT_DOUBLE_EQ(f.parameter("gap_decay_per_m").value, 250.0);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("com_x_m"));
}

}  // namespace stage6_time_test
}  // namespace lpvid
