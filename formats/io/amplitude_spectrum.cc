#include "formats/io/amplitude_spectrum.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "formats/io/csv_detail.h"
#include "idlib/core/error.h"

namespace lpvid {

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
      detail::fail_at(path, at.line, detail::cell_column(path, nullptr, at.line, a_col),
                      fmt::format("amplitude {} is not positive; give a positive (relative) amplitude at every "
                                  "frequency",
                                  a));
    s.f_hz.push_back(f);
    s.amplitude.push_back(a);
  }
  return s;
}

}  // namespace lpvid
