// lpvid — time-domain logs in MATLAB .mat files (v5 and v7.3), docs/formats.md
// "Logs in .mat files".  read_log (csv_log.h) hands a path ending in ".mat" (any
// case), or a file starting with a MAT-file header, to read_log_mat, so every
// command that reads logs takes .mat files.  Data layout: idlib/core/types.h.
//
// Layouts, tried in this order (the first that applies wins; docs/formats.md):
//   (d) matrix + names   variables `data` (N x m, numeric, real) and `names` (a
//                        cell array of m char names, one holding "t"): column j
//                        of data is the channel names{j}.  What `lpvid excite`,
//                        dSPACE and Simulink "To Workspace" (Array) + a names
//                        list give; other variables (e.g. excitation_design) are
//                        ignored.
//   (a) one per signal   a top-level numeric variable `t`: every other top-level
//                        numeric variable with more than one element is a
//                        channel named as the variable, a vector of N entries;
//                        scalars, text, cells and structs are ignored.
//   (c) Simulink         one or more top-level structs with fields `time` and
//       "Structure With  `signals` (To Workspace / scope "Structure With Time"):
//       Time"            x.time N-vector; x.signals a 1 x k struct array, each
//                        with `values` N x w and optional `label`.  Signal i is
//                        named label, or x when k = 1 and the label is empty, or
//                        x_i; a signal of width w > 1 gives channels <name>1 ..
//                        <name>w.  Several such structs must share t bit for bit.
//   (b) one struct       exactly one top-level struct with a field `t`: its
//                        fields are the signals, by the rules of (a).
// The log then obeys the CSV rules (csv_log.h): unique non-empty names, a channel
// "t" in seconds, every value finite, at least 2 samples, t strictly increasing
// and uniform within LogReadOptions::sampling_tolerance, sample_period_s =
// (t_last - t_first) / (N - 1) — computed exactly as the CSV reader does, so a
// .mat log and a CSV log of the same doubles give identical Log values.  Numeric
// classes double, single, integer and logical are read (converted to double).
#pragma once

#include <string>

#include "formats/io/csv_log.h"

namespace lpvid {

// Reads a .mat log.  Throws InputError "path:variable: what; what to do", e.g.
//   "run.mat:data: column 3 ('u1') holds a NaN at row 1207; ..."
//   "run.mat:u1: has 999 entries but t has 1000; ..."
// and the file-level errors of the FRD .mat reader ("cannot open ...", "... is not
// a MATLAB .mat file (v5 or v7.3); ...", "... damaged or truncated ...").
Log read_log_mat(const std::string& path, const LogReadOptions& options = {});

// True when path names a .mat log: it ends in ".mat" (any case), or it is a
// regular file whose first 128 bytes are a MAT-file header.
bool is_mat_log(const std::string& path);

// Writes names/data as the (d) layout: `data` (N x m double) and `names` (1 x m
// cell of char), plus each of extra_text as a char variable (name, text).  Atomic
// (a temporary renamed over path).  For tests and tools; the checks of write_log.
// {"excitation_design", excitation_design_json(d)} records the log's excitation
// design as periodic frf reads it (excitation_file.h, read_log_excitation_design).
void write_log_mat(const std::string& path, const std::vector<std::string>& names, const Eigen::MatrixXd& data,
                   bool v73 = false, const std::vector<std::pair<std::string, std::string>>& extra_text = {});

}  // namespace lpvid
