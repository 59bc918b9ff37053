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
#include "formats/io/frd_detail.h"
#include "formats/io/mat_detail.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using mat_detail::Array;
using mat_detail::MatPtr;
using mat_detail::MatSource;
using mat_detail::VarPtr;
using mat_detail::dims_text;
using mat_detail::silence_matio;

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
    if (has("sample_rate_hz")) {
      const Array a = source_->load("sample_rate_hz", false);
      if (a.re.size() != 1 || !std::isfinite(a.re[0]) || !(a.re[0] > 0) || a.re[0] > frd_detail::kMaxSampleRateHz)
        fail(fmt::format("'sample_rate_hz' must be one number > 0 (the rate in Hz of the log the response was "
                         "estimated from, at most {:g}): give one number, or delete the variable if the rate is "
                         "not known; got {} value(s){}",
                         frd_detail::kMaxSampleRateHz, a.re.size(),
                         a.re.size() == 1 ? fmt::format(" = {}", a.re[0]) : std::string()));
      frd.sample_rate_hz = a.re[0];
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
    source_ = mat_detail::open_mat(path_);
    variables_ = source_->variables();
  }

  bool has(const std::string& name) const {
    return std::find(variables_.begin(), variables_.end(), name) != variables_.end();
  }
  std::string holds() const { return mat_detail::variables_text(variables_); }

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

using mat_detail::MatWriter;
using mat_detail::name_cells;
using mat_detail::real_array;

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
  MatWriter out(file, version == MatVersion::kV73);
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
  if (frd.sample_rate_hz > 0) {
    std::vector<double> rate{frd.sample_rate_hz};
    out.add(real_array("sample_rate_hz", {1, 1}, rate));
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
