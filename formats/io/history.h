// lpvid — the fit history beside a model (docs/formats.md, "Fit history"): every
// fit of a model appends one record, so `lpvid history` can show the error falling
// model by model.
//
// File: <model>.history.jsonl next to the model (history_path_for), JSON lines —
// one JSON object per line, oldest first, no blank lines:
//
//   {"timestamp":"2026-11-23T12:00:00Z","model":"plant.json","effects":["rigid body","suspension"],
//    "free_parameters":9,"cost":1.25e-3,"error_mean":0.031,"error_max":0.12,
//    "channels":[{"output":"psi","input":"T_psi","error_mean":0.02,"error_max":0.08}, ...],
//    "aic":-812.5,"bic":-790.1,"note":"first fit"}
//
// | key             | type / unit | rule |
// |-----------------|-------------|------|
// | timestamp       | string, ISO 8601 UTC "YYYY-MM-DDThh:mm:ssZ" | required |
// | model           | string, the model file as the fit wrote it | required, not empty |
// | effects         | array of strings, the effects in the model | required (may be empty) |
// | free_parameters | integer >= 0 | required |
// | cost            | number >= 0, the fit's final cost | required |
// | error_mean      | number >= 0, mean weighted error (fraction, 0.01 = 1 %) | required |
// | error_max       | number >= error_mean, largest weighted error (fraction) | required |
// | error           | number >= 0 or null: the fit's error figure (idlib/fit/fit.h; fraction) | optional |
// | noise_floor     | number >= 0 or null: the same figure for the data's noise | optional |
// | channels        | array of {output, input: string; error_mean, error_max: number >= 0} | optional |
// | aic, bic        | number or null (not computed) | optional |
// | note            | string | optional |
// Unknown keys are errors (a typo would otherwise vanish).
//
// Errors: InputError "path:line:column: what; what to do" — the line of the
// record, and the byte column of a JSON syntax error or 1 for a bad value.
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct HistoryChannelError {
  std::string output, input;
  double error_mean = 0, error_max = 0;  // fractions
};

struct HistoryRecord {
  std::string timestamp;             // ISO 8601 UTC, e.g. "2026-11-23T12:00:00Z"
  std::string model;                 // model file
  std::vector<std::string> effects;  // effects in the model, in the fit's order
  Index free_parameters = 0;
  double cost = 0;
  double error_mean = 0, error_max = 0;         // fractions (0.01 = 1 %)
  // The error figure of the fit (rms over channels; the number fit and diagnose print)
  // and its noise floor; NaN = not recorded (records of an earlier lpvid).
  double error = std::numeric_limits<double>::quiet_NaN();
  double noise_floor = std::numeric_limits<double>::quiet_NaN();
  std::vector<HistoryChannelError> channels;    // may be empty
  double aic = std::numeric_limits<double>::quiet_NaN();  // NaN = not computed (null)
  double bic = std::numeric_limits<double>::quiet_NaN();
  std::string note;

  // @throws InputError naming the first field that breaks the table's rules.
  void validate() const;
};

// "<model>.history.jsonl": plant.json -> plant.json.history.jsonl.
std::string history_path_for(const std::string& model_path);

// The current time as "YYYY-MM-DDThh:mm:ssZ".
std::string utc_timestamp_now();

// Appends one record (one line) to the history file, creating it if needed.  The
// file is rewritten atomically (atomic_file.h) with the old lines kept byte for
// byte, so a failed append never leaves a half line.
// @throws InputError  the record is invalid (validate); the existing file cannot be
//                     read or is not a valid history (read_history's messages);
//                     the file cannot be written.
void append_history(const std::string& path, const HistoryRecord& record);

// Every record, oldest first; text_out (if given) receives the file's bytes, to
// copy a checked history unchanged.  A missing file is an error ("no history ... fit
// a model first").  @throws InputError "path:line:column: ..." for a bad line.
std::vector<HistoryRecord> read_history(const std::string& path, std::string* text_out = nullptr);

// One record as its JSON line (without the newline).
std::string history_line(const HistoryRecord& record);

}  // namespace lpvid
