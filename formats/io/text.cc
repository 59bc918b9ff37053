#include "formats/io/text.h"

#include <fast_float/fast_float.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <system_error>

namespace lpvid {

bool parse_decimal(std::string_view text, double& value) {
  const char* b = text.data();
  const char* e = b + text.size();
  if (b < e && *b == '+' && b + 1 < e && *(b + 1) != '-') ++b;
  if (b == e || std::any_of(b, e, [](char c) { return !(std::isdigit(static_cast<unsigned char>(c)) || c == '.' ||
                                                        c == 'e' || c == 'E' || c == '+' || c == '-'); }))
    return false;
  const auto r = fast_float::from_chars(b, e, value);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(value);
}

bool valid_utf8(std::string_view text) {
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const auto* e = p + text.size();
  while (p < e) {
    const unsigned c = *p;
    if (c < 0x80) {
      ++p;
      continue;
    }
    int n;
    unsigned cp;
    if ((c & 0xE0) == 0xC0) {
      n = 1;
      cp = c & 0x1F;
    } else if ((c & 0xF0) == 0xE0) {
      n = 2;
      cp = c & 0x0F;
    } else if ((c & 0xF8) == 0xF0) {
      n = 3;
      cp = c & 0x07;
    } else {
      return false;
    }
    if (e - p <= n) return false;
    for (int k = 1; k <= n; ++k) {
      if ((p[k] & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (p[k] & 0x3F);
    }
    static constexpr unsigned kMin[] = {0, 0x80, 0x800, 0x10000};
    if (cp < kMin[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return false;
    p += n + 1;
  }
  return true;
}

}  // namespace lpvid
