// lpvid — text rules shared by every reader and by the command line: what a
// decimal number is (cells, metadata, flags), and well-formed UTF-8 (names
// that go into JSON files must be).
#pragma once

#include <string_view>

namespace lpvid {

// A decimal number as cells and flags are written: optional sign ('+' or '-'),
// digits with an optional point and exponent; no hex floats, nan or inf, no
// blanks.  Returns false unless all of text is such a number with a finite value.
bool parse_decimal(std::string_view text, double& value);

// Whether text is well-formed UTF-8 (no overlong forms, surrogates or code
// points above U+10FFFF).
bool valid_utf8(std::string_view text);

}  // namespace lpvid
