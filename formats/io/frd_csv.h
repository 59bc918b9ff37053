// lpvid — frequency-response (FRD) files from analyzers (SigLab-style), CSV
// form (docs/formats.md, "FRD files").  Data layout: idlib/core/types.h
// (FrequencyResponse: response[k] is outputs x inputs at omega_rad_s[k]).
//
//   # SigLab export, rig 2
//   # outputs: psi,theta          (optional metadata, see "Names" below)
//   # inputs: u1,u2
//   freq_hz,S_psi_u1_re,S_psi_u1_im,S_psi_u2_db,S_psi_u2_deg,...,coh_psi_u1,...,flag
//   0.5,1.25,-0.5,-3.2,171.5,...,0.998,...,0
//
// Columns (any order; cells follow the log rules of csv_log.h, so NaN/Inf,
// empty cells and duplicate column names are errors):
//   freq_hz               frequency in Hz, > 0, strictly increasing; one row per
//                         frequency, at least one row.  omega_rad_s = 2*pi*freq_hz.
//   <Q>_<i>_<j>_re / _im  real and imaginary part of the response from input j
//                         to output i, or
//   <Q>_<i>_<j>_db / _deg magnitude 20*log10|H| in dB and phase in degrees
//                         (H = 10^(db/20) * exp(1i*deg*pi/180)).  One pair per
//                         (i, j): re with im, or db with deg — never mixed.
//   coh_<i>_<j>           optional coherence in [0, 1]; when one is given,
//                         every (i, j) needs one.
//   var_<i>_<j>           optional variance E|Ĥ − H|² (total), >= 0; all pairs or none.
//   dvar_<i>_<j>          optional part of var_<i>_<j> due to nonlinear distortions
//                         (a BLA), 0 <= dvar <= var; all pairs or none; needs var_.
//   flag                  optional, 0 or 1 per frequency (1 = untrusted).
// <Q> is the quantity (S, P, G, ...): letters and digits, not "coh", the text
// before the first '_'.  FrdReadOptions::quantity selects one; other quantities
// in the file are then ignored.  Empty: the file must use exactly one.
//
// Names.  i and j are either 1-based indices (digits only) or channel names.
// Without metadata, a name has no '_' and "<i>_<j>" splits at its only '_';
// an axis (outputs or inputs) is all indices or all names.  Index columns give
// empty output_names / input_names (the unnamed-channel convention of
// types.h); name columns give the names in the order of the '# outputs:' /
// '# inputs:' metadata if present, else in the order they first appear in the
// header.  With "# outputs: a,b" and/or "# inputs: x,y" comment lines before the
// header, the names of that axis are exactly those listed (they may then hold
// '_'), and "<i>_<j>" must split at exactly one '_' into a listed output (or an
// underscore-free token when outputs are not listed) and a listed input (same).
// Other comments are ignored.
//
// "# sample_rate_hz: X" (optional, at most once, X > 0): the rate of the log the
// response was estimated from (lpvid frf writes it), FrequencyResponse::sample_rate_hz;
// 0 when absent.  Written when sample_rate_hz > 0.
//
// Errors: InputError "path:line:column: what; what to do" (columns are byte
// columns of the offending header or data cell).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "formats/io/atomic_file.h"
#include "idlib/core/types.h"

namespace lpvid {

struct FrdReadOptions {
  // Quantity prefix to read (CSV: the <Q> of the columns; .mat: the name of the
  // response variable).  Empty: the single quantity the file holds.  Letters
  // and digits only, not "coh".
  std::string quantity;

