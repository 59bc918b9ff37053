// lpvid — physical model files (JSON), docs/formats.md "Physical model files".
//
//   {
//     "format": "lpvid-physical-model",
//     "version": 1,
//     "base": "platform",
//     "effects": ["rod_twist", "com_offset", "beam_gravity"],
//     "parameters": {
//       "J_psi_kgm2": {"value": 0.05, "unit": "kg·m²", "lower": 0.0001, "upper": 10, "free": true},
//       ...
//     },
//     "fit": { ... }      (optional; written by lpvid fit, ignored when read)
//   }
//
// "parameters" holds exactly the base's parameters and those of each listed
// effect (idlib/physical/physical_model.h), each with all five fields.  Errors
// are InputError "path:line:column: what; what to do", the position being that
// of the offending parameter (or key), for: invalid JSON, wrong format tag or
// version, unknown base, unknown effect, unknown parameter, missing parameter
// or field, unknown field, wrong type, wrong unit, non-finite numbers, bounds
// reversed, value outside its bounds.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "idlib/physical/physical_model.h"

namespace lpvid {

inline constexpr const char* kPhysicalModelFormat = "lpvid-physical-model";

// Reads and validates a model file ("-" reads stdin).
PhysicalModel read_physical_model(const std::string& path);
// The same from text (path used in messages only).
PhysicalModel parse_physical_model(const std::string& text, const std::string& path);

// The file text: canonical parameter order (base, then each effect's), numbers
// that read back to the identical doubles; fit_section (null or an object) is
// written as "fit".  Calls model.validate().
std::string physical_model_to_json(const PhysicalModel& model, const nlohmann::json& fit_section = {});

// Writes physical_model_to_json atomically (formats/io/atomic_file.h); "-" is stdout.
void write_physical_model(const std::string& path, const PhysicalModel& model,
                          const nlohmann::json& fit_section = {});

}  // namespace lpvid
