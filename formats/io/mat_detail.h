// lpvid — internals shared by the MATLAB .mat readers of formats/io (frd_mat.cc,
// mat_log.cc).  Not a public interface: include only from formats/io/*.cc (and
// their tests, and fuzz/).
//
// v5 (MATLAB's default '-v7' save, compressed or not) is parsed by lpvid itself,
// every size checked against the bytes present (a truncated or damaged file is an
// error, never a value read from nowhere); v7.3 (HDF5) is read through libmatio.
// Limits: a regular file (not a pipe) of at most kMaxInflatedBytes, variables of
// at most kMaxInflatedBytes uncompressed, cell arrays and structs nested at most
// 8 levels deep, at most 2^20 cells or struct members per array.
#pragma once

#include <matio.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "formats/io/atomic_file.h"
#include "formats/io/matio_detail.h"

namespace lpvid::mat_detail {

// Bytes a file's variables may take once inflated (and the largest file).
inline constexpr uint64_t kMaxInflatedBytes = uint64_t{512} << 20;

// The matio closers and the silenced matio log (shared with excitation_file.cc).
using detail::MatPtr;
using detail::silence_matio;
using detail::VarPtr;

// "2×3×5".
std::string dims_text(const std::vector<size_t>& dims);
// The variables' names for a message: each cut to 40 bytes with control bytes as
// \xNN (detail::quote_cell, without its quotes), at most 20 of them; "no variables".
std::string variables_text(const std::vector<std::string>& variables);

// A numeric variable as the FRD reader needs it.
struct Array {
  std::vector<size_t> dims;
  std::vector<double> re, im;  // column-major; im empty when real
};

// Any variable, as a tree (the log reader's view: structs, cells, text, numbers).
struct Value {
  enum class Kind { kNumeric, kChar, kCell, kStruct, kOther };
  Kind kind = Kind::kOther;
  std::vector<size_t> dims;
  bool complex = false;           // numeric: the imaginary part is not kept
  std::vector<double> re;         // numeric: column-major, converted to double
  std::string text;               // char: the characters in storage order, as UTF-8
  std::vector<Value> cells;       // cell: column-major
  std::vector<std::string> fields;  // struct: field names
  std::vector<Value> members;     // struct: element e, field f at e * fields.size() + f

  size_t count() const;  // product of dims
  // Field `name` of struct element `element`, or nullptr.
  const Value* field(const std::string& name, size_t element = 0) const;
  // "double array", "char array", "cell array", "struct", "other".
  std::string kind_text() const;
};

// The variables of a .mat file (one implementation per file version).
class MatSource {
 public:
  virtual ~MatSource() = default;
  // In file order (v7.3: the order libmatio lists them, HDF5's).
  virtual const std::vector<std::string>& variables() const = 0;
  // The numeric array `name` (a listed variable).  Throws InputError
  // "'path': variable 'x' is not a numeric array; ..." (and complex when not allowed).
  virtual Array load(const std::string& name, bool complex_allowed) = 0;
  // The cell array of `count` names `name`.
  virtual std::vector<std::string> names(const std::string& name, size_t count) = 0;
  // The variable `name` (a listed variable) as a tree.  Throws InputError on a damaged file.
  virtual Value value(const std::string& name) = 0;
};

// True when the first 128 bytes hold a MAT-file header (text starting "MATLAB",
// endian indicator "IM" or "MI" at bytes 126-127).
bool has_mat_header(const std::string& first_bytes);

// Opens path (a regular file; "-" is refused) as a v5 or v7.3 MAT-file.  Throws
// InputError "cannot open 'x.mat': ...; check the path", "'x.mat' is not a MATLAB
// .mat file (v5 or v7.3); ...", "'x.mat': the file is damaged or truncated (...)".
std::unique_ptr<MatSource> open_mat(const std::string& path);

// Writes through libmatio into the temporary of an AtomicFileWriter (matio
// opens files by name); the caller's commit renames it into place.  Throws
// InputError for a file that streams ("-", a pipe, a device) and on write errors.
class MatWriter {
 public:
  MatWriter(AtomicFileWriter& out, bool v73);
  MatWriter(const MatWriter&) = delete;
  MatWriter& operator=(const MatWriter&) = delete;
  // Writes the variable (uncompressed) and frees it.
  void add(matvar_t* raw);
  void finish();

 private:
  [[noreturn]] void fail(int err) const;
  std::string path_;
  MatPtr mat_;
};

// A real double array (data is not copied: it must outlive the write).
matvar_t* real_array(const char* name, std::vector<size_t> dims, std::vector<double>& data);
// A 1 x n cell array of char.
matvar_t* name_cells(const char* name, const std::vector<std::string>& names);

}  // namespace lpvid::mat_detail
