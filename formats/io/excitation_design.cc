#include "formats/io/excitation_design.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>

#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using nlohmann::json;

// The parsed line, with what is needed to point at a key in an error.
class DesignReader {
 public:
  DesignReader(const std::string& padded, const std::string& path, int64_t line)
      : text_(padded), path_(path), line_(line), root_(detail::parse_json(path, padded, {}, line)) {
    if (!root_.is_object()) fail_at(text_.find_first_not_of(' '), "the excitation design must be a JSON object {...}; write it as lpvid excite does");
  }

  [[noreturn]] void fail_at(size_t offset, const std::string& what) const {
    const detail::CellPosition at = detail::text_position(text_, offset);
    detail::fail_at(path_, line_ + at.line - 1, at.column, what);
  }
  [[noreturn]] void fail_key(const std::string& key, const std::string& what) const {
    size_t offset = detail::find_top_level_key(text_, key);
    if (offset == 0) offset = text_.find('{');
    fail_at(offset, fmt::format("excitation design \"{}\": {}", key, what));
  }

  const json& get(const std::string& key) const {
    auto it = root_.find(key);
    if (it == root_.end())
      fail_at(text_.find('{'), fmt::format("excitation design: no key \"{}\"; the line is written by lpvid excite "
                                           "(docs/formats.md, \"Excitation design line\")",
                                           key));
    return *it;
  }
  bool has(const std::string& key) const { return root_.contains(key); }

  std::string string(const std::string& key, bool null_allowed = false) const {
    const json& v = get(key);
    if (null_allowed && v.is_null()) return "";
    if (!v.is_string()) fail_key(key, fmt::format("{} is not a string", detail::json_excerpt(v)));
    return v.get<std::string>();
  }
  double number(const std::string& key) const {
    const json& v = get(key);
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      fail_key(key, fmt::format("{} is not a finite number", detail::json_excerpt(v)));
    return v.get<double>();
  }
  Index integer(const std::string& key) const { return to_integer(get(key), key); }
  Index to_integer(const json& v, const std::string& key) const {
    if (v.is_number_unsigned() && v.get<std::uint64_t>() <= (std::uint64_t{1} << 62))
      return static_cast<Index>(v.get<std::uint64_t>());
    if (v.is_number_integer()) return static_cast<Index>(v.get<std::int64_t>());
    fail_key(key, fmt::format("{} is not a whole number", detail::json_excerpt(v)));
  }
  std::vector<double> numbers(const std::string& key) const {
    const json& v = get(key);
    if (!v.is_array()) fail_key(key, fmt::format("{} is not an array of numbers", detail::json_excerpt(v)));
    std::vector<double> out;
    for (const json& x : v) {
      if (!x.is_number() || !std::isfinite(x.get<double>()))
        fail_key(key, fmt::format("{} is not a finite number", detail::json_excerpt(x)));
      out.push_back(x.get<double>());
    }
    return out;
  }
  const json& root() const { return root_; }

 private:
  const std::string& text_;
  std::string path_;
  int64_t line_;
  json root_;
};

json coding_json(const Eigen::MatrixXd& coding) {
  if (coding.size() == 0) return nullptr;
  json rows = json::array();
  for (Index e = 0; e < coding.rows(); ++e) {
    json row = json::array();
    for (Index j = 0; j < coding.cols(); ++j) row.push_back(coding(e, j));
    rows.push_back(row);
  }
  return rows;
}

bool one_of(const std::string& value, std::initializer_list<const char*> allowed) {
  for (const char* a : allowed)
    if (value == a) return true;
  return false;
}

}  // namespace

