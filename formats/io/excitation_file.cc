#include "formats/io/excitation_file.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <matio.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>

#include "formats/io/csv_detail.h"
#include "formats/io/mat_detail.h"
#include "formats/io/mat_log.h"
#include "formats/io/matio_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using detail::MatPtr;
using detail::silence_matio;
using detail::VarPtr;

std::vector<std::string> expected_names(Index channels) {
  std::vector<std::string> names = {"t"};
  for (Index j = 1; j <= channels; ++j) names.push_back(fmt::format("v{}", j));
  return names;
}

size_t element_count(const matvar_t* var) {
  size_t n = 1;
  for (int d = 0; d < var->rank; ++d) n *= var->dims[d];
  return n;
}

// Text of a char variable or cell (matio gives UTF-8 or UTF-16 units).
bool char_text(const matvar_t* var, std::string& text) {
  if (var == nullptr || var->class_type != MAT_C_CHAR) return false;
  const size_t len = element_count(var);
  text.clear();
  if (len == 0) return true;
  if (var->data == nullptr) return false;
  if (var->data_type == MAT_T_UINT16 || var->data_type == MAT_T_UTF16) {
    const auto* p = static_cast<const uint16_t*>(var->data);
    for (size_t c = 0; c < len; ++c) {
      if (p[c] > 0x7F) return false;  // lpvid writes ASCII only
      text += static_cast<char>(p[c]);
    }
    return true;
  }
  if (var->data_type == MAT_T_UINT8 || var->data_type == MAT_T_UTF8 || var->data_type == MAT_T_INT8) {
    text.assign(static_cast<const char*>(var->data), static_cast<const char*>(var->data) + len);
    return true;
  }
  return false;
}

Log read_mat_log(const std::string& path, std::string& design_json) {
  silence_matio();
  const std::string shown = detail::display_path(path);
  errno = 0;
  if (FILE* probe = std::fopen(path.c_str(), "rb"); probe == nullptr)
    throw InputError(fmt::format("cannot open '{}': {}; check the path", shown, std::strerror(errno)));
  else
    std::fclose(probe);
  MatPtr mat(Mat_Open(path.c_str(), MAT_ACC_RDONLY));
  if (mat == nullptr)
    throw InputError(fmt::format("'{}' is not a MATLAB .mat file that lpvid can read; write it with lpvid excite "
                                 "--out FILE.mat",
                                 shown));
  auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("{}: {}; write the file with lpvid excite --out FILE.mat", shown, what));
  };
  VarPtr design(Mat_VarRead(mat.get(), kExcitationDesignVariable));
  if (design == nullptr) fail("no variable 'excitation_design'");
  if (!char_text(design.get(), design_json)) fail("'excitation_design' is not ASCII char text");
  VarPtr data(Mat_VarRead(mat.get(), "data"));
  if (data == nullptr) fail("no variable 'data'");
  if (data->class_type != MAT_C_DOUBLE || data->isComplex || data->rank != 2 || data->data == nullptr)
    fail("'data' is not a real N x (n+1) double matrix");
  Log log;
  log.path = path;
  const Index rows = static_cast<Index>(data->dims[0]), cols = static_cast<Index>(data->dims[1]);
  if (rows < 2 || cols < 2) fail(fmt::format("'data' is {} x {}; it needs at least 2 rows and the columns t, v1", rows, cols));
  log.data = Eigen::Map<const Eigen::MatrixXd>(static_cast<const double*>(data->data), rows, cols);
  if (!log.data.allFinite()) fail("'data' holds a NaN or Inf");
  VarPtr names(Mat_VarRead(mat.get(), "names"));
  if (names == nullptr) fail("no variable 'names'");
  if (names->class_type != MAT_C_CELL || element_count(names.get()) != static_cast<size_t>(cols))
    fail(fmt::format("'names' must be a cell array of {} names (one per column of data)", cols));
  for (Index k = 0; k < cols; ++k) {
    std::string text;
    if (!char_text(Mat_VarGetCell(names.get(), static_cast<int>(k)), text))
      fail(fmt::format("names{{{}}} is not char text", k + 1));
    log.names.push_back(text);
  }
  return log;
}

// t strictly increasing and uniform to 1e-3 relative (LogReadOptions' default), as read_log checks a CSV.
void check_time(const Log& log) {
  const Index t_col = log.column("t");
  const auto t = log.data.col(t_col);
  const Index n = t.size();
  const double ts = (t(n - 1) - t(0)) / static_cast<double>(n - 1);
  constexpr double kSamplingTolerance = 1e-3;  // LogReadOptions::sampling_tolerance's default
  for (Index k = 1; k < n; ++k)
    if (!(std::abs(t(k) - t(k - 1) - ts) <= kSamplingTolerance * ts))
      throw InputError(fmt::format("{}: t is not uniformly sampled at row {} ({} after {}); write the file with "
                                   "lpvid excite",
                                   detail::display_path(log.path), k + 1, t(k), t(k - 1)));
}

}  // namespace

bool is_mat_path(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".mat";
}

