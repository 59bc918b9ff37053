#include "formats/io/mat_detail.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>
#include <mutex>

#include "formats/io/csv_detail.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid::mat_detail {
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

}  // namespace

std::string dims_text(const std::vector<size_t>& dims) { return fmt::format("{}", fmt::join(dims, "×")); }

size_t Value::count() const {
  size_t n = 1;
  for (const size_t d : dims) n *= d;
  return n;
}

const Value* Value::field(const std::string& name, size_t element) const {
  if (kind != Kind::kStruct) return nullptr;
  for (size_t f = 0; f < fields.size(); ++f)
    if (fields[f] == name && element * fields.size() + f < members.size()) return &members[element * fields.size() + f];
  return nullptr;
}

std::string Value::kind_text() const {
  switch (kind) {
    case Kind::kNumeric: return complex ? "complex numeric array" : "numeric array";
    case Kind::kChar: return "char array";
    case Kind::kCell: return "cell array";
    case Kind::kStruct: return "struct";
    case Kind::kOther: break;
  }
  return "array of a class lpvid does not read (sparse, object, function handle, ...)";
}

namespace {

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

// Limits: the dimensions of one variable, the bytes of a name.
constexpr int kMaxDims = 32;
constexpr size_t kMaxNameBytes = 4096;
// Cells or struct members of one array (bounded so a damaged count fails at once).
constexpr uint64_t kMaxMembers = uint64_t{1} << 20;

[[noreturn]] void not_mat(const std::string& path) {
  throw InputError(fmt::format("'{}' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB "
                               "with save(name, '-v7')",
                               path));
}

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
enum : uint32_t { kMxCell = 1, kMxStruct = 2, kMxChar = 4, kMxDouble = 6, kMxUint64 = 15 };

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
        text = chars(cell, fmt::format("'{}'{{{}}}", name, k + 1));
      } catch (const Damaged& d) {
        fail_damaged(d.what);
      }
      out.push_back(std::move(text));
    }
    return out;
  }

  Value value(const std::string& name) override {
    try {
      return tree(var(name), name, 0);
    } catch (const Damaged& d) {
      fail_damaged(d.what);
    }
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
    std::vector<Var> cells;   // cell arrays; structs: element e, field f at e * fields.size() + f
    std::vector<std::string> fields;  // structs
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
    if (depth > 8) throw Damaged{"cell arrays or structs nest deeper than 8 levels"};
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
      if (total > kMaxMembers) throw Damaged{"a cell array has too many cells"};
      for (uint64_t k = 0; k < total; ++k) {
        const Element cell = element(p2, e);
        if (cell.type != kMiMatrix) throw Damaged{"a cell is not an array"};
        v.cells.push_back(parse(cell.data, cell.bytes, depth + 1));
        p2 = cell.next;
      }
    } else if (v.klass == kMxStruct) {
      // Field name length (one int32), then the names, each NUL-padded to that length,
      // then one miMATRIX per field of each element, element by element.
      const Element length = element(p2, e);
      if (length.type != kMiInt32 || length.bytes != 4) throw Damaged{"a struct has no field name length"};
      const int32_t len = static_cast<int32_t>(u32(length.data));
      if (len <= 0 || static_cast<size_t>(len) > kMaxNameBytes) throw Damaged{"a struct's field name length is not valid"};
      const Element names = element(length.next, e);
      if ((names.type != kMiInt8 && names.type != kMiUint8) || names.bytes % static_cast<size_t>(len) != 0)
        throw Damaged{"a struct's field names do not fill their length"};
      for (size_t f = 0; f < names.bytes / static_cast<size_t>(len); ++f) {
        const char* at = names.data + f * static_cast<size_t>(len);
        v.fields.emplace_back(at, strnlen(at, static_cast<size_t>(len)));
      }
      if (!v.fields.empty() && total > kMaxMembers / v.fields.size()) throw Damaged{"a struct has too many members"};
      p2 = names.next;
      for (uint64_t k = 0; k < total * v.fields.size(); ++k) {
        const Element member = element(p2, e);
        if (member.type != kMiMatrix) throw Damaged{"a struct field is not an array"};
        v.cells.push_back(parse(member.data, member.bytes, depth + 1));
        p2 = member.next;
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
    if (part.type == kMiDouble && !swap_) {  // the common case: the bytes are the doubles
      std::memcpy(out.data(), p, n * sizeof(double));
      return out;
    }
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
  // label names the text in messages, e.g. "'outputs'{2}".
  std::string chars(const Var& cell, const std::string& label) const {
    const size_t n = count(cell.dims);
    std::string text;
    if (n == 0) return text;
    const Part& part = cell.real;
    const size_t size = type_size(part.type);
    if (part.type == kMiUtf8 || part.type == kMiUint8 || part.type == kMiInt8) {
      if (part.bytes < n) throw Damaged{fmt::format("{} holds fewer characters than its size", label)};
      text.assign(part.data, n);
    } else if (part.type == kMiUtf16 || part.type == kMiUint16) {
      if (part.bytes != n * size) throw Damaged{fmt::format("{} holds fewer characters than its size", label)};
      for (size_t c = 0; c < n; ++c) {  // UTF-16 code units of the BMP to UTF-8
        append_utf8(text, get<uint16_t>(part.data + 2 * c));
      }
    } else {
      fail(fmt::format("{} is text of an encoding lpvid cannot read; save names as char", label));
    }
    return text;
  }

  // The tree of a parsed variable; where names it in messages.
  Value tree(const Var& v, const std::string& where, int depth) const {
    Value out;
    out.dims = v.dims;
    const size_t n = count(v.dims);
    if (v.klass == 0 || (v.klass >= kMxDouble && v.klass <= kMxUint64)) {
      out.kind = Value::Kind::kNumeric;
      out.complex = v.complex;
      if (n > 0) out.re = values(v.real, n, where);
    } else if (v.klass == kMxChar) {
      out.kind = Value::Kind::kChar;
      out.text = chars(v, fmt::format("'{}'", where));
    } else if (v.klass == kMxCell) {
      out.kind = Value::Kind::kCell;
      for (size_t k = 0; k < v.cells.size(); ++k)
        out.cells.push_back(tree(v.cells[k], fmt::format("{}{{{}}}", where, k + 1), depth + 1));
    } else if (v.klass == kMxStruct) {
      out.kind = Value::Kind::kStruct;
      out.fields = v.fields;
      for (size_t k = 0; k < v.cells.size(); ++k)
        out.members.push_back(tree(v.cells[k], fmt::format("{}.{}", where, v.fields[k % v.fields.size()]), depth + 1));
    }
    return out;
  }

  std::string path_;
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
  // The tree of a matio variable; where names it in messages.
  Value tree(const matvar_t* var, const std::string& where, int depth) const {
    if (depth > 8) fail(fmt::format("'{}': cell arrays or structs nest deeper than 8 levels; save a flatter layout", where));
    Value out;
    size_t n = 1;
    for (int d = 0; d < var->rank; ++d) {
      out.dims.push_back(var->dims[d]);
      n *= var->dims[d];
    }
    switch (var->class_type) {
      case MAT_C_CHAR: {
        out.kind = Value::Kind::kChar;
        if (n > 0 && var->data != nullptr) {
          if (var->data_type == MAT_T_UINT16 || var->data_type == MAT_T_UTF16) {
            const auto* p = static_cast<const uint16_t*>(var->data);
            for (size_t c = 0; c < n; ++c) append_utf8(out.text, p[c]);
          } else if (var->data_type == MAT_T_UINT8 || var->data_type == MAT_T_UTF8 || var->data_type == MAT_T_INT8) {
            out.text.assign(static_cast<const char*>(var->data), static_cast<const char*>(var->data) + n);
          } else {
            fail(fmt::format("'{}' is text of an encoding lpvid cannot read; save it as char", where));
          }
        }
        return out;
      }
      case MAT_C_CELL: {
        out.kind = Value::Kind::kCell;
        if (n > kMaxMembers) fail(fmt::format("'{}' has more than {} cells; save fewer", where, kMaxMembers));
        for (size_t k = 0; k < n; ++k) {
          const matvar_t* cell = Mat_VarGetCell(const_cast<matvar_t*>(var), static_cast<int>(k));
          if (cell == nullptr) fail(fmt::format("cannot read '{}{{{}}}'; the file may be damaged", where, k + 1));
          out.cells.push_back(tree(cell, fmt::format("{}{{{}}}", where, k + 1), depth + 1));
        }
        return out;
      }
      case MAT_C_STRUCT: {
        out.kind = Value::Kind::kStruct;
        const unsigned nfields = Mat_VarGetNumberOfFields(const_cast<matvar_t*>(var));
        char* const* names = Mat_VarGetStructFieldnames(var);
        if (nfields > 0 && names == nullptr) fail(fmt::format("cannot read '{}'; the file may be damaged", where));
        for (unsigned f = 0; f < nfields; ++f) out.fields.emplace_back(names[f] != nullptr ? names[f] : "");
        if (nfields > 0 && n > kMaxMembers / nfields) fail(fmt::format("'{}' has more than {} struct members; save fewer", where, kMaxMembers));
        for (size_t e = 0; e < n; ++e)
          for (unsigned f = 0; f < nfields; ++f) {
            const matvar_t* member = Mat_VarGetStructFieldByIndex(const_cast<matvar_t*>(var), f, e);
            const std::string at = fmt::format("{}.{}", where, out.fields[f]);
            if (member == nullptr) {
              out.members.emplace_back();  // an empty field
              out.members.back().kind = Value::Kind::kNumeric;
              out.members.back().dims = {0, 0};
            } else {
              out.members.push_back(tree(member, at, depth + 1));
            }
          }
        return out;
      }
      case MAT_C_EMPTY:
        out.kind = Value::Kind::kNumeric;
        return out;
      default: break;
    }
    const bool numeric = var->class_type != MAT_C_SPARSE && var->class_type != MAT_C_OBJECT &&
                         var->class_type != MAT_C_FUNCTION && var->class_type != MAT_C_OPAQUE;
    if (!numeric) return out;  // kOther
    out.kind = Value::Kind::kNumeric;
    out.complex = var->isComplex != 0;
    if (n == 0) return out;
    if (var->data == nullptr) fail(fmt::format("cannot read '{}'; the file may be damaged", where));
    const void* re = var->isComplex ? static_cast<const mat_complex_split_t*>(var->data)->Re : var->data;
    if (!to_double(var, re, n, out.re)) out.kind = Value::Kind::kOther;
    return out;
  }

 public:
  Value value(const std::string& name) override {
    VarPtr var(Mat_VarRead(mat_.get(), name.c_str()));
    if (var == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    return tree(var.get(), name, 0);
  }

 private:
  std::string path_;
  MatPtr mat_;
  std::vector<std::string> variables_;
};

}  // namespace

bool has_mat_header(const std::string& first) {
  return first.size() >= 128 && first.compare(0, 6, "MATLAB") == 0 &&
         ((first[126] == 'I' && first[127] == 'M') || (first[126] == 'M' && first[127] == 'I'));
}

std::unique_ptr<MatSource> open_mat(const std::string& path) {
  if (path == "-") throw InputError("cannot read a .mat file from stdin; give a file path");
  struct stat st;
  if (::stat(path.c_str(), &st) != 0)
    throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
  if (S_ISDIR(st.st_mode))
    throw InputError(fmt::format("cannot open '{}': {}; give a file, not a directory", path, std::strerror(EISDIR)));
  if (!S_ISREG(st.st_mode))
    throw InputError(fmt::format("cannot read '{}': a .mat file must be a regular file (not a pipe or device); save "
                                 "it to a file first",
                                 path));
  if (static_cast<uint64_t>(st.st_size) > kMaxInflatedBytes)
    throw InputError(fmt::format("'{}': larger than {} MiB; lpvid reads smaller .mat files (split the data)", path,
                                 kMaxInflatedBytes >> 20));
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
  // Read straight into a buffer of the file's size (a log's file is large: no
  // growth by copies); what a growing file adds meanwhile is appended, up to the limit.
  std::string bytes;
  bytes.resize(static_cast<size_t>(st.st_size));
  size_t have = 0;
  while (have < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + have, bytes.size() - have);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    have += static_cast<size_t>(n);
  }
  bytes.resize(have);
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
  if (bytes.size() < 128) not_mat(path);
  const bool little = bytes[126] == 'I' && bytes[127] == 'M';
  const bool big = bytes[126] == 'M' && bytes[127] == 'I';
  if (!little && !big) not_mat(path);
  const unsigned version = little ? (static_cast<unsigned char>(bytes[125]) << 8 | static_cast<unsigned char>(bytes[124]))
                                   : (static_cast<unsigned char>(bytes[124]) << 8 | static_cast<unsigned char>(bytes[125]));
  if (version == 0x0100) return std::make_unique<V5Source>(path, std::move(bytes));
  if (version == 0x0200) return std::make_unique<MatioSource>(path);
  not_mat(path);
}

