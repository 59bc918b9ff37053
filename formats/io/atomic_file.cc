#include "formats/io/atomic_file.h"

#include <dirent.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "idlib/core/error.h"

namespace lpvid {
namespace fs = std::filesystem;

namespace {

std::atomic<unsigned long> temp_counter{0};

std::string write_error(const std::string& path, int err) {
  if (path == "-")
    return fmt::format("cannot write to standard output: {}; check where the output is redirected", std::strerror(err));
  return fmt::format("cannot write '{}': {}; check the directory exists and is writable", path, std::strerror(err));
}

// Writes all of bytes to fd; returns 0 or an errno value.
int write_all(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    data += n;
    size -= static_cast<size_t>(n);
  }
  return 0;
}

// Whether name is ".<target>.tmp.<pid>.<n>" (digits only) of a process other
// than this one that no longer exists.
bool stale_temporary(std::string_view name, std::string_view prefix) {
  if (name.size() <= prefix.size() || name.substr(0, prefix.size()) != prefix) return false;
  const std::string_view rest = name.substr(prefix.size());
  const size_t dot = rest.find('.');
  if (dot == std::string_view::npos || dot == 0 || dot + 1 == rest.size()) return false;
  long pid = 0;
  const auto [end, ec] = std::from_chars(rest.data(), rest.data() + dot, pid);
  if (ec != std::errc() || end != rest.data() + dot || pid <= 0) return false;
  for (const char c : rest.substr(dot + 1))
    if (c < '0' || c > '9') return false;
  if (pid == static_cast<long>(::getpid())) return false;
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

// Removes the temporaries of `target_name` in `dir` that a killed run left.
// Best effort: a failure to list or remove is ignored (the write goes on).
void remove_stale_temporaries(const std::string& dir, const std::string& target_name) {
  DIR* d = ::opendir(dir.empty() ? "." : dir.c_str());
  if (d == nullptr) return;
  const std::string prefix = "." + target_name + ".tmp.";
  std::vector<std::string> stale;
  while (const dirent* e = ::readdir(d))
    if (stale_temporary(e->d_name, prefix)) stale.emplace_back(e->d_name);
  ::closedir(d);
  for (const std::string& name : stale) ::unlink((dir.empty() ? name : (fs::path(dir) / name).string()).c_str());
}

}  // namespace

OutputTargetKind output_target_kind(const std::string& path) {
  if (path == "-") return OutputTargetKind::kStdout;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) return OutputTargetKind::kAbsent;
  if (S_ISREG(st.st_mode)) return OutputTargetKind::kRegular;
  if (S_ISDIR(st.st_mode)) return OutputTargetKind::kDirectory;
  if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) return OutputTargetKind::kStream;
  return OutputTargetKind::kOther;
}

AtomicFileWriter::AtomicFileWriter(const std::string& path, bool fsync)
    : AtomicFileWriter(path, AtomicWriteOptions{fsync, false}) {}

AtomicFileWriter::AtomicFileWriter(const std::string& path, const AtomicWriteOptions& options)
    : path_(path), fsync_(options.fsync) {
  kind_ = output_target_kind(path);
  switch (kind_) {
    case OutputTargetKind::kStdout:
    case OutputTargetKind::kStream:
      return;  // kept in memory, written at commit
    case OutputTargetKind::kDirectory:
      throw InputError(fmt::format("cannot write '{}': it is a directory; give a file path", path));
    case OutputTargetKind::kOther:
      throw InputError(fmt::format("cannot write '{}': it is a device or socket, not a file; give a file path (or a "
                                   "FIFO, or /dev/null)",
                                   path));
    default:
      break;
  }
  const fs::path target(path);
  if (path.empty() || !target.has_filename() || target.filename() == "." || target.filename() == "..")
    throw InputError(fmt::format("cannot write '{}': the path names no file; give a file path such as out/model.json", path));
  // The directory the temporary goes to: the target's own, or with
  // create_directories the nearest one that exists.
  fs::path dir = target.parent_path();
  if (options.create_directories) {
    while (!dir.empty()) {
      struct stat st;
      if (::stat(dir.c_str(), &st) == 0) {
        if (!S_ISDIR(st.st_mode))
          throw InputError(fmt::format("cannot write '{}': '{}' is a file, not a directory; choose another output "
                                       "directory",
                                       path, dir.string()));
        break;
      }
      create_dirs_.insert(create_dirs_.begin(), dir.string());
      dir = dir.parent_path();
    }
  }
  const std::string name = target.filename().string();
  remove_stale_temporaries(dir.string(), name);
  const std::string temp_name = fmt::format(".{}.tmp.{}.{}", name, static_cast<long>(::getpid()), temp_counter.fetch_add(1));
  temp_ = dir.empty() ? temp_name : (dir / temp_name).string();
  fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd_ < 0) {
    const int err = errno;
    temp_.clear();  // nothing was created
    throw InputError(write_error(path_, err));
  }
}

