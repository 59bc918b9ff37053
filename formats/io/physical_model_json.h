// lpvid — physical model files (JSON), docs/formats.md "Physical model files".
//
//   {
//     "format": "lpvid-physical-model",
//     "version": 2,
//     "base": "platform",
//     "effects": ["beam_gravity", "theta_mount"],
//     "definitions": {"theta_mount": {"description": ..., "blocks": [...], "parameters": {...}}},
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

#include "idlib/physical/mechanical/mechanical_base.h"
#include "idlib/physical/physical_model.h"

namespace lpvid {

inline constexpr const char* kPhysicalModelFormat = "lpvid-physical-model";
inline constexpr int kPhysicalModelVersion = 2;
inline constexpr const char* kMechanicalBaseFormat = "lpvid-mechanical-base";
inline constexpr int kMechanicalBaseVersion = 1;

// A mechanical base's description (idlib/physical/mechanical/mechanical_base.h) as
// the JSON object a model file holds under "mechanical" (without format/version).
nlohmann::ordered_json mechanical_description_json(const MechanicalDescription& description);
// Reads a description file {"format": "lpvid-mechanical-base", "version": 1, "name",
// "dofs", "inputs", "outputs", "parameters", "mass", "damping", "stiffness",
// "input_map", "output_map"} (docs/formats.md) and checks it (make_mechanical_base).
// @throws InputError "path:line:column: ..." at the offending key.
MechanicalDescription read_mechanical_description(const std::string& path);
MechanicalDescription parse_mechanical_description(const std::string& text, const std::string& path);

// A user-defined effect as JSON {"description", "blocks": [{"kind", "side",
// "channels", "parameters"}], "parameters": {name: {value, unit, lower, upper, free}}}
// (the "definitions" entries of a model file).
nlohmann::ordered_json effect_definition_json(const EffectInfo& effect);
// The same with its "name", as a file of its own (lpvid diagnose --out-effect,
// lpvid model define --from).
std::string effect_definition_file(const EffectInfo& effect);
// Reads an effect definition file.  @throws InputError "path:line:column: ..." for
// invalid JSON, a missing name, unknown fields, kinds or sides, wrong types.  The
// rules that need a base (channels, units) are checked when the effect is defined
// in a model (PhysicalModel::define_effect).
EffectInfo read_effect_definition(const std::string& path);
EffectInfo parse_effect_definition(const std::string& text, const std::string& path);

// True when path is a readable JSON file whose "format" is kPhysicalModelFormat
// (no validation beyond that; errors are left to read_physical_model).
bool is_physical_model_file(const std::string& path);

// Reads and validates a model file ("-" reads stdin).
PhysicalModel read_physical_model(const std::string& path);
// The same, and the file's "fit" section (null when it has none): what the fit that
// wrote the model recorded (e.g. the force-error route's smoothing, which compare
// reuses).
PhysicalModel read_physical_model(const std::string& path, nlohmann::json* fit_section);
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
