#include "formats/io/frd_mat.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <matio.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>

#include "formats/io/csv_detail.h"
#include "formats/io/matio_detail.h"
#include "formats/io/frd_detail.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

// One UTF-16 code unit of the Basic Multilingual Plane, appended as UTF-8 (MATLAB's
// char arrays; surrogate pairs are not combined: names and labels are BMP text).
void append_utf8(std::string& text, unsigned u) {
  if (u < 0x80) {
    text += static_cast<char>(u);
  } else if (u < 0x800) {
    text += static_cast<char>(0xC0 | (u >> 6));
    text += static_cast<char>(0x80 | (u & 0x3F));
  } else {
    text += static_cast<char>(0xE0 | (u >> 12));
    text += static_cast<char>(0x80 | ((u >> 6) & 0x3F));
    text += static_cast<char>(0x80 | (u & 0x3F));
  }
}

using detail::MatPtr;
using detail::silence_matio;
using detail::VarPtr;

// Converts n elements of a matio numeric array to double.
bool to_double(const matvar_t* var, const void* data, size_t n, std::vector<double>& out) {
  out.resize(n);
  auto copy = [&](auto* p) {
    for (size_t k = 0; k < n; ++k) out[k] = static_cast<double>(p[k]);
  };
  switch (var->class_type) {
    case MAT_C_DOUBLE: copy(static_cast<const double*>(data)); return true;
    case MAT_C_SINGLE: copy(static_cast<const float*>(data)); return true;
    case MAT_C_INT8: copy(static_cast<const int8_t*>(data)); return true;
    case MAT_C_UINT8: copy(static_cast<const uint8_t*>(data)); return true;
    case MAT_C_INT16: copy(static_cast<const int16_t*>(data)); return true;
    case MAT_C_UINT16: copy(static_cast<const uint16_t*>(data)); return true;
    case MAT_C_INT32: copy(static_cast<const int32_t*>(data)); return true;
    case MAT_C_UINT32: copy(static_cast<const uint32_t*>(data)); return true;
    case MAT_C_INT64: copy(static_cast<const int64_t*>(data)); return true;
    case MAT_C_UINT64: copy(static_cast<const uint64_t*>(data)); return true;
    default: return false;
  }
}

std::string dims_text(const std::vector<size_t>& dims) { return fmt::format("{}", fmt::join(dims, "×")); }

// A numeric variable as the FRD reader needs it.
struct Array {
  std::vector<size_t> dims;
  std::vector<double> re, im;  // column-major; im empty when real
};

// Limits (frd_mat.h): bytes a file's variables may take once inflated, and
// the dimensions of one variable.
constexpr uint64_t kMaxInflatedBytes = uint64_t{512} << 20;
constexpr int kMaxDims = 32;
constexpr size_t kMaxNameBytes = 4096;

// The variables of a .mat file, as the reader sees them (one per file version).
class MatSource {
 public:
  virtual ~MatSource() = default;
  virtual const std::vector<std::string>& variables() const = 0;
  // The numeric array `name` (a listed variable).  Throws via fail.
  virtual Array load(const std::string& name, bool complex_allowed) = 0;
  // The cell array of `count` names `name`.
  virtual std::vector<std::string> names(const std::string& name, size_t count) = 0;
};

// ---- MATLAB v5 (Level 5 MAT-file), read by lpvid itself --------------------
// Every size in the file is checked against the bytes that are really there,
// so a truncated or damaged file is an error and never leaves values unread
// (libmatio's v5 reader does not check: issue 12, class 3).  Layout: a 128-byte
// header (text, subsystem offset, version 0x0100, endian indicator "IM"), then
// data elements, each a tag (type, byte count; or both packed into 4 bytes for
// at most 4 bytes of data) and its data padded to 8 bytes.  A variable is an
// miMATRIX element (array flags, dimensions, name, real part, imaginary part;
// or the cells of a cell array, or the characters of a char array), or an
// miCOMPRESSED element: a zlib stream of one miMATRIX element.
enum : uint32_t {
  kMiInt8 = 1, kMiUint8 = 2, kMiInt16 = 3, kMiUint16 = 4, kMiInt32 = 5, kMiUint32 = 6, kMiSingle = 7,
  kMiDouble = 9, kMiInt64 = 12, kMiUint64 = 13, kMiMatrix = 14, kMiCompressed = 15, kMiUtf8 = 16,
  kMiUtf16 = 17, kMiUtf32 = 18
};
enum : uint32_t { kMxCell = 1, kMxChar = 4, kMxDouble = 6, kMxUint64 = 15 };

size_t type_size(uint32_t type) {
  switch (type) {
    case kMiInt8: case kMiUint8: case kMiUtf8: return 1;
    case kMiInt16: case kMiUint16: case kMiUtf16: return 2;
    case kMiInt32: case kMiUint32: case kMiSingle: case kMiUtf32: return 4;
    case kMiDouble: case kMiInt64: case kMiUint64: return 8;
    default: return 0;
  }
}

struct Damaged {  // a structural fault; V5Source::fail_damaged turns it into an InputError
  std::string what;
};