void ExcitationDesign::validate(const std::string& where) const {
  auto fail = [&](const std::string& what) { throw InputError(fmt::format("{}: excitation design: {}", where, what)); };
  if (format != 1) fail(fmt::format("format {} is not known (this lpvid reads format 1); update lpvid", format));
  if (!one_of(kind, {"multisine", "prbs", "noise"}))
    fail(fmt::format("kind {} is not multisine, prbs or noise", detail::quote_cell(kind)));
  if (!one_of(mimo, {"single", "one-at-a-time", "hadamard", "zipper"}))
    fail(fmt::format("mimo {} is not single, one-at-a-time, hadamard or zipper", detail::quote_cell(mimo)));
  if (!phase.empty() && !one_of(phase, {"random", "schroeder"}))
    fail(fmt::format("phase {} is not random, schroeder or null", detail::quote_cell(phase)));
  if (!std::isfinite(sample_rate_hz) || !(sample_rate_hz > 0)) fail("sample_rate_hz must be a positive number");
  if (channels < 1 || channels > 256) fail(fmt::format("channels {} is not 1..256", channels));
  if (period_samples < 0 || periods < 1 || transient_periods < 0 || realisations < 1 || experiments < 1)
    fail(fmt::format("period_samples {}, periods {}, transient_periods {}, realisations {}, experiments {}: they must "
                     "be >= 0, >= 1, >= 0, >= 1, >= 1",
                     period_samples, periods, transient_periods, realisations, experiments));
  if (kind == "multisine" && !periodic()) fail("a multisine needs period_samples > 0");
  // Bound the sizes so that total_samples() cannot overflow (excite writes at most 1e8 values).
  if (static_cast<double>(realisations) * static_cast<double>(experiments) *
          static_cast<double>(transient_periods + periods) * static_cast<double>(period_samples) >
      4e8)
    fail("the design describes more than 4e8 samples; check the numbers");
  const Index expected_e = mimo == "one-at-a-time" ? channels : coding.rows() == 0 ? 1 : coding.rows();
  if (experiments != expected_e)
    fail(fmt::format("experiments {} does not match mimo {} with {} channels (expected {})", experiments, mimo, channels,
                     expected_e));
  if ((mimo == "hadamard" || mimo == "one-at-a-time") && (coding.rows() != experiments || coding.cols() != channels))
    fail(fmt::format("mimo {} needs a coding matrix of experiments x channels = {} x {} (got {} x {})", mimo,
                     experiments, channels, coding.rows(), coding.cols()));
  if (coding.size() != 0 && (coding.cols() != channels || !coding.allFinite()))
    fail(fmt::format("coding is {} x {}; it must be experiments x channels = {} x {} finite numbers", coding.rows(),
                     coding.cols(), experiments, channels));
  if (static_cast<Index>(excited_bins.size()) != channels)
    fail(fmt::format("excited_bins has {} lists for {} channels; give one list per channel", excited_bins.size(),
                     channels));
  for (std::size_t j = 0; j < excited_bins.size(); ++j) {
    const auto& bins = excited_bins[j];
    if (!periodic() && !bins.empty()) fail(fmt::format("excited_bins of v{}: a non-periodic signal has none", j + 1));
    for (std::size_t i = 0; i < bins.size(); ++i)
      if (bins[i] < 1 || 2 * bins[i] >= period_samples || (i > 0 && bins[i] <= bins[i - 1]))
        fail(fmt::format("excited_bins of v{}: bin {} is not in 1..{} or not ascending", j + 1, bins[i],
                         (period_samples - 1) / 2));
  }
  if (!amplitudes.empty()) {
    if (static_cast<Index>(amplitudes.size()) != channels)
      fail(fmt::format("amplitudes has {} lists for {} channels; give one list per channel (or leave the key out)",
                       amplitudes.size(), channels));
    for (std::size_t j = 0; j < amplitudes.size(); ++j) {
      if (amplitudes[j].size() != excited_bins[j].size())
        fail(fmt::format("amplitudes of v{}: {} values for {} excited bins; give one per bin", j + 1,
                         amplitudes[j].size(), excited_bins[j].size()));
      for (double a : amplitudes[j])
        if (!std::isfinite(a) || !(a > 0)) fail(fmt::format("amplitudes of v{}: {} is not a positive number", j + 1, a));
    }
  }
  for (const auto* list : {&crest_factor, &rms, &peak})
    if (static_cast<Index>(list->size()) != channels)
      fail(fmt::format("crest_factor, rms and peak need one value per channel ({}), one has {}", channels,
                       list->size()));
}

