// lpvid — excitation signal files as `lpvid excite` writes them and the
// simulators read them (docs/formats.md, "Excitation files").
//
// CSV: a log (formats/io/csv_log.h) with columns t, v1..vn and ONE comment line
//   "# lpvid-excitation: {JSON}" before the header (formats/io/excitation_design.h).
// .mat (MATLAB v5, written with libmatio, uncompressed):
//   data               N x (n+1) double, column 1 = t in s, then v1..vn
//   names              1 x (n+1) cell array of char: 't', 'v1', ..., 'vn'
//   excitation_design  1 x len char: the same JSON as the CSV's design line
#pragma once

#include <optional>
#include <string>

#include "formats/io/atomic_file.h"
#include "formats/io/csv_log.h"
#include "formats/io/excitation_design.h"

namespace lpvid {

struct ExcitationFile {
  Log log;                    // names t, v1..vn; data N x (n+1)
  ExcitationDesign design;
};

// True when the path ends in ".mat" (any case).
bool is_mat_path(const std::string& path);

// Writes the .mat layout above into a staged file (the caller commits).  names
// has data.cols() entries starting with "t"; entries finite.  A file that
// streams ("-", a FIFO, a device) is refused: matio writes by name.
// Throws InputError.
void write_excitation_mat(AtomicFileWriter& out, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
                          const ExcitationDesign& design);

// Reads an excitation file: ".mat" through libmatio (the layout above: what
// write_excitation_mat writes), anything else as a CSV log.  Checks that the
// design is present and valid, that the columns are t, v1..vn for its n
// channels, that t is uniform (as read_log), and check_design_matches.
// Throws InputError "path: what; what to do" (or path:line:column), e.g.
//   "x.csv: no '# lpvid-excitation:' line before the header; write the signal with lpvid excite"
ExcitationFile read_excitation_file(const std::string& path);

// The design a log carries, whatever its format: a CSV log's '# lpvid-excitation:'
// comment line (read_excitation_design), or a .mat log's (mat_log.h: a path ending
// in ".mat" or a file with a MAT-file header) char variable `excitation_design`
// (kExcitationDesignVariable) holding the same JSON as one row of text — what
// write_excitation_mat writes and write_log_mat writes given
// {kExcitationDesignVariable, excitation_design_json(d)} as extra text.  No design:
// nullopt.  Throws InputError "cannot open ...", the errors of
// read_excitation_design, and for a .mat log
//   "x.mat:excitation_design: is a double array, not text; ..." or
//   "x.mat:excitation_design:1:COLUMN: what; what to do" (a bad JSON or design).
std::optional<ExcitationDesign> read_log_excitation_design(const std::string& log_path);

}  // namespace lpvid
