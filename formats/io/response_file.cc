#include "formats/io/response_file.h"

#include "formats/io/frd_csv.h"
#include "formats/io/frd_mat.h"
#include "formats/io/json_detail.h"
#include "formats/io/model_json.h"

namespace lpvid {
namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Whether text starts like JSON: '{' after an optional UTF-8 byte-order mark and blanks.
bool looks_like_json(const std::string& text) {
  size_t i = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
  while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r' || text[i] == '\n')) ++i;
  return i < text.size() && text[i] == '{';
}

}  // namespace

ResponseFile read_response_file(const std::string& path) {
  ResponseFile r;
  if (path == "-") {
    detail::JsonLimits limits;
    limits.max_bytes = kMaxStdinBytes;
    const std::string text = detail::read_json_text(path, "a model or frequency-response file", limits);
    if (looks_like_json(text))
      r.model = parse_state_space(text, path);
    else
      r.frd = parse_frd_csv(text, path);
  } else if (ends_with(path, ".json")) {
    r.model = read_state_space(path);
  } else if (ends_with(path, ".mat")) {
    r.frd = read_frd_mat(path);
  } else {
    r.frd = read_frd_csv(path);
  }
  return r;
}

}  // namespace lpvid
