#include "formats/io/frd_mat.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <matio.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>

#include "formats/io/frd_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

// matio reports problems through a global log function that prints to stderr;
// every problem here becomes an InputError instead, so the log is silenced.
void silence_matio() {
  static std::once_flag once;
  std::call_once(once, [] { Mat_LogInitFunc("lpvid", [](int, char*) {}); });
}

struct MatCloser {
  void operator()(mat_t* mat) const { Mat_Close(mat); }
};
struct VarFreer {
  void operator()(matvar_t* var) const { Mat_VarFree(var); }
};
using MatPtr = std::unique_ptr<mat_t, MatCloser>;
using VarPtr = std::unique_ptr<matvar_t, VarFreer>;

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
      const Array f = load(freq_name, false);
      const size_t nf = f.re.size();
      if (nf == 0 || std::count_if(f.dims.begin(), f.dims.end(), [](size_t d) { return d != 1; }) > 1)
        fail(fmt::format("frequency '{}' is {}; give a vector of one or more frequencies", freq_name,
                         dims_text(f.dims)));
      frd.omega_rad_s.resize(static_cast<Index>(nf));
      for (size_t k = 0; k < nf; ++k) {
        const double v = f.re[k];
        if (!std::isfinite(v) || !(v > 0))
          fail(fmt::format("frequency '{}'({}) = {} is not a positive finite number; frequencies must be > 0",
                           freq_name, k + 1, v));
        if (k > 0 && !(v > f.re[k - 1]))
          fail(fmt::format("frequency '{}'({}) = {} is not above '{}'({}) = {}; frequencies must increase strictly",
                           freq_name, k + 1, v, freq_name, k, f.re[k - 1]));
        frd.omega_rad_s[static_cast<Index>(k)] = in_hz ? frd_detail::omega_from_hz(v) : v;
      }
    }
    const size_t nf = static_cast<size_t>(frd.omega_rad_s.size());
    const Array h = load(response_name, true);
    const auto [ny, nu] = shape(h, response_name, nf, "response");
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
      const Array c = load("coh", false);
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
      const Array c = load("var", false);
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
    if (has("averages")) {
      const Array a = load("averages", false);
      if (a.re.size() != 1 || !std::isfinite(a.re[0]) || a.re[0] < 1 || a.re[0] > 1e9)
        fail(fmt::format("'averages' must be one number >= 1 (the independent averages behind the coherence); got {} "
                         "value(s){}",
                         a.re.size(), a.re.size() == 1 ? fmt::format(" = {}", a.re[0]) : std::string()));
      frd.averages = a.re[0];
    }
    if (has("flag")) {
      const Array g = load("flag", false);
      if (g.re.size() != nf || std::count_if(g.dims.begin(), g.dims.end(), [](size_t d) { return d != 1; }) > 1)
        fail(fmt::format("'flag' is {} but there are {} frequencies; give a vector of one 0/1 flag per frequency",
                         dims_text(g.dims), nf));
      frd.flagged.resize(nf);
      for (size_t k = 0; k < nf; ++k) {
        if (g.re[k] != 0 && g.re[k] != 1)
          fail(fmt::format("'flag'({}) is {}; a flag is 0 or 1 (1 = untrusted frequency)", k + 1, g.re[k]));
        frd.flagged[k] = g.re[k] == 1;
      }
    }
    if (has("outputs")) frd.output_names = names("outputs", ny);
    if (has("inputs")) frd.input_names = names("inputs", nu);
    return frd;
  }

 private:
  struct Array {
    std::vector<size_t> dims;
    std::vector<double> re, im;  // column-major; im empty when real
  };

  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(fmt::format("'{}': {}", path_, what));
  }

  void open() {
    if (path_ == "-") throw InputError("cannot read a .mat file from stdin; give a file path");
    struct stat st;
    if (::stat(path_.c_str(), &st) != 0)
      throw InputError(fmt::format("cannot open '{}': {}; check the path", path_, std::strerror(errno)));
    if (S_ISDIR(st.st_mode))
      throw InputError(
          fmt::format("cannot open '{}': {}; give a file, not a directory", path_, std::strerror(EISDIR)));
    const int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(fmt::format("cannot open '{}': {}; check the path", path_, std::strerror(errno)));
    ::close(fd);
    silence_matio();
    mat_.reset(Mat_Open(path_.c_str(), MAT_ACC_RDONLY));
    // matio falls back to the headerless v4 format for anything else; lpvid
    // reads v5 and v7.3 only, which carry a 128-byte header.
    if (mat_ == nullptr || Mat_GetVersion(mat_.get()) == MAT_FT_MAT4) not_mat();
    size_t n = 0;
    char** dir = Mat_GetDir(mat_.get(), &n);
    if (dir == nullptr && n > 0) not_mat();
    for (size_t k = 0; k < n; ++k)
      if (dir[k] != nullptr) variables_.emplace_back(dir[k]);
  }

  [[noreturn]] void not_mat() const {
    throw InputError(fmt::format("'{}' is not a MATLAB .mat file (v5 or v7.3); check the file, or save it in MATLAB "
                                 "with save(name, '-v7')",
                                 path_));
  }

  bool has(const std::string& name) const {
    return std::find(variables_.begin(), variables_.end(), name) != variables_.end();
  }
  std::string holds() const {
    return variables_.empty() ? std::string("no variables") : fmt::format("{}", fmt::join(variables_, ", "));
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
        fail(fmt::format("no variable '{}' (the quantity asked for); the file holds: {}", options_.quantity, holds()));
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

  Array load(const std::string& name, bool complex_allowed) const {
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
      fail(fmt::format("variable '{}' is not a numeric array (a full double, single or integer array is needed)", name));
    if (n == 0) return out;
    if (var->data == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    if (var->isComplex) {
      if (!complex_allowed) fail(fmt::format("variable '{}' is complex; it must be real", name));
      const auto* split = static_cast<const mat_complex_split_t*>(var->data);
      if (!to_double(var.get(), split->Re, n, out.re) || !to_double(var.get(), split->Im, n, out.im))
        fail(fmt::format("variable '{}' is not a numeric array (a full double, single or integer array is needed)", name));
    } else if (!to_double(var.get(), var->data, n, out.re)) {
      fail(fmt::format("variable '{}' is not a numeric array (a full double, single or integer array is needed)", name));
    }
    return out;
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
    VarPtr var(Mat_VarRead(mat_.get(), name.c_str()));
    if (var == nullptr) fail(fmt::format("cannot read variable '{}'; the file may be damaged", name));
    size_t n = 1;
    for (int d = 0; d < var->rank; ++d) n *= var->dims[d];
    if (var->class_type != MAT_C_CELL || n != count)
      fail(fmt::format("'{}' must be a cell array of {} names (one per {}), e.g. {{'psi','theta'}}", name, count,
                       name == "outputs" ? "output" : "input"));
    std::vector<std::string> out;
    for (size_t k = 0; k < n; ++k) {
      const matvar_t* cell = Mat_VarGetCell(var.get(), static_cast<int>(k));
      if (cell == nullptr || cell->class_type != MAT_C_CHAR)
        fail(fmt::format("'{}'{{{}}} is not text; '{}' must be a cell array of names", name, k + 1, name));
      size_t len = 1;
      for (int d = 0; d < cell->rank; ++d) len *= cell->dims[d];
      std::string text;
      if (len > 0 && cell->data != nullptr) {
        if (cell->data_type == MAT_T_UINT16 || cell->data_type == MAT_T_UTF16) {
          const auto* p = static_cast<const uint16_t*>(cell->data);
          for (size_t c = 0; c < len; ++c) {  // UTF-16 code units of the BMP to UTF-8
            const unsigned u = p[c];
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
        } else if (cell->data_type == MAT_T_UINT8 || cell->data_type == MAT_T_UTF8 || cell->data_type == MAT_T_INT8) {
          text.assign(static_cast<const char*>(cell->data), static_cast<const char*>(cell->data) + len);
        } else {
          fail(fmt::format("'{}'{{{}}} is text of an encoding lpvid cannot read; save names as char", name, k + 1));
        }
      }
      if (text.empty()) fail(fmt::format("'{}'{{{}}} is empty; give every channel a name", name, k + 1));
      if (std::find(out.begin(), out.end(), text) != out.end())
        fail(fmt::format("name '{}' appears twice in '{}'; give every channel its own name", text, name));
      out.push_back(std::move(text));
    }
    return out;
  }

  const std::string& path_;
  const FrdReadOptions& options_;
  MatPtr mat_;
  std::vector<std::string> variables_;
};

// ---- writing ---------------------------------------------------------------

class MatWriter {
 public:
  MatWriter(const std::string& path, MatVersion version) : path_(path) {
    if (path == "-") throw InputError("cannot write a .mat file to stdout; give a file path");
    static std::atomic<unsigned> counter{0};
    const std::filesystem::path target(path);
    const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
    temp_ = (dir / fmt::format(".{}.tmp.{}.{}", target.filename().string(), ::getpid(), counter++)).string();
    silence_matio();
    errno = 0;
    mat_.reset(Mat_CreateVer(temp_.c_str(), nullptr, version == MatVersion::kV73 ? MAT_FT_MAT73 : MAT_FT_MAT5));
    if (mat_ == nullptr) fail(errno != 0 ? errno : EIO);
  }
  ~MatWriter() {
    if (!committed_) {
      mat_.reset();
      std::remove(temp_.c_str());
    }
  }
  MatWriter(const MatWriter&) = delete;
  MatWriter& operator=(const MatWriter&) = delete;

  void add(matvar_t* raw) {
    VarPtr var(raw);
    if (var == nullptr || Mat_VarWrite(mat_.get(), var.get(), MAT_COMPRESSION_NONE) != 0) fail(EIO);
  }

  void commit() {
    if (Mat_Close(mat_.release()) != 0) fail(EIO);
    std::error_code ec;
    if (std::filesystem::is_directory(path_, ec)) fail(EISDIR);
    if (std::rename(temp_.c_str(), path_.c_str()) != 0) fail(errno);
    committed_ = true;
  }

 private:
  [[noreturn]] void fail(int err) const {
    throw InputError(fmt::format("cannot write '{}': {}; check the directory exists and is writable", path_,
                                 std::strerror(err)));
  }

  std::string path_, temp_;
  MatPtr mat_;
  bool committed_ = false;
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
  if (!frd_detail::quantity_allowed(quantity))
    throw InputError(fmt::format("cannot write '{}': quantity '{}' is not allowed; a quantity is letters and digits "
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
  MatWriter out(path, version);
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
  out.commit();
}

}  // namespace lpvid
