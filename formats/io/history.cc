#include "formats/io/history.h"

#include <fmt/format.h>

#include <sys/stat.h>

#include <cerrno>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "formats/io/atomic_file.h"
#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using nlohmann::json;

bool iso_utc(const std::string& t) {
  // YYYY-MM-DDThh:mm:ssZ
  if (t.size() != 20 || t[4] != '-' || t[7] != '-' || t[10] != 'T' || t[13] != ':' || t[16] != ':' || t[19] != 'Z')
    return false;
  for (std::size_t i : {0, 1, 2, 3, 5, 6, 8, 9, 11, 12, 14, 15, 17, 18})
    if (t[i] < '0' || t[i] > '9') return false;
  return true;
}

bool nonneg(double v) { return std::isfinite(v) && v >= 0; }

json number_or_null(double v) { return std::isnan(v) ? json(nullptr) : json(v); }

// The whole file (at most 64 MiB: detail::JsonLimits); exists = false when there is none.
std::string read_all(const std::string& path, bool& exists) {
  struct stat st;
  exists = !(::stat(path.c_str(), &st) != 0 && errno == ENOENT);
  if (!exists) return {};
  return detail::read_json_text(path, "a fit history");
}

// The record on one line; throws "path:line:column: ..." for anything wrong.
HistoryRecord parse_line(const std::string& path, int64_t line, const std::string& text) {
  const json j = detail::parse_json(path, text, {}, line);
  auto fail = [&](const std::string& what) { detail::fail_at(path, line, 1, what); };
  if (!j.is_object()) fail(fmt::format("the line holds {} where a JSON object (one fit record) is expected", j.type_name()));
  static const std::set<std::string> known = {"timestamp", "model", "effects", "free_parameters", "cost", "error_mean",
                                              "error_max", "error", "noise_floor", "channels", "aic", "bic",
                                              "note"};
  for (const auto& [key, value] : j.items())
    if (!known.count(key))
      fail(fmt::format("unknown key {}; remove it (a fit record has timestamp, model, effects, free_parameters, "
                       "cost, error_mean, error_max, error, noise_floor, channels, aic, bic, note)",
                       detail::quote_cell(key)));
  auto need = [&](const char* key) -> const json& {
    if (!j.contains(key)) fail(fmt::format("no key '{}'; every fit record needs it (docs/formats.md, \"Fit history\")", key));
    return j.at(key);
  };
  auto string_at = [&](const json& v, const std::string& key) {
    if (!v.is_string()) fail(fmt::format("key '{}' must be a string, got {}; write it as a quoted string", key, v.type_name()));
    return v.get<std::string>();
  };
  auto number_at = [&](const json& v, const std::string& key) {
    if (!v.is_number()) fail(fmt::format("key '{}' must be a number, got {}; write a number", key, v.type_name()));
    return v.get<double>();
  };
  HistoryRecord r;
  r.timestamp = string_at(need("timestamp"), "timestamp");
  r.model = string_at(need("model"), "model");
  const json& effects = need("effects");
  if (!effects.is_array()) fail(fmt::format("key 'effects' must be an array of strings, got {}; write e.g. [\"input_delay\"]", effects.type_name()));
  for (const json& e : effects) r.effects.push_back(string_at(e, "effects"));
  const json& fp = need("free_parameters");
  if (!fp.is_number_integer())
    fail(fmt::format("key 'free_parameters' must be an integer, got {}; write a whole number", detail::json_excerpt(fp)));
  r.free_parameters = fp.get<Index>();
  r.cost = number_at(need("cost"), "cost");
  r.error_mean = number_at(need("error_mean"), "error_mean");
  r.error_max = number_at(need("error_max"), "error_max");
  if (j.contains("channels")) {
    const json& ch = j.at("channels");
    if (!ch.is_array()) fail(fmt::format("key 'channels' must be an array, got {}; write an array of channel records", ch.type_name()));
    for (const json& c : ch) {
      if (!c.is_object() || !c.contains("output") || !c.contains("input") || !c.contains("error_mean") ||
          !c.contains("error_max") || c.size() != 4)
        fail("each entry of 'channels' must be {\"output\", \"input\", \"error_mean\", \"error_max\"} and nothing else");
      r.channels.push_back({string_at(c.at("output"), "channels.output"), string_at(c.at("input"), "channels.input"),
                            number_at(c.at("error_mean"), "channels.error_mean"),
                            number_at(c.at("error_max"), "channels.error_max")});
    }
  }
  for (const char* key : {"aic", "bic"})
    if (j.contains(key) && !j.at(key).is_null()) (key[0] == 'a' ? r.aic : r.bic) = number_at(j.at(key), key);
  if (j.contains("error") && !j.at("error").is_null()) r.error = number_at(j.at("error"), "error");
  if (j.contains("noise_floor") && !j.at("noise_floor").is_null())
    r.noise_floor = number_at(j.at("noise_floor"), "noise_floor");
  if (j.contains("note")) r.note = string_at(j.at("note"), "note");
  try {
    r.validate();
  } catch (const InputError& e) {
    fail(e.what());
  }
  return r;
}

}  // namespace

