#include "cli/common.h"

#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <system_error>

#include "idlib/core/error.h"

namespace lpvid::cli {

std::vector<std::string> split_names(const std::string& text, const std::string& flag) {
  std::vector<std::string> names;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::size_t first = item.find_first_not_of(' ');
    item = first == std::string::npos ? std::string() : item.substr(first, item.find_last_not_of(' ') - first + 1);
    if (item.empty())
      throw InputError(fmt::format("{} '{}': empty name; give names separated by commas, e.g. v1,v2,v3", flag, text));
    names.push_back(item);
    if (comma == std::string::npos) return names;
    start = comma + 1;
  }
}

void print_summary(bool as_json, const nlohmann::json& summary, const std::string& text) {
  if (as_json) {
    std::fputs((summary.dump(2) + "\n").c_str(), stdout);
  } else {
    std::fputs(text.c_str(), stdout);
  }
}

void ensure_directory(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw InputError(fmt::format("'{}' exists and is not a directory; give --out a directory path", dir));
  fs::create_directories(dir, ec);
  if (ec) throw InputError(fmt::format("cannot create directory '{}': {}; check the path and permissions", dir, ec.message()));
}

std::string join_path(const std::string& dir, const std::string& name) {
  if (dir.empty() || dir.back() == '/') return dir + name;
  return dir + "/" + name;
}

}  // namespace lpvid::cli

#include "formats/io/markov_csv.h"
#include "idlib/realization/era.h"

namespace lpvid::cli {

EraOptions era_options_from(const MarkovFile& file) {
  EraOptions o;
  o.sample_period_s = file.sample_period_s;
  o.input_scale = file.input_rms;
  o.output_scale = file.output_rms;
  o.markov_noise_std = file.noise_std;
  o.input_names = file.inputs;
  o.output_names = file.outputs;
  return o;
}

}  // namespace lpvid::cli
