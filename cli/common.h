// Shared plumbing for subcommands: option parsing helpers and summaries.
// No mathematics here (STYLE.md item 8).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace lpvid::cli {

// Splits "a,b,c" into names, trimming spaces around each (inner spaces stay:
// "P from S, truth"); rejects empty names (InputError naming the flag).
std::vector<std::string> split_names(const std::string& text, const std::string& flag);

// Prints a summary: as JSON when as_json, else as the given human text.
void print_summary(bool as_json, const nlohmann::json& summary, const std::string& text);

// Ensures the output directory exists (creating it) and is not a file.
void ensure_directory(const std::string& dir);

// dir + "/" + name, without doubling the slash.
std::string join_path(const std::string& dir, const std::string& name);

}  // namespace lpvid::cli

namespace lpvid {
struct EraOptions;
struct MarkovFile;
}  // namespace lpvid

namespace lpvid::cli {
// ERA options carrying the scales and noise levels recorded in a Markov file.
EraOptions era_options_from(const MarkovFile& file);
}  // namespace lpvid::cli