class V5Source : public MatSource {
 public:
  V5Source(const std::string& path, std::string bytes) : path_(path), file_(std::move(bytes)) {
    swap_ = file_[126] == 'M' && file_[127] == 'I';
    try {
      const char* p = file_.data() + 128;
      const char* e = file_.data() + file_.size();
      while (p < e) {
        if (e - p < 8 && std::all_of(p, e, [](char c) { return c == 0; })) break;  // trailing padding
        const Element el = element(p, e);
        if (el.type == kMiMatrix) {
          add(el.data, el.bytes);
        } else if (el.type == kMiCompressed) {
          inflated_.push_back(inflate(el.data, el.bytes));
          const std::string& body = inflated_.back();
          const Element inner = element(body.data(), body.data() + body.size());
          if (inner.type != kMiMatrix) throw Damaged{"a compressed element does not hold a variable"};
          add(inner.data, inner.bytes);
        }  // other top-level elements are not variables: skipped
        p = el.next;
      }
    } catch (const Damaged& d) {
      fail_damaged(d.what);
    }
  }

  const std::vector<std::string>& variables() const override { return names_; }

  Array load(const std::string& name, bool complex_allowed) override {
    const Var& v = var(name);
    Array out;
    out.dims = v.dims;
    const size_t n = count(v.dims);
    const bool numeric = v.klass >= kMxDouble && v.klass <= kMxUint64;
    if (!numeric && n > 0)
      fail(fmt::format("variable '{}' is not a numeric array; save it as a full double, single or integer array", name));
    if (n == 0) return out;
    if (v.complex && !complex_allowed) fail(fmt::format("variable '{}' is complex; save it as a real array", name));
    try {
      out.re = values(v.real, n, name);
      if (v.complex) out.im = values(v.imag, n, name);
    } catch (const Damaged& d) {
      fail_damaged(d.what);
    }
    return out;
  }

  std::vector<std::string> names(const std::string& name, size_t wanted) override {
    const Var& v = var(name);
    if (v.klass != kMxCell || v.cells.size() != wanted)
      fail(fmt::format("'{}' must be a cell array of {} names (one per {}), e.g. save outputs = {{'psi','theta'}}", name, wanted,
                       name == "outputs" ? "output" : "input"));
    std::vector<std::string> out;
    for (size_t k = 0; k < v.cells.size(); ++k) {
      const Var& cell = v.cells[k];
      if (cell.klass != kMxChar)
        fail(fmt::format("'{}'{{{}}} is not text; '{}' must be a cell array of names: save each name as char", name, k + 1, name));
      std::string text;
      try {
        text = chars(cell, name, k);
      } catch (const Damaged& d) {
        fail_damaged(d.what);
      }
      out.push_back(std::move(text));
    }
    return out;
  }

