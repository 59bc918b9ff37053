#include "formats/io/platform_json.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/formats/io/test_util.h"

namespace lpvid {
namespace platform_json_test {

using ::testing::HasSubstr;
using ::testing::StartsWith;

class PlatformJson : public test::TempDirTest {};

TEST_F(PlatformJson, WrittenParametersReadBackIdentically) {
  PlatformParameters p;
  p.J_theta_kgm2 = 0.0731;
  p.beam_mass_kg = 1.0 / 3.0;
  p.rod_axis_angles_rad = {0.1, 2.2, 4.3};
  const std::string file = write("p.json", platform_parameters_to_json(p, {{"provenance", "test"}}));
  const PlatformParameters q = read_platform_parameters(file);
  PlatformParameters a = p, b = q;
  for (std::size_t i = 0; i < platform_parameter_fields(a).size(); ++i)
    EXPECT_EQ(*platform_parameter_fields(a)[i].second, *platform_parameter_fields(b)[i].second)
        << platform_parameter_fields(a)[i].first;
  EXPECT_EQ(q.rod_axis_angles_rad, p.rod_axis_angles_rad);
}

TEST_F(PlatformJson, MissingKeysKeepTheDefaults) {
  const PlatformParameters q = read_platform_parameters(write("p.json", "{\"beam_mass_kg\": 1.5}"));
  EXPECT_EQ(q.beam_mass_kg, 1.5);
  EXPECT_EQ(q.J_psi_kgm2, PlatformParameters{}.J_psi_kgm2);
}

TEST_F(PlatformJson, UnknownKeyIsReportedAtItsLineAndColumn) {
  const std::string file = write("p.json", "{\n  \"beam_mass_kg\": 1,\n  \"mass\": 3\n}\n");
  EXPECT_THAT(test::input_error([&] { read_platform_parameters(file); }),
              StartsWith(file + ":3:3: unknown parameter 'mass'; use one of J_psi_kgm2"));
}

TEST_F(PlatformJson, NonNumberAndInvalidValuesAreErrors) {
  std::string file = write("a.json", "{\"beam_mass_kg\": \"heavy\"}");
  EXPECT_THAT(test::input_error([&] { read_platform_parameters(file); }), HasSubstr(":1:2: key 'beam_mass_kg' must be"));
  file = write("b.json", "{\"beam_mass_kg\": -1}");
  EXPECT_THAT(test::input_error([&] { read_platform_parameters(file); }), HasSubstr("beam_mass_kg = -1"));
  file = write("c.json", "{\"beam_mass_kg\": 1,}");
  EXPECT_THAT(test::input_error([&] { read_platform_parameters(file); }), HasSubstr("invalid JSON"));
}

TEST_F(PlatformJson, BeamOutsideTheStrokeIsReportedAtItsCell) {
  const std::string file = write("r.csv", "# a comment\nt, x_b\n0,0\n\n0.001, 0.2\n0.002,0\n");
  EXPECT_THAT(test::input_error([&] { read_beam_samples(file, 0.15); }),
              StartsWith(file + ":5:8: x_b = 0.2 m is outside the stroke |x_b| <= 0.15 m"));
  const BeamSamples s = read_beam_samples(file, 0.25);
  EXPECT_EQ(s.x_b_m.size(), 3);
}

TEST_F(PlatformJson, OverridesApplyAndUnknownNamesAreListed) {
  PlatformParameters p;
  apply_parameter_overrides(p, {"beam_mass_kg=2"});
  EXPECT_EQ(p.beam_mass_kg, 2.0);
  EXPECT_THAT(test::input_error([&] { apply_parameter_overrides(p, {"mass=2"}); }),
              HasSubstr("unknown parameter 'mass'"));
}

}  // namespace platform_json_test
}  // namespace lpvid
