#include "idlib/core/error.h"

#include <cstdio>
#include <cstdlib>

namespace lpvid {

void assertion_failed(const char* expr, const char* file, int line) {
  std::fprintf(stderr, "lpvid: internal error: assertion '%s' failed at %s:%d\n", expr, file, line);
  std::abort();
}

}  // namespace lpvid
