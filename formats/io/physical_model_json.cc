#include "formats/io/physical_model_json.h"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>

#include "formats/io/atomic_file.h"
#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using nlohmann::json;

// 1-based line and byte column of text[offset].
std::pair<int64_t, int64_t> position_of(const std::string& text, size_t offset) {
  const detail::CellPosition at = detail::text_position(text, offset);
  return {at.line, at.column};
}

// Offset of the key "name" (a quoted string followed by ':') at or after from; npos if none.
size_t find_key(const std::string& text, const std::string& name, size_t from) {
  const std::string quoted = "\"" + name + "\"";
  for (size_t at = text.find(quoted, from); at != std::string::npos; at = text.find(quoted, at + 1)) {
    size_t j = at + quoted.size();
    while (j < text.size() && std::strchr(" \t\r\n", text[j]) != nullptr) ++j;
    if (j < text.size() && text[j] == ':') return at;
  }
  return std::string::npos;
}

class Reader {
 public:
  Reader(const std::string& text, const std::string& path) : text_(text), path_(path) {}

  [[noreturn]] void fail_at(size_t offset, const std::string& what) const {
    const auto [line, column] = position_of(text_, offset == std::string::npos ? 0 : offset);
    detail::fail_at(path_, line, column, what);
  }
  size_t top(const std::string& key) const {
    const size_t at = find_key(text_, key, 0);
    return at == std::string::npos ? 0 : at;
  }
  size_t param(const std::string& name) const {
    const size_t params = find_key(text_, "parameters", 0);
    const size_t at = find_key(text_, name, params == std::string::npos ? 0 : params);
    return at == std::string::npos ? (params == std::string::npos ? 0 : params) : at;
  }

  PhysicalModel read() const {
    const json root = detail::parse_json(path_, text_);
    if (!root.is_object())
      fail_at(0, "a physical model file is a JSON object {\"format\": \"lpvid-physical-model\", ...}; see "
                 "docs/formats.md or run 'lpvid model init'");
    const auto format = root.find("format");
    if (format == root.end() || !format->is_string() || format->get<std::string>() != kPhysicalModelFormat)
      fail_at(top("format"), fmt::format("key 'format' must be \"{}\"; is this a physical model file? ('lpvid model "
                                         "init' writes one)",
                                         kPhysicalModelFormat));
    const auto version = root.find("version");
    if (version == root.end() || !version->is_number_integer() || version->get<int>() != 1)
      fail_at(top("version"), "key 'version' must be 1; write version 1 (the version this lpvid reads)");
    for (auto it = root.begin(); it != root.end(); ++it) {
      static const char* const kKeys[] = {"format", "version", "base", "effects", "parameters", "fit"};
      bool known = false;
      for (const char* k : kKeys) known = known || it.key() == k;
      if (!known)
        fail_at(top(it.key()), fmt::format("unknown key {}; remove it (a model file has format, version, base, "
                                           "effects, parameters and optionally fit)",
                                           detail::quote_cell(it.key())));
    }
    PhysicalModel model;
    const auto base = root.find("base");
    if (base == root.end() || !base->is_string())
      fail_at(top("base"), "missing key 'base' (a string); give \"base\": \"platform\"");
    model.base = base->get<std::string>();
    if (model.base != kPlatformBase)
      fail_at(top("base"), fmt::format("unknown base model '{}'; write \"base\": \"platform\" (the only base)", model.base));
    const auto effects = root.find("effects");
    if (effects == root.end() || !effects->is_array())
      fail_at(top("effects"), "missing key 'effects' (an array of effect names, [] for none); see 'lpvid model effects'");
    for (const json& e : *effects) {
      if (!e.is_string())
        fail_at(top("effects"), fmt::format("effects: {} is not a name; write names as strings", detail::json_excerpt(e)));
      const std::string name = e.get<std::string>();
      if (find_effect(name) == nullptr) {
        std::string names;
        for (const auto& x : effect_library()) names += (names.empty() ? "" : ", ") + x.name;
        fail_at(find_key(text_, "effects", 0) == std::string::npos ? 0 : text_.find("\"" + name + "\"", top("effects")),
                fmt::format("unknown effect {}; use one of {} (lpvid model effects)", detail::quote_cell(name), names));
      }
      for (const auto& prev : model.effects)
        if (prev == name)
          fail_at(top("effects"), fmt::format("effect '{}' is listed twice; list each effect once", name));
      model.effects.push_back(name);
    }
    const auto params = root.find("parameters");
    if (params == root.end() || !params->is_object())
      fail_at(top("parameters"), "missing key 'parameters' (an object name -> {value, unit, lower, upper, free})");
    // A model has a few dozen parameters; more is not a model file (and would
    // make the ordering below quadratic).
    constexpr std::size_t kMaxParameters = 1000;
    if (params->size() > kMaxParameters)
      fail_at(top("parameters"), fmt::format("'parameters' lists {} entries; a model has at most a few dozen: check "
                                             "that this is the right file",
                                             params->size()));
    // Canonical order first (base, then each effect's), then any unknown names
    // (validate() reports them).
    std::vector<std::string> order;
    for (const auto& q : platform_base_parameters()) order.push_back(q.name);
    for (const auto& e : model.effects)
      for (const auto& q : find_effect(e)->parameters) order.push_back(q.name);
    for (auto it = params->begin(); it != params->end(); ++it)
      if (std::find(order.begin(), order.end(), it.key()) == order.end()) order.push_back(it.key());
    for (const auto& name : order) {
      const auto it = params->find(name);
      if (it == params->end()) continue;  // missing: validate() names it
      model.parameters.push_back(parameter(name, *it));
    }
    try {
      model.validate();
    } catch (const InputError& e) {
      // Point at the parameter the message names ('name'), else at "parameters".
      const std::string what = e.what();
      const size_t q1 = what.find('\'');
      const size_t q2 = q1 == std::string::npos ? std::string::npos : what.find('\'', q1 + 1);
      const std::string name = q2 == std::string::npos ? "" : what.substr(q1 + 1, q2 - q1 - 1);
      const bool missing = what.rfind("missing", 0) == 0;
      fail_at(name.empty() || missing ? top("parameters") : param(name), what);
    }
    return model;
  }

