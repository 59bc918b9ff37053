#include "cli/common.h"

#include <CLI/CLI.hpp>
#include <fast_float/fast_float.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>

#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid::cli {

namespace common_names {

// "a1..a28" -> a1, a2, ..., a28 (a range of numbered channels: the same non-empty prefix
// ending in a non-digit, ascending numbers; "a01..a12" keeps the width).  False when
// item is not such a range (then it is a name as it stands).
bool expand_name_range(const std::string& item, std::vector<std::string>& names) {
  const std::size_t dots = item.find("..");
  if (dots == std::string::npos || dots == 0 || item.find("..", dots + 1) != std::string::npos) return false;
  auto split = [](const std::string& s, std::string& prefix, std::string& digits) {
    std::size_t k = s.size();
    while (k > 0 && std::isdigit(static_cast<unsigned char>(s[k - 1])) != 0) --k;
    prefix = s.substr(0, k);
    digits = s.substr(k);
    return !prefix.empty() && !digits.empty() && digits.size() <= 6;
  };
  std::string p1, d1, p2, d2;
  if (!split(item.substr(0, dots), p1, d1) || !split(item.substr(dots + 2), p2, d2) || p1 != p2) return false;
  const int a = std::stoi(d1), b = std::stoi(d2);
  if (b < a || b - a >= 10000) return false;
  const std::size_t width = d1.size() > 1 && d1[0] == '0' ? d1.size() : 0;
  for (int k = a; k <= b; ++k) names.push_back(fmt::format("{}{:0{}}", p1, k, width));
  return true;
}

}  // namespace common_names

std::vector<std::string> split_names(const std::string& text, const std::string& flag) {
  std::vector<std::string> names;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    const std::size_t first = item.find_first_not_of(' ');
    item = first == std::string::npos ? std::string() : item.substr(first, item.find_last_not_of(' ') - first + 1);
    if (item.empty())
      throw InputError(fmt::format("{} '{}': empty name; give names separated by commas, e.g. v1,v2,v3", flag,
                                   text.size() <= 40 ? text : text.substr(0, 40) + "..."));
    if (!valid_utf8(item))
      throw InputError(fmt::format("{}: a name is not valid UTF-8; give names as UTF-8 text (as in the file's header)",
                                   flag));
    if (!common_names::expand_name_range(item, names)) names.push_back(item);
    if (comma == std::string::npos) return names;
    start = comma + 1;
  }
}

std::vector<double> split_numbers(const std::string& text, const std::string& flag, const std::string& what) {
  std::vector<double> out;
  for (const std::string& item : split_names(text, flag)) {
    double v = 0;
    if (!parse_decimal(item, v))
      throw InputError(fmt::format("{}: '{}' is not a number; give each {} as a finite decimal number, comma "
                                   "separated (e.g. 0.1,0.1,1)",
                                   flag, item.size() <= 40 ? item : item.substr(0, 40) + "...", what));
    out.push_back(v);
  }
  return out;
}

std::string json_text(const nlohmann::json& value) {
  return value.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

void print_summary(bool as_json, const nlohmann::json& summary, const std::string& text) {
  if (as_json) {
    std::fputs(json_text(summary).c_str(), stdout);
  } else {
    std::fputs(text.c_str(), stdout);
  }
}

namespace {

// The value as given, cut for a one-line message.
std::string shown(const std::string& text) {
  constexpr std::size_t kMaxShown = 40;
  return text.size() <= kMaxShown ? text : text.substr(0, kMaxShown) + "...";
}

std::string number_text(double v) { return fmt::format("{:g}", v); }

}  // namespace

CLI::Validator integer_in(int64_t lo, int64_t hi, const std::string& what) {
  const std::string range = fmt::format("a whole number from {} to {}", lo, hi);
  return CLI::Validator(
      [lo, hi, what, range](std::string& text) -> std::string {
        const char* b = text.data();
        const char* e = b + text.size();
        if (b < e && *b == '+') ++b;
        int64_t v = 0;
        const auto [end, ec] = std::from_chars(b, e, v);
        if (b == e || end != e || (ec != std::errc() && ec != std::errc::result_out_of_range))
          return fmt::format("'{}' is not a whole number; give {} as {}", shown(text), what, range);
        if (ec == std::errc::result_out_of_range || v < lo || v > hi)
          return fmt::format("'{}' is out of range; give {} as {}", shown(text), what, range);
        return {};
      },
      fmt::format("INT in [{}, {}]", lo, hi));
}

CLI::Validator seed_value() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        uint64_t v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (text.empty() || end != text.data() + text.size() || ec != std::errc())
          return fmt::format("'{}' is not a seed; give a whole number from 0 to {}", shown(text),
                             std::numeric_limits<uint64_t>::max());
        return {};
      },
      "UINT64");
}

CLI::Validator number_in(double lo, double hi, const std::string& what, bool lo_open, bool hi_open) {
  std::string range;
  if (std::isinf(hi))
    range = fmt::format("{} {}", lo_open ? ">" : ">=", number_text(lo));
  else
    range = fmt::format("{} {} and {} {}", lo_open ? ">" : ">=", number_text(lo), hi_open ? "<" : "<=",
                        number_text(hi));
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        const char* b = text.data();
        const char* e = b + text.size();
        double v = 0;
        if (!parse_decimal(std::string_view(b, static_cast<std::size_t>(e - b)), v)) {
          // A decimal beyond the range of a double ("1e400") is out of range, not "not a number".
          const bool overflow = fast_float::from_chars(b, e, v).ptr == e && std::isinf(v) &&
                                std::none_of(b, e, [](char c) { return c == 'i' || c == 'I'; });
          if (!overflow)
            return fmt::format("'{}' is not a number; give {} as a decimal number {}", shown(text), what, range);
        }
        const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
        if (!ok) return fmt::format("'{}' is out of range; give {} {}", shown(text), what, range);
        return {};
      },
      fmt::format("NUMBER {}", range));
}

CLI::Validator positive_up_to(double hi, const std::string& what) { return number_in(0, hi, what, true, false); }

void check_simulated_samples(double duration_s, const std::vector<double>& rates_hz) {
  for (const double rate : rates_hz)
    if (!(duration_s * rate <= kMaxSimulatedSamples))
      throw InputError(fmt::format("--duration-s {:g} at --rate-hz {:g} gives {:.3g} samples per experiment; lpvid "
                                   "simulates at most {:g} (e.g. 2000 s at 10 kHz): shorten --duration-s",
                                   duration_s, rate, duration_s * rate, kMaxSimulatedSamples));
}

std::string join_path(const std::string& dir, const std::string& name) {
  if (dir.empty() || dir.back() == '/') return dir + name;
  return dir + "/" + name;
}

}  // namespace lpvid::cli

#include "formats/io/markov_csv.h"
#include "idlib/realization/era.h"

namespace lpvid::cli {

EraOptions era_options_from(const MarkovFile& file) {
  EraOptions o;
  o.sample_period_s = file.sample_period_s;
  o.input_scale = file.input_rms;
  o.output_scale = file.output_rms;
  o.markov_noise_std = file.noise_std;
  o.input_names = file.inputs;
  o.output_names = file.outputs;
  return o;
}

}  // namespace lpvid::cli