 private:
  struct Element {
    uint32_t type = 0;
    const char* data = nullptr;
    size_t bytes = 0;
    const char* next = nullptr;
  };
  struct Part {
    uint32_t type = 0;
    const char* data = nullptr;
    size_t bytes = 0;
  };
  struct Var {
    std::string name;
    uint32_t klass = 0;
    bool complex = false;
    std::vector<size_t> dims;
    Part real, imag;          // numeric arrays; real = the characters of a char array
    std::vector<Var> cells;   // cell arrays
  };

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("'{}': {}", path_, detail::one_line_message(what)));
  }
  [[noreturn]] void fail_damaged(const std::string& what) const {
    fail(fmt::format("the file is damaged or truncated ({}); save it again, e.g. in MATLAB with save(name, '-v7')", what));
  }

  uint32_t u32(const char* p) const {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return swap_ ? __builtin_bswap32(v) : v;
  }

  Element element(const char* p, const char* e) const {
    if (e - p < 8) throw Damaged{"a data element is cut short"};
    Element el;
    const uint32_t first = u32(p);
    if ((first >> 16) != 0) {  // small data element: 2 bytes count, 2 bytes type, 4 bytes data
      el.type = first & 0xFFFF;
      el.bytes = first >> 16;
      if (el.bytes > 4) throw Damaged{"a small data element claims more than 4 bytes"};
      el.data = p + 4;
      el.next = p + 8;
      return el;
    }
    el.type = first;
    el.bytes = u32(p + 4);
    el.data = p + 8;
    if (el.bytes > static_cast<size_t>(e - el.data))
      throw Damaged{fmt::format("an element of {} bytes runs past the end of the data", el.bytes)};
    const size_t padded = el.type == kMiCompressed ? el.bytes : (el.bytes + 7) / 8 * 8;
    el.next = padded <= static_cast<size_t>(e - el.data) ? el.data + padded : e;
    return el;
  }

  std::string inflate(const char* data, size_t bytes) {
    z_stream z{};
    if (inflateInit(&z) != Z_OK) throw Damaged{"zlib cannot start"};
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data));
    z.avail_in = static_cast<uInt>(std::min<size_t>(bytes, std::numeric_limits<uInt>::max()));
    std::string out;
    int rc = Z_OK;
    while (rc == Z_OK) {
      const size_t have = out.size();
      const size_t grow = std::max<size_t>(have, 4096);
      if (inflated_bytes_ + have + grow > kMaxInflatedBytes) {
        inflateEnd(&z);
        fail(fmt::format("its variables take more than {} MiB uncompressed; lpvid reads smaller files (split the data)",
                         kMaxInflatedBytes >> 20));
      }
      out.resize(have + grow);
      z.next_out = reinterpret_cast<Bytef*>(out.data() + have);
      z.avail_out = static_cast<uInt>(grow);
      rc = ::inflate(&z, Z_NO_FLUSH);
      out.resize(have + grow - z.avail_out);
    }
    inflateEnd(&z);
    if (rc != Z_STREAM_END) throw Damaged{"a compressed variable does not decompress"};
    inflated_bytes_ += out.size();
    return out;
  }

  static size_t count(const std::vector<size_t>& dims) {
    size_t n = 1;
    for (const size_t d : dims) n *= d;  // bounded in parse (no overflow)
    return n;
  }

  // An miMATRIX element's content [p, p + bytes) at nesting depth.
  Var parse(const char* p, size_t bytes, int depth) const {
    if (depth > 8) throw Damaged{"cell arrays nest deeper than 8 levels"};
    Var v;
    if (bytes == 0) return v;  // an empty array
    const char* e = p + bytes;
    const Element flags = element(p, e);
    if (flags.type != kMiUint32 || flags.bytes != 8) throw Damaged{"a variable has no array flags"};
    const uint32_t f = u32(flags.data);
    v.klass = f & 0xFF;
    v.complex = (f & 0x800) != 0;
    const Element dims = element(flags.next, e);
    if (dims.type != kMiInt32 || dims.bytes % 4 != 0 || dims.bytes < 8 || dims.bytes > 4 * kMaxDims)
      throw Damaged{"a variable has no valid dimensions"};
    uint64_t total = 1;
    for (size_t k = 0; k < dims.bytes / 4; ++k) {
      const int32_t d = static_cast<int32_t>(u32(dims.data + 4 * k));
      if (d < 0) throw Damaged{"a dimension is negative"};
      v.dims.push_back(static_cast<size_t>(d));
      constexpr uint64_t kMaxElements = uint64_t{1} << 40;  // far beyond any 512 MiB file
      if (d > 0 && total > kMaxElements / static_cast<uint64_t>(d))
        throw Damaged{"a variable's dimensions multiply beyond any file"};
      total *= static_cast<uint64_t>(d);
    }
    const Element name = element(dims.next, e);
    if ((name.type != kMiInt8 && name.type != kMiUint8 && name.type != kMiUtf8) || name.bytes > kMaxNameBytes)
      throw Damaged{"a variable has no valid name"};
    v.name.assign(name.data, name.bytes);
    const char* p2 = name.next;
    if (v.klass == kMxCell) {
      if (total > (uint64_t{1} << 20)) throw Damaged{"a cell array has too many cells"};
      for (uint64_t k = 0; k < total; ++k) {
        const Element cell = element(p2, e);
        if (cell.type != kMiMatrix) throw Damaged{"a cell is not an array"};
        v.cells.push_back(parse(cell.data, cell.bytes, depth + 1));
        p2 = cell.next;
      }
    } else if ((v.klass >= kMxDouble && v.klass <= kMxUint64) || v.klass == kMxChar) {
      if (total > 0 || p2 < e) {
        const Element re = element(p2, e);
        v.real = {re.type, re.data, re.bytes};
        if (v.complex) {
          const Element im = element(re.next, e);
          v.imag = {im.type, im.data, im.bytes};
        }
      }
    }  // struct, object, sparse, ...: not read (not numeric)
    return v;
  }

  void add(const char* data, size_t bytes) {
    Var v = parse(data, bytes, 0);
    if (v.name.empty()) return;  // an empty top-level array, or a nameless one: not a variable
    if (std::find(names_.begin(), names_.end(), v.name) != names_.end())
      throw Damaged{fmt::format("variable '{}' appears twice", v.name)};
    names_.push_back(v.name);
    vars_.push_back(std::move(v));
  }

  const Var& var(const std::string& name) const {
    for (const Var& v : vars_)
      if (v.name == name) return v;
    LPVID_ASSERT(false);  // only listed variables are asked for
    return vars_.front();
  }

  template <typename T>
  T get(const char* p) const {
    T v;
    std::memcpy(&v, p, sizeof v);
    if (swap_) {
      char* b = reinterpret_cast<char*>(&v);
      std::reverse(b, b + sizeof v);
    }
    return v;
  }

  std::vector<double> values(const Part& part, size_t n, const std::string& name) const {
    const size_t size = type_size(part.type);
    if (size == 0 || part.type == kMiUtf8 || part.type == kMiUtf16 || part.type == kMiUtf32)
      fail(fmt::format("variable '{}' is not a numeric array; save it as a full double, single or integer array", name));
    if (part.bytes != n * size)
      throw Damaged{fmt::format("variable '{}' holds {} bytes for {} values", name, part.bytes, n)};
    std::vector<double> out(n);
    const char* p = part.data;
    for (size_t k = 0; k < n; ++k, p += size) {
      switch (part.type) {
        case kMiInt8: out[k] = get<int8_t>(p); break;
        case kMiUint8: out[k] = get<uint8_t>(p); break;
        case kMiInt16: out[k] = get<int16_t>(p); break;
        case kMiUint16: out[k] = get<uint16_t>(p); break;
        case kMiInt32: out[k] = get<int32_t>(p); break;
        case kMiUint32: out[k] = get<uint32_t>(p); break;
        case kMiSingle: out[k] = get<float>(p); break;
        case kMiDouble: out[k] = get<double>(p); break;
        case kMiInt64: out[k] = static_cast<double>(get<int64_t>(p)); break;
        case kMiUint64: out[k] = static_cast<double>(get<uint64_t>(p)); break;
        default: break;
      }
    }
    return out;
  }

  // The text of a char array (UTF-8, UTF-16 or the 8/16-bit integer forms).
  std::string chars(const Var& cell, const std::string& name, size_t k) const {
    const size_t n = count(cell.dims);
    std::string text;
    if (n == 0) return text;
    const Part& part = cell.real;
    const size_t size = type_size(part.type);
    if (part.type == kMiUtf8 || part.type == kMiUint8 || part.type == kMiInt8) {
      if (part.bytes < n) throw Damaged{fmt::format("'{}'{{{}}} holds fewer characters than its size", name, k + 1)};
      text.assign(part.data, n);
    } else if (part.type == kMiUtf16 || part.type == kMiUint16) {
      if (part.bytes != n * size) throw Damaged{fmt::format("'{}'{{{}}} holds fewer characters than its size", name, k + 1)};
      for (size_t c = 0; c < n; ++c) {  // UTF-16 code units of the BMP to UTF-8
        append_utf8(text, get<uint16_t>(part.data + 2 * c));
      }
    } else {
      fail(fmt::format("'{}'{{{}}} is text of an encoding lpvid cannot read; save names as char", name, k + 1));
    }
    return text;
  }

  const std::string& path_;
  std::string file_;
  bool swap_ = false;
  std::vector<std::string> inflated_;
  uint64_t inflated_bytes_ = 0;
  std::vector<std::string> names_;
  std::vector<Var> vars_;
};

