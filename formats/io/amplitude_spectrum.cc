#include "formats/io/amplitude_spectrum.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>

#include "formats/io/csv_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

// Byte column (1-based) of cell `column` on line `line` of the file (error path only:
// re-reads the file; the cell's first non-blank byte).
int64_t cell_column(const std::string& path, int64_t line, Index column) {
  if (path == "-") return 1;  // stdin cannot be read twice
  std::ifstream in(path, std::ios::binary);
  std::string text;
  for (int64_t k = 0; k < line; ++k)
    if (!std::getline(in, text)) return 1;
  if (line == 1 && text.rfind("\xEF\xBB\xBF", 0) == 0) text.erase(0, 3);
  size_t p = 0;
  for (Index c = 0; c < column; ++c) {
    p = text.find(',', p);
    if (p == std::string::npos) return 1;
    ++p;
  }
  while (p < text.size() && (text[p] == ' ' || text[p] == '\t')) ++p;
  return static_cast<int64_t>(p) + 1;
}

}  // namespace

AmplitudeSpectrum read_amplitude_spectrum(const std::string& path) {
  const std::string hint = "give the columns f_hz (Hz) and amplitude (relative), e.g. 'f_hz,amplitude'";
  const detail::NumericCsv csv = detail::read_numeric_csv(path, "f_hz", hint);
  const auto it = std::find(csv.names.begin(), csv.names.end(), "amplitude");
  if (it == csv.names.end())
    detail::fail_at(path, csv.header_line, 1, "no column 'amplitude' in the header; " + hint);
  const Index a_col = it - csv.names.begin();
  const Index rows = csv.data.rows();
  if (rows < 2)
    detail::fail_at(path, csv.end_line, 1,
                    fmt::format("{} row{} after the header; an amplitude spectrum needs at least 2 points "
                                "(f_hz, amplitude), one per row",
                                rows, rows == 1 ? "" : "s"));
  AmplitudeSpectrum s;
  for (Index k = 0; k < rows; ++k) {
    const double f = csv.data(k, csv.key), a = csv.data(k, a_col);
    const detail::CellPosition at = csv.key_position(k);
    if (!std::isfinite(f) || !(f > 0))
      detail::fail_at(path, at.line, at.column, fmt::format("frequency {} Hz is not positive; give f_hz > 0 in Hz", f));
    if (k > 0 && !(f > s.f_hz.back()))
      detail::fail_at(path, at.line, at.column,
                      fmt::format("frequency {} Hz is not above the previous row's {} Hz; f_hz must increase strictly "
                                  "from row to row",
                                  f, s.f_hz.back()));
    if (!std::isfinite(a) || !(a > 0))
      detail::fail_at(path, at.line, cell_column(path, at.line, a_col),
                      fmt::format("amplitude {} is not positive; give a positive (relative) amplitude at every "
                                  "frequency",
                                  a));
    s.f_hz.push_back(f);
    s.amplitude.push_back(a);
  }
  return s;
}

}  // namespace lpvid
