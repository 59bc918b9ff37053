#include "formats/io/mat_log.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <deque>

#include "formats/io/csv_detail.h"
#include "formats/io/mat_detail.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using mat_detail::Value;

// One channel of the log: a run of N doubles inside a variable the reader holds.
struct Column {
  std::string name;
  std::string where;  // the variable (path inside the file) for messages: "data", "u1", "run.u1"
  std::string label;  // "column 3 ('u1') " inside a matrix, else ""
  const Value* source = nullptr;
  size_t offset = 0;  // first of the N values in source->re
  size_t stride = 1;  // between successive samples in source->re (a channels × N matrix: its row count)
};

// The names a lab file may give its sample rate in, as a scalar: Hz, or seconds.
constexpr const char* kRateNamesHz[] = {"Fs", "fs"};
constexpr const char* kPeriodNamesS[] = {"Ts", "ts", "dt"};

class MatLogReader {
 public:
  MatLogReader(const std::string& path, const LogReadOptions& options) : path_(path), options_(options) {}

  Log read() {
    options_.validate();
    source_ = mat_detail::open_mat(path_);
    variables_ = source_->variables();
    const bool given = options_.sample_rate_hz > 0 || !options_.channel_names.empty();
    auto not_given = [&](const char* layout) {
      if (given)
        fail_file(fmt::format("the file gives its own time and channel names ({}); --log-columns and --log-rate are "
                              "for a file without them (drop them)",
                              layout));
    };
    if (has("data") && has("names")) {
      not_given("data and names");
      matrix_layout();
    } else if (has("t")) {
      not_given("a variable t");
      per_signal_layout();
    } else if (simulink_layout()) {
      not_given("Simulink 'Structure With Time'");
    } else if (struct_layout()) {
      not_given("a struct with a field t");
    } else if (!lab_layout()) {
      fail_file(fmt::format("no log in the file; save t and the signals as N-vectors, or data (N × channels) and "
                            "names, or a struct of signals, or Simulink 'Structure With Time', or the signals with "
                            "their sample rate as a scalar Fs (Hz) or Ts (s) (docs/formats.md, \"Logs in .mat "
                            "files\"); the file holds: {}",
                            holds()));
    }
    return assemble();
  }

