// lpvid — platform parameter files (JSON) and beam trajectories (CSV), the inputs of
// the moving-beam simulation and of the time-domain compare (docs/formats.md).
//
// Parameter file: one object, keys = the PlatformParameters field names of
// idlib/plants/platform/platform.h (units in the names); a missing key keeps its
// documented default, an unknown key is an error, other types are errors:
//
//   {
//     "type": "platform_parameters",
//     "J_theta_kgm2": 0.06,
//     "beam_mass_kg": 1.0,
//     "rod_axis_angles_rad": [1.5708, 3.6652, 5.7596]
//   }
//
// "type" is optional on reading; "provenance" (any JSON) is allowed and ignored.
#pragma once

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "idlib/plants/platform/platform.h"

namespace lpvid {

// Scalar fields by name (all of PlatformParameters except rod_axis_angles_rad).
std::vector<std::pair<std::string, double*>> platform_parameter_fields(PlatformParameters& p);

// Reads a parameter file.  Throws InputError "path:line:column: what; what to do"
// (invalid JSON, unknown key, a value not a finite number), then whatever
// PlatformParameters::validate rejects, prefixed with the path.
PlatformParameters read_platform_parameters(const std::string& path);

// Applies NAME=VALUE overrides (the --set flag) to params, then validates.
// Throws InputError "--set 'x': expected NAME=VALUE ..." / "unknown parameter".
void apply_parameter_overrides(PlatformParameters& params, const std::vector<std::string>& overrides);

// Every field, numbers that read back to the identical doubles; extra keys after.
std::string platform_parameters_to_json(const PlatformParameters& params, const nlohmann::json& extra = {});

// The x_b column of a log (csv_log.h rules: t strictly increasing and uniform,
// finite numbers), checked against the stroke: |x_b| <= stroke_m, else
// "path:line:column: x_b = 0.3 m is outside the stroke |x_b| <= 0.15 m; ...".
struct BeamSamples {
  Eigen::VectorXd t_s;
  Eigen::VectorXd x_b_m;
};
BeamSamples read_beam_samples(const std::string& path, double stroke_m, const std::string& column = "x_b");

// The same check on a log already read (path and the matrix as csv_log.h read
// it): throws with the file position of the first sample outside the stroke.
void check_beam_stroke(const std::string& path, const Eigen::VectorXd& x_b_m, double stroke_m,
                       const std::string& column = "x_b");

}  // namespace lpvid
