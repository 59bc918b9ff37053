#include "formats/io/physical_model_json.h"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "formats/io/atomic_file.h"
#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"
#include "idlib/physical/mechanical/mechanical_base.h"

namespace lpvid {
namespace {

// ordered: a user-defined effect's parameters keep the order of the file
using json = nlohmann::ordered_json;

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

// The file's JSON, checked by the bounded reader (depth, syntax, range; errors at
// file:line:column), then parsed again in the file's order (user-defined effects).
json parse_ordered(const std::string& path, const std::string& text) {
  detail::parse_json(path, text);
  return json::parse(text);
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

  PhysicalModel read(nlohmann::json* fit_section = nullptr) const {
    const json root = parse_ordered(path_, text_);
    if (!root.is_object())
      fail_at(0, "a physical model file is a JSON object {\"format\": \"lpvid-physical-model\", ...}; see "
                 "docs/formats.md or run 'lpvid model init'");
    const auto format = root.find("format");
    if (format == root.end() || !format->is_string() || format->get<std::string>() != kPhysicalModelFormat)
      fail_at(top("format"), fmt::format("key 'format' must be \"{}\"; is this a physical model file? ('lpvid model "
                                         "init' writes one)",
                                         kPhysicalModelFormat));
    const auto version = root.find("version");
    if (version == root.end() || !version->is_number_integer() || version->get<int>() != kPhysicalModelVersion) {
      if (version != root.end() && version->is_number_integer() && version->get<int>() == 1)
        fail_at(top("version"), "this model file is version 1, written by an earlier lpvid whose platform base had "
                                "no damping per DOF or bending tolerance; write a new one with 'lpvid model init' and "
                                "copy your values into it");
      fail_at(top("version"), fmt::format("key 'version' must be {}; write version {} (the version this lpvid "
                                          "reads; 'lpvid model init' writes one)",
                                          kPhysicalModelVersion, kPhysicalModelVersion));
    }
    for (auto it = root.begin(); it != root.end(); ++it) {
      static const char* const kKeys[] = {"format", "version", "base", "mechanical", "effects", "definitions",
                                          "parameters", "design_values", "fit"};
      bool known = false;
      for (const char* k : kKeys) known = known || it.key() == k;
      if (!known)
        fail_at(top(it.key()), fmt::format("unknown key {}; remove it (a model file has format, version, base, "
                                           "effects, parameters and optionally definitions, design_values and fit; "
                                           "mechanical with the base mechanical)",
                                           detail::quote_cell(it.key())));
    }
    PhysicalModel model;
    const auto base = root.find("base");
    if (base == root.end() || !base->is_string())
      fail_at(top("base"), "missing key 'base' (a string); give \"base\": \"platform\"");
    model.base = base->get<std::string>();
    const auto mech = root.find("mechanical");
    if (model.base == "mechanical") {
      if (mech == root.end())
        fail_at(top("base"), "base 'mechanical' needs its description under key \"mechanical\"; write the model with "
                             "'lpvid model init --base mechanical --from DESCRIPTION.json'");
      const MechanicalDescription d = mechanical_description(*mech, top("mechanical"));
      try {
        model.user_base = make_mechanical_base(d);
      } catch (const InputError& e) {
        fail_at(top("mechanical"), e.what());
      }
    } else {
      if (mech != root.end())
        fail_at(top("mechanical"), fmt::format("key 'mechanical' describes a user's base, but the model's base is '{}'; "
                                               "remove it or write \"base\": \"mechanical\"",
                                               model.base));
      if (find_base(model.base) == nullptr) {
        try {
          model.base_info();
        } catch (const InputError& e) {
          fail_at(top("base"), e.what());
        }
      }
    }
    // User-defined effects first: "effects" may name them.
    const auto defs = root.find("definitions");
    if (defs != root.end()) {
      if (!defs->is_object())
        fail_at(top("definitions"), "key 'definitions' must be an object; write effect name -> {description, blocks, "
                                    "parameters} (docs/formats.md)");
      for (auto it = defs->begin(); it != defs->end(); ++it) {
        const size_t at = find_key(text_, it.key(), top("definitions"));
        // effect_definition's own errors carry their position already
        EffectInfo definition = effect_definition(it.key(), it.value(), at == std::string::npos ? top("definitions") : at);
        try {
          model.define_effect(definition);
        } catch (const InputError& e) {
          fail_at(at == std::string::npos ? top("definitions") : at, e.what());
        }
      }
    }
    const auto effects = root.find("effects");
    if (effects == root.end() || !effects->is_array())
      fail_at(top("effects"), "missing key 'effects' (an array of effect names, [] for none); see 'lpvid model effects'");
    for (const json& e : *effects) {
      if (!e.is_string())
        fail_at(top("effects"), fmt::format("effects: {} is not a name; write names as strings", detail::json_excerpt(e)));
      const std::string name = e.get<std::string>();
      if (model.effect_info(name) == nullptr) {
        std::string names;
        for (const auto& x : model.library()) names += (names.empty() ? "" : ", ") + x.name;
        for (const auto& x : model.definitions) names += ", " + x.name + " (defined in the file)";
        fail_at(find_key(text_, "effects", 0) == std::string::npos ? 0 : text_.find("\"" + name + "\"", top("effects")),
                fmt::format("unknown effect {}; use one of {} (the library of base '{}'; lpvid model effects)",
                            detail::quote_cell(name), names, model.base));
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
    for (const auto& q : model.base_info().parameters) order.push_back(q.name);
    for (const auto& e : model.effects)
      for (const auto& q : model.effect_info(e)->parameters) order.push_back(q.name);
    for (auto it = params->begin(); it != params->end(); ++it)
      if (std::find(order.begin(), order.end(), it.key()) == order.end()) order.push_back(it.key());
    for (const auto& name : order) {
      const auto it = params->find(name);
      if (it == params->end()) continue;  // missing: validate() names it
      model.parameters.push_back(parameter(name, *it));
    }
    // Values and priors for effects the model does not have yet (after "parameters"
    // in the file, so that a rule's message finds the name there).
    if (const auto designs = root.find("design_values"); designs != root.end()) {
      if (!designs->is_object())
        fail_at(top("design_values"), "key 'design_values' must be an object name -> {value, unit, lower, upper, "
                                      "free, prior} (parameters of effects the model does not have yet)");
      for (auto it = designs->begin(); it != designs->end(); ++it)
        model.design_values.push_back(parameter(it.key(), it.value(), find_key(text_, it.key(), top("design_values"))));
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
    check_smoothing(root);
    if (fit_section != nullptr) {
      const auto fit = root.find("fit");
      *fit_section = fit == root.end() ? nlohmann::json() : nlohmann::json::parse(fit->dump());
    }
    return model;
  }

  // The force-error route's smoothing in the fit section, which compare reuses
  // (cli/mechanical_time.h): checked when present.
  void check_smoothing(const json& root) const {
    const auto fit = root.find("fit");
    if (fit == root.end() || !fit->is_object() || !fit->contains("smoothing")) return;
    const json& sm = (*fit)["smoothing"];
    const bool ok = sm.is_object() && sm.contains("window_s") && sm["window_s"].is_number() &&
                    sm["window_s"].get<double>() > 0.0 && std::isfinite(sm["window_s"].get<double>()) &&
                    sm.contains("input") && sm["input"].is_string() && (sm["input"] == "held" || sm["input"] == "measured");
    if (!ok)
      fail_at(top("smoothing"), "fit.smoothing must be {\"window_s\": seconds > 0, \"input\": \"held\" or "
                                "\"measured\"} (as lpvid fit --log writes it); correct it, or remove it to use the "
                                "defaults");
  }

  // A mechanical base's description (docs/formats.md, "Mechanical base descriptions"),
  // the object at offset `at`; `standalone`: a description file of its own, which
  // also carries "format" and "version".
  MechanicalDescription mechanical_description(const json& v, size_t at, bool standalone = false) const {
    const char* const kForm = "(docs/formats.md, \"Mechanical base descriptions\")";
    auto key_at = [&](const std::string& key) {
      const size_t k = find_key(text_, key, at);
      return k == std::string::npos ? at : k;
    };
    if (!v.is_object())
      fail_at(at, fmt::format("a mechanical base description is an object {{\"name\", \"dofs\", \"inputs\", "
                              "\"outputs\", \"parameters\", \"mass\", \"damping\", \"stiffness\", \"input_map\", "
                              "\"output_map\"}} {}",
                              kForm));
    for (auto it = v.begin(); it != v.end(); ++it) {
      static const char* const kFields[] = {"name",       "description", "dofs",      "inputs",    "outputs",
                                            "parameters", "mass",        "damping",   "stiffness", "input_map",
                                            "output_map", "format",      "version"};
      bool known = false;
      for (const char* k : kFields) known = known || it.key() == k;
      if (!standalone && (it.key() == "format" || it.key() == "version")) known = false;
      if (!known)
        fail_at(key_at(it.key()), fmt::format("mechanical base: unknown field {}; remove it (the fields are name, "
                                              "description, dofs, inputs, outputs, parameters, mass, damping, "
                                              "stiffness, input_map, output_map) {}",
                                              detail::quote_cell(it.key()), kForm));
    }
    if (standalone) {
      const auto f = v.find("format");
      if (f == v.end() || !f->is_string() || f->get<std::string>() != kMechanicalBaseFormat)
        fail_at(key_at("format"), fmt::format("key 'format' must be \"{}\"; is this a mechanical base description? {}",
                                              kMechanicalBaseFormat, kForm));
      const auto ver = v.find("version");
      if (ver == v.end() || !ver->is_number_integer() || ver->get<int>() != kMechanicalBaseVersion)
        fail_at(key_at("version"), fmt::format("key 'version' must be {}", kMechanicalBaseVersion));
    }
    MechanicalDescription d;
    auto text = [&](const char* key, bool required) {
      const auto f = v.find(key);
      if (f == v.end()) {
        if (required) fail_at(at, fmt::format("mechanical base: missing key '{}' (a string) {}", key, kForm));
        return std::string();
      }
      if (!f->is_string()) fail_at(key_at(key), fmt::format("mechanical base: '{}' must be a string", key));
      return f->get<std::string>();
    };
    d.name = text("name", true);
    d.description = text("description", false);
    auto channels = [&](const char* key) {
      std::vector<MechanicalChannel> out;
      const auto f = v.find(key);
      if (f == v.end() || !f->is_array())
        fail_at(f == v.end() ? at : key_at(key),
                fmt::format("mechanical base: '{}' must be an array of {{\"name\", \"unit\"}} {}", key, kForm));
      const bool outputs = std::string(key) == "outputs";
      for (const json& c : *f) {
        const std::size_t extra = outputs && c.is_object() && c.contains("measures") ? 1 : 0;
        if (!c.is_object() || c.size() != 2 + extra || !c.contains("name") || !c.contains("unit") ||
            !c["name"].is_string() || !c["unit"].is_string())
          fail_at(key_at(key), fmt::format("mechanical base: '{}' holds {}; each entry is {{\"name\": \"...\", "
                                           "\"unit\": \"...\"}}{}",
                                           key, detail::json_excerpt(c),
                                           outputs ? " with optionally \"measures\": \"position\", \"velocity\" or "
                                                     "\"acceleration\""
                                                   : ""));
        MechanicalChannel ch{c["name"].get<std::string>(), c["unit"].get<std::string>(), 0};
        if (extra) {
          const json& m = c["measures"];
          const std::string what = m.is_string() ? m.get<std::string>() : std::string();
          if (what == "position") ch.derivative = 0;
          else if (what == "velocity") ch.derivative = 1;
          else if (what == "acceleration") ch.derivative = 2;
          else
            fail_at(key_at(key), fmt::format("mechanical base: output {} measures {}; write \"position\", "
                                             "\"velocity\" or \"acceleration\"",
                                             detail::json_excerpt(c["name"]), detail::json_excerpt(m)));
        }
        out.push_back(ch);
      }
      return out;
    };
    d.dofs = channels("dofs");
    d.inputs = channels("inputs");
    d.outputs = channels("outputs");
    const auto params = v.find("parameters");
    if (params == v.end() || !params->is_object())
      fail_at(params == v.end() ? at : key_at("parameters"),
              "mechanical base: 'parameters' must be an object name -> {value, unit, lower, upper, free} (the design "
              "values)");
    for (auto it = params->begin(); it != params->end(); ++it)
      d.parameters.push_back(parameter(it.key(), it.value(), key_at(it.key())));
    auto matrix = [&](const char* key) {
      std::vector<std::vector<LinearExpression>> out;
      const auto f = v.find(key);
      if (f == v.end() || !f->is_array())
        fail_at(f == v.end() ? at : key_at(key),
                fmt::format("mechanical base: '{}' must be an array of rows, each an array of entries (a number or an "
                            "expression such as \"m1_kg + m2_kg\") {}",
                            key, kForm));
      for (const json& row : *f) {
        if (!row.is_array())
          fail_at(key_at(key), fmt::format("mechanical base: '{}' holds the row {}; write each row as an array", key,
                                           detail::json_excerpt(row)));
        std::vector<LinearExpression> r;
        for (const json& e : row) {
          if (e.is_number()) {
            const double x = e.get<double>();
            r.push_back(x == 0.0 ? LinearExpression{} : LinearExpression{{x, ""}});
          } else if (e.is_string()) {
            try {
              r.push_back(parse_linear_expression(e.get<std::string>()));
            } catch (const InputError& err) {
              fail_at(key_at(key), fmt::format("mechanical base: '{}': {}", key, err.what()));
            }
          } else {
            fail_at(key_at(key), fmt::format("mechanical base: '{}' holds {}; an entry is a number or an expression "
                                             "string",
                                             key, detail::json_excerpt(e)));
          }
        }
        out.push_back(std::move(r));
      }
      return out;
    };
    d.mass = matrix("mass");
    d.damping = matrix("damping");
    d.stiffness = matrix("stiffness");
    d.input_map = matrix("input_map");
    d.output_map = matrix("output_map");
    return d;
  }

  // One user-defined effect: {"description", "blocks": [...], "parameters": {...}}.
  EffectInfo effect_definition(const std::string& name, const json& v, size_t at) const {
    if (!v.is_object())
      fail_at(at, fmt::format("definition '{}' must be an object; write {{\"description\", \"blocks\", \"parameters\"}}",
                              name));
    for (auto it = v.begin(); it != v.end(); ++it) {
      static const char* const kFields[] = {"name", "description", "blocks", "parameters"};
      bool known = false;
      for (const char* k : kFields) known = known || it.key() == k;
      if (!known)
        fail_at(at, fmt::format("definition '{}' has unknown field {}; remove it (the fields are description, blocks, "
                                "parameters)",
                                name, detail::quote_cell(it.key())));
    }
    EffectInfo e;
    e.name = name;
    e.user_defined = true;
    const auto d = v.find("description");
    if (d != v.end()) {
      if (!d->is_string())
        fail_at(at, fmt::format("definition '{}': 'description' must be a string; write it in double quotes", name));
      e.description = d->get<std::string>();
    }
    if (e.description.empty()) e.description = "user-defined effect";
    e.changes = "user-defined (docs/effects.md, building blocks)";
    e.signature = "as its blocks say";
    const auto blocks = v.find("blocks");
    if (blocks == v.end() || !blocks->is_array() || blocks->empty())
      fail_at(at, fmt::format("definition '{}' needs 'blocks'; give a non-empty array of {{\"kind\", \"side\", "
                              "\"channels\", \"parameters\"}}",
                              name));
    for (const json& b : *blocks) {
      if (!b.is_object())
        fail_at(at, fmt::format("definition '{}': each block is an object; write {{\"kind\", \"side\", \"channels\", "
                                "\"parameters\"}}",
                                name));
      for (auto it = b.begin(); it != b.end(); ++it)
        if (it.key() != "kind" && it.key() != "side" && it.key() != "channels" && it.key() != "parameters")
          fail_at(at, fmt::format("definition '{}': a block has unknown field {}; remove it (the fields are kind, side, "
                                  "channels, parameters)",
                                  name, detail::quote_cell(it.key())));
      Block blk;
      auto text_field = [&](const char* field) {
        const auto f = b.find(field);
        if (f == b.end() || !f->is_string())
          fail_at(at, fmt::format("definition '{}': a block needs '{}'; give it as a string", name, field));
        return f->get<std::string>();
      };
      auto names_field = [&](const char* field, bool required) {
        std::vector<std::string> out;
        const auto f = b.find(field);
        if (f == b.end()) {
          if (required) fail_at(at, fmt::format("definition '{}': a block needs '{}'; give an array of names", name, field));
          return out;
        }
        if (!f->is_array())
          fail_at(at, fmt::format("definition '{}': '{}' must be an array; give an array of names", name, field));
        for (const json& x : *f) {
          if (!x.is_string()) fail_at(at, fmt::format("definition '{}': '{}' holds {}, not a name; write names as strings", name, field,
                                    detail::json_excerpt(x)));
          out.push_back(x.get<std::string>());
        }
        return out;
      };
      try {
        blk.kind = parse_block_kind(text_field("kind"));
        blk.side = parse_block_side(text_field("side"));
      } catch (const InputError& err) {
        fail_at(at, fmt::format("definition '{}': {}", name, err.what()));
      }
      blk.channels = names_field("channels", false);
      blk.parameters = names_field("parameters", true);
      e.blocks.push_back(std::move(blk));
    }
    const auto params = v.find("parameters");
    if (params == v.end() || !params->is_object())
      fail_at(at, fmt::format("definition '{}' needs 'parameters'; give name -> {{value, unit, lower, upper, free}} (the "
                              "defaults)",
                              name));
    for (auto it = params->begin(); it != params->end(); ++it) e.parameters.push_back(parameter(it.key(), it.value(), at));
    return e;
  }

 private:
  PhysicalParameter parameter(const std::string& name, const json& v, size_t at_hint = std::string::npos) const {
    const size_t at = at_hint != std::string::npos ? at_hint : param(name);
    if (!v.is_object())
      fail_at(at, fmt::format("parameter '{}' must be an object; write {{\"value\", \"unit\", \"lower\", \"upper\", \"free\"}}",
                              name));
    for (auto it = v.begin(); it != v.end(); ++it) {
      static const char* const kFields[] = {"value", "unit", "lower", "upper", "free", "prior"};
      bool known = false;
      for (const char* k : kFields) known = known || it.key() == k;
      if (!known)
        fail_at(at, fmt::format("parameter '{}' has unknown field {}; remove it (the fields are value, unit, lower, upper, free and optionally prior)",
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
    const auto prior = v.find("prior");
    if (prior != v.end()) {
      const char* const kPriorForm = "write \"prior\": {\"mean\": DESIGN_VALUE, \"sigma\": UNCERTAINTY > 0}";
      if (!prior->is_object() || prior->size() != 2 || !prior->contains("mean") || !prior->contains("sigma"))
        fail_at(at, fmt::format("parameter '{}': field 'prior' must hold exactly 'mean' and 'sigma'; {}", name, kPriorForm));
      const json& mean = (*prior)["mean"];
      const json& sigma = (*prior)["sigma"];
      if (!mean.is_number() || !sigma.is_number() || !(sigma.get<double>() > 0.0) ||
          !std::isfinite(sigma.get<double>()) || !std::isfinite(mean.get<double>()))
        fail_at(at, fmt::format("parameter '{}': prior mean {} and sigma {} must be finite numbers, sigma > 0; {}", name,
                                detail::json_excerpt(mean), detail::json_excerpt(sigma), kPriorForm));
      p.prior_mean = mean.get<double>();
      p.prior_sigma = sigma.get<double>();
    }
    return p;
  }

  const std::string& text_;
  const std::string& path_;
};

std::string parameter_json_text(const PhysicalParameter& p) {
  const std::string prior = p.has_prior() ? fmt::format(", \"prior\": {{\"mean\": {}, \"sigma\": {}}}",
                                                        json(p.prior_mean).dump(), json(p.prior_sigma).dump())
                                          : std::string();
  return fmt::format("{{\"value\": {}, \"unit\": {}, \"lower\": {}, \"upper\": {}, \"free\": {}{}}}",
                     json(p.value).dump(), json(p.unit).dump(), json(p.lower).dump(), json(p.upper).dump(),
                     p.free ? "true" : "false", prior);
}

}  // namespace

nlohmann::ordered_json mechanical_description_json(const MechanicalDescription& d) {
  auto channels = [](const std::vector<MechanicalChannel>& list) {
    json a = json::array();
    static const char* const kMeasures[] = {"position", "velocity", "acceleration"};
    for (const auto& c : list) {
      json e = {{"name", c.name}, {"unit", c.unit}};
      if (c.derivative != 0) e["measures"] = kMeasures[c.derivative];
      a.push_back(e);
    }
    return a;
  };
  auto matrix = [](const std::vector<std::vector<LinearExpression>>& m) {
    json rows = json::array();
    for (const auto& row : m) {
      json r = json::array();
      for (const LinearExpression& e : row) {
        if (e.empty())
          r.push_back(0);
        else if (e.size() == 1 && e[0].parameter.empty())
          r.push_back(e[0].coefficient);
        else
          r.push_back(linear_expression_text(e));
      }
      rows.push_back(r);
    }
    return rows;
  };
  json params = json::object();
  for (const PhysicalParameter& p : d.parameters) params[p.name] = json::parse(parameter_json_text(p));
  json out = {{"name", d.name}};
  if (!d.description.empty()) out["description"] = d.description;
  out["dofs"] = channels(d.dofs);
  out["inputs"] = channels(d.inputs);
  out["outputs"] = channels(d.outputs);
  out["parameters"] = params;
  out["mass"] = matrix(d.mass);
  out["damping"] = matrix(d.damping);
  out["stiffness"] = matrix(d.stiffness);
  out["input_map"] = matrix(d.input_map);
  out["output_map"] = matrix(d.output_map);
  return out;
}

MechanicalDescription parse_mechanical_description(const std::string& text, const std::string& path) {
  const json root = parse_ordered(path, text);
  const Reader reader(text, path);
  MechanicalDescription d = reader.mechanical_description(root, 0, true);
  try {
    make_mechanical_base(d);
  } catch (const InputError& e) {
    detail::fail_at(path, 1, 1, e.what());
  }
  return d;
}

MechanicalDescription read_mechanical_description(const std::string& path) {
  return parse_mechanical_description(detail::read_json_text(path, "a mechanical base description"), path);
}

nlohmann::ordered_json effect_definition_json(const EffectInfo& e) {
  json blocks = json::array();
  for (const Block& b : e.blocks)
    blocks.push_back({{"kind", block_kind_name(b.kind)},
                      {"side", block_side_name(b.side)},
                      {"channels", b.channels},
                      {"parameters", b.parameters}});
  json params = json::object();
  for (const PhysicalParameter& p : e.parameters) params[p.name] = json::parse(parameter_json_text(p));
  return {{"description", e.description}, {"blocks", blocks}, {"parameters", params}};
}

std::string effect_definition_file(const EffectInfo& e) {
  json j = effect_definition_json(e);
  j["name"] = e.name;
  return j.dump(2) + "\n";
}

EffectInfo parse_effect_definition(const std::string& text, const std::string& path) {
  const json root = parse_ordered(path, text);
  if (!root.is_object() || !root.contains("name") || !root["name"].is_string())
    detail::fail_at(path, 1, 1, "an effect definition file is a JSON object with a 'name' (a string), 'description', "
                                "'blocks' and 'parameters' (docs/formats.md; lpvid diagnose --out-effect writes one)");
  const std::string name = root["name"].get<std::string>();
  return Reader(text, path).effect_definition(name, root, 0);
}

EffectInfo read_effect_definition(const std::string& path) {
  return parse_effect_definition(detail::read_json_text(path, "an effect definition file"), path);
}

PhysicalModel parse_physical_model(const std::string& text, const std::string& path) {
  return Reader(text, path).read();
}

bool is_physical_model_file(const std::string& path) {
  // Only a regular file is probed: a pipe or stdin would be consumed by the probe.
  std::error_code ec;
  if (path == "-" || !std::filesystem::is_regular_file(path, ec)) return false;
  try {
    const std::string text = detail::read_json_text(path, "a physical model file");
    const nlohmann::json j = detail::parse_json(path, text);
    return j.is_object() && j.contains("format") && j["format"] == kPhysicalModelFormat;
  } catch (const InputError&) {
    return false;  // not readable JSON: the caller's other reader says why
  }
}

PhysicalModel read_physical_model(const std::string& path) {
  return parse_physical_model(detail::read_json_text(path, "a physical model file"), path);
}

PhysicalModel read_physical_model(const std::string& path, nlohmann::json* fit_section) {
  return Reader(detail::read_json_text(path, "a physical model file"), path).read(fit_section);
}

std::string physical_model_to_json(const PhysicalModel& model, const nlohmann::json& fit_section) {
  model.validate();
  if (!fit_section.is_null() && !fit_section.is_object())
    throw InputError("the fit section of a model file must be a JSON object");
  std::string out = fmt::format("{{\n  \"format\": \"{}\",\n  \"version\": {},\n  \"base\": {},\n",
                                kPhysicalModelFormat, kPhysicalModelVersion, json(model.base).dump());
  if (model.user_base != nullptr) {
    // one line per key (per parameter), each value compact: a reader sees the matrices' rows
    const json d = mechanical_description_json(model.user_base->description);
    out += "  \"mechanical\": {\n";
    std::size_t k = 0;
    for (auto it = d.begin(); it != d.end(); ++it, ++k) {
      const std::string comma = k + 1 < d.size() ? "," : "";
      if (it.key() == "parameters") {
        out += "    \"parameters\": {\n";
        std::size_t i = 0;
        for (auto p = it->begin(); p != it->end(); ++p, ++i)
          out += fmt::format("      {}: {}{}\n", json(p.key()).dump(), p->dump(), i + 1 < it->size() ? "," : "");
        out += "    }" + comma + "\n";
      } else {
        out += fmt::format("    {}: {}{}\n", json(it.key()).dump(), it->dump(), comma);
      }
    }
    out += "  },\n";
  }
  out += fmt::format("  \"effects\": {},\n", json(model.effects).dump());
  if (!model.definitions.empty()) {
    out += "  \"definitions\": {\n";
    for (std::size_t k = 0; k < model.definitions.size(); ++k) {
      std::string d = effect_definition_json(model.definitions[k]).dump(2);
      for (size_t pos = d.find('\n'); pos != std::string::npos; pos = d.find('\n', pos + 1)) d.insert(pos + 1, "    ");
      out += fmt::format("    {}: {}{}\n", json(model.definitions[k].name).dump(), d,
                         k + 1 < model.definitions.size() ? "," : "");
    }
    out += "  },\n";
  }
  out += "  \"parameters\": {\n";
  for (std::size_t i = 0; i < model.parameters.size(); ++i) {
    out += fmt::format("    {}: {}{}\n", json(model.parameters[i].name).dump(), parameter_json_text(model.parameters[i]),
                       i + 1 < model.parameters.size() ? "," : "");
  }
  out += "  }";
  if (!model.design_values.empty()) {
    out += ",\n  \"design_values\": {\n";
    for (std::size_t i = 0; i < model.design_values.size(); ++i)
      out += fmt::format("    {}: {}{}\n", json(model.design_values[i].name).dump(),
                         parameter_json_text(model.design_values[i]), i + 1 < model.design_values.size() ? "," : "");
    out += "  }";
  }
  if (fit_section.is_object() && !fit_section.empty()) {
    // The fit section names data files, which may not be UTF-8: written with U+FFFD.
    std::string fit = fit_section.dump(2, ' ', false, json::error_handler_t::replace);
    for (size_t pos = fit.find('\n'); pos != std::string::npos; pos = fit.find('\n', pos + 1)) fit.insert(pos + 1, "  ");
    out += ",\n  \"fit\": " + fit;
  }
  out += "\n}\n";
  return out;
}

void write_physical_model(const std::string& path, const PhysicalModel& model, const nlohmann::json& fit_section) {
  write_file_atomic(path, physical_model_to_json(model, fit_section));
}

}  // namespace lpvid