 private:
  // The location names variables and fields as the file spells them: their bytes
  // (a line break, a NUL) are escaped with the rest so the message stays one line.
  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw InputError(detail::one_line_message(fmt::format("{}:{}: {}", path_, where, what)));
  }
  [[noreturn]] void fail_file(const std::string& what) const {
    throw InputError(detail::one_line_message(fmt::format("{}: {}", path_, what)));
  }

  bool has(const std::string& name) const {
    return std::find(variables_.begin(), variables_.end(), name) != variables_.end();
  }
  std::string holds() const { return mat_detail::variables_text(variables_); }
  const Value& keep(Value v) {
    held_.push_back(std::move(v));
    return held_.back();
  }
  // The variable `name`, read once.
  const Value& get(const std::string& name) {
    for (const auto& [n, v] : cache_)
      if (n == name) return *v;
    cache_.emplace_back(name, &keep(source_->value(name)));
    return *cache_.back().second;
  }
  static bool is_vector(const Value& v) {
    return std::count_if(v.dims.begin(), v.dims.end(), [](size_t d) { return d != 1; }) <= 1;
  }
  void need_real_numeric(const Value& v, const std::string& where, const char* what) const {
    if (v.kind != Value::Kind::kNumeric)
      fail(where, fmt::format("is a {}, not numbers; save {} as a real numeric array", v.kind_text(), what));
    if (v.complex) fail(where, fmt::format("is complex; save {} as a real array", what));
  }

  // (d): data (N x m) and names (m char names).
  void matrix_layout() {
    const Value& data = get("data");
    const Value& names = get("names");
    need_real_numeric(data, "data", "the log");
    if (data.dims.size() != 2)
      fail("data", fmt::format("is {}; give an N × channels matrix (time along rows)", mat_detail::dims_text(data.dims)));
    const size_t n = data.dims[0], m = data.dims[1];
    if (names.kind != Value::Kind::kCell || names.count() != m || !is_vector(names))
      fail("names", fmt::format("must be a cell array of {} names, one per column of data ({}), e.g. names = "
                                "{{'t','v1','q1'}}; it is a {} {}",
                                m, mat_detail::dims_text(data.dims), mat_detail::dims_text(names.dims), names.kind_text()));
    for (size_t j = 0; j < m; ++j) {
      const Value& cell = names.cells[j];
      const std::string where = fmt::format("names{{{}}}", j + 1);
      if (cell.kind != Value::Kind::kChar)
        fail("names", fmt::format("cell {} is a {}, not text; save every name as char", j + 1, cell.kind_text()));
      columns_.push_back({cell.text, "data",
                          fmt::format("column {} ({}) ", j + 1, detail::quote_cell(cell.text)), &data, j * n});
      name_where_.push_back(where);
    }
    rows_ = n;
    time_where_ = "data";
  }

  // Adds the signals of a set of named members (top-level variables or struct fields).
  void add_signals(const std::vector<std::pair<std::string, const Value*>>& members, const std::string& prefix) {
    const Value* t = nullptr;
    for (const auto& [name, v] : members)
      if (name == "t") t = v;
    LPVID_ASSERT(t != nullptr);
    const std::string twhere = prefix + "t";
    need_real_numeric(*t, twhere, "t");
    if (!is_vector(*t)) fail(twhere, fmt::format("is {}; give t as a vector of N times in s", mat_detail::dims_text(t->dims)));
    rows_ = t->count();
    time_where_ = twhere;
    for (const auto& [name, v] : members) {
      const std::string where = prefix + name;
      if (v->kind != Value::Kind::kNumeric || (name != "t" && v->count() <= 1)) continue;  // not a signal
      need_real_numeric(*v, where, "a signal");
      if (!is_vector(*v))
        fail(where, fmt::format("is {}; save each signal as its own vector of N samples, or the log as data and names",
                                mat_detail::dims_text(v->dims)));
      if (v->count() != rows_)
        fail(where, fmt::format("has {} samples but {} has {}; every signal needs one sample per time", v->count(), twhere,
                                rows_));
      columns_.push_back({name, where, "", v, 0});
      name_where_.push_back(where);
    }
  }

  // (a): t and one variable per signal.
  void per_signal_layout() {
    std::vector<std::pair<std::string, const Value*>> members;
    for (const std::string& name : variables_) members.emplace_back(name, &get(name));
    add_signals(members, "");
  }

  // (b): one struct with a field t.
  bool struct_layout() {
    std::vector<std::string> found;
    const Value* chosen = nullptr;
    for (const std::string& name : variables_) {
      const Value& v = get(name);
      if (v.kind == Value::Kind::kStruct && v.field("t") != nullptr) {
        found.push_back(name);
        chosen = &v;
      }
    }
    if (found.empty()) return false;
    if (found.size() > 1)
      fail_file(fmt::format("several structs hold a field t ({}); save one experiment per file", fmt::join(found, ", ")));
    if (chosen->count() != 1)
      fail(found[0], fmt::format("is a {} struct array; give one struct (1×1) whose fields are the signals",
                                 mat_detail::dims_text(chosen->dims)));
    std::vector<std::pair<std::string, const Value*>> members;
    for (size_t f = 0; f < chosen->fields.size(); ++f) members.emplace_back(chosen->fields[f], &chosen->members[f]);
    add_signals(members, found[0] + ".");
    return true;
  }

  // (c): Simulink "Structure With Time" variables.
  bool simulink_layout() {
    const Value* time = nullptr;
    for (const std::string& name : variables_) {
      const Value& v = get(name);
      if (v.kind != Value::Kind::kStruct || v.field("time") == nullptr || v.field("signals") == nullptr) continue;
      if (v.count() != 1) fail(name, fmt::format("is a {} struct array; give one structure per variable", mat_detail::dims_text(v.dims)));
      const Value& t = *v.field("time");
      const std::string twhere = name + ".time";
      if (t.kind == Value::Kind::kNumeric && t.count() == 0)
        fail(twhere, "is empty (Simulink 'Structure' format, without time); log with 'Structure With Time'");
      need_real_numeric(t, twhere, "time");
      if (!is_vector(t)) fail(twhere, fmt::format("is {}; give time as a vector of N times in s", mat_detail::dims_text(t.dims)));
      if (time == nullptr) {
        time = &t;
        rows_ = t.count();
        time_where_ = twhere;
        columns_.push_back({"t", twhere, "", &t, 0});
        name_where_.push_back(twhere);
      } else {
        if (t.count() != rows_)
          fail(twhere, fmt::format("has {} samples but {} has {}; save signals logged at one rate in one file", t.count(),
                                   time_where_, rows_));
        for (size_t r = 0; r < rows_; ++r)
          if (!(t.re[r] == time->re[r]) && !(std::isnan(t.re[r]) && std::isnan(time->re[r])))
            fail(twhere, fmt::format("differs from {} at row {} ({} vs {} s); save signals logged on one time grid in "
                                     "one file",
                                     time_where_, r + 1, t.re[r], time->re[r]));
      }
      const Value& signals = *v.field("signals");
      const std::string swhere = name + ".signals";
      if (signals.kind != Value::Kind::kStruct || signals.field("values") == nullptr)
        fail(swhere, "is not a struct with a field values; save with Simulink's 'Structure With Time' format");
      const size_t k = signals.count();
      for (size_t i = 0; i < k; ++i) {
        const std::string vwhere = k == 1 ? swhere + ".values" : fmt::format("{}({}).values", swhere, i + 1);
        const Value& values = *signals.field("values", i);
        need_real_numeric(values, vwhere, "the signal");
        if (values.dims.size() != 2 || values.dims[0] != rows_)
          fail(vwhere, fmt::format("is {} but {} has {} samples; give N × width values (time along rows)",
                                   mat_detail::dims_text(values.dims), time_where_, rows_));
        std::string base;
        const Value* label = signals.field("label", i);
        if (label != nullptr && label->kind == Value::Kind::kChar && !label->text.empty()) base = label->text;
        else base = k == 1 ? name : fmt::format("{}_{}", name, i + 1);
        const size_t w = values.dims[1];
        for (size_t j = 0; j < w; ++j) {
          const std::string channel = w == 1 ? base : fmt::format("{}{}", base, j + 1);
          columns_.push_back({channel, vwhere, w == 1 ? "" : fmt::format("column {} ({}) ", j + 1, detail::quote_cell(channel)),
                              &values, j * rows_});
          name_where_.push_back(label != nullptr && !label->text.empty()
                                    ? (k == 1 ? swhere + ".label" : fmt::format("{}({}).label", swhere, i + 1))
                                    : vwhere);
        }
      }
    }
    return time != nullptr;
  }

  // (e): a lab's file without a time vector: a scalar sample rate Fs/fs (Hz) or sample
  // period Ts/ts/dt (s), and the signals as row or column vectors of N samples or as
  // channels × N or N × channels matrices (a matrix X of k channels gives X1..Xk); other
  // scalars are metadata.  N is the longest dimension of the signals; t = 0, Ts, ...
  bool lab_layout() {
    std::string rate_name;
    bool in_hz = false;
    for (const std::string& name : variables_) {
      const bool hz = std::find(std::begin(kRateNamesHz), std::end(kRateNamesHz), name) != std::end(kRateNamesHz);
      const bool s = std::find(std::begin(kPeriodNamesS), std::end(kPeriodNamesS), name) != std::end(kPeriodNamesS);
      if (!hz && !s) continue;
      const Value& v = get(name);
      if (v.kind != Value::Kind::kNumeric || v.count() != 1) continue;
      if (!rate_name.empty())
        fail(name, fmt::format("gives the sample rate and so does {}; keep one of them", rate_name));
      rate_name = name;
      in_hz = hz;
    }
    double ts = 0;
    if (!rate_name.empty() && options_.sample_rate_hz > 0)
      fail(rate_name, fmt::format("gives the sample rate and so does --log-rate {:g}; drop --log-rate",
                                  options_.sample_rate_hz));
    if (rate_name.empty()) {
      if (!(options_.sample_rate_hz > 0)) {
        if (!options_.channel_names.empty())
          fail_file(fmt::format("--log-columns names the channels but the file has no time t and no rate (Fs, Ts); "
                                "give --log-rate HZ too; the file holds: {}",
                                holds()));
        return false;
      }
      rate_name = "--log-rate";
      ts = 1.0 / options_.sample_rate_hz;
    } else {
      const Value& rate = get(rate_name);
      need_real_numeric(rate, rate_name, in_hz ? "the sample rate in Hz" : "the sample period in s");
      const double r = rate.re[0];
      if (!(std::isfinite(r) && r > 0))
        fail(rate_name, fmt::format("is {}; give the {} as a positive number", r,
                                    in_hz ? "sample rate in Hz" : "sample period in s"));
      ts = in_hz ? 1.0 / r : r;
    }
    // The signals and N.
    std::vector<std::string> signals;
    size_t n = 0;
    for (const std::string& name : variables_) {
      if (name == rate_name) continue;
      const Value& v = get(name);
      if (v.kind != Value::Kind::kNumeric || v.count() <= 1) continue;  // metadata
      need_real_numeric(v, name, "a signal");
      if (v.dims.size() != 2)
        fail(name, fmt::format("is {}; give a signal as a vector of N samples or channels as a 2-D matrix",
                               mat_detail::dims_text(v.dims)));
      signals.push_back(name);
      n = std::max({n, v.dims[0], v.dims[1]});
    }
    if (signals.empty())
      fail(rate_name, fmt::format("gives a sample rate but the file holds no signal (a numeric vector or matrix); "
                                  "the file holds: {}",
                                  holds()));
    Value t;
    t.kind = Value::Kind::kNumeric;
    t.dims = {n, 1};
    t.re.resize(n);
    for (size_t k = 0; k < n; ++k) t.re[k] = static_cast<double>(k) * ts;
    const Value& time = keep(std::move(t));
    rows_ = n;
    time_where_ = rate_name;
    columns_.push_back({"t", rate_name, "", &time, 0});
    name_where_.push_back(rate_name);
    for (const std::string& name : signals) {
      const Value& v = get(name);
      const size_t rows = v.dims[0], cols = v.dims[1];
      if (is_vector(v)) {
        if (v.count() != n)
          fail(name, fmt::format("has {} samples but the longest signal has {}; every signal needs one sample per "
                                 "time",
                                 v.count(), n));
        columns_.push_back({name, name, "", &v, 0});
        name_where_.push_back(name);
        continue;
      }
      if (rows == n && cols == n)
        fail(name, fmt::format("is {} × {}: time could run along either dimension; save it as N × channels with a "
                               "longer record, or as separate vectors",
                               rows, cols));
      if (rows != n && cols != n)
        fail(name, fmt::format("is {}, but the longest signal has {} samples; give channels × N or N × channels",
                               mat_detail::dims_text(v.dims), n));
      const bool by_rows = cols == n;  // channels × N: each row a channel
      const size_t k = by_rows ? rows : cols;
      for (size_t c = 0; c < k; ++c) {
        const std::string channel = fmt::format("{}{}", name, c + 1);
        const std::string label = fmt::format("{} {} ({}) ", by_rows ? "row" : "column", c + 1, detail::quote_cell(channel));
        columns_.push_back({channel, name, label, &v, by_rows ? c : c * n, by_rows ? rows : 1});
        name_where_.push_back(name);
      }
    }
    if (!options_.channel_names.empty()) {  // the command line names the channels, in the file's order
      const std::vector<std::string>& names = options_.channel_names;
      std::vector<std::string> found;
      for (std::size_t j = 1; j < columns_.size(); ++j) found.push_back(columns_[j].name);
      if (names.size() != found.size())
        fail_file(fmt::format("--log-columns gives {} name(s) but the file holds {} channel(s) ({}); give one name "
                              "per channel, in the file's order",
                              names.size(), found.size(),
                              found.size() <= 6 ? fmt::format("{}", fmt::join(found, ", "))
                                                : fmt::format("{}, {}, ..., {}", found[0], found[1], found.back())));
      for (std::size_t j = 1; j < columns_.size(); ++j) {
        Column& c = columns_[j];
        c.name = names[j - 1];
        if (!c.label.empty())
          c.label = fmt::format("{} {} ({}) ", c.stride == 1 ? "column" : "row",
                                c.stride == 1 ? c.offset / n + 1 : c.offset + 1, detail::quote_cell(c.name));
      }
    }
    return true;
  }

  Log assemble() {
    source_.reset();  // the values are copied out: free the file's bytes before the matrix is allocated
    // Names: non-empty, valid UTF-8 without control bytes, unique, one "t".
    for (size_t j = 0; j < columns_.size(); ++j) {
      const std::string& name = columns_[j].name;
      const std::string& where = name_where_[j];
      if (name.empty()) fail(where, "a channel name is empty; give every channel a name");
      if (!valid_utf8(name) || std::any_of(name.begin(), name.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; }))
        fail(where, fmt::format("channel name {} is not printable UTF-8 text; give plain names", detail::quote_cell(name)));
      for (size_t i = 0; i < j; ++i)
        if (columns_[i].name == name)
          fail(where, fmt::format("channel name {} appears twice (also at {}); give every channel its own name",
                                  detail::quote_cell(name), name_where_[i]));
    }
    const auto t_it = std::find_if(columns_.begin(), columns_.end(), [](const Column& c) { return c.name == "t"; });
    if (t_it == columns_.end())
      fail(time_where_, "no channel named 't'; add a time channel 't' in seconds (docs/formats.md)");
    const size_t n = rows_;
    const Index key = t_it - columns_.begin();
    if (n < 2)
      fail(time_where_, fmt::format("the log has {} sample{}; a log needs at least 2 samples: record a longer log", n,
                                    n == 1 ? "" : "s"));
    Log log;
    log.path = path_;
    log.data.resize(static_cast<Index>(n), static_cast<Index>(columns_.size()));
    for (size_t j = 0; j < columns_.size(); ++j) {
      const Column& c = columns_[j];
      const double* src = c.source->re.data() + c.offset;
      double* dst = log.data.col(static_cast<Index>(j)).data();
      for (size_t r = 0; r < n; ++r) {
        const double x = src[r * c.stride];
        if (!std::isfinite(x))
          fail(c.where, fmt::format("{}holds {} at {} {}; a log holds finite numbers only: remove or interpolate the "
                                    "bad samples",
                                    c.label, std::isnan(x) ? "a NaN" : (x > 0 ? "Inf" : "-Inf"),
                                    c.stride == 1 ? "row" : "sample", r + 1));
        dst[r] = x;
      }
      log.names.push_back(c.name);
    }
    // The time rules of read_log (csv_log.cc), row numbers 1-based.
    const auto t = log.data.col(key);
    const Column& tc = columns_[static_cast<size_t>(key)];
    for (Index k = 1; k < static_cast<Index>(n); ++k)
      if (!(t[k] > t[k - 1]))
        fail(tc.where, fmt::format("{}time t = {} s at row {} is not after the previous row's t = {} s; t must increase "
                                   "strictly from row to row (one file = one experiment)",
                                   tc.label, t[k], k + 1, t[k - 1]));
    const Index last = static_cast<Index>(n) - 1;
    const double ts = (t[last] - t[0]) / static_cast<double>(last);
    for (Index k = 1; k < static_cast<Index>(n); ++k) {
      const double dt = t[k] - t[k - 1];
      const double deviation = std::abs(dt - ts) / ts;
      if (deviation > options_.sampling_tolerance)
        fail(tc.where, fmt::format("{}time step {} s (from t = {} s, row {}) differs from the mean sample period {} s "
                                   "by a relative {:.3g}, above the sampling tolerance {}; resample the log to a "
                                   "uniform grid (or split it at the gap), or raise the sampling tolerance",
                                   tc.label, dt, t[k - 1], k, ts, deviation, options_.sampling_tolerance));
    }
    log.sample_period_s = ts;
    return log;
  }

  const std::string& path_;
  const LogReadOptions& options_;
  std::unique_ptr<mat_detail::MatSource> source_;
  std::vector<std::string> variables_;
  std::deque<Value> held_;  // stable addresses for columns_
  std::vector<std::pair<std::string, const Value*>> cache_;
  std::vector<Column> columns_;
  std::vector<std::string> name_where_;  // where each channel's name comes from
  size_t rows_ = 0;
  std::string time_where_;
};

}  // namespace

