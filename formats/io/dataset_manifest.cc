#include "formats/io/dataset_manifest.h"

#include <fmt/format.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"

namespace lpvid {

DatasetManifest read_dataset_manifest(const std::string& path) {
  using nlohmann::json;
  const std::string text = detail::read_json_text(path, "a dataset manifest");
  auto fail = [&](const std::string& key, const std::string& what) {
    const size_t at = key.empty() ? 0 : detail::find_top_level_key(text, key);
    const detail::CellPosition pos = detail::text_position(text, at);
    detail::fail_at(path, pos.line, pos.column, what);
  };
  const json root = detail::parse_json(path, text);
  if (!root.is_object())
    fail("", "a dataset manifest is a JSON object; write {\"format\": \"lpvid-datasets\", \"datasets\": [...]} "
             "(docs/formats.md)");
  if (!root.contains("format") || root["format"] != "lpvid-datasets")
    fail("format", "key 'format' must be \"lpvid-datasets\"; give a dataset manifest (docs/formats.md, \"Data-set "
                   "manifest\")");
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  auto resolve = [&](const std::string& p) {
    const std::filesystem::path q(p);
    return (q.is_absolute() || dir.empty() ? q : dir / q).lexically_normal().string();
  };
  DatasetManifest m;
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string& key = it.key();
    const json& v = it.value();
    auto number = [&](double& out) {
      if (!v.is_number()) fail(key, fmt::format("key '{}' must be a number; give it as a JSON number", key));
      out = v.get<double>();
    };
    if (key == "format") {
      continue;
    } else if (key == "target" || key == "controller") {
      if (!v.is_string()) fail(key, fmt::format("key '{}' must be a string; give it in double quotes", key));
      (key == "target" ? m.target : m.controller) = key == "controller" ? resolve(v.get<std::string>()) : v.get<std::string>();
    } else if (key == "rate_hz") {
      number(m.rate_hz);
    } else if (key == "averages") {
      number(m.averages);
    } else if (key == "noise_level") {
      number(m.noise_level);
    } else if (key == "band_rad_s") {
      if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number())
        fail(key, "key 'band_rad_s' must be a pair; give [low, high] in rad/s, e.g. [1, 600]");
      m.band_min = v[0].get<double>();
      m.band_max = v[1].get<double>();
    } else if (key == "datasets") {
      if (!v.is_array() || v.empty())
        fail(key, "key 'datasets' must be a non-empty array; give [{\"beam_position_m\": X, \"files\": [...]}, ...]");
      for (const json& d : v) {
        if (!d.is_object() || !d.contains("beam_position_m") || !d["beam_position_m"].is_number() ||
            !d.contains("files") || !d["files"].is_array() || d["files"].empty())
          fail(key, "each data set is an object; give {\"beam_position_m\": X (m), \"files\": [\"a.csv\", ...]} (one "
                    "file, or one per excited input)");
        for (auto f = d.begin(); f != d.end(); ++f)
          if (f.key() != "beam_position_m" && f.key() != "files" && f.key() != "label")
            fail(key, fmt::format("a data set has unknown key {}; give beam_position_m, files and optionally label",
                                  detail::quote_cell(f.key())));
        ManifestDataset s;
        s.beam_position_m = d["beam_position_m"].get<double>();
        for (const json& f : d["files"]) {
          if (!f.is_string()) fail(key, fmt::format("files: {} is not a path; give each file as a string", detail::json_excerpt(f)));
          s.files.push_back(resolve(f.get<std::string>()));
        }
        s.label = d.contains("label") && d["label"].is_string() ? d["label"].get<std::string>()
                                                                : fmt::format("x_b = {:g} m", s.beam_position_m);
        m.datasets.push_back(std::move(s));
      }
    } else {
      fail(key, fmt::format("unknown key {}; remove it (a manifest has format, datasets and optionally target, "
                            "controller, rate_hz, averages, noise_level, band_rad_s)",
                            detail::quote_cell(key)));
    }
  }
  if (m.datasets.empty()) fail("", "the manifest has no 'datasets'; list the files and x_b of every data set");
  return m;
}

}  // namespace lpvid