// ---- MATLAB v7.3 (HDF5), read through libmatio ------------------------------
class MatioSource : public MatSource {
 public:
  explicit MatioSource(const std::string& path) : path_(path) {
    silence_matio();
    mat_.reset(Mat_Open(path_.c_str(), MAT_ACC_RDONLY));
    if (mat_ == nullptr || Mat_GetVersion(mat_.get()) != MAT_FT_MAT73) not_mat(path_);
    size_t n = 0;
    char** dir = Mat_GetDir(mat_.get(), &n);
    if (dir == nullptr && n > 0) not_mat(path_);
    for (size_t k = 0; k < n; ++k)
      if (dir[k] != nullptr) variables_.emplace_back(dir[k]);
  }

  const std::vector<std::string>& variables() const override { return variables_; }

  Array load(const std::string& name, bool complex_allowed) override {
    VarPtr var(Mat_VarRead(mat_.get(), name.c_str()));
    if (var == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    Array out;
    size_t n = 1;
    for (int d = 0; d < var->rank; ++d) {
      out.dims.push_back(var->dims[d]);
      n *= var->dims[d];
    }
    const bool numeric = var->class_type != MAT_C_CELL && var->class_type != MAT_C_STRUCT &&
                         var->class_type != MAT_C_CHAR && var->class_type != MAT_C_SPARSE &&
                         var->class_type != MAT_C_OBJECT && var->class_type != MAT_C_FUNCTION &&
                         var->class_type != MAT_C_OPAQUE && var->class_type != MAT_C_EMPTY;
    if (!numeric && n > 0)
      fail(fmt::format("variable '{}' is not a numeric array; save it as a full double, single or integer array", name));
    if (n == 0) return out;
    if (var->data == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    if (var->isComplex) {
      if (!complex_allowed) fail(fmt::format("variable '{}' is complex; save it as a real array", name));
      const auto* split = static_cast<const mat_complex_split_t*>(var->data);
      if (!to_double(var.get(), split->Re, n, out.re) || !to_double(var.get(), split->Im, n, out.im))
        fail(fmt::format("variable '{}' is not a numeric array; save it as a full double, single or integer array", name));
    } else if (!to_double(var.get(), var->data, n, out.re)) {
      fail(fmt::format("variable '{}' is not a numeric array; save it as a full double, single or integer array", name));
    }
    return out;
  }

  std::vector<std::string> names(const std::string& name, size_t count) override {
    VarPtr var(Mat_VarRead(mat_.get(), name.c_str()));
    if (var == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    size_t n = 1;
    for (int d = 0; d < var->rank; ++d) n *= var->dims[d];
    if (var->class_type != MAT_C_CELL || n != count)
      fail(fmt::format("'{}' must be a cell array of {} names (one per {}), e.g. save outputs = {{'psi','theta'}}", name, count,
                       name == "outputs" ? "output" : "input"));
    std::vector<std::string> out;
    for (size_t k = 0; k < n; ++k) {
      const matvar_t* cell = Mat_VarGetCell(var.get(), static_cast<int>(k));
      if (cell == nullptr || cell->class_type != MAT_C_CHAR)
        fail(fmt::format("'{}'{{{}}} is not text; '{}' must be a cell array of names: save each name as char", name, k + 1, name));
      size_t len = 1;
      for (int d = 0; d < cell->rank; ++d) len *= cell->dims[d];
      std::string text;
      if (len > 0 && cell->data != nullptr) {
        if (cell->data_type == MAT_T_UINT16 || cell->data_type == MAT_T_UTF16) {
          const auto* p = static_cast<const uint16_t*>(cell->data);
          for (size_t c = 0; c < len; ++c) append_utf8(text, p[c]);  // UTF-16 of the BMP to UTF-8
        } else if (cell->data_type == MAT_T_UINT8 || cell->data_type == MAT_T_UTF8 || cell->data_type == MAT_T_INT8) {
          text.assign(static_cast<const char*>(cell->data), static_cast<const char*>(cell->data) + len);
        } else {
          fail(fmt::format("'{}'{{{}}} is text of an encoding lpvid cannot read; save names as char", name, k + 1));
        }
      }
      out.push_back(std::move(text));
    }
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("'{}': {}", path_, detail::one_line_message(what)));
  }
  [[noreturn]] static void not_mat(const std::string& path) {
    throw InputError(fmt::format("'{}' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB "
                                 "with save(name, '-v7')",
                                 path));
  }

  const std::string& path_;
  MatPtr mat_;
  std::vector<std::string> variables_;
};

class MatReader {
 public:
  MatReader(const std::string& path, const FrdReadOptions& options) : path_(path), options_(options) {}

  FrequencyResponse read() {
    options_.validate();
    open();
    const std::string freq_name = pick_frequency();
    const std::string response_name = pick_response();
    FrequencyResponse frd;
    const bool in_hz = freq_name == "freq_hz" || freq_name == "f" || freq_name == "freq";
    {
      const Array f = source_->load(freq_name, false);
      const size_t nf = f.re.size();
      if (nf == 0 || std::count_if(f.dims.begin(), f.dims.end(), [](size_t d) { return d != 1; }) > 1)
        fail(fmt::format("frequency '{}' is {}; give a vector of one or more frequencies", freq_name,
                         dims_text(f.dims)));
      frd.omega_rad_s.resize(static_cast<Index>(nf));
      for (size_t k = 0; k < nf; ++k) {
        const double v = f.re[k];
        if (!std::isfinite(v) || !(v > 0))
          fail(fmt::format("frequency '{}'({}) = {} is not a positive finite number; give frequencies > 0",
                           freq_name, k + 1, v));
        if (k > 0 && !(v > f.re[k - 1]))
          fail(fmt::format("frequency '{}'({}) = {} is not above '{}'({}) = {}; give strictly increasing frequencies",
                           freq_name, k + 1, v, freq_name, k, f.re[k - 1]));
        frd.omega_rad_s[static_cast<Index>(k)] = in_hz ? frd_detail::omega_from_hz(v) : v;
      }
    }
    const size_t nf = static_cast<size_t>(frd.omega_rad_s.size());
    const Array h = source_->load(response_name, true);
    const auto [ny, nu] = shape(h, response_name, nf, "response");
    if (ny > static_cast<size_t>(frd_detail::kMaxChannels) || nu > static_cast<size_t>(frd_detail::kMaxChannels) ||
        nf * ny * nu > static_cast<size_t>(frd_detail::kMaxEntries))
      fail(fmt::format("response '{}' is {}×{}×{}: lpvid reads responses of at most {} outputs and inputs and {} "
                       "entries; split the data",
                       response_name, ny, nu, nf, frd_detail::kMaxChannels, frd_detail::kMaxEntries));
    frd.response.assign(nf, Eigen::MatrixXcd(static_cast<Index>(ny), static_cast<Index>(nu)));
    for (size_t k = 0; k < nf; ++k)
      for (size_t j = 0; j < nu; ++j)
        for (size_t i = 0; i < ny; ++i) {
          const size_t at = i + ny * (j + nu * k);
          const Complex v(h.re[at], h.im.empty() ? 0.0 : h.im[at]);
          if (!std::isfinite(v.real()) || !std::isfinite(v.imag()))
            fail(fmt::format("response '{}' is {} at output {}, input {}, frequency {}; NaN/Inf not allowed",
                             response_name, std::isfinite(v.real()) ? v.imag() : v.real(), i + 1, j + 1, k + 1));
          frd.response[k](static_cast<Index>(i), static_cast<Index>(j)) = v;
        }
    if (has("coh")) {
      const Array c = source_->load("coh", false);
      const auto [cy, cu] = shape(c, "coh", nf, "coherence");
      if (cy != ny || cu != nu)
        fail(fmt::format("coherence 'coh' is {}×{} per frequency but response '{}' is {}×{}; give coherence of the "
                         "response's shape",
                         cy, cu, response_name, ny, nu));
      frd.coherence.assign(nf, Eigen::MatrixXd(static_cast<Index>(ny), static_cast<Index>(nu)));
      for (size_t k = 0; k < nf; ++k)
        for (size_t j = 0; j < nu; ++j)
          for (size_t i = 0; i < ny; ++i) {
            const double v = c.re[i + ny * (j + nu * k)];
            if (!(v >= 0 && v <= 1))
              fail(fmt::format("coherence 'coh' is {} at output {}, input {}, frequency {}; coherence must be in "
                               "[0, 1]",
                               v, i + 1, j + 1, k + 1));
            frd.coherence[k](static_cast<Index>(i), static_cast<Index>(j)) = v;
          }
    }
    if (has("var")) {
      const Array c = source_->load("var", false);
      const auto [cy, cu] = shape(c, "var", nf, "variance");
      if (cy != ny || cu != nu)
        fail(fmt::format("variance 'var' is {}×{} per frequency but response '{}' is {}×{}; give variance of the "
                         "response's shape",
                         cy, cu, response_name, ny, nu));
      frd.variance.assign(nf, Eigen::MatrixXd(static_cast<Index>(ny), static_cast<Index>(nu)));
      for (size_t k = 0; k < nf; ++k)
        for (size_t j = 0; j < nu; ++j)
          for (size_t i = 0; i < ny; ++i) {
            const double v = c.re[i + ny * (j + nu * k)];
            if (!(v >= 0) || !std::isfinite(v))
              fail(fmt::format("variance 'var' is {} at output {}, input {}, frequency {}; a variance is finite and "
                               ">= 0",
                               v, i + 1, j + 1, k + 1));
            frd.variance[k](static_cast<Index>(i), static_cast<Index>(j)) = v;
          }
    }
    if (has("dvar")) {
      if (frd.variance.empty())
        fail("distortion variance 'dvar' without the total variance 'var'; give both (var includes the distortion "
             "part)");
      const Array c = source_->load("dvar", false);
      const auto [cy, cu] = shape(c, "dvar", nf, "distortion variance");
      if (cy != ny || cu != nu)
        fail(fmt::format("distortion variance 'dvar' is {}×{} per frequency but response '{}' is {}×{}; give it of the "
                         "response's shape",
                         cy, cu, response_name, ny, nu));
      frd.distortion_variance.assign(nf, Eigen::MatrixXd(static_cast<Index>(ny), static_cast<Index>(nu)));
      for (size_t k = 0; k < nf; ++k)
        for (size_t j = 0; j < nu; ++j)
          for (size_t i = 0; i < ny; ++i) {
            const double v = c.re[i + ny * (j + nu * k)];
            if (!(v >= 0) || !std::isfinite(v) || v > frd.variance[k](static_cast<Index>(i), static_cast<Index>(j)) * (1 + 1e-12))
              fail(fmt::format("distortion variance 'dvar' is {} at output {}, input {}, frequency {}; it is finite, "
                               ">= 0 and at most the total variance 'var'",
                               v, i + 1, j + 1, k + 1));
            frd.distortion_variance[k](static_cast<Index>(i), static_cast<Index>(j)) = v;
          }
    }
    if (has("averages")) {
      const Array a = source_->load("averages", false);
      if (a.re.size() != 1 || !std::isfinite(a.re[0]) || a.re[0] < 1 || a.re[0] > 1e9)
        fail(fmt::format("'averages' must be one number >= 1 (the independent averages behind the coherence): give one number; got {} "
                         "value(s){}",
                         a.re.size(), a.re.size() == 1 ? fmt::format(" = {}", a.re[0]) : std::string()));
      frd.averages = a.re[0];
    }
    if (has("flag")) {
      const Array g = source_->load("flag", false);
      if (g.re.size() != nf || std::count_if(g.dims.begin(), g.dims.end(), [](size_t d) { return d != 1; }) > 1)
        fail(fmt::format("'flag' is {} but there are {} frequencies; give a vector of one 0/1 flag per frequency",
                         dims_text(g.dims), nf));
      frd.flagged.resize(nf);
      for (size_t k = 0; k < nf; ++k) {
        if (g.re[k] != 0 && g.re[k] != 1)
          fail(fmt::format("'flag'({}) is {}; write 0 or 1 (1 = untrusted frequency)", k + 1, g.re[k]));
        frd.flagged[k] = g.re[k] == 1;
      }
    }
    if (has("outputs")) frd.output_names = names("outputs", ny);
    if (has("inputs")) frd.input_names = names("inputs", nu);
    return frd;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("'{}': {}", path_, detail::one_line_message(what)));
  }

  void open() {
    if (path_ == "-") throw InputError("cannot read a .mat file from stdin; give a file path");
    struct stat st;
    if (::stat(path_.c_str(), &st) != 0)
      throw InputError(fmt::format("cannot open '{}': {}; check the path", path_, std::strerror(errno)));
    if (S_ISDIR(st.st_mode))
      throw InputError(
          fmt::format("cannot open '{}': {}; give a file, not a directory", path_, std::strerror(EISDIR)));
    if (!S_ISREG(st.st_mode))
      throw InputError(fmt::format("cannot read '{}': a .mat file must be a regular file (not a pipe or device); save "
                                   "it to a file first",
                                   path_));
    if (static_cast<uint64_t>(st.st_size) > kMaxInflatedBytes)
      fail(fmt::format("larger than {} MiB; lpvid reads smaller .mat files (split the data)", kMaxInflatedBytes >> 20));
    const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(fmt::format("cannot open '{}': {}; check the path", path_, std::strerror(errno)));
    std::string bytes;
    char chunk[65536];
    for (;;) {
      const ssize_t n = ::read(fd, chunk, sizeof chunk);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0 || bytes.size() + static_cast<size_t>(n) > kMaxInflatedBytes) break;
      bytes.append(chunk, static_cast<size_t>(n));
    }
    ::close(fd);
    // The 128-byte header: version 0x0100 (v5, read here) or 0x0200 (v7.3,
    // HDF5 through libmatio); anything else (v4 has no header) is refused.
    if (bytes.size() < 128) not_mat();
    const bool little = bytes[126] == 'I' && bytes[127] == 'M';
    const bool big = bytes[126] == 'M' && bytes[127] == 'I';
    if (!little && !big) not_mat();
    const unsigned version = little ? (static_cast<unsigned char>(bytes[125]) << 8 | static_cast<unsigned char>(bytes[124]))
                                     : (static_cast<unsigned char>(bytes[124]) << 8 | static_cast<unsigned char>(bytes[125]));
    if (version == 0x0100) {
      source_ = std::make_unique<V5Source>(path_, std::move(bytes));
    } else if (version == 0x0200) {
      source_ = std::make_unique<MatioSource>(path_);
    } else {
      not_mat();
    }
    variables_ = source_->variables();
  }

