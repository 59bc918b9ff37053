#include "formats/io/csv_log.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "formats/io/csv_detail.h"
#include "formats/io/mat_log.h"
#include "idlib/core/error.h"

namespace lpvid {

void LogReadOptions::validate() const {
  if (!std::isfinite(sampling_tolerance) || sampling_tolerance < 0)
    throw InputError(fmt::format(
        "sampling tolerance {} is not allowed; give a finite relative tolerance >= 0, e.g. 1e-3", sampling_tolerance));
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz < 0)
    throw InputError(fmt::format("--log-rate {}: give the sample rate in Hz as a positive number", sample_rate_hz));
  for (std::size_t i = 0; i < channel_names.size(); ++i) {
    if (channel_names[i].empty() || channel_names[i] == "t")
      throw InputError(fmt::format("--log-columns: name {} is '{}'; give each channel a non-empty name other than 't' "
                                   "(the time comes from --log-rate)",
                                   i + 1, channel_names[i]));
    for (std::size_t k = 0; k < i; ++k)
      if (channel_names[k] == channel_names[i])
        throw InputError(fmt::format("--log-columns: '{}' is given twice (names {} and {}); give every channel its own "
                                     "name",
                                     channel_names[i], k + 1, i + 1));
  }
}

Index Log::column(const std::string& name) const {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end())
    throw InputError(fmt::format("{}: no column '{}'; columns are: {}; check --excitation/--output names",
                                 detail::display_path(path), name, fmt::join(names, ", ")));
  return it - names.begin();
}

Eigen::MatrixXd Log::columns(const std::vector<std::string>& wanted) const {
  Eigen::MatrixXd out(data.rows(), static_cast<Index>(wanted.size()));
  for (size_t k = 0; k < wanted.size(); ++k) out.col(static_cast<Index>(k)) = data.col(column(wanted[k]));
  return out;
}

Log read_log(const std::string& path, const LogReadOptions& options) {
  options.validate();
  if (is_mat_log(path)) return read_log_mat(path, options);
  if (options.sample_rate_hz > 0 || !options.channel_names.empty())
    throw InputError(fmt::format("{}: a CSV log names its channels and its time t in its header; --log-columns and "
                                 "--log-rate are for a .mat file without them (drop them)",
                                 detail::display_path(path)));
  detail::NumericCsv csv =
      detail::read_numeric_csv(path, "t", "add a time column 't' in seconds (see docs/formats.md)");
  const Index n = csv.data.rows();
  if (n < 2)
    detail::fail_at(path, csv.end_line, 1,
                    fmt::format("the log has {} sample{}; a log needs at least 2 rows of samples after the header: record a longer log", n,
                                n == 1 ? "" : "s"));
  const auto t = csv.data.col(csv.key);
  for (Index k = 1; k < n; ++k) {
    if (!(t[k] > t[k - 1])) {
      const detail::CellPosition at = csv.key_position(k);
      detail::fail_at(path, at.line, at.column,
                      fmt::format("time t = {} s is not after the previous row's t = {} s; t must increase strictly "
                                  "from row to row (one file = one experiment)",
                                  t[k], t[k - 1]));
    }
  }
  const double ts = (t[n - 1] - t[0]) / static_cast<double>(n - 1);
  for (Index k = 1; k < n; ++k) {
    const double dt = t[k] - t[k - 1];
    const double deviation = std::abs(dt - ts) / ts;
    if (deviation > options.sampling_tolerance) {
      const detail::CellPosition at = csv.key_position(k);
      detail::fail_at(path, at.line, at.column,
                      fmt::format("time step {} s (from t = {} s) differs from the mean sample period {} s by a "
                                  "relative {:.3g}, above the sampling tolerance {}; resample the log to a uniform grid "
                                  "(or split it at the gap), or raise the sampling tolerance",
                                  dt, t[k - 1], ts, deviation, options.sampling_tolerance));
    }
  }
  Log log;
  log.path = path;
  log.names = std::move(csv.names);
  log.data = std::move(csv.data);
  log.sample_period_s = ts;
  return log;
}

void write_log(AtomicFileWriter& out, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
               const std::vector<std::string>& comments) {
  const std::string& path = out.path();
  detail::check_log_columns(path, names, data.cols());
  std::string head;
  detail::append_comments(head, comments);
  head += fmt::format("{}\n", fmt::join(names, ","));
  const int64_t first_data_line = static_cast<int64_t>(std::count(head.begin(), head.end(), '\n')) + 1;
  detail::write_numeric_rows(out, std::move(head), data, names, first_data_line);
}

void write_log(const std::string& path, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
               const std::vector<std::string>& comments) {
  AtomicFileWriter out(path);
  write_log(out, names, data, comments);
  out.commit();
}

}  // namespace lpvid
