// Test support: where the real measured data sets live (../shared/real-data/README.md).
// They are not the project's to ship: tests read them from `../shared/real-data`
// relative to the source tree (CI has shared/ beside the clone), or from the directory
// in the environment variable LPVID_REAL_DATA when set (a worktree elsewhere), and
// skip with a clear message when they are absent.  Never copy them into the repository.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace lpvid::testing {

inline std::filesystem::path real_data_dir() {
  if (const char* env = std::getenv("LPVID_REAL_DATA"); env != nullptr && *env != '\0') return env;
  return std::filesystem::path(LPVID_SOURCE_DIR) / ".." / "shared" / "real-data";
}

// The path of `relative` under the real-data directory, or "" when the file is absent.
inline std::string real_data_file(const std::string& relative) {
  const std::filesystem::path p = real_data_dir() / relative;
  return std::filesystem::is_regular_file(p) ? p.string() : std::string();
}

}  // namespace lpvid::testing

// In a test body: the real-data file's path, or GTEST_SKIP with the reason.
#define LPVID_REAL_DATA_OR_SKIP(var, relative)                                                                  \
  const std::string var = ::lpvid::testing::real_data_file(relative);                                         \
  if (var.empty())                                                                                            \
  GTEST_SKIP() << "real data " << (relative) << " not found under " << ::lpvid::testing::real_data_dir().string() \
               << " (the public benchmark sets live in ../shared/real-data beside the source tree, or set "   \
                  "LPVID_REAL_DATA to their directory)"