void write_excitation_mat(AtomicFileWriter& out, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
                          const ExcitationDesign& design) {
  const std::string& path = out.path();
  if (static_cast<Index>(names.size()) != data.cols() || names.empty() || names[0] != "t" || !data.allFinite())
    throw InputError(fmt::format("cannot write '{}': the columns must be t, v1..vn with finite values", path));
  if (out.temp_path().empty())
    throw InputError(fmt::format("cannot write '{}': a .mat file cannot be streamed to standard output, a pipe or a "
                                 "device; give a file path",
                                 detail::display_path(path)));
  out.release_descriptor();
  silence_matio();
  errno = 0;
  MatPtr mat(Mat_CreateVer(out.temp_path().c_str(), nullptr, MAT_FT_MAT5));
  auto fail = [&](int err) {
    throw InputError(fmt::format("cannot write '{}': {}; check the directory exists and is writable", path,
                                 std::strerror(err != 0 ? err : EIO)));
  };
  if (mat == nullptr) fail(errno);
  auto add = [&](matvar_t* raw) {
    VarPtr var(raw);
    if (var == nullptr || Mat_VarWrite(mat.get(), var.get(), MAT_COMPRESSION_NONE) != 0) fail(EIO);
  };
  size_t dims[2] = {static_cast<size_t>(data.rows()), static_cast<size_t>(data.cols())};
  // matio only reads the buffer (MAT_F_DONT_COPY_DATA: no 2nd copy of a large signal).
  add(Mat_VarCreate("data", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, const_cast<double*>(data.data()),
                    MAT_F_DONT_COPY_DATA));
  {
    std::vector<matvar_t*> cells;
    for (const std::string& text : names) {
      size_t cdims[2] = {1, text.size()};
      cells.push_back(Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UTF8, 2, cdims, const_cast<char*>(text.data()), 0));
    }
    size_t ndims[2] = {1, names.size()};
    add(Mat_VarCreate("names", MAT_C_CELL, MAT_T_CELL, 2, ndims, cells.data(), 0));
  }
  const std::string json = excitation_design_json(design);
  size_t jdims[2] = {1, json.size()};
  add(Mat_VarCreate(kExcitationDesignVariable, MAT_C_CHAR, MAT_T_UTF8, 2, jdims, const_cast<char*>(json.data()), 0));
  if (Mat_Close(mat.release()) != 0) fail(EIO);
}

ExcitationFile read_excitation_file(const std::string& path) {
  ExcitationFile file;
  const std::string shown = detail::display_path(path);
  if (is_mat_path(path)) {
    std::string json;
    file.log = read_mat_log(path, json);
    file.design = parse_excitation_design(json, path + ":" + kExcitationDesignVariable);
    check_time(file.log);
    const Index n = file.log.num_samples();
    const auto t = file.log.data.col(0);
    file.log.sample_period_s = (t(n - 1) - t(0)) / static_cast<double>(n - 1);
  } else {
    file.log = read_log(path);
    std::optional<ExcitationDesign> design = read_excitation_design(path);
    if (!design)
      throw InputError(fmt::format("{}: no '# {}' line before the header; write the signal with lpvid excite", shown,
                                   kExcitationDesignTag));
    file.design = *design;
  }
  if (file.log.names.empty() || file.log.names[0] != "t")
    throw InputError(fmt::format("{}: the first column must be t; write the signal with lpvid excite", shown));
  const std::vector<std::string> want = expected_names(file.design.channels);
  if (file.log.names != want)
    throw InputError(fmt::format("{}: the columns are {} but the excitation design has {} channels (t, v1..v{}); "
                                 "write the signal with lpvid excite",
                                 shown, fmt::join(file.log.names, ","), file.design.channels, file.design.channels));
  check_design_matches(file.design, file.log.num_samples(), file.log.sample_period_s, file.design.channels, shown);
  return file;
}

std::optional<ExcitationDesign> read_log_excitation_design(const std::string& log_path) {
  if (log_path == "-" || !is_mat_log(log_path)) return read_excitation_design(log_path);
  const std::unique_ptr<mat_detail::MatSource> mat = mat_detail::open_mat(log_path);
  const std::vector<std::string>& variables = mat->variables();
  const std::string name = kExcitationDesignVariable;
  if (std::find(variables.begin(), variables.end(), name) == variables.end()) return std::nullopt;
  const mat_detail::Value v = mat->value(name);
  const std::string where = detail::display_path(log_path) + ":" + name;
  // One row of text (a char matrix is stored column by column: its text would be scrambled).
  const bool row = v.dims.size() == 2 && (v.dims[0] == 1 || v.dims[1] == 0);
  if (v.kind != mat_detail::Value::Kind::kChar || !row)
    throw InputError(fmt::format("{}: is a {} {}, not one row of text; save the excitation design's JSON as a char "
                                 "row vector (as lpvid excite --out FILE.mat writes it), or remove the variable",
                                 where, mat_detail::dims_text(v.dims), v.kind_text()));
  return parse_excitation_design(v.text, where);
}

}  // namespace lpvid