  [[noreturn]] void not_mat() const {
    throw InputError(fmt::format("'{}' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB "
                                 "with save(name, '-v7')",
                                 path_));
  }

  bool has(const std::string& name) const {
    return std::find(variables_.begin(), variables_.end(), name) != variables_.end();
  }
  // The variables' names for a message: each cut to 40 bytes with control bytes as
  // \xNN (detail::quote_cell, without its quotes), at most 20 of them.
  std::string holds() const {
    constexpr size_t kMaxListed = 20;
    if (variables_.empty()) return "no variables";
    std::string out;
    for (size_t i = 0; i < variables_.size() && i < kMaxListed; ++i) {
      const std::string quoted = detail::quote_cell(variables_[i]);
      out += (i ? ", " : "") + quoted.substr(1, quoted.size() - 2);
    }
    if (variables_.size() > kMaxListed) out += fmt::format(", ... ({} in all)", variables_.size());
    return out;
  }

  std::string pick_frequency() const {
    std::vector<std::string> found;
    for (const char* name : {"freq_hz", "f", "freq", "w", "omega"})
      if (has(name)) found.emplace_back(name);
    if (found.empty())
      fail(fmt::format("no frequency variable; give one of freq_hz, f, freq (Hz) or w, omega (rad/s); the file holds: "
                       "{}",
                       holds()));
    if (found.size() > 1)
      fail(fmt::format("several frequency variables ({}); keep one", fmt::join(found, ", ")));
    return found.front();
  }

