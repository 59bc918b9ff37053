// lpvid — writing output files so that a failed run never leaves a half-written
// file (DESIGN.md, "formats/" layer; docs/formats.md, "Writing: atomic outputs").
//
// Every writer in formats/io writes into a temporary file in the target's own
// directory, named ".<name>.tmp.<pid>.<counter>", and renames it over the target
// only when everything has been written.  rename(2) within one directory is
// atomic: a reader sees either the old file or the complete new one.  On any
// failure the temporary is removed and an InputError is thrown:
//   "cannot write 'out/x.json': No such file or directory; check the directory exists and is writable"
//
// Targets that are not regular files:
//  - "-" means standard output: bytes are kept in memory and written in one go
//    when committed (standard output cannot be renamed);
//  - an existing FIFO or character device (a named pipe, /dev/null) is written
//    into directly, also in one go at commit: it is never replaced or unlinked;
//  - a directory, block device or socket is refused.
//
// Temporaries left by a killed run (".<name>.tmp.<pid>.<n>" whose process no
// longer exists) are removed the next time the same target is written.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace lpvid {

struct AtomicWriteOptions {
  // Flush the data to disk before the rename (slower; outputs can be recomputed).
  bool fsync = false;
  // Missing directories above the target are created at commit (and only then);
  // until then the temporary lives in the nearest existing ancestor directory
  // (the same file system, so the final rename stays atomic).  false: a missing
  // directory is an error.
  bool create_directories = false;
};

// What an output path names now (stat(2), following symbolic links).
enum class OutputTargetKind {
  kStdout,     // "-"
  kAbsent,     // nothing there yet (or a dangling symbolic link): created by rename
  kRegular,    // an existing regular file: replaced by rename
  kStream,     // an existing FIFO or character device: written into at commit
  kDirectory,  // refused
  kOther,      // block device, socket: refused
};
OutputTargetKind output_target_kind(const std::string& path);

// One output file being written.  Construction creates the temporary (so a
// missing or read-only directory is reported before any bytes are produced);
// the destructor removes the temporary unless commit() succeeded.
class AtomicFileWriter {
 public:
  // Throws InputError if the temporary cannot be created or the target is a
  // directory, block device or socket.
  explicit AtomicFileWriter(const std::string& path, bool fsync = false);
  AtomicFileWriter(const std::string& path, const AtomicWriteOptions& options);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  // Appends bytes (unbuffered: callers pass large blocks).  Throws InputError.
  void write(std::string_view bytes);
  // Closes the temporary (fsync if asked) and renames it over the target.
  void commit();

  // The two halves of commit(), for AtomicOutputSet: prepare() closes and checks
  // that the target is still writable; publish() renames (creating missing
  // directories first) or streams the bytes.
  void prepare();
  void publish();

  // For writers that must open the file by name themselves (matio): the
  // temporary's path, to be written before prepare().  Empty for "-" and
  // FIFO/device targets (which such writers refuse).
  const std::string& temp_path() const { return temp_; }
  // Replaces the temporary's content by the file at temp_path() as written by
  // name (closes the descriptor this writer holds, so the named writer owns it).
  void release_descriptor();

  const std::string& path() const { return path_; }
  OutputTargetKind kind() const { return kind_; }

 private:
  [[noreturn]] void fail(int err);
  void discard() noexcept;

  std::string path_;
  std::string temp_;
  std::string memory_;                   // "-" and FIFO/device targets
  std::vector<std::string> create_dirs_;  // missing directories, outermost first
  int fd_ = -1;
  OutputTargetKind kind_ = OutputTargetKind::kAbsent;
  bool fsync_ = false;
  bool prepared_ = false;
  bool committed_ = false;
};

// Writes bytes to path atomically (see above).  "-" writes to stdout.
// Throws InputError "cannot write '<path>': <strerror>; check the directory exists and is writable".
void write_file_atomic(const std::string& path, const std::string& bytes);

// Throws InputError "refusing to overwrite input 'a.csv' with output; choose another output path"
// when output names the same file as one of inputs (same device and inode, so
// "./a.csv", "a.csv", a hard link or a symlink are all caught).  "-" and paths
// that do not exist yet never conflict.  (Commands use cli/output_set.h, which
// checks every output of a command at once; this is the single-pair form.)
void check_not_overwriting(const std::vector<std::string>& inputs, const std::string& output);

// Several output files of one command: each is staged into its temporary, and
// commit() renames them all at the very end.  If the command fails before
// commit(), the destructor removes every temporary and no output appears.
//
//   AtomicOutputSet out;
//   write_log(out.stage(dir + "/sim.csv"), names, data);
//   out.stage(dir + "/model.json", state_space_to_json(model));
//   out.commit();
//
// commit() first closes every temporary and checks every target, then renames;
// a rename can fail only for reasons the checks cannot see (e.g. the directory
// was removed meanwhile); the files renamed before it stay (each complete) and the
// rest are removed.
class AtomicOutputSet {
 public:
  AtomicOutputSet() = default;
  ~AtomicOutputSet() = default;
  AtomicOutputSet(const AtomicOutputSet&) = delete;
  AtomicOutputSet& operator=(const AtomicOutputSet&) = delete;

  // Starts a staged file to be written by the caller.  Throws InputError if path
  // is already staged in this set ("output 'x' is given twice; ...").
  AtomicFileWriter& stage(const std::string& path, const AtomicWriteOptions& options = {});
  // Stages a file with the given content.
  void stage(const std::string& path, std::string_view bytes, const AtomicWriteOptions& options = {});
  // Renames every staged file over its target.
  void commit();

 private:
  std::vector<std::unique_ptr<AtomicFileWriter>> files_;
  bool committed_ = false;
};

}  // namespace lpvid
