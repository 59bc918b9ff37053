// JSON texts for the readers of formats/io (model, platform parameter, physical
// model and history files): reading with a size limit, parsing with a depth
// limit and positioned errors, positions of keys for file:line:column messages.
// Not a public interface: include only from formats/io/*.cc (and their tests).
#pragma once

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

#include "formats/io/csv_detail.h"

namespace lpvid::detail {

// What a JSON file may ask of the reader (docs/formats.md, "Limits").
struct JsonLimits {
  // Largest file read, in bytes: a 500-state model is about 6 MB of text.
  std::size_t max_bytes = std::size_t{64} << 20;
  // Deepest nesting of arrays and objects: lpvid's files nest at most 5 deep.
  int max_depth = 64;
};

// The whole file ("-": stdin; a FIFO or device is read to its end), at most
// limits.max_bytes bytes.  `kind` names the file in messages ("a model file").
// Throws InputError "cannot open 'x.json': ...; check the path",
// "x.json: larger than 64 MiB; a model file is far smaller: check that this is the right file".
std::string read_json_text(const std::string& path, const char* kind, const JsonLimits& limits = {});

// Parses text (read from `path`, which starts at line first_line) into JSON.
// Throws InputError "path:line:column: what; what to do" for a syntax error (at
// the offending byte), a number beyond the range of a double ("1e400", at the
// number), or nesting deeper than limits.max_depth (at the opening bracket).
nlohmann::json parse_json(const std::string& path, const std::string& text, const JsonLimits& limits = {},
                          int64_t first_line = 1);

// A value for a message: its compact JSON text (self-delimiting, so not
// quoted), at most 40 bytes (longer text cut with "..."), invalid UTF-8 replaced.
std::string json_excerpt(const nlohmann::json& value);

// 1-based line and byte column of text[offset] (offset clamped to the text).
CellPosition text_position(const std::string& text, size_t offset);

// Offset of the top-level key "name" in a syntactically valid JSON object text;
// 0 if not found.
size_t find_top_level_key(const std::string& text, const std::string& name);

}  // namespace lpvid::detail