std::string excitation_design_json(const ExcitationDesign& d) {
  json bins = json::array();
  for (const auto& b : d.excited_bins) bins.push_back(b);
  std::string out = "{";  // keys in the documented order (a json object would sort them)
  auto add = [&](const char* key, const json& value) {
    if (out.size() > 1) out += ',';
    out += json(key).dump() + ":" + value.dump(-1, ' ', false, json::error_handler_t::replace);
  };
  add("format", d.format);
  add("kind", d.kind);
  add("sample_rate_hz", d.sample_rate_hz);
  add("channels", d.channels);
  add("period_samples", d.period_samples);
  add("periods", d.periods);
  add("transient_periods", d.transient_periods);
  add("realisations", d.realisations);
  add("experiments", d.experiments);
  add("mimo", d.mimo);
  add("excited_bins", bins);
  add("coding", coding_json(d.coding));
  add("phase", d.phase.empty() ? json(nullptr) : json(d.phase));
  add("seed", d.seed);
  add("crest_factor", d.crest_factor);
  add("rms", d.rms);
  add("peak", d.peak);
  if (d.kind == "prbs") {
    add("prbs_order", d.prbs_order);
    add("clock_divider", d.clock_divider);
  }
  if (!d.amplitudes.empty()) {
    json amplitudes = json::array();
    for (const auto& a : d.amplitudes) amplitudes.push_back(a);
    add("amplitudes", amplitudes);
  }
  return out + "}";
}

std::string excitation_design_comment(const ExcitationDesign& design) {
  return std::string(kExcitationDesignTag) + " " + excitation_design_json(design);
}

ExcitationDesign parse_excitation_design(const std::string& text, const std::string& path, int64_t line,
                                         int64_t column) {
  // Blanks in front of the text put every reported column where it is in the file.
  const std::string padded = std::string(static_cast<size_t>(std::max<int64_t>(column - 1, 0)), ' ') + text;
  const DesignReader r(padded, path, line);
  ExcitationDesign d;
  d.format = static_cast<int>(r.integer("format"));
  if (d.format != 1) r.fail_key("format", fmt::format("{} is not known (this lpvid reads format 1); update lpvid", d.format));
  d.kind = r.string("kind");
  d.sample_rate_hz = r.number("sample_rate_hz");
  d.channels = r.integer("channels");
  d.period_samples = r.integer("period_samples");
  d.periods = r.integer("periods");
  d.transient_periods = r.integer("transient_periods");
  d.realisations = r.integer("realisations");
  d.experiments = r.integer("experiments");
  d.mimo = r.string("mimo");
  const json& bins = r.get("excited_bins");
  if (!bins.is_array()) r.fail_key("excited_bins", "must be an array with one array of bins per channel");
  for (const json& list : bins) {
    if (!list.is_array()) r.fail_key("excited_bins", fmt::format("{} is not an array of bins", detail::json_excerpt(list)));
    std::vector<Index> b;
    b.reserve(list.size());
    for (const json& k : list) b.push_back(r.to_integer(k, "excited_bins"));
    d.excited_bins.push_back(std::move(b));
  }
  const json& coding = r.get("coding");
  if (!coding.is_null()) {
    if (!coding.is_array() || coding.empty() || !coding[0].is_array())
      r.fail_key("coding", "must be null or an array of rows (experiments x channels)");
    d.coding.resize(static_cast<Index>(coding.size()), static_cast<Index>(coding[0].size()));
    for (std::size_t e = 0; e < coding.size(); ++e) {
      if (!coding[e].is_array() || coding[e].size() != coding[0].size())
        r.fail_key("coding", "rows must be arrays of equal length (experiments x channels)");
      for (std::size_t j = 0; j < coding[e].size(); ++j) {
        if (!coding[e][j].is_number()) r.fail_key("coding", fmt::format("{} is not a number", detail::json_excerpt(coding[e][j])));
        d.coding(static_cast<Index>(e), static_cast<Index>(j)) = coding[e][j].get<double>();
      }
    }
  }
  d.phase = r.string("phase", true);
  const json& seed = r.get("seed");
  if (!seed.is_number_unsigned()) r.fail_key("seed", fmt::format("{} is not a whole number >= 0", detail::json_excerpt(seed)));
  d.seed = seed.get<std::uint64_t>();
  d.crest_factor = r.numbers("crest_factor");
  d.rms = r.numbers("rms");
  d.peak = r.numbers("peak");
  if (r.has("prbs_order")) d.prbs_order = static_cast<int>(r.integer("prbs_order"));
  if (r.has("clock_divider")) d.clock_divider = r.integer("clock_divider");
  if (r.has("amplitudes")) {  // optional: designs before excite --amplitude have none
    const json& amplitudes = r.get("amplitudes");
    if (!amplitudes.is_array()) r.fail_key("amplitudes", "must be an array with one array of amplitudes per channel");
    for (const json& list : amplitudes) {
      if (!list.is_array())
        r.fail_key("amplitudes", fmt::format("{} is not an array of numbers", detail::json_excerpt(list)));
      std::vector<double> a;
      for (const json& x : list) {
        if (!x.is_number()) r.fail_key("amplitudes", fmt::format("{} is not a number", detail::json_excerpt(x)));
        a.push_back(x.get<double>());
      }
      d.amplitudes.push_back(std::move(a));
    }
  }
  const detail::CellPosition at = detail::text_position(padded, padded.find('{'));
  d.validate(fmt::format("{}:{}:{}", detail::display_path(path), line, at.column));
  return d;
}

