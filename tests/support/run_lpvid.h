// Test support: run the built lpvid program and capture exit code, stdout, stderr.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <sys/wait.h>

namespace lpvid::testing {

struct RunResult {
  int exit_code = -1;
  std::string out, err;
};

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A fresh, empty directory under the system temp dir, removed by the destructor.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() / ("lpvid_" + tag + "_" + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

// Runs `sh -c CMD` in the directory `cwd` when given, capturing exit code, stdout
// and stderr.
inline RunResult run_shell(const std::string& cmd, const std::string& cwd = "") {
  TempDir tmp("run");
  const std::string line = (cwd.empty() ? std::string() : "cd '" + cwd + "' && ") + cmd + " > " + (tmp / "out") +
                           " 2> " + (tmp / "err");
  const int status = std::system(line.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.out = slurp(tmp / "out");
  r.err = slurp(tmp / "err");
  return r;
}

// Runs `lpvid ARGS` through the shell (args are passed verbatim: quote them),
// in the directory `cwd` when given.
inline RunResult run_lpvid(const std::string& args, const std::string& stdin_file = "", const std::string& cwd = "") {
  return run_shell(std::string(LPVID_BINARY) + " " + args + (stdin_file.empty() ? "" : " < " + stdin_file), cwd);
}

inline int count_files(const std::filesystem::path& dir) {
  if (!std::filesystem::exists(dir)) return 0;
  int n = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) n += e.is_regular_file() ? 1 : 0;
  return n;
}

}  // namespace lpvid::testing
