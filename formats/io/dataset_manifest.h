// lpvid — the dataset manifest read by fit, diagnose and compare with a physical
// model (--datasets FILE; docs/formats.md, "Data-set manifest"): the data files and
// beam positions of every data set, given once instead of --data FILE@X_B flags.
//
//   {"format": "lpvid-datasets",
//    "target": "S", "controller": "middle/controller.json", "rate_hz": 1000,
//    "averages": 16, "noise_level": 0.01, "band_rad_s": [1, 600],
//    "datasets": [{"beam_position_m": -0.1, "files": ["left/S_v1.csv", "left/S_v2.csv", "left/S_v3.csv"]},
//                 {"beam_position_m": 0, "files": ["middle/S.csv"], "label": "middle"}]}
//
// | key             | type / unit | rule |
// |-----------------|-------------|------|
// | format          | "lpvid-datasets" | required |
// | datasets        | non-empty array of {beam_position_m: number (m), files: non-empty array of paths, label: string} | required; label optional |
// | target          | string: plant, G or S | optional (checked by the caller) |
// | controller      | string: a state-space JSON path, or a measured controller's FRD (.csv/.mat) | optional |
// | rate_hz, averages, noise_level | numbers (Hz, count, fraction) | optional (ranges checked by the caller) |
// | band_rad_s      | [low, high], rad/s | optional |
// Relative paths are relative to the manifest's folder.  Unknown keys are errors.
// Read with the bounded JSON reader (formats/io/json_detail.h: 64 MiB, 64 levels).
#pragma once

#include <limits>
#include <string>
#include <vector>

namespace lpvid {

struct ManifestDataset {
  std::vector<std::string> files;  // resolved against the manifest's folder; one, or one per excited input
  double beam_position_m = 0.0;
  std::string label;               // the file's, else "x_b = X m"
};

// The manifest's values; NaN or empty where it does not say.
struct DatasetManifest {
  std::string target, controller;
  double rate_hz = std::numeric_limits<double>::quiet_NaN();
  double averages = std::numeric_limits<double>::quiet_NaN();
  double noise_level = std::numeric_limits<double>::quiet_NaN();
  double band_min = std::numeric_limits<double>::quiet_NaN();
  double band_max = std::numeric_limits<double>::quiet_NaN();
  std::vector<ManifestDataset> datasets;
};

// @throws InputError "path:line:column: what; what to do" (the key's place) for
//   anything that breaks the table, and as detail::read_json_text / parse_json.
DatasetManifest read_dataset_manifest(const std::string& path);

}  // namespace lpvid