  std::string pick_response() const {
    if (!options_.quantity.empty()) {
      if (!has(options_.quantity))
        fail(fmt::format("no variable '{}' (the quantity asked for); choose one the file holds: {}", options_.quantity, holds()));
      return options_.quantity;
    }
    std::vector<std::string> found;
    for (const char* name : {"S", "P", "G", "H", "frd"})
      if (has(name)) found.emplace_back(name);
    if (found.empty())
      fail(fmt::format("no response variable; give one of S, P, G, H, frd, or choose one with the quantity option; "
                       "the file holds: {}",
                       holds()));
    if (found.size() > 1)
      fail(fmt::format("several response variables ({}); choose one with the quantity option", fmt::join(found, ", ")));
    return found.front();
  }

  // (ny, nu) of an array holding nf matrices, by the rules in frd_mat.h.
  std::pair<size_t, size_t> shape(const Array& a, const std::string& name, size_t nf, const char* what) const {
    std::vector<size_t> dims = a.dims;
    while (dims.size() > 3 && dims.back() == 1) dims.pop_back();
    if (dims.size() == 3 && dims[2] == nf && dims[0] > 0 && dims[1] > 0) return {dims[0], dims[1]};
    if (dims.size() == 2) {
      if (nf == 1 && dims[0] > 0 && dims[1] > 0) return {dims[0], dims[1]};
      if (nf > 1 && (dims[0] == 1 || dims[1] == 1) && dims[0] * dims[1] == nf) return {1, 1};
    }
    fail(fmt::format("{} '{}' is {} but there are {} frequencies; give an outputs × inputs × frequencies array (or a "
                     "vector of {} entries for one output and one input)",
                     what, name, dims_text(a.dims), nf, nf));
  }

