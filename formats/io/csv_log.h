// lpvid — time-domain logs: one CSV file = one experiment (docs/formats.md).
//
//   # rig 2, 2026-11-20, x_b = 0.10 m
//   t,v1,q1
//   0,0.12,1e-06
//   0.001,-0.3,1.2e-06
//
// Rules: one header row of column names (trimmed; unique; a name may be wrapped
// in double quotes), a column "t" in seconds, every other column a channel in SI
// units; comma separated, blanks around cells allowed, "\n" or "\r\n" line ends;
// lines whose first non-blank character is '#' and blank lines are skipped
// anywhere; every other cell is a finite number (NaN/Inf rejected); at least 2
// rows; t strictly increasing and uniformly sampled within
// LogReadOptions::sampling_tolerance.  Data layout: idlib/core/types.h (N x
// channels, time along rows).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "formats/io/atomic_file.h"
#include "idlib/core/types.h"

namespace lpvid {

struct LogReadOptions {
  // Largest relative deviation max_k |dt_k - Ts| / Ts of a time step dt_k from
  // the mean sample period Ts = (t_last - t_first) / (N - 1).  t written by
  // lpvid deviates by ~1e-12; t rounded to d decimals deviates by up to
  // 10^-d / Ts (6 decimals at 1 kHz: 1e-3, at the limit); a dropped sample
  // deviates by 1.  Must be finite and >= 0.
  double sampling_tolerance = 1e-3;

  // For a .mat file that names neither its time nor its channels (a DaISy file: one
  // unnamed N × k matrix): the sample rate in Hz (t = 0, 1/rate, ...) and the k channel
  // names in the matrix's order (the CLI's --log-rate and --log-columns).  0 and empty:
  // not given.  Refused for a file that has its own (a CSV header, a .mat t or rate,
  // a .mat layout with names): never two sources for one thing.
  double sample_rate_hz = 0;
  std::vector<std::string> channel_names;

  // Throws InputError if a field is out of range.
  void validate() const;
};

struct Log {
  std::string path;                // as given ("-" for stdin)
  std::vector<std::string> names;  // header order, including "t"
  Eigen::MatrixXd data;            // N x names.size(), time along rows
  double sample_period_s = 0;      // (t_last - t_first) / (N - 1)

  Index num_samples() const { return data.rows(); }
  // Index of the column named name.  Throws InputError
  // "path: no column 'x'; columns are: t, v1, ...; check --excitation/--output names".
  Index column(const std::string& name) const;
  // N x names.size() copy of the named columns, in the order given.  Throws as column().
  Eigen::MatrixXd columns(const std::vector<std::string>& names) const;
};

// Reads a log; "-" reads stdin.  A path ending in ".mat" (any case) or a file
// starting with a MAT-file header is read by read_log_mat (mat_log.h: MATLAB v5
// and v7.3 logs, the same rules).  Otherwise CSV:  Reads in 4 MiB chunks; a regular file of 8 MiB
// or more is counted and parsed on parallel threads (csv_detail.h; stdin on one
// thread, slower).  Throws InputError "path:line:column: what; what to do" for every
// broken rule above, and "cannot open 'x.csv': <strerror>; check the path".
Log read_log(const std::string& path, const LogReadOptions& options = {});

// Writes a log atomically (atomic_file.h); "-" writes stdout.  comments become
// "# ..." lines before the header.  Numbers are written in the shortest form that
// reads back to the identical double.  names must have data.cols() entries and
// hold "t"; every entry must be finite.  Throws InputError.
void write_log(const std::string& path, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
               const std::vector<std::string>& comments = {});
// The same into a staged file (AtomicOutputSet::stage); the caller commits.
void write_log(AtomicFileWriter& out, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
               const std::vector<std::string>& comments = {});

}  // namespace lpvid
