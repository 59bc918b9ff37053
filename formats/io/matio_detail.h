// libmatio plumbing shared by the .mat readers and writers of formats/io
// (frd_mat.cc, excitation_file.cc).  Not a public interface.
#pragma once

#include <matio.h>

#include <memory>
#include <mutex>

namespace lpvid::detail {

struct MatCloser {
  void operator()(mat_t* mat) const { Mat_Close(mat); }
};
struct VarFreer {
  void operator()(matvar_t* var) const { Mat_VarFree(var); }
};
using MatPtr = std::unique_ptr<mat_t, MatCloser>;
using VarPtr = std::unique_ptr<matvar_t, VarFreer>;

// matio reports problems through a global log function that prints to stderr;
// every problem here becomes an InputError instead, so the log is silenced.
inline void silence_matio() {
  static std::once_flag once;
  std::call_once(once, [] { Mat_LogInitFunc("lpvid", [](int, char*) {}); });
}

}  // namespace lpvid::detail
