// lpvid — the three kinds of failure (STYLE.md item 4).
//
// 1. A programming bug: LPVID_ASSERT, always on, aborts with file:line.
// 2. Bad user input (anything that can come from a file or a flag): InputError.
//    Its message names the value and the broken rule, in one line, and says
//    what to do.  The CLI maps it to exit code 2.
// 3. A numerical outcome: a Report returned with the result (usable or not,
//    termination, warnings).  When a computation cannot produce any usable
//    result, it throws NumericalError (exit code 1).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace lpvid {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Outcome of a numerical computation, returned beside its result.
struct Report {
  bool usable = true;
  std::string termination;            // one line: how the computation ended
  std::vector<std::string> warnings;  // kept apart from errors; each one line
};

[[noreturn]] void assertion_failed(const char* expr, const char* file, int line);

}  // namespace lpvid

#define LPVID_ASSERT(cond) \
  ((cond) ? static_cast<void>(0) : ::lpvid::assertion_failed(#cond, __FILE__, __LINE__))
