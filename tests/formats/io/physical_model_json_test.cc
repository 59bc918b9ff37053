#include "formats/io/physical_model_json.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

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
  PhysicalModel m = PhysicalModel::default_platform();
  m.add_effect("input_delay");
  m.parameter("coil_damping_Ns_per_m").value = 0.1 + 0.2;  // a double with 17 significant digits
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

TEST(PhysicalModelJson, BadFilesNameFileLineColumnAndTheRule) {
  const std::string good = physical_model_to_json(PhysicalModel::default_platform());
  const int damping_line = line_of(good, "\"coil_damping_Ns_per_m\"");
  const std::string at_damping = fmt::format("m.json:{}:5: ", damping_line);

  std::string e = error_of(edit(good, "\"coil_damping_Ns_per_m\"", "\"coil_dampin_Ns_per_m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("unknown parameter 'coil_dampin_Ns_per_m'"));

  e = error_of(edit(good, "\"value\": 30.0, \"unit\": \"N·s/m\", \"lower\": 0.001, \"upper\": 10000.0",
                    "\"value\": 30.0, \"unit\": \"N·s/m\", \"lower\": 10000.0, \"upper\": 0.001"));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("bounds reversed"));

  e = error_of(edit(good, "\"value\": 30.0, \"unit\": \"N·s/m\"", "\"value\": 3e5, \"unit\": \"N·s/m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("outside its bounds"));

  e = error_of(edit(good, "\"unit\": \"N·s/m\"", "\"unit\": \"kN·s/m\""));
  EXPECT_THAT(e, StartsWith(at_damping));
  EXPECT_THAT(e, HasSubstr("its unit is 'N·s/m'"));

  e = error_of(edit(good, "\"value\": 30.0, \"unit\": \"N·s/m\", ", "\"unit\": \"N·s/m\", "));
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
  const std::string good = physical_model_to_json(PhysicalModel::default_platform());
  const size_t a = good.find("    \"com_x_m\"");
  const size_t b = good.find('\n', a);
  std::string text = good;
  text.erase(a, b - a + 1);
  EXPECT_THAT(error_of(text), HasSubstr("missing parameter 'com_x_m'"));
}

}  // namespace
}  // namespace lpvid