  std::vector<std::string> names(const std::string& name, size_t count) const {
    std::vector<std::string> out = source_->names(name, count);
    for (size_t k = 0; k < out.size(); ++k) {
      if (out[k].empty()) fail(fmt::format("'{}'{{{}}} is empty; give every channel a name", name, k + 1));
      if (!valid_utf8(out[k]))
        fail(fmt::format("'{}'{{{}}} is not valid UTF-8 text; save the names as char", name, k + 1));
      if (std::find(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(k), out[k]) !=
          out.begin() + static_cast<std::ptrdiff_t>(k))
        fail(fmt::format("name '{}' appears twice in '{}'; give every channel its own name", out[k], name));
    }
    return out;
  }

  const std::string& path_;
  const FrdReadOptions& options_;
  std::unique_ptr<MatSource> source_;
  std::vector<std::string> variables_;
};

// ---- writing ---------------------------------------------------------------

// Writes through libmatio into the temporary of an AtomicFileWriter (matio
// opens files by name); the caller's commit renames it into place.
class MatWriter {
 public:
  MatWriter(AtomicFileWriter& out, MatVersion version) : path_(out.path()) {
    if (out.temp_path().empty())
      throw InputError(fmt::format("cannot write '{}': a .mat file cannot be streamed to standard output, a pipe or a "
                                   "device; give a file path",
                                   detail::display_path(path_)));
    out.release_descriptor();
    silence_matio();
    errno = 0;
    mat_.reset(Mat_CreateVer(out.temp_path().c_str(), nullptr, version == MatVersion::kV73 ? MAT_FT_MAT73 : MAT_FT_MAT5));
    if (mat_ == nullptr) fail(errno != 0 ? errno : EIO);
  }
  MatWriter(const MatWriter&) = delete;
  MatWriter& operator=(const MatWriter&) = delete;

  void add(matvar_t* raw) {
    VarPtr var(raw);
    if (var == nullptr || Mat_VarWrite(mat_.get(), var.get(), MAT_COMPRESSION_NONE) != 0) fail(EIO);
  }

  void finish() {
    if (Mat_Close(mat_.release()) != 0) fail(EIO);
  }

 private:
  [[noreturn]] void fail(int err) const {
    throw InputError(fmt::format("cannot write '{}': {}; check the directory exists and is writable", path_,
                                 std::strerror(err)));
  }

