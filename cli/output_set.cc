#include "cli/output_set.h"

#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <optional>

#include "cli/common.h"
#include "idlib/core/error.h"

namespace lpvid::cli {
namespace fs = std::filesystem;

struct OutputSet::Entry {
  std::string flag, path;
  bool rewrite = false;       // may replace an input on purpose
  bool in_directory = false;  // inside an output directory created at commit
  bool staged = false;
};

namespace {

struct Identity {
  bool exists = false;
  dev_t dev = 0;
  ino_t ino = 0;
  std::string key;  // absolute, normalised, symbolic links resolved where the path exists
};

Identity identity(const std::string& path) {
  Identity id;
  struct stat st;
  if (::stat(path.c_str(), &st) == 0) {
    id.exists = true;
    id.dev = st.st_dev;
    id.ino = st.st_ino;
  }
  std::error_code ec;
  fs::path p = fs::absolute(path, ec);
  if (!ec) {
    const fs::path c = fs::weakly_canonical(p, ec);
    id.key = (ec ? p.lexically_normal() : c).string();
  } else {
    id.key = path;
  }
  return id;
}

bool same(const Identity& a, const Identity& b) {
  if (a.exists && b.exists) return a.dev == b.dev && a.ino == b.ino;
  return a.key == b.key;
}

std::string named(const std::string& flag, const std::string& path) { return fmt::format("{} '{}'", flag, path); }

// A directory the command writes into, existing or to be created: the nearest
// existing ancestor must be a writable directory.
void check_writable_directory(const std::string& flag, const std::string& shown_as, const fs::path& dir,
                              bool may_create) {
  fs::path at = dir.empty() ? fs::path(".") : dir;
  for (;;) {
    struct stat st;
    if (::stat(at.c_str(), &st) == 0) {
      if (!S_ISDIR(st.st_mode))
        throw InputError(fmt::format("{}: '{}' is not a directory; choose a path inside a directory", named(flag, shown_as),
                                     at.string()));
      if (::access(at.c_str(), W_OK | X_OK) != 0)
        throw InputError(fmt::format("{}: directory '{}' is not writable ({}); choose another directory or fix its "
                                     "permissions",
                                     named(flag, shown_as), at.string(), std::strerror(errno)));
      return;
    }
    if (!may_create || (errno != ENOENT && errno != ENOTDIR) || at == "." || at == at.root_path())
      throw InputError(fmt::format("{}: directory '{}' does not exist; create it first or choose another path",
                                   named(flag, shown_as), at.string()));
    at = at.has_parent_path() ? at.parent_path() : fs::path(".");
  }
}

}  // namespace

OutputSet::OutputSet() = default;
OutputSet::~OutputSet() = default;

void OutputSet::input(const std::string& path) {
  LPVID_ASSERT(!checked_);
  if (!path.empty()) inputs_.push_back(path);
}

void OutputSet::inputs(const std::vector<std::string>& paths) {
  for (const auto& p : paths) input(p);
}

void OutputSet::file(const std::string& flag, const std::string& path) {
  LPVID_ASSERT(!checked_);
  if (path.empty()) return;
  outputs_.push_back({flag, path, false, false, false});
}

void OutputSet::rewrite(const std::string& flag, const std::string& path) {
  LPVID_ASSERT(!checked_);
  if (path.empty()) return;
  outputs_.push_back({flag, path, true, false, false});
}

void OutputSet::directory(const std::string& flag, const std::string& dir) {
  LPVID_ASSERT(!checked_);
  directories_.emplace_back(flag, dir);
}

std::string OutputSet::file_in(const std::string& dir, const std::string& name) {
  LPVID_ASSERT(!checked_);
  const auto it = std::find_if(directories_.begin(), directories_.end(), [&](const auto& d) { return d.second == dir; });
  LPVID_ASSERT(it != directories_.end());
  std::string path = join_path(dir, name);
  outputs_.push_back({it->first, path, false, true, false});
  return path;
}

void OutputSet::check() {
  LPVID_ASSERT(!checked_);
  for (const auto& [flag, dir] : directories_) {
    if (dir.empty()) throw InputError(fmt::format("{} is empty; give a directory path", flag));
    if (dir == "-")
      throw InputError(fmt::format("{} '-': this output is a directory, not standard output; give a directory path", flag));
    check_writable_directory(flag, dir, fs::path(dir), true);
  }
  if (std::count(inputs_.begin(), inputs_.end(), "-") > 1)
    throw InputError("standard input ('-') is given for two inputs; it can be read once: give files for all but one");
  std::vector<Identity> in;
  for (const auto& p : inputs_) in.push_back(p == "-" ? Identity{} : identity(p));
  std::vector<Identity> out;
  const Entry* on_stdout = nullptr;
  for (const Entry& e : outputs_) {
    Identity id;
    if (e.path == "-") {
      if (on_stdout != nullptr)
        throw InputError(fmt::format("{} and {} both write to standard output ('-'); send at most one output there",
                                     on_stdout->flag, e.flag));
      on_stdout = &e;
      out.push_back(id);
      continue;
    }
    const fs::path target(e.path);
    if (!target.has_filename() || target.filename() == "." || target.filename() == "..")
      throw InputError(fmt::format("{} names no file; give a file path such as out/model.json", named(e.flag, e.path)));
    switch (output_target_kind(e.path)) {
      case OutputTargetKind::kDirectory:
        throw InputError(fmt::format("{} is a directory; give a file path", named(e.flag, e.path)));
      case OutputTargetKind::kOther:
        throw InputError(fmt::format("{} is a device or socket, not a file; give a file path (or a FIFO, or /dev/null)",
                                     named(e.flag, e.path)));
      case OutputTargetKind::kRegular:
        if (::access(e.path.c_str(), W_OK) != 0)
          throw InputError(fmt::format("{} is read-only; make it writable (chmod u+w) or choose another path",
                                       named(e.flag, e.path)));
        break;
      default:
        break;
    }
    if (!e.in_directory) check_writable_directory(e.flag, e.path, target.parent_path(), false);
    id = identity(e.path);
    if (!e.rewrite)
      for (std::size_t k = 0; k < in.size(); ++k)
        if (inputs_[k] != "-" && same(id, in[k]))
          throw InputError(fmt::format("refusing to overwrite input '{}' with {}; choose another output path",
                                       inputs_[k], named(e.flag, e.path)));
    for (std::size_t k = 0; k < out.size(); ++k)
      if (outputs_[k].path != "-" && same(id, out[k]))
        throw InputError(fmt::format("{} and {} name the same file; give each output its own path",
                                     named(outputs_[k].flag, outputs_[k].path), named(e.flag, e.path)));
    out.push_back(id);
  }
  checked_ = true;
}

bool OutputSet::to_stdout() const {
  return std::any_of(outputs_.begin(), outputs_.end(), [](const Entry& e) { return e.path == "-"; });
}

OutputSet::Entry* OutputSet::find(const std::string& path) {
  for (Entry& e : outputs_)
    if (e.path == path) return &e;
  return nullptr;
}

AtomicFileWriter& OutputSet::stage(const std::string& path) {
  LPVID_ASSERT(checked_);
  Entry* e = find(path);
  LPVID_ASSERT(e != nullptr && !e->staged);  // every output is registered before check()
  e->staged = true;
  AtomicWriteOptions options;
  options.create_directories = e->in_directory;
  return staged_.stage(path, options);
}

void OutputSet::stage(const std::string& path, std::string_view bytes) { stage(path).write(bytes); }

void OutputSet::stage(const std::string& path, const std::vector<unsigned char>& bytes) {
  stage(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

void OutputSet::commit() {
  LPVID_ASSERT(checked_);
  staged_.commit();
}

}  // namespace lpvid::cli
