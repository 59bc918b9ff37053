#include "formats/io/json_detail.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "idlib/core/error.h"

namespace lpvid::detail {

namespace {

using nlohmann::json;

// Builds the document (nlohmann's own DOM builder) and keeps the position and
// text of the first error instead of throwing it without a position.
class PositionedSax {
 public:
  explicit PositionedSax(json& root) : dom_(root, false) {}

  bool null() { return dom_.null(); }
  bool boolean(bool v) { return dom_.boolean(v); }
  bool number_integer(json::number_integer_t v) { return dom_.number_integer(v); }
  bool number_unsigned(json::number_unsigned_t v) { return dom_.number_unsigned(v); }
  bool number_float(json::number_float_t v, const json::string_t& s) { return dom_.number_float(v, s); }
  bool string(json::string_t& v) { return dom_.string(v); }
  bool binary(json::binary_t& v) { return dom_.binary(v); }
  bool start_object(std::size_t n) { return dom_.start_object(n); }
  bool key(json::string_t& v) { return dom_.key(v); }
  bool end_object() { return dom_.end_object(); }
  bool start_array(std::size_t n) { return dom_.start_array(n); }
  bool end_array() { return dom_.end_array(); }
  bool parse_error(std::size_t position, const std::string& token, const nlohmann::detail::exception& ex) {
    failed = true;
    error_position = position;
    error_token = token;
    error_id = ex.id;
    error_what = ex.what();
    return false;
  }

  bool failed = false;
  std::size_t error_position = 0;
  std::string error_token;
  int error_id = 0;
  std::string error_what;

 private:
  nlohmann::detail::json_sax_dom_parser<json> dom_;
};

[[noreturn]] void fail_at_offset(const std::string& path, const std::string& text, size_t offset, int64_t first_line,
                                 const std::string& what) {
  const CellPosition at = text_position(text, offset);
  fail_at(path, at.line + first_line - 1, at.column, what);
}

// Offset of the first '[' or '{' that opens level max_depth + 1, or npos.
size_t too_deep(const std::string& text, int max_depth) {
  int depth = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"') {
      for (++i; i < text.size() && text[i] != '"'; ++i)
        if (text[i] == '\\') ++i;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::string::npos;
}

}  // namespace

std::string read_json_text(const std::string& path, const char* kind, const JsonLimits& limits) {
  const int fd = path == "-" ? STDIN_FILENO : ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
  struct Closer {
    int fd;
    ~Closer() {
      if (fd != STDIN_FILENO) ::close(fd);
    }
  } closer{fd};
  struct stat st;
  if (::fstat(fd, &st) == 0 && S_ISDIR(st.st_mode))
    throw InputError(fmt::format("cannot read '{}': it is a directory; give {}", path, kind));
  std::string text;
  char chunk[65536];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      throw InputError(fmt::format("cannot read '{}': {}; give a readable file", display_path(path), std::strerror(errno)));
    if (n == 0) break;
    if (text.size() + static_cast<size_t>(n) > limits.max_bytes)
      throw InputError(fmt::format("{}: larger than {} MiB; {} is far smaller: check that this is the right file",
                                   display_path(path), limits.max_bytes >> 20, kind));
    text.append(chunk, static_cast<size_t>(n));
  }
  return text;
}

json parse_json(const std::string& path, const std::string& text, const JsonLimits& limits, int64_t first_line) {
  if (const size_t deep = too_deep(text, limits.max_depth); deep != std::string::npos)
    fail_at_offset(path, text, deep, first_line,
                   fmt::format("arrays and objects nested deeper than {} levels; lpvid's files nest a few levels: "
                               "check that this is the right file",
                               limits.max_depth));
  json root;
  PositionedSax sax(root);
  json::sax_parse(text, &sax, json::input_format_t::json, true, false);
  if (!sax.failed) return root;
  if (sax.error_id == 406) {  // number overflow: at the start of the number
    const size_t start = sax.error_position >= sax.error_token.size() ? sax.error_position - sax.error_token.size() : 0;
    fail_at_offset(path, text, start, first_line,
                   fmt::format("number {} is out of range (a double holds up to about 1.8e308); write a finite number",
                               quote_cell(sax.error_token)));
  }
  std::string what = sax.error_what;
  // "[json.exception.parse_error.101] parse error at line 1, column 5: syntax error ..." -> "syntax error ..."
  const size_t column = what.find("column ");
  const size_t colon = column == std::string::npos ? std::string::npos : what.find(": ", column);
  if (colon != std::string::npos) what = what.substr(colon + 2);
  if (what.size() > 200) what = what.substr(0, 200) + "...";
  fail_at_offset(path, text, sax.error_position == 0 ? 0 : sax.error_position - 1, first_line,
                 fmt::format("invalid JSON: {}; fix the JSON syntax", what));
}

std::string json_excerpt(const json& value) {
  constexpr size_t kMaxShown = 40;  // as quote_cell
  std::string text = value.dump(-1, ' ', false, json::error_handler_t::replace);
  if (text.size() > kMaxShown) text = text.substr(0, kMaxShown) + "...";
  return text;
}

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