  std::string path_;
  MatPtr mat_;
};

matvar_t* real_array(const char* name, std::vector<size_t> dims, std::vector<double>& data) {
  return Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, static_cast<int>(dims.size()), dims.data(), data.data(), 0);
}

matvar_t* name_cells(const char* name, const std::vector<std::string>& names) {
  std::vector<matvar_t*> cells;
  for (const std::string& text : names) {
    size_t dims[2] = {1, text.size()};
    cells.push_back(Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UTF8, 2, dims, const_cast<char*>(text.data()), 0));
  }
  size_t dims[2] = {1, names.size()};
  return Mat_VarCreate(name, MAT_C_CELL, MAT_T_CELL, 2, dims, cells.data(), 0);
}

}  // namespace

FrequencyResponse read_frd_mat(const std::string& path, const FrdReadOptions& options) {
  return MatReader(path, options).read();
}

void write_frd_mat(const std::string& path, const FrequencyResponse& frd, const std::string& quantity,
                   MatVersion version) {
  if (path == "-") throw InputError("cannot write a .mat file to stdout; give a file path");
  AtomicFileWriter out(path);
  write_frd_mat(out, frd, quantity, version);
  out.commit();
}

void write_frd_mat(AtomicFileWriter& file, const FrequencyResponse& frd, const std::string& quantity,
                   MatVersion version) {
  const std::string& path = file.path();
  if (!frd_detail::quantity_allowed(quantity))
    throw InputError(fmt::format("cannot write '{}': quantity '{}' is not allowed; use letters and digits "
                                 "(not 'coh'), e.g. S",
                                 path, quantity));
  if (quantity == "freq_hz" || quantity == "f" || quantity == "freq" || quantity == "w" || quantity == "omega" ||
      quantity == "flag" || quantity == "outputs" || quantity == "inputs" || quantity == "averages")
    throw InputError(fmt::format("cannot write '{}': quantity '{}' is the name of another variable of the file; use "
                                 "S, P, G, ...",
                                 path, quantity));
  frd_detail::check_frd_for_writing(path, frd);
  const size_t nf = static_cast<size_t>(frd.num_frequencies());
  const size_t ny = static_cast<size_t>(frd.num_outputs()), nu = static_cast<size_t>(frd.num_inputs());
  MatWriter out(file, version);
  std::vector<double> hz(nf);
  for (size_t k = 0; k < nf; ++k) hz[k] = frd_detail::hz_from_omega(frd.omega_rad_s[static_cast<Index>(k)]);
  out.add(real_array("freq_hz", {nf, 1}, hz));
  std::vector<double> re(ny * nu * nf), im(ny * nu * nf);
  for (size_t k = 0; k < nf; ++k)
    for (size_t j = 0; j < nu; ++j)
      for (size_t i = 0; i < ny; ++i) {
        const Complex v = frd.response[k](static_cast<Index>(i), static_cast<Index>(j));
        re[i + ny * (j + nu * k)] = v.real();
        im[i + ny * (j + nu * k)] = v.imag();
      }
  mat_complex_split_t split{re.data(), im.data()};
  size_t dims[3] = {ny, nu, nf};
  out.add(Mat_VarCreate(quantity.c_str(), MAT_C_DOUBLE, MAT_T_DOUBLE, 3, dims, &split, MAT_F_COMPLEX));
  if (!frd.coherence.empty()) {
    std::vector<double> coh(ny * nu * nf);
    for (size_t k = 0; k < nf; ++k)
      for (size_t j = 0; j < nu; ++j)
        for (size_t i = 0; i < ny; ++i)
          coh[i + ny * (j + nu * k)] = frd.coherence[k](static_cast<Index>(i), static_cast<Index>(j));
    out.add(real_array("coh", {ny, nu, nf}, coh));
  }
  if (!frd.variance.empty()) {
    std::vector<double> var(ny * nu * nf);
    for (size_t k = 0; k < nf; ++k)
      for (size_t j = 0; j < nu; ++j)
        for (size_t i = 0; i < ny; ++i)
          var[i + ny * (j + nu * k)] = frd.variance[k](static_cast<Index>(i), static_cast<Index>(j));
    out.add(real_array("var", {ny, nu, nf}, var));
  }
  if (!frd.distortion_variance.empty()) {
    std::vector<double> dvar(ny * nu * nf);
    for (size_t k = 0; k < nf; ++k)
      for (size_t j = 0; j < nu; ++j)
        for (size_t i = 0; i < ny; ++i)
          dvar[i + ny * (j + nu * k)] = frd.distortion_variance[k](static_cast<Index>(i), static_cast<Index>(j));
    out.add(real_array("dvar", {ny, nu, nf}, dvar));
  }
  if (frd.averages > 0) {
    std::vector<double> averages{frd.averages};
    out.add(real_array("averages", {1, 1}, averages));
  }
  if (!frd.flagged.empty()) {
    std::vector<double> flag(nf);
    for (size_t k = 0; k < nf; ++k) flag[k] = frd.flagged[k] ? 1.0 : 0.0;
    out.add(real_array("flag", {nf, 1}, flag));
  }
  if (!frd.output_names.empty()) out.add(name_cells("outputs", frd.output_names));
  if (!frd.input_names.empty()) out.add(name_cells("inputs", frd.input_names));
  out.finish();
}

}  // namespace lpvid
