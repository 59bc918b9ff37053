// Shared plumbing for subcommands: option parsing helpers and summaries.
// No mathematics here (STYLE.md item 8).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace CLI {
class Validator;
}

namespace lpvid::cli {

// Splits "a,b,c" into names, trimming spaces around each (inner spaces stay:
// "P from S, truth"); a numbered range "a1..a28" stands for a1, a2, ..., a28 (the same
// prefix, ascending; "a01..a12" keeps the width); rejects empty names (InputError naming
// the flag).
std::vector<std::string> split_names(const std::string& text, const std::string& flag);

// "1,0.5,2" -> {1, 0.5, 2}: finite decimal numbers (parse_decimal), each
// described as `what` in the message ("--weights: '1x' is not a number; give
// each weight as a decimal number, e.g. 0.1,0.1,1").
std::vector<double> split_numbers(const std::string& text, const std::string& flag, const std::string& what);

// Pretty JSON text of a summary or report file, ending in a newline; strings
// that are not valid UTF-8 (file names) are written with U+FFFD.
std::string json_text(const nlohmann::json& value);

// A number for a report, or null where it is not finite (JSON has no NaN or inf).
nlohmann::json number_or_null(double v);

// Prints a summary: as JSON when as_json, else as the given human text.  Text
// that is not valid UTF-8 (a name from a file) is shown with U+FFFD.
void print_summary(bool as_json, const nlohmann::json& summary, const std::string& text);

// Flag ranges (docs/subcommands.md, "Flag ranges"): CLI11 checks run while the
// command line is parsed, before any file is read.  A value outside the range,
// or not a plain decimal number (hex floats, "nan", "inf", "1e3" for an
// integer are refused), gives one line naming the flag, the value and the range:
//   "--points: '0' is out of range; give the number of frequencies as a whole number from 2 to 100000"
// A flag that is not given keeps its default (e.g. "automatic"), which is not
// checked: giving 0 never means "automatic".  `what` names the value
// ("the number of frequencies").
CLI::Validator integer_in(int64_t lo, int64_t hi, const std::string& what);
// Any 64-bit unsigned integer (random seeds).
CLI::Validator seed_value();
// A finite decimal number in [lo, hi]; lo_open / hi_open exclude the bound.
CLI::Validator number_in(double lo, double hi, const std::string& what, bool lo_open = false, bool hi_open = false);
// A finite decimal number > 0 and <= hi.
CLI::Validator positive_up_to(double hi, const std::string& what);

// Refuses an experiment longer than kMaxSimulatedSamples at any of the rates:
// "--duration-s 1e+12 at --rate-hz 1000 gives 1e+15 samples per experiment; ...".
void check_simulated_samples(double duration_s, const std::vector<double>& rates_hz);

// Upper ends of the flag ranges (docs/subcommands.md, "Flag ranges"): far above
// any real use, low enough that no flag can ask for unbounded memory or time.
// Markov lags (markov, identify): 10^6 lags of a 3 x 3 system are 72 MB of
// parameters and far beyond any record (lags must stay below a quarter of it).
inline constexpr int64_t kMaxLags = 1'000'000;
// Impulse-response horizon in s (markov, identify --horizon-s).
inline constexpr double kMaxHorizonS = 1e6;
// Rows listed (hankel --count, compare --top).
inline constexpr int64_t kMaxListed = 10'000;
// Frequency grids (bode, compare --points, fit --grid-count, --analyzer-points):
// a 3 x 3 response at 10^5 frequencies is 14 MB; 10^8 ran out of memory.
inline constexpr int64_t kMaxFrequencyPoints = 100'000;
// Samples per FRF segment (frf --segment): 2^24, a 16 M-point FFT.
inline constexpr int64_t kMaxSegment = int64_t{1} << 24;
// Frequencies in rad/s or Hz (bode --min/--max, compare --band-*, fit --grid-*).
inline constexpr double kMaxFrequency = 1e9;
// Sample rates in Hz (simulate, fit and model export --rate-hz).
inline constexpr double kMaxRateHz = 1e7;
// Simulated time in s (simulate --duration-s).
inline constexpr double kMaxDurationS = 1e6;
// Scale factors (--noise-scale, --excitation-scale).
inline constexpr double kMaxScale = 1e6;
// Samples of one simulated experiment (--duration-s x --rate-hz): a log of
// 2 x 10^7 samples and 10 columns is 1.6 GB in memory.
inline constexpr double kMaxSimulatedSamples = 2e7;

// dir + "/" + name, without doubling the slash.
std::string join_path(const std::string& dir, const std::string& name);

}  // namespace lpvid::cli

namespace lpvid {
struct EraOptions;
struct MarkovFile;
}  // namespace lpvid

namespace lpvid::cli {
// ERA options carrying the scales and noise levels recorded in a Markov file.
EraOptions era_options_from(const MarkovFile& file);
}  // namespace lpvid::cli
