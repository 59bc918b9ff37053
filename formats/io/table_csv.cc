#include "formats/io/table_csv.h"

#include <fmt/format.h>

#include <algorithm>

#include "formats/io/csv_detail.h"
#include "idlib/core/error.h"

namespace lpvid {

void write_table_csv(AtomicFileWriter& out, const std::vector<std::string>& header, const Eigen::MatrixXd& rows,
                     const std::vector<std::string>& comments) {
  if (static_cast<Index>(header.size()) != rows.cols())
    throw InputError(fmt::format("cannot write '{}': {} column names for {} columns; give one name per column",
                                 detail::display_path(out.path()), header.size(), rows.cols()));
  detail::check_header_names(out.path(), header);
  std::string head;
  detail::append_comments(head, comments);
  head += fmt::format("{}\n", fmt::join(header, ","));
  const int64_t first_data_line = static_cast<int64_t>(std::count(head.begin(), head.end(), '\n')) + 1;
  detail::write_numeric_rows(out, std::move(head), rows, header, first_data_line);
}

void write_table_csv(const std::string& path, const std::vector<std::string>& header, const Eigen::MatrixXd& rows,
                     const std::vector<std::string>& comments) {
  AtomicFileWriter out(path);
  write_table_csv(out, header, rows, comments);
  out.commit();
}

}  // namespace lpvid