std::optional<ExcitationDesign> find_excitation_design(const std::vector<std::string>& comments,
                                                       const std::vector<int64_t>& line_numbers,
                                                       const std::string& path) {
  LPVID_ASSERT(comments.size() == line_numbers.size());
  std::optional<ExcitationDesign> found;
  int64_t found_line = 0;
  const std::string tag = kExcitationDesignTag;
  for (std::size_t i = 0; i < comments.size(); ++i) {
    const std::string& c = comments[i];
    // The text after '#' (the '#' is column 1): blanks, the tag, blanks, the JSON.
    size_t at = c.find_first_not_of(" \t");
    if (at == std::string::npos || c.compare(at, tag.size(), tag) != 0) continue;
    if (found)
      throw InputError(fmt::format("{}:{}:1: a second excitation design line (the first is on line {}); a log "
                                   "holds one design: remove one",
                                   detail::display_path(path), line_numbers[i], found_line));
    at += tag.size();
    while (at < c.size() && (c[at] == ' ' || c[at] == '\t')) ++at;
    std::string json_text = c.substr(at);
    while (!json_text.empty() && (json_text.back() == '\r' || json_text.back() == ' ')) json_text.pop_back();
    found = parse_excitation_design(json_text, path, line_numbers[i], static_cast<int64_t>(at) + 2);
    found_line = line_numbers[i];
  }
  return found;
}

std::optional<ExcitationDesign> read_excitation_design(const std::string& log_path) {
  if (log_path == "-")
    throw InputError("the excitation design cannot be read from stdin (the log is read from there); give the log's path");
  struct Closer {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, Closer> f(std::fopen(log_path.c_str(), "rb"));
  if (!f)
    throw InputError(fmt::format("cannot open '{}': {}; check the path", detail::display_path(log_path),
                                 std::strerror(errno)));
  constexpr size_t kMaxCommentBytes = size_t{16} << 20;  // leading comments are short; stop on a runaway file
  std::vector<std::string> comments;
  std::vector<int64_t> lines;
  std::string line;
  size_t total = 0;
  int64_t number = 0;
  for (;;) {
    line.clear();
    int ch;
    while ((ch = std::fgetc(f.get())) != EOF && ch != '\n') {
      line += static_cast<char>(ch);
      if (++total > kMaxCommentBytes)
        throw InputError(fmt::format("{}: more than 16 MiB before the header row; check that this is a log",
                                     detail::display_path(log_path)));
    }
    ++number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos) {
      if (ch == EOF) break;
      continue;
    }
    if (line[first] != '#') break;  // the header row: the comments are over
    comments.push_back(line.substr(first + 1));
    lines.push_back(number);
    if (ch == EOF) break;
  }
  return find_excitation_design(comments, lines, log_path);
}

void check_design_matches(const ExcitationDesign& design, Index rows, double sample_period_s, Index channels,
                          const std::string& where) {
  const double fs = 1.0 / sample_period_s;
  // 1e-6: t is written with ~17 digits; a different rate differs by far more.
  constexpr double kRateRelTolerance = 1e-6;
  if (!(std::abs(fs - design.sample_rate_hz) <= kRateRelTolerance * design.sample_rate_hz))
    throw InputError(fmt::format("{}: sampled at {} Hz but the excitation design says {} Hz; use the file made for "
                                 "this rate (lpvid excite --rate-hz)",
                                 where, fs, design.sample_rate_hz));
  if (channels != design.channels)
    throw InputError(fmt::format("{}: {} excitation columns but the excitation design has {} channels; check the file",
                                 where, channels, design.channels));
  if (design.periodic() && rows != design.total_samples())
    throw InputError(fmt::format("{}: {} samples but the excitation design describes {} (R {} x E {} x (T {} + P {}) "
                                 "x L {}); the file was cut or edited: write it again with lpvid excite",
                                 where, rows, design.total_samples(), design.realisations, design.experiments,
                                 design.transient_periods, design.periods, design.period_samples));
}

}  // namespace lpvid