 private:
  PhysicalParameter parameter(const std::string& name, const json& v) const {
    const size_t at = param(name);
    if (!v.is_object())
      fail_at(at, fmt::format("parameter '{}' must be an object; write {{\"value\", \"unit\", \"lower\", \"upper\", \"free\"}}",
                              name));
    for (auto it = v.begin(); it != v.end(); ++it) {
      static const char* const kFields[] = {"value", "unit", "lower", "upper", "free"};
      bool known = false;
      for (const char* k : kFields) known = known || it.key() == k;
      if (!known)
        fail_at(at, fmt::format("parameter '{}' has unknown field {}; remove it (the fields are value, unit, lower, upper, free)",
                                name, detail::quote_cell(it.key())));
    }
    PhysicalParameter p;
    p.name = name;
    auto number = [&](const char* field) {
      const auto f = v.find(field);
      if (f == v.end()) fail_at(at, fmt::format("parameter '{}' has no field '{}'; give all of value, unit, lower, upper, free", name, field));
      if (!f->is_number())
        fail_at(at, fmt::format("parameter '{}': field '{}' must be a number, got {}; write a number", name, field, detail::json_excerpt(*f)));
      return f->get<double>();
    };
    p.value = number("value");
    p.lower = number("lower");
    p.upper = number("upper");
    const auto unit = v.find("unit");
    if (unit == v.end() || !unit->is_string())
      fail_at(at, fmt::format("parameter '{}': field 'unit' must be a string; write the library's unit, e.g. \"kg\"", name));
    p.unit = unit->get<std::string>();
    const auto free = v.find("free");
    if (free == v.end() || !free->is_boolean())
      fail_at(at, fmt::format("parameter '{}': field 'free' must be true or false; write one of them", name));
    p.free = free->get<bool>();
    return p;
  }

  const std::string& text_;
  const std::string& path_;
};

}  // namespace

PhysicalModel parse_physical_model(const std::string& text, const std::string& path) {
  return Reader(text, path).read();
}

PhysicalModel read_physical_model(const std::string& path) {
  return parse_physical_model(detail::read_json_text(path, "a physical model file"), path);
}

std::string physical_model_to_json(const PhysicalModel& model, const json& fit_section) {
  model.validate();
  if (!fit_section.is_null() && !fit_section.is_object())
    throw InputError("the fit section of a model file must be a JSON object");
  std::string out = fmt::format("{{\n  \"format\": \"{}\",\n  \"version\": 1,\n  \"base\": {},\n  \"effects\": {},\n",
                                kPhysicalModelFormat, json(model.base).dump(), json(model.effects).dump());
  out += "  \"parameters\": {\n";
  for (std::size_t i = 0; i < model.parameters.size(); ++i) {
    const auto& p = model.parameters[i];
    out += fmt::format("    {}: {{\"value\": {}, \"unit\": {}, \"lower\": {}, \"upper\": {}, \"free\": {}}}{}\n",
                       json(p.name).dump(), json(p.value).dump(), json(p.unit).dump(), json(p.lower).dump(),
                       json(p.upper).dump(), p.free ? "true" : "false", i + 1 < model.parameters.size() ? "," : "");
  }
  out += "  }";
  if (fit_section.is_object() && !fit_section.empty()) {
    // The fit section names data files, which may not be UTF-8: written with U+FFFD.
    std::string fit = fit_section.dump(2, ' ', false, json::error_handler_t::replace);
    for (size_t pos = fit.find('\n'); pos != std::string::npos; pos = fit.find('\n', pos + 1)) fit.insert(pos + 1, "  ");
    out += ",\n  \"fit\": " + fit;
  }
  out += "\n}\n";
  return out;
}

void write_physical_model(const std::string& path, const PhysicalModel& model, const json& fit_section) {
  write_file_atomic(path, physical_model_to_json(model, fit_section));
}

}  // namespace lpvid
