// Every output of one command, checked before anything is read or computed and
// published together at the end (docs/formats.md, "Writing: atomic outputs").
//
//   OutputSet outputs;
//   outputs.inputs(o.logs);                       // every file the command reads
//   outputs.file("--out", o.out);                 // every file it may write
//   outputs.file("--png", o.png);                 // (an empty path: not asked for)
//   outputs.check();                              // before reading anything
//   ... read, compute ...
//   write_table_csv(outputs.stage(o.out), ...);   // into temporaries
//   outputs.commit();                             // all renamed at the very end
//
// check() refuses, with one line naming the flag, the path and what to do:
//  - an output that is an input (same device and inode, however it is spelled:
//    "./a.csv", a symlink, a hard link; or the same normalised path);
//  - two outputs naming one file (also through "-": one output at most on stdout);
//  - an output whose directory does not exist (unless the command creates it:
//    directory()) or is not writable, an existing read-only file, a directory,
//    a block device or a socket.
// An existing FIFO or character device (/dev/null) is written into at commit,
// never replaced.  Output directories are created only at commit, so a failed
// run leaves no empty directory behind; until then the temporaries live in the
// nearest existing directory (formats/io/atomic_file.h).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "formats/io/atomic_file.h"

namespace lpvid::cli {

class OutputSet {
 public:
  OutputSet();
  ~OutputSet();
  OutputSet(const OutputSet&) = delete;
  OutputSet& operator=(const OutputSet&) = delete;

  // A file the command reads ("-" = stdin; empty = none).
  void input(const std::string& path);
  void inputs(const std::vector<std::string>& paths);

  // An output file given by `flag` ("-" = stdout; empty = not asked for).
  void file(const std::string& flag, const std::string& path);
  // An output that deliberately replaces one of the inputs (`model add`, a
  // history that is read and rewritten with one more line).
  void rewrite(const std::string& flag, const std::string& path);
  // An output directory given by `flag`, created at commit if missing; returns
  // dir/name for each file the command writes into it (register each with
  // file_in before check()).
  void directory(const std::string& flag, const std::string& dir);
  std::string file_in(const std::string& dir, const std::string& name);

  // Checks every registered path (see above).  Throws InputError.
  void check();

  // True when some output is standard output (then the command prints no summary there).
  bool to_stdout() const;

  // A registered output's temporary (after check()).
  AtomicFileWriter& stage(const std::string& path);
  void stage(const std::string& path, std::string_view bytes);
  void stage(const std::string& path, const std::vector<unsigned char>& bytes);

  // Publishes every staged output; an output registered but never staged is
  // left alone (e.g. a figure the command decided not to draw).
  void commit();

 private:
  struct Entry;
  Entry* find(const std::string& path);
  std::vector<std::string> inputs_;
  std::vector<Entry> outputs_;
  std::vector<std::pair<std::string, std::string>> directories_;  // flag, path
  AtomicOutputSet staged_;
  bool checked_ = false;
};

}  // namespace lpvid::cli
