// lpvid — the design of an excitation signal, as `lpvid excite` records it in
// the signal's file and the simulators copy it into their logs, so that
// periodic `frf` knows the period and the excited lines (docs/formats.md,
// "Excitation design line").
//
// In a CSV log it is ONE comment line before the header:
//   # lpvid-excitation: {"format":1,"kind":"multisine","sample_rate_hz":1000,...}
// and in a .mat file the char variable excitation_design holds the same JSON.
//
// Signal layout (idlib/signal/excitation.h): a periodic signal is R x E blocks,
// realisation-major, each of (T + P) L samples = T transient periods then P
// periods of L samples; input j of experiment e carries coding[e][j] times its
// own periodic signal (coding null: 1).  A non-periodic signal is N samples.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct ExcitationDesign {
  int format = 1;
  std::string kind;           // "multisine" | "prbs" | "noise"
  double sample_rate_hz = 0;  // fs
  Index channels = 0;         // n inputs (columns v1..vn)
  Index period_samples = 0;   // L; 0 = not periodic
  Index periods = 1;          // P
  Index transient_periods = 0;  // T
  Index realisations = 1;     // R
  Index experiments = 1;      // E
  std::string mimo;           // "single" | "one-at-a-time" | "hadamard" | "zipper"
  // Per input: ascending DFT bins k of one period (frequency k fs / L), 0 < k < L/2.
  std::vector<std::vector<Index>> excited_bins;
  // Multisine with a shaped spectrum (excite --amplitude): per input, the amplitude
  // A_k of each excited bin (same order as excited_bins; input units, before the
  // coding weight).  Empty (key absent): not recorded, every line of an input has the
  // same amplitude, rms sqrt(2 / K).
  std::vector<std::vector<double>> amplitudes;
  Eigen::MatrixXd coding;     // E x n weights, or 0 x 0 (JSON null): every weight 1
  std::string phase;          // "random" | "schroeder" | "" (JSON null: a PRBS)
  std::uint64_t seed = 0;
  std::vector<double> crest_factor, rms, peak;  // per input
  // PRBS only (0 otherwise): order m (2^m - 1 levels per period) and samples per level.
  int prbs_order = 0;
  Index clock_divider = 0;

  bool periodic() const { return period_samples > 0; }
  // (T + P) L for a periodic signal; 0 otherwise.
  Index block_samples() const { return periodic() ? (transient_periods + periods) * period_samples : 0; }
  // R E (T + P) L for a periodic signal; 0 otherwise (any length).
  Index total_samples() const { return realisations * experiments * block_samples(); }

  // Throws InputError "where: what; what to do" for the first broken rule: format
  // != 1, unknown kind/mimo/phase, fs not positive, n < 1, negative L, P < 1,
  // T < 0, R < 1, E not 1 / n / the coding's rows, excited_bins not n lists of
  // ascending bins in (0, L/2), coding not E x n of finite numbers, per-input
  // lists not of length n, amplitudes (when given) not one positive finite value
  // per excited bin.
  void validate(const std::string& where) const;
};

// The tag that starts the comment line (after "#" and blanks).
inline constexpr const char* kExcitationDesignTag = "lpvid-excitation:";

// The char variable of a .mat file (an excitation file or a log) that holds the JSON.
inline constexpr const char* kExcitationDesignVariable = "excitation_design";

// The JSON of the design on one line (keys in the order of docs/formats.md).
std::string excitation_design_json(const ExcitationDesign& design);
// The comment text "lpvid-excitation: {...}" (write_log adds the "# ").
std::string excitation_design_comment(const ExcitationDesign& design);

// Parses the JSON text.  `path` and `line` name where it came from, and `column`
// is the 1-based column of the text's first byte in that line: errors read
// "path:line:column: what; what to do", pointing at the JSON syntax error or at
// the offending key.  Unknown keys are ignored (later formats may add some).
ExcitationDesign parse_excitation_design(const std::string& text, const std::string& path, int64_t line = 1,
                                         int64_t column = 1);

// Scans comment lines (the text after '#') for the tag.  line_numbers[i] is the
// file line of comments[i].  No tag: nullopt.  Two tags: InputError (a log holds
// one design).  A malformed line: InputError as parse_excitation_design.
std::optional<ExcitationDesign> find_excitation_design(const std::vector<std::string>& comments,
                                                       const std::vector<int64_t>& line_numbers,
                                                       const std::string& path);

// Reads the comment lines of a CSV log up to its header row (the first line that
// is neither blank nor a comment) and returns its design, if any.  Reads at most
// 16 MiB of leading comments.  "-" (stdin) is refused: the log itself must then be
// read from stdin.  Throws InputError "cannot open 'x.csv': ...; check the path"
// and as find_excitation_design.
std::optional<ExcitationDesign> read_excitation_design(const std::string& log_path);

// Checks that a log of `rows` samples at `sample_period_s` with `channels`
// excitation columns can hold this design: the rate agrees to 1e-6 relative, the
// channel count matches, and a periodic design has exactly total_samples() rows.
// Throws InputError "where: what; what to do".
void check_design_matches(const ExcitationDesign& design, Index rows, double sample_period_s, Index channels,
                          const std::string& where);

}  // namespace lpvid