MatWriter::MatWriter(AtomicFileWriter& out, bool v73) : path_(out.path()) {
  if (out.temp_path().empty())
    throw InputError(fmt::format("cannot write '{}': a .mat file cannot be streamed to standard output, a pipe or a "
                                 "device; give a file path",
                                 detail::display_path(path_)));
  out.release_descriptor();
  silence_matio();
  errno = 0;
  mat_.reset(Mat_CreateVer(out.temp_path().c_str(), nullptr, v73 ? MAT_FT_MAT73 : MAT_FT_MAT5));
  if (mat_ == nullptr) fail(errno != 0 ? errno : EIO);
}

void MatWriter::add(matvar_t* raw) {
  VarPtr var(raw);
  if (var == nullptr || Mat_VarWrite(mat_.get(), var.get(), MAT_COMPRESSION_NONE) != 0) fail(EIO);
}

void MatWriter::finish() {
  if (Mat_Close(mat_.release()) != 0) fail(EIO);
}

void MatWriter::fail(int err) const {
  throw InputError(
      fmt::format("cannot write '{}': {}; check the directory exists and is writable", path_, std::strerror(err)));
}

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

std::string variables_text(const std::vector<std::string>& variables) {
  constexpr size_t kMaxListed = 20;
  if (variables.empty()) return "no variables";
  std::string out;
  for (size_t i = 0; i < variables.size() && i < kMaxListed; ++i) {
    const std::string quoted = detail::quote_cell(variables[i]);
    out += (i ? ", " : "") + quoted.substr(1, quoted.size() - 2);
  }
  if (variables.size() > kMaxListed) out += fmt::format(", ... ({} in all)", variables.size());
  return out;
}

}  // namespace lpvid::mat_detail