void HistoryRecord::validate() const {
  if (!iso_utc(timestamp))
    throw InputError(fmt::format("timestamp {} is not ISO 8601 UTC; write it as YYYY-MM-DDThh:mm:ssZ",
                                 detail::quote_cell(timestamp)));
  if (model.empty()) throw InputError("model is empty; name the model file the fit wrote");
  if (free_parameters < 0)
    throw InputError(fmt::format("free_parameters is {}; write the number of free parameters (>= 0)", free_parameters));
  if (!nonneg(cost)) throw InputError(fmt::format("cost is {}; write the fit's cost, finite and >= 0", cost));
  if (!nonneg(error_mean) || !nonneg(error_max) || error_max < error_mean)
    throw InputError(fmt::format("error_mean {} and error_max {}; write both finite and >= 0, with max >= mean", error_mean,
                                 error_max));
  for (const auto& c : channels)
    if (c.output.empty() || c.input.empty() || !nonneg(c.error_mean) || !nonneg(c.error_max))
      throw InputError(fmt::format("channel '{}' <- '{}': give non-empty names and finite errors >= 0",
                                   c.output, c.input));
  if (std::isinf(aic) || std::isinf(bic)) throw InputError("aic and bic are not finite; write finite numbers or null (not computed)");
  if (!(std::isnan(error) || nonneg(error)) || !(std::isnan(noise_floor) || nonneg(noise_floor)))
    throw InputError(fmt::format("error {} and noise_floor {}: write finite numbers >= 0, or null (not recorded)",
                                 error, noise_floor));
}

std::string history_path_for(const std::string& model_path) { return model_path + ".history.jsonl"; }

std::string utc_timestamp_now() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string history_line(const HistoryRecord& r) {
  r.validate();
  json channels = json::array();
  for (const auto& c : r.channels)
    channels.push_back({{"output", c.output}, {"input", c.input}, {"error_mean", c.error_mean}, {"error_max", c.error_max}});
  json j = {{"timestamp", r.timestamp},
            {"model", r.model},
            {"effects", r.effects},
            {"free_parameters", r.free_parameters},
            {"cost", r.cost},
            {"error_mean", r.error_mean},
            {"error_max", r.error_max},
            {"error", number_or_null(r.error)},
            {"noise_floor", number_or_null(r.noise_floor)},
            {"channels", channels},
            {"aic", number_or_null(r.aic)},
            {"bic", number_or_null(r.bic)},
            {"note", r.note}};
  // Model paths and notes may not be UTF-8: written with U+FFFD.
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

void append_history(const std::string& path, const HistoryRecord& record) {
  const std::string line = history_line(record);
  bool exists = false;
  std::string old = read_all(path, exists);
  if (exists) {
    read_history(path);  // never append to a broken history
    if (!old.empty() && old.back() != '\n') old += '\n';
  }
  write_file_atomic(path, old + line + "\n");
}

std::vector<HistoryRecord> read_history(const std::string& path, std::string* text_out) {
  bool exists = false;
  const std::string text = read_all(path, exists);
  if (!exists)
    throw InputError(fmt::format("no history file '{}'; fit a model first (each fit appends a record) or give the "
                                 "model the history belongs to",
                                 path));
  std::vector<HistoryRecord> out;
  int64_t line = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    ++line;
    const std::string row = text.substr(start, end - start);
    if (row.find_first_not_of(" \t\r") == std::string::npos)
      detail::fail_at(path, line, 1, "empty line; a history file has one JSON record per line and no blank lines");
    out.push_back(parse_line(path, line, row));
    start = end + 1;
  }
  if (text_out != nullptr) *text_out = text;
  return out;
}

}  // namespace lpvid
