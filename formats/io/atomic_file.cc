#include "formats/io/atomic_file.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
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

}  // namespace

AtomicFileWriter::AtomicFileWriter(const std::string& path, bool fsync) : path_(path), fsync_(fsync) {
  if (path == "-") {
    to_stdout_ = true;
    return;
  }
  const fs::path target(path);
  if (path.empty() || !target.has_filename())
    throw InputError(fmt::format("cannot write '{}': the path names no file; give a file path such as out/model.json", path));
  const fs::path dir = target.parent_path();
  const std::string name = target.filename().string();
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
}

void AtomicFileWriter::fail(int err) {
  discard();
  throw InputError(write_error(path_, err));
}

void AtomicFileWriter::write(std::string_view bytes) {
  LPVID_ASSERT(!prepared_ && !committed_);
  if (to_stdout_) {
    stdout_bytes_.append(bytes);
    return;
  }
  LPVID_ASSERT(fd_ >= 0);
  if (const int err = write_all(fd_, bytes.data(), bytes.size())) fail(err);
}

void AtomicFileWriter::prepare() {
  LPVID_ASSERT(!committed_);
  if (prepared_) return;
  if (!to_stdout_) {
    LPVID_ASSERT(fd_ >= 0);
    if (fsync_ && ::fsync(fd_) != 0) fail(errno);
    const int rc = ::close(fd_);
    fd_ = -1;
    if (rc != 0) fail(errno);
    struct stat st;
    if (::stat(path_.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) fail(EISDIR);
  }
  prepared_ = true;
}

void AtomicFileWriter::publish() {
  LPVID_ASSERT(prepared_ && !committed_);
  if (to_stdout_) {
    if (const int err = write_all(STDOUT_FILENO, stdout_bytes_.data(), stdout_bytes_.size()))
      throw InputError(write_error(path_, err));
    stdout_bytes_.clear();
    committed_ = true;
    return;
  }
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
  for (const std::string& input : inputs) {
    if (input == "-") continue;
    std::error_code ec;
    if (fs::equivalent(input, output, ec) && !ec)
      throw InputError(fmt::format("refusing to overwrite input '{}' with output; choose another output path", input));
  }
}

AtomicFileWriter& AtomicOutputSet::stage(const std::string& path) {
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
  files_.push_back(std::make_unique<AtomicFileWriter>(path));
  return *files_.back();
}

void AtomicOutputSet::stage(const std::string& path, std::string_view bytes) { stage(path).write(bytes); }

void AtomicOutputSet::commit() {
  LPVID_ASSERT(!committed_);
  for (auto& file : files_) file->prepare();
  for (auto& file : files_) file->publish();
  committed_ = true;
}

}  // namespace lpvid