  // Throws InputError if quantity is not allowed.
  void validate() const;
};

// Reads a complete FRD CSV file ("-": stdin): every (output, input) pair must
// have its columns.  Throws InputError (see above), e.g.
//   "s.csv:3:19: no column 'S_2_1_im' for the imaginary part of output 2, input 1 (its real part is column 'S_2_1_re');
//    give both 'S_2_1_re' and 'S_2_1_im', or 'S_2_1_db' and 'S_2_1_deg'"
FrequencyResponse read_frd_csv(const std::string& path, const FrdReadOptions& options = {});
// The same from text already read (path for messages only).
FrequencyResponse parse_frd_csv(const std::string& text, const std::string& path, const FrdReadOptions& options = {});

// Writes frd atomically (atomic_file.h; "-" is stdout): comments as "# ..."
// lines, then "# outputs:"/"# inputs:" metadata for the named axes, then the
// header freq_hz, <Q>_<i>_<j>_re, <Q>_<i>_<j>_im over outputs (outer) and inputs
// (inner), coh_<i>_<j> when frd.coherence is not empty, flag when frd.flagged is
// not empty.  Channels without names are written as indices 1, 2, ...  Numbers
// are written in the shortest form that reads back to the identical double;
// freq_hz is chosen so that 2*pi*freq_hz reads back to the identical omega when
// such a double exists (always for a response read from a file), else the
// nearest.  Throws InputError on inconsistent shapes, non-finite values,
// coherence outside [0, 1], non-positive or non-increasing frequencies, names
// that cannot be written (empty; ',', '"', blanks or line breaks; duplicates;
// a column that would split two ways), a bad quantity, a sample rate that is
// not 0 or in (0, 1e12], or a comment that would read as metadata ("outputs: ...",
// "inputs: ...", "averages: ...", "sample_rate_hz: ...").
void write_frd_csv(const std::string& path, const FrequencyResponse& frd, const std::string& quantity,
                   const std::vector<std::string>& comments = {});
// The same into a staged file (AtomicOutputSet::stage); the caller commits.
void write_frd_csv(AtomicFileWriter& out, const FrequencyResponse& frd, const std::string& quantity,
                   const std::vector<std::string>& comments = {});

// Part of a MIMO measurement: a file holding the columns of some (output,
// input) pairs only — e.g. one file per excited input, file k holding input k.
struct FrdPart {
  std::string path;      // as given, for messages
  std::string quantity;  // the <Q> of its columns
  // outputs x inputs as named by the file (metadata, names or largest index);
  // entries of pairs the file does not hold are 0 (coherence too).
  FrequencyResponse frd;
  // The (output, input) pairs the file holds, 0-based, in header order.
  std::vector<std::pair<Index, Index>> pairs;
};

// Reads an FRD CSV file as read_frd_csv does, but a pair may be absent.  A
// pair's half (re without im, db without deg) is still an error.
FrdPart read_frd_part(const std::string& path, const FrdReadOptions& options = {});

struct FrdMergeOptions {
  // Largest relative difference |w_a - w_b| / max(|w_a|, |w_b|) between the
  // frequencies of two parts at the same row.  Files exported by one analyzer
  // run share their grid to the last digit; 1e-9 also accepts grids printed with
  // 10 significant digits.  Must be finite and >= 0.
  double frequency_tolerance = 1e-9;

  // Throws InputError if a field is out of range.
  void validate() const;
};

// Merges parts onto one response.  Every part must hold the same quantity and
// the same number of frequencies, equal within frequency_tolerance (the result
// takes the first part's grid); every axis is indexed in all parts or named in
// all parts.  Named axes are matched by name (order: first appearance over the
// parts in order), indexed axes by index (size: the largest).  Every (output,
// input) pair must be held by exactly one part.  Coherence: all parts or none.
// flagged: a frequency is flagged if any part flags it; empty if no part has a
// flag column.  Throws InputError naming the part(s), e.g.
//   "cannot merge FRD parts: output 2, input 1 is in both 'a.csv' and 'b.csv'; give every pair in exactly one file"
FrequencyResponse merge_frd_parts(const std::vector<FrdPart>& parts, const FrdMergeOptions& options = {});

}  // namespace lpvid
