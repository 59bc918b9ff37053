#include "formats/io/diagnosis_json.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

#include "formats/io/json_detail.h"
#include "idlib/core/error.h"

namespace lpvid {

DiagnosisStart read_diagnosis_start(const std::string& path, const std::vector<std::string>& effects) {
  const std::string text = detail::read_json_text(path, "a diagnose report");
  const nlohmann::json j = detail::parse_json(path, text);
  auto at_key = [&](const char* key) {
    const detail::CellPosition p = detail::text_position(text, detail::find_top_level_key(text, key));
    return fmt::format("{}:{}:{}", path, p.line, p.column);
  };
  if (!j.is_object() || !j.contains("candidates") || !j["candidates"].is_array())
    throw InputError(fmt::format("{}:1:1: not a diagnose report (no \"candidates\" list); write one with lpvid diagnose "
                                 "--model MODEL --datasets DATA --json > {}",
                                 path, path));
  std::vector<std::string> wanted = effects;
  std::sort(wanted.begin(), wanted.end());
  std::vector<std::string> offered;
  for (const char* list : {"candidates", "combinations"}) {
    if (!j.contains(list)) continue;
    if (!j[list].is_array()) throw InputError(fmt::format("{}: \"{}\" must be a list of candidates", at_key(list), list));
    for (const nlohmann::json& c : j[list]) {
      if (!c.is_object() || !c.contains("effect") || !c["effect"].is_string())
        throw InputError(fmt::format("{}: a candidate without its \"effect\" name; write the report again with lpvid "
                                     "diagnose --json",
                                     at_key(list)));
      const std::string name = c["effect"].get<std::string>();
      offered.push_back(name);
      std::vector<std::string> members;
      if (c.contains("members") && c["members"].is_array()) {
        for (const nlohmann::json& m : c["members"])
          if (m.is_string()) members.push_back(m.get<std::string>());
      } else {
        members = {name};  // a report written before combinations
      }
      std::sort(members.begin(), members.end());
      if (members != wanted) continue;
      if (!c.value("fitted", false) || !c.contains("values") || !c["values"].is_object())
        throw InputError(fmt::format("{}: the candidate '{}' was not refitted in this report ({}); there is no start "
                                     "to take: add it without --from-diagnosis and fit",
                                     at_key(list), name, c.value("failure", std::string("no values"))));
      DiagnosisStart out;
      out.candidate = name;
      out.significant = c.value("significant", false);
      out.verdict = c.value("verdict", std::string());
      if (c.contains("error") && c["error"].is_number()) out.error = c["error"].get<double>();
      for (const auto& [key, v] : c["values"].items()) {
        if (!v.is_number() || !std::isfinite(v.get<double>()))
          throw InputError(fmt::format("{}: candidate '{}': the value of {} is {}, not a finite number", at_key(list),
                                       name, key, detail::json_excerpt(v)));
        out.values.emplace_back(key, v.get<double>());
      }
      return out;
    }
  }
  throw InputError(fmt::format("{}: no candidate '{}' in this report (it has: {}); name one of them, or diagnose again "
                               "with --candidates {}",
                               path, fmt::join(effects, " + "), fmt::join(offered, ", "), fmt::join(effects, ",")));
}

}  // namespace lpvid
