// lpvid — plain numeric tables (singular values, fit histories, ...):
//   # comment lines
//   header,names
//   rows of numbers
// Same cell rules as logs (csv_log.h) but no "t" column and no sampling rule.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "formats/io/atomic_file.h"

namespace lpvid {

// Writes atomically (atomic_file.h); "-" is stdout.  header must have rows.cols()
// names (non-empty, unique, no comma/quote/line break, not starting with '#');
// every entry must be finite.  Throws InputError.
void write_table_csv(const std::string& path, const std::vector<std::string>& header, const Eigen::MatrixXd& rows,
                     const std::vector<std::string>& comments = {});
// The same into a staged file (AtomicOutputSet::stage); the caller commits.
void write_table_csv(AtomicFileWriter& out, const std::vector<std::string>& header, const Eigen::MatrixXd& rows,
                     const std::vector<std::string>& comments = {});

}  // namespace lpvid