Log read_log_mat(const std::string& path, const LogReadOptions& options) {
  return MatLogReader(path, options).read();
}

bool is_mat_log(const std::string& path) {
  if (path.size() >= 4) {
    std::string ext = path.substr(path.size() - 4);
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext == ".mat") return true;
  }
  if (path == "-") return false;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  std::string head(128, '\0');
  const ssize_t got = ::pread(fd, head.data(), head.size(), 0);
  ::close(fd);
  return got == 128 && mat_detail::has_mat_header(head);
}

void write_log_mat(const std::string& path, const std::vector<std::string>& names, const Eigen::MatrixXd& data, bool v73,
                   const std::vector<std::pair<std::string, std::string>>& extra_text) {
  detail::check_log_columns(path, names, data.cols());
  if (!data.allFinite())
    throw InputError(fmt::format("cannot write '{}': the data holds NaN or Inf; a log holds finite numbers only",
                                 detail::display_path(path)));
  AtomicFileWriter file(path);
  mat_detail::MatWriter out(file, v73);
  std::vector<double> values(data.data(), data.data() + data.size());  // column-major, as MATLAB
  out.add(mat_detail::real_array("data", {static_cast<size_t>(data.rows()), static_cast<size_t>(data.cols())}, values));
  out.add(mat_detail::name_cells("names", names));
  for (const auto& [name, text] : extra_text) {
    size_t dims[2] = {1, text.size()};
    out.add(Mat_VarCreate(name.c_str(), MAT_C_CHAR, MAT_T_UTF8, 2, dims, const_cast<char*>(text.data()), 0));
  }
  out.finish();
  file.commit();
}

}  // namespace lpvid
