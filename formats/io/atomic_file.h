// lpvid — writing output files so that a failed run never leaves a half-written
// file (DESIGN.md, "formats/" layer).
//
// Every writer in formats/io writes into a temporary file in the target's own
// directory, named ".<name>.tmp.<pid>.<counter>", and renames it over the target
// only when everything has been written.  rename(2) within one directory is
// atomic: a reader sees either the old file or the complete new one.  On any
// failure the temporary is removed and an InputError is thrown:
//   "cannot write 'out/x.json': No such file or directory; check the directory exists and is writable"
//
// The path "-" means standard output.  Standard output cannot be renamed, so
// bytes for "-" are kept in memory and written in one go when committed.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace lpvid {

// One output file being written.  Construction creates the temporary (so a
// missing or read-only directory is reported before any work is done); the
// destructor removes the temporary unless commit() succeeded.
class AtomicFileWriter {
 public:
  // fsync: flush the data to disk before the rename (slower; default off, as
  // outputs can be recomputed).  Throws InputError if the temporary cannot be
  // created.
  explicit AtomicFileWriter(const std::string& path, bool fsync = false);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  // Appends bytes (unbuffered: callers pass large blocks).  Throws InputError.
  void write(std::string_view bytes);
  // Closes the temporary (fsync if asked) and renames it over the target.
  void commit();

  // The two halves of commit(), for AtomicOutputSet: prepare() closes and checks
  // that the target is not a directory; publish() renames.
  void prepare();
  void publish();

  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(int err);
  void discard() noexcept;

  std::string path_;
  std::string temp_;
  std::string stdout_bytes_;
  int fd_ = -1;
  bool to_stdout_ = false;
  bool fsync_ = false;
  bool prepared_ = false;
  bool committed_ = false;
};

// Writes bytes to path atomically (see above).  "-" writes to stdout.
// Throws InputError "cannot write '<path>': <strerror>; check the directory exists and is writable".
void write_file_atomic(const std::string& path, const std::string& bytes);

// Throws InputError "refusing to overwrite input 'a.csv' with output; choose another output path"
// when output names the same file as one of inputs (std::filesystem::equivalent,
// so "./a.csv", "a.csv", a hard link or a symlink are all caught).  "-" and
// paths that do not exist yet never conflict.
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
  AtomicFileWriter& stage(const std::string& path);
  // Stages a file with the given content.
  void stage(const std::string& path, std::string_view bytes);
  // Renames every staged file over its target.
  void commit();

 private:
  std::vector<std::unique_ptr<AtomicFileWriter>> files_;
  bool committed_ = false;
};

}  // namespace lpvid
