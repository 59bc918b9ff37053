// Parts of a mechanical base's description built in code (the library tests link no
// JSON reader): a parameter with its unit, value, bounds and whether it is free, and an
// entry as a linear expression of the parameters (docs/formats.md, "Mechanical base").
#pragma once

#include <string>

#include "idlib/physical/mechanical/mechanical_base.h"

namespace lpvid::described_base {

inline PhysicalParameter parameter(const char* name, const char* unit, double value, double lower, double upper,
                                   bool free) {
  PhysicalParameter p;
  p.name = name;
  p.unit = unit;
  p.value = value;
  p.lower = lower;
  p.upper = upper;
  p.free = free;
  return p;
}

inline auto entry(const char* text) { return parse_linear_expression(text); }

}  // namespace lpvid::described_base