AtomicFileWriter::~AtomicFileWriter() {
  if (!committed_) discard();
}

void AtomicFileWriter::discard() noexcept {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
  if (!temp_.empty()) {
    ::unlink(temp_.c_str());
    temp_.clear();
  }
  memory_.clear();
}

void AtomicFileWriter::fail(int err) {
  discard();
  throw InputError(write_error(path_, err));
}

void AtomicFileWriter::write(std::string_view bytes) {
  LPVID_ASSERT(!prepared_ && !committed_);
  if (temp_.empty()) {
    memory_.append(bytes);
    return;
  }
  LPVID_ASSERT(fd_ >= 0);
  if (const int err = write_all(fd_, bytes.data(), bytes.size())) fail(err);
}

void AtomicFileWriter::release_descriptor() {
  LPVID_ASSERT(!prepared_ && !temp_.empty());
  if (fd_ >= 0) {
    const int rc = ::close(fd_);
    fd_ = -1;
    if (rc != 0) fail(errno);
  }
}

void AtomicFileWriter::prepare() {
  LPVID_ASSERT(!committed_);
  if (prepared_) return;
  if (!temp_.empty()) {
    if (fd_ >= 0) {
      if (fsync_ && ::fsync(fd_) != 0) fail(errno);
      const int rc = ::close(fd_);
      fd_ = -1;
      if (rc != 0) fail(errno);
    }
    if (output_target_kind(path_) == OutputTargetKind::kDirectory) fail(EISDIR);
  }
  prepared_ = true;
}

void AtomicFileWriter::publish() {
  LPVID_ASSERT(prepared_ && !committed_);
  if (kind_ == OutputTargetKind::kStdout) {
    if (const int err = write_all(STDOUT_FILENO, memory_.data(), memory_.size())) throw InputError(write_error(path_, err));
    memory_.clear();
    committed_ = true;
    return;
  }
  if (kind_ == OutputTargetKind::kStream) {
    // Written into, never replaced: no O_CREAT (a FIFO that vanished is an error,
    // not a new regular file), no O_TRUNC.
    const int fd = ::open(path_.c_str(), O_WRONLY | O_NOCTTY | O_CLOEXEC);
    if (fd < 0) throw InputError(write_error(path_, errno));
    const int err = write_all(fd, memory_.data(), memory_.size());
    const int rc = ::close(fd);
    if (err != 0 || rc != 0) throw InputError(write_error(path_, err != 0 ? err : errno));
    memory_.clear();
    committed_ = true;
    return;
  }
  for (const std::string& dir : create_dirs_)
    if (::mkdir(dir.c_str(), 0777) != 0 && errno != EEXIST) fail(errno);
  if (::rename(temp_.c_str(), path_.c_str()) != 0) fail(errno);
  temp_.clear();
  committed_ = true;
}

void AtomicFileWriter::commit() {
  prepare();
  publish();
}

void write_file_atomic(const std::string& path, const std::string& bytes) {
  AtomicFileWriter out(path);
  out.write(bytes);
  out.commit();
}

void check_not_overwriting(const std::vector<std::string>& inputs, const std::string& output) {
  if (output == "-") return;
  struct stat out;
  if (::stat(output.c_str(), &out) != 0) return;
  for (const std::string& input : inputs) {
    struct stat in;
    if (input == "-" || ::stat(input.c_str(), &in) != 0) continue;
    if (in.st_dev == out.st_dev && in.st_ino == out.st_ino)
      throw InputError(fmt::format("refusing to overwrite input '{}' with output; choose another output path", input));
  }
}

AtomicFileWriter& AtomicOutputSet::stage(const std::string& path, const AtomicWriteOptions& options) {
  LPVID_ASSERT(!committed_);
  if (path != "-") {
    std::error_code ec;
    const fs::path key = fs::weakly_canonical(fs::absolute(path, ec), ec);
    for (const auto& file : files_) {
      if (file->path() == "-") continue;
      std::error_code ec2;
      if (fs::weakly_canonical(fs::absolute(file->path(), ec2), ec2) == key)
        throw InputError(fmt::format("output '{}' is given twice (also as '{}'); give each output its own path", path, file->path()));
    }
  }
  files_.push_back(std::make_unique<AtomicFileWriter>(path, options));
  return *files_.back();
}

void AtomicOutputSet::stage(const std::string& path, std::string_view bytes, const AtomicWriteOptions& options) {
  stage(path, options).write(bytes);
}

void AtomicOutputSet::commit() {
  LPVID_ASSERT(!committed_);
  for (auto& file : files_) file->prepare();
  for (auto& file : files_) file->publish();
  committed_ = true;
}

}  // namespace lpvid
