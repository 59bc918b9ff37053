#include "formats/io/physical_model_json.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"
#include "idlib/physical/platform/platform_base.h"
#include "tests/support/two_mass_axis.h"

namespace lpvid {
namespace physical_model_json_test {

using ::testing::HasSubstr;
using ::testing::StartsWith;

std::string error_of(const std::string& text) {
  try {
    parse_physical_model(text, "m.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Replaces the first occurrence of from by to (the test edits a valid file).
std::string edit(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

// 1-based line of the first occurrence of needle.
int line_of(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

TEST(PhysicalModelJson, RoundTripIsExact) {
  PhysicalModel m = platform_defaults_model();
  m.add_effect("input_delay");
  m.parameter("damping_psi_Nms_per_rad").value = 0.1 + 0.2;  // a double with 17 significant digits
  const std::string text = physical_model_to_json(m, {{"cost", 1.5}});
  const PhysicalModel back = parse_physical_model(text, "m.json");
  ASSERT_EQ(back.parameters.size(), m.parameters.size());
  EXPECT_EQ(back.effects, m.effects);
  for (std::size_t i = 0; i < m.parameters.size(); ++i) {
    EXPECT_EQ(back.parameters[i].name, m.parameters[i].name);
    EXPECT_EQ(back.parameters[i].value, m.parameters[i].value);
    EXPECT_EQ(back.parameters[i].lower, m.parameters[i].lower);
    EXPECT_EQ(back.parameters[i].upper, m.parameters[i].upper);
    EXPECT_EQ(back.parameters[i].free, m.parameters[i].free);
    EXPECT_EQ(back.parameters[i].unit, m.parameters[i].unit);
  }
}

// Design values of absent effects (issue 25) travel in the file, after "parameters";
// a broken one is positioned at its name.
TEST(PhysicalModelJson, DesignValuesOfAbsentEffectsRoundTripAndAreChecked) {
  PhysicalModel m = platform_defaults_model();
  PhysicalParameter& tau = m.parameter_or_design_value("actuator_time_constant_s");
  tau.value = tau.prior_mean = 5e-5;
  tau.prior_sigma = 5e-5;
  const std::string text = physical_model_to_json(m);
  EXPECT_LT(text.find("\"parameters\""), text.find("\"design_values\"")) << text;
  const PhysicalModel back = parse_physical_model(text, "m.json");
  ASSERT_EQ(back.design_values.size(), 1u);
  EXPECT_EQ(back.design_values.front().name, "actuator_time_constant_s");
  EXPECT_EQ(back.design_values.front().value, 5e-5);
  EXPECT_EQ(back.design_values.front().prior_mean, 5e-5);
  EXPECT_EQ(back.design_values.front().prior_sigma, 5e-5);
  EXPECT_EQ(physical_model_to_json(back), text);
  const int at = line_of(text, "\"actuator_time_constant_s\"");
  std::string e = error_of(edit(text, "\"actuator_time_constant_s\"", "\"actuator_time_constant_ms\""));
  EXPECT_THAT(e, StartsWith(fmt::format("m.json:{}:5: ", at)));
  EXPECT_THAT(e, HasSubstr("no parameter of an effect the model could add"));
  e = error_of(edit(text, "\"actuator_time_constant_s\"", "\"platform_mass_kg\""));
  EXPECT_THAT(e, HasSubstr("is a parameter the model has"));
  e = error_of(edit(text, "\"design_values\": {", "\"design_values\": [{") );
  EXPECT_THAT(e, HasSubstr("m.json:"));
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

TEST(PhysicalModelJson, BadFilesNameFileLineColumnAndTheRule) {
  const std::string good = physical_model_to_json(platform_defaults_model());
  const int damping_line = line_of(good, "\"damping_z_Ns_per_m\"");
  const std::string at_damping = fmt::format("m.json:{}:5: ", damping_line);

  std::string e = error_of(edit(good, "\"damping_z_Ns_per_m\"", "\"dampin_z_Ns_per_m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("unknown parameter 'dampin_z_Ns_per_m'"));

  e = error_of(edit(good, "\"value\": 270.0, \"unit\": \"N·s/m\", \"lower\": 0.001, \"upper\": 1000000.0",
                    "\"value\": 270.0, \"unit\": \"N·s/m\", \"lower\": 1000000.0, \"upper\": 0.001"));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("bounds reversed"));

  e = error_of(edit(good, "\"value\": 270.0, \"unit\": \"N·s/m\"", "\"value\": 3e7, \"unit\": \"N·s/m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("outside its bounds"));

  e = error_of(edit(good, "\"unit\": \"N·s/m\"", "\"unit\": \"kN·s/m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("its unit is 'N·s/m'"));

  e = error_of(edit(good, "\"value\": 270.0, \"unit\": \"N·s/m\", ", "\"unit\": \"N·s/m\", "));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("no field 'value'"));

  e = error_of(edit(good, "\"beam_gravity\"]", "\"beam_gravity\", \"friction\"]"));
  EXPECT_THAT(e, StartsWith(fmt::format("m.json:{}:", line_of(good, "\"effects\""))));
  EXPECT_THAT(e, HasSubstr("unknown effect 'friction'"));

  e = error_of(edit(good, "\"format\": \"lpvid-physical-model\"", "\"format\": \"x\""));
  EXPECT_THAT(e, StartsWith("m.json:2:3: "));

  e = error_of(edit(good, "}\n}", "}\n"));
  EXPECT_THAT(e, HasSubstr("invalid JSON"));
  // Every message is one line.
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

TEST(PhysicalModelJson, MissingParameterIsNamed) {
  const std::string good = physical_model_to_json(platform_defaults_model());
  const size_t a = good.find("    \"com_x_m\"");
  const size_t b = good.find('\n', a);
  std::string text = good;
  text.erase(a, b - a + 1);
  EXPECT_THAT(error_of(text), HasSubstr("missing parameter 'com_x_m'"));
}

TEST(PhysicalModelJson, UserDefinedEffectsRoundTripAndTheirRulesArePositioned) {
  PhysicalModel m = PhysicalModel::initial();
  EffectInfo e;
  e.name = "theta_mount";
  e.description = "a resonance of the theta sensor's mount";
  e.parameters = {{"mount_wp_rad_s", "rad/s", 800, 300, 3000, true}, {"mount_zp", "1", 0.05, 1e-3, 0.7, true},
                  {"mount_wz_rad_s", "rad/s", 900, 300, 3000, true}, {"mount_zz", "1", 0.1, 1e-3, 0.7, true}};
  e.blocks = {{BlockKind::kResonance, BlockSide::kOutput, {"theta"},
               {"mount_wp_rad_s", "mount_zp", "mount_wz_rad_s", "mount_zz"}}};
  m.define_effect(e);
  m.add_effect("theta_mount");
  m.parameter("mount_wp_rad_s").value = 812.5;
  const std::string text = physical_model_to_json(m);
  const PhysicalModel back = parse_physical_model(text, "m.json");
  ASSERT_EQ(back.definitions.size(), 1u);
  EXPECT_EQ(back.definitions[0].name, "theta_mount");
  EXPECT_EQ(back.definitions[0].description, e.description);
  EXPECT_EQ(back.parameter("mount_wp_rad_s").value, 812.5);
  EXPECT_EQ(back.definitions[0].parameters[0].value, 800);  // the definition keeps its default
  EXPECT_EQ(physical_model_to_json(back), text);
  // a block channel the base does not have: positioned at the definition
  const std::string bad = edit(text, "\"theta\"", "\"phi\"");
  const std::string err = error_of(bad);
  EXPECT_THAT(err, StartsWith(fmt::format("m.json:{}:", line_of(bad, "\"theta_mount\": {"))));
  EXPECT_THAT(err, HasSubstr("channel 'phi' is not an output of base 'platform'"));
  // a malformed definition: its position once (it was printed twice)
  const std::string bad_kind = edit(text, "\"resonance\"", "\"wobble\"");
  const std::string err_kind = error_of(bad_kind);
  EXPECT_THAT(err_kind, StartsWith("m.json:"));
  EXPECT_EQ(err_kind.find("m.json:", 1), std::string::npos) << err_kind;
  // a definition file of its own reads back to the same effect
  const EffectInfo again = parse_effect_definition(effect_definition_file(back.definitions[0]), "e.json");
  EXPECT_EQ(again.name, "theta_mount");
  EXPECT_EQ(again.blocks.size(), 1u);
  EXPECT_EQ(again.parameters.size(), 4u);
}

TEST(PhysicalModelJson, AVersionOneFileIsRefusedWithWhatToDo) {
  const std::string good = physical_model_to_json(PhysicalModel::initial());
  const std::string e = error_of(edit(good, "\"version\": 2", "\"version\": 1"));
  EXPECT_THAT(e, StartsWith("m.json:3:3: "));
  EXPECT_THAT(e, HasSubstr("write a new one with 'lpvid model init'"));
}


// A mechanical base travels in the model file (key "mechanical"): the file alone gives
// back the same base, the same parameters and the same response; its own rules and the
// key's misuse are refused at their position.
TEST(PhysicalModelJson, AMechanicalBaseRoundTripsInTheModelFileAndItsErrorsArePositioned) {
  MechanicalDescription d = two_mass_axis::axis();
  d.outputs[1].derivative = 2;  // an accelerometer: "measures" is written and read back
  PhysicalModel m = PhysicalModel::bare(make_mechanical_base(d));
  m.add_effect("structural_mode");
  m.parameter("m_load_kg").value = 0.1 + 6.2;  // 17 significant digits
  const std::string text = physical_model_to_json(m);
  EXPECT_THAT(text, HasSubstr("\"measures\":\"acceleration\""));
  const PhysicalModel back = parse_physical_model(text, "m.json");
  ASSERT_NE(back.user_base, nullptr);
  EXPECT_EQ(back.base, "mechanical");
  EXPECT_EQ(back.effects, m.effects);
  ASSERT_EQ(back.parameters.size(), m.parameters.size());
  for (std::size_t i = 0; i < m.parameters.size(); ++i) EXPECT_EQ(back.parameters[i].value, m.parameters[i].value);
  const Eigen::VectorXd w = Eigen::VectorXd::LinSpaced(7, 10.0, 3000.0);
  const auto P = physical_response(m, 0.0, w, 0.0), Q = physical_response(back, 0.0, w, 0.0);
  for (std::size_t k = 0; k < P.size(); ++k) EXPECT_EQ(P[k], Q[k]) << k;  // the same base, bit for bit
  // a second write gives the same text (the description is canonical)
  EXPECT_EQ(physical_model_to_json(back), text);

  const int mech_line = line_of(text, "\"mechanical\": {");
  EXPECT_THAT(error_of(edit(text, "  \"mechanical\": {", "  \"mechanica\": {")),
              HasSubstr("unknown key 'mechanica'; remove it"));
  const std::string without = edit(text, "\"mechanical\": {", "\"unused\": {");
  EXPECT_THAT(error_of(edit(without, "\"unused\": {", "\"fit\": {")),
              HasSubstr("base 'mechanical' needs its description under key \"mechanical\""));
  EXPECT_THAT(error_of(edit(text, "\"base\": \"mechanical\"", "\"base\": \"platform\"")),
              HasSubstr("key 'mechanical' describes a user's base, but the model's base is 'platform'"));
  EXPECT_THAT(error_of(edit(text, "[[\"m_carriage_kg\",0],[0,\"m_load_kg\"]]", "[[\"m_carriage_kg\",0],[\"m_load_kg\",\"m_load_kg\"]]")),
              StartsWith(fmt::format("m.json:{}:3: mechanical base 'two_mass_axis': the mass matrix is not symmetric", mech_line)));
  EXPECT_THAT(error_of(edit(text, "\"measures\":\"acceleration\"", "\"measures\":\"jerk\"")),
              HasSubstr("output \"load\" measures \"jerk\"; write \"position\", \"velocity\" or \"acceleration\""));
}

}  // namespace physical_model_json_test
}  // namespace lpvid
