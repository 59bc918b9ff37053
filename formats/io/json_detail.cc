#include "formats/io/json_detail.h"

#include <algorithm>
#include <cstring>

namespace lpvid::detail {

CellPosition text_position(const std::string& text, size_t offset) {
  offset = std::min(offset, text.size());
  CellPosition at{1, 1};
  for (size_t i = 0; i < offset; ++i) {
    if (text[i] == '\n') {
      ++at.line;
      at.column = 1;
    } else {
      ++at.column;
    }
  }
  return at;
}

size_t find_top_level_key(const std::string& text, const std::string& name) {
  int depth = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '{' || c == '[') {
      ++depth;
    } else if (c == '}' || c == ']') {
      --depth;
    } else if (c == '"') {
      const size_t start = i;
      for (++i; i < text.size() && text[i] != '"'; ++i)
        if (text[i] == '\\') ++i;
      if (depth != 1) continue;
      size_t j = i + 1;
      while (j < text.size() && std::strchr(" \t\r\n", text[j]) != nullptr) ++j;
      if (j < text.size() && text[j] == ':' && text.compare(start + 1, i - start - 1, name) == 0) return start;
    }
  }
  return 0;
}

}  // namespace lpvid::detail
