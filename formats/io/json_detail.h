// Positions inside JSON texts, shared by the JSON readers of formats/io (model,
// platform parameter and physical model files), for file:line:column messages.
#pragma once

#include <cstddef>
#include <string>

#include "formats/io/csv_detail.h"

namespace lpvid::detail {

// 1-based line and byte column of text[offset] (offset clamped to the text).
CellPosition text_position(const std::string& text, size_t offset);

// Offset of the top-level key "name" in a syntactically valid JSON object text;
// 0 if not found.
size_t find_top_level_key(const std::string& text, const std::string& name);

}  // namespace lpvid::detail
