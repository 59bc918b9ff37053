// lpvid — a relative amplitude spectrum for `lpvid excite --amplitude` (docs/formats.md,
// "Amplitude spectrum files"): a CSV table
//   # comment lines (optional)
//   f_hz,amplitude
//   1,10
//   20,1
// with the cell rules of the other numeric tables (formats/io/csv_detail.h); other
// columns are ignored.  At least 2 rows; f_hz > 0 (Hz) strictly increasing from row
// to row; amplitude > 0, any unit (only ratios matter).  How excite uses it:
// idlib/signal/excitation.h, ExcitationSpec::shape_*.
#pragma once

#include <string>
#include <vector>

namespace lpvid {

struct AmplitudeSpectrum {
  std::vector<double> f_hz;       // strictly increasing, > 0
  std::vector<double> amplitude;  // > 0, relative
};

// Reads the table.  Throws InputError at the cell at fault, "path:line:column: what;
// what to do", e.g. "amp.csv:4:1: frequency 5 Hz is not above the previous row's 8 Hz;
// ...", "amp.csv:3:4: amplitude -1 is not positive; ...", "amp.csv:2:1: no column
// 'f_hz' in the header; ...", "cannot open ...".
AmplitudeSpectrum read_amplitude_spectrum(const std::string& path);

}  // namespace lpvid
