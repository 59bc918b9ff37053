#include "formats/io/frd_csv.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>
#include <string_view>

#include "formats/io/csv_detail.h"
#include "formats/io/frd_detail.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace frd_detail {

bool quantity_allowed(std::string_view q) {
  if (q.empty() || q == "coh" || q == "var") return false;
  return std::all_of(q.begin(), q.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
  });
}

double omega_from_hz(double hz) { return hz * kTwoPi; }

double hz_from_omega(double omega) {
  const double guess = omega / kTwoPi;
  if (omega_from_hz(guess) == omega) return guess;
  // Multiplying by 2*pi (between 4 and 8) skips some doubles, so not every omega
  // has an exact preimage; when one exists it is within a few ulps of the guess.
  constexpr int kUlpsSearched = 4;
  double below = guess, above = guess;
  for (int k = 0; k < kUlpsSearched; ++k) {
    below = std::nextafter(below, 0.0);
    above = std::nextafter(above, INFINITY);
    if (omega_from_hz(below) == omega) return below;
    if (omega_from_hz(above) == omega) return above;
  }
  return guess;
}

}  // namespace frd_detail

namespace {

using frd_detail::kTwoPi;

using detail::is_blank;

std::string_view trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && is_blank(s[b])) ++b;
  while (e > b && is_blank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

bool all_digits(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// Names listed in "# outputs: ..." / "# inputs: ..." metadata.
struct AxisMeta {
  bool given = false;
  std::vector<std::string> names;
  int64_t line = 0;
};

// Splits "<out>_<in>" at the one '_' where the left part is an output and the
// right part an input: a listed name when the axis has metadata, else a token
// without '_'.  Returns the number of valid splits (0, 1 or 2 = "two or more")
// and the first one (and the second in *other).
int split_pair(std::string_view rest, const AxisMeta& outs, const AxisMeta& ins,
               std::pair<std::string, std::string>* first, std::pair<std::string, std::string>* other) {
  int found = 0;
  for (size_t k = rest.find('_'); k != std::string_view::npos; k = rest.find('_', k + 1)) {
    const std::string_view left = rest.substr(0, k), right = rest.substr(k + 1);
    auto ok = [](std::string_view token, const AxisMeta& meta) {
      if (meta.given) return std::find(meta.names.begin(), meta.names.end(), token) != meta.names.end();
      return !token.empty() && token.find('_') == std::string_view::npos;
    };
    if (!ok(left, outs) || !ok(right, ins)) continue;
    std::pair<std::string, std::string> split{std::string(left), std::string(right)};
    if (found == 0) *first = std::move(split);
    else if (found == 1 && other != nullptr) *other = std::move(split);
    if (++found == 2) break;
  }
  return found;
}

enum Part { kRe = 0, kIm, kDb, kDeg, kParts };
constexpr std::array<const char*, kParts> kSuffix = {"re", "im", "db", "deg"};

struct Slot {
  std::array<Index, kParts> col{-1, -1, -1, -1};  // csv column of each part
  Index coh = -1;
  Index var = -1;
  Index dvar = -1;
};

// Which column kind an extra per-pair column is.
enum class Extra { kNone, kCoherence, kVariance, kDistortion };

struct Axis {
  bool indexed = true;
  std::vector<std::string> names;  // when named
  Index size = 0;
};

class FrdCsvReader {
 public:
  FrdCsvReader(const std::string& path, const FrdReadOptions& options, const std::string* text = nullptr)
      : path_(path), options_(options), text_(text) {}

  FrdPart read(bool allow_missing_pairs) {
    options_.validate();
    const std::string hint =
        "the header must name 'freq_hz' (Hz) and the response columns, e.g. 'freq_hz,S_1_1_re,S_1_1_im' (see "
        "docs/formats.md)";
    csv_ = text_ != nullptr ? detail::read_numeric_csv_text(*text_, path_, "freq_hz", hint)
                            : detail::read_numeric_csv(path_, "freq_hz", hint);
    parse_metadata();
    classify_columns();
    resolve_axes();
    fill_slots();
    FrdPart part;
    part.path = path_;
    part.quantity = quantity_;
    check_slots(allow_missing_pairs, part.pairs);
    part.frd = build(part.pairs);
    return part;
  }

 private:
  struct ResponseColumn {
    Index column;
    Part part;
    Extra extra;  // kNone: a response part
    std::string out, in;
  };

  [[noreturn]] void fail_header(Index column, const std::string& what) const {
    detail::fail_at(path_, csv_.header_line, csv_.name_columns[static_cast<size_t>(column)], what);
  }

  void parse_metadata() {
    for (const auto& comment : csv_.leading_comments) {
      const size_t colon = comment.text.find(':');
      if (colon == std::string::npos) continue;
      const std::string_view key = trim(std::string_view(comment.text).substr(0, colon));
      if (key == "averages") {
        parse_averages(comment, colon);
        continue;
      }
      if (key == "sample_rate_hz") {
        parse_sample_rate(comment, colon);
        continue;
      }
      AxisMeta* meta = key == "outputs" ? &outs_meta_ : key == "inputs" ? &ins_meta_ : nullptr;
      if (meta == nullptr) continue;
      const int64_t key_column = comment.column + static_cast<int64_t>(comment.text.find_first_not_of(" \t"));
      if (meta->given)
        detail::fail_at(path_, comment.line, key_column,
                        fmt::format("'{}' is given twice (also on line {}); give it once", key, meta->line));
      meta->given = true;
      meta->line = comment.line;
      const std::string_view value = std::string_view(comment.text).substr(colon + 1);
      size_t start = 0;
      for (;;) {
        const size_t comma = value.find(',', start);
        const size_t end = comma == std::string_view::npos ? value.size() : comma;
        const std::string_view raw = value.substr(start, end - start);
        const std::string_view name = trim(raw);
        const int64_t column = comment.column + static_cast<int64_t>(colon + 1 + start) +
                               static_cast<int64_t>(raw.find_first_not_of(" \t") == std::string_view::npos
                                                        ? 0
                                                        : raw.find_first_not_of(" \t"));
        if (name.empty())
          detail::fail_at(path_, comment.line, column,
                          fmt::format("empty name in '{}'; list the names separated by commas, e.g. {}", key,
                                      key == "outputs" ? "psi,theta" : "u1,u2"));
        if (!valid_utf8(name))
          detail::fail_at(path_, comment.line, column,
                          fmt::format("name {} in '{}' is not valid UTF-8; save the file as UTF-8",
                                      detail::quote_cell(name), key));
        if (meta->names.size() == static_cast<size_t>(frd_detail::kMaxChannels))
          detail::fail_at(path_, comment.line, column,
                          fmt::format("'{}' lists more than {} names; lpvid reads responses of at most {} outputs and "
                                      "inputs: split the file",
                                      key, frd_detail::kMaxChannels, frd_detail::kMaxChannels));
        if (std::find(meta->names.begin(), meta->names.end(), name) != meta->names.end())
          detail::fail_at(path_, comment.line, column,
                          fmt::format("name '{}' appears twice in '{}'; give every channel its own name", name, key));
        meta->names.emplace_back(name);
        if (comma == std::string_view::npos) break;
        start = comma + 1;
      }
    }
  }

  // "# averages: K": the independent averages behind the coherence, a number >= 1.
  template <class Comment>
  void parse_averages(const Comment& comment, size_t colon) {
    const int64_t key_column = comment.column + static_cast<int64_t>(comment.text.find_first_not_of(" \t"));
    if (averages_line_ > 0)
      detail::fail_at(path_, comment.line, key_column,
                      fmt::format("'averages' is given twice (also on line {}); give it once", averages_line_));
    averages_line_ = comment.line;
    const std::string value(trim(std::string_view(comment.text).substr(colon + 1)));
    char* end = nullptr;
    const double v = value.empty() ? NAN : std::strtod(value.c_str(), &end);
    if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v) || v < 1 || v > 1e9)
      detail::fail_at(path_, comment.line, key_column,
                      fmt::format("'averages: {}' is not a number of averages; give the independent averages behind "
                                  "the coherence as a number >= 1, e.g. '# averages: 16'",
                                  value));
    averages_ = v;
  }

  // "# sample_rate_hz: X": the rate of the log the response was estimated from, > 0.
  template <class Comment>
  void parse_sample_rate(const Comment& comment, size_t colon) {
    const int64_t key_column = comment.column + static_cast<int64_t>(comment.text.find_first_not_of(" \t"));
    if (sample_rate_line_ > 0)
      detail::fail_at(path_, comment.line, key_column,
                      fmt::format("'sample_rate_hz' is given twice (also on line {}); give it once", sample_rate_line_));
    sample_rate_line_ = comment.line;
    const std::string_view raw = std::string_view(comment.text).substr(colon + 1);
    const std::string value(trim(raw));
    const int64_t value_column = comment.column + static_cast<int64_t>(colon + 1) +
                                 static_cast<int64_t>(value.empty() ? 0 : raw.find_first_not_of(" \t"));
    char* end = nullptr;
    const double v = value.empty() ? NAN : std::strtod(value.c_str(), &end);
    if (value.empty() || end != value.c_str() + value.size() || !std::isfinite(v) || !(v > 0) ||
        v > frd_detail::kMaxSampleRateHz)
      detail::fail_at(path_, comment.line, value_column,
                      fmt::format("'sample_rate_hz: {}' is not a sample rate; give the rate in Hz of the log the "
                                  "response was estimated from, a number > 0 (at most {:g}), e.g. "
                                  "'# sample_rate_hz: 1000', or delete the line if it is not known",
                                  value, frd_detail::kMaxSampleRateHz));
    sample_rate_hz_ = v;
  }

  std::string metadata_hint() const {
    auto list = [](const AxisMeta& m) {
      return m.given ? fmt::format("{}", fmt::join(m.names, ",")) : std::string("<names without '_' or indices>");
    };
    return fmt::format("outputs {}; inputs {}", list(outs_meta_), list(ins_meta_));
  }

  void classify_columns() {
    const auto& names = csv_.names;
    Index first_quantity_column = -1;
    for (size_t c = 0; c < names.size(); ++c) {
      const Index column = static_cast<Index>(c);
      if (column == csv_.key) continue;
      const std::string& name = names[c];
      if (name == "flag") {
        flag_ = column;
        continue;
      }
      std::string_view rest;
      Part part = kRe;
      Extra extra = Extra::kNone;
      if (name.rfind("coh_", 0) == 0) {
        extra = Extra::kCoherence;
        rest = std::string_view(name).substr(4);
      } else if (name.rfind("var_", 0) == 0) {
        extra = Extra::kVariance;
        rest = std::string_view(name).substr(4);
      } else if (name.rfind("dvar_", 0) == 0) {
        extra = Extra::kDistortion;
        rest = std::string_view(name).substr(5);
      } else {
        const size_t last = name.rfind('_');
        const size_t first = name.find('_');
        const std::string_view suffix = last == std::string::npos ? std::string_view() : std::string_view(name).substr(last + 1);
        const auto it = std::find(kSuffix.begin(), kSuffix.end(), suffix);
        if (it == kSuffix.end() || first == last || !frd_detail::quantity_allowed(std::string_view(name).substr(0, first)))
          fail_header(column, fmt::format("column '{}' is not an FRD column; the columns are freq_hz, "
                                          "<Q>_<output>_<input>_re and _im (or _db and _deg), coh_<output>_<input>, "
                                          "var_<output>_<input>, dvar_<output>_<input> and flag, with <Q> letters and digits (S, P, G, ...): rename or remove the column",
                                          name));
        part = static_cast<Part>(it - kSuffix.begin());
        const std::string quantity = name.substr(0, first);
        if (!options_.quantity.empty()) {
          if (quantity != options_.quantity) {
            if (std::find(other_quantities_.begin(), other_quantities_.end(), quantity) == other_quantities_.end())
              other_quantities_.push_back(quantity);
            continue;
          }
        } else if (quantity_.empty()) {
          quantity_ = quantity;
          first_quantity_column = column;
        } else if (quantity != quantity_) {
          fail_header(column, fmt::format("column '{}' holds quantity '{}' but column '{}' holds '{}'; a file holds "
                                          "one quantity, or choose one with the quantity option",
                                          name, quantity, names[static_cast<size_t>(first_quantity_column)],
                                          quantity_));
        }
        rest = std::string_view(name).substr(first + 1, last - first - 1);
      }
      std::pair<std::string, std::string> split, other;
      const int count = split_pair(rest, outs_meta_, ins_meta_, &split, &other);
      if (count == 0) {
        if (!outs_meta_.given && !ins_meta_.given)
          fail_header(column, fmt::format("cannot split '{}' of column '{}' into an output and an input; without "
                                          "'# outputs:' and '# inputs:' metadata a channel is an index or a name "
                                          "without '_', so write <output>_<input> with one '_' or list the names in "
                                          "'# outputs: ...' and '# inputs: ...' lines before the header",
                                          rest, name));
        fail_header(column, fmt::format("cannot split '{}' of column '{}' into a listed output and input ({}); "
                                        "check the names against the '# outputs:' and '# inputs:' lines",
                                        rest, name, metadata_hint()));
      }
      if (count > 1)
        fail_header(column, fmt::format("column '{}' splits two ways (output '{}', input '{}' or output '{}', input "
                                        "'{}'); rename the channels so that <output>_<input> splits one way",
                                        name, split.first, split.second, other.first, other.second));
      columns_.push_back({column, part, extra, std::move(split.first), std::move(split.second)});
    }
    if (!options_.quantity.empty()) quantity_ = options_.quantity;
    const bool any_response =
        std::any_of(columns_.begin(), columns_.end(), [](const auto& c) { return c.extra == Extra::kNone; });
    if (!any_response) {
      if (!other_quantities_.empty())
        detail::fail_at(path_, csv_.header_line, 1,
                        fmt::format("no columns of quantity '{}'; the file holds {}; choose one of them", quantity_,
                                    fmt::join(other_quantities_, ", ")));
      detail::fail_at(path_, csv_.header_line, 1,
                      "no response columns; add <Q>_<output>_<input>_re and _im (or _db and _deg) columns, e.g. "
                      "'S_1_1_re,S_1_1_im'");
    }
  }

  // Index of token on an axis (0-based), or -1 if the axis does not have it.
  Index find(const Axis& axis, const std::string& token) const {
    if (axis.indexed) {
      constexpr size_t kMaxIndexDigits = 5;  // as in resolve_axis
      if (token.size() > kMaxIndexDigits) return -1;
      const Index i = std::stol(token) - 1;
      return i >= 0 && i < axis.size ? i : -1;
    }
    const auto it = std::find(axis.names.begin(), axis.names.end(), token);
    return it == axis.names.end() ? -1 : it - axis.names.begin();
  }

  void resolve_axis(Axis& axis, const AxisMeta& meta, bool outputs) {
    const char* what = outputs ? "output" : "input";
    if (meta.given) {
      axis.indexed = false;
      axis.names = meta.names;
      axis.size = static_cast<Index>(axis.names.size());
      return;
    }
    const ResponseColumn* first = nullptr;
    for (const ResponseColumn& c : columns_) {
      if (c.extra != Extra::kNone) continue;
      const std::string& token = outputs ? c.out : c.in;
      if (first == nullptr) {
        first = &c;
        axis.indexed = all_digits(token);
      }
      if (all_digits(token) != axis.indexed) {
        const std::string& first_token = outputs ? first->out : first->in;
        fail_header(c.column,
                    fmt::format("column '{}' names {} {}'{}' but column '{}' names {} {}'{}'; name all {}s by index "
                                "or all by name",
                                csv_.names[static_cast<size_t>(c.column)], what, axis.indexed ? "" : "index ", token,
                                csv_.names[static_cast<size_t>(first->column)], what, axis.indexed ? "index " : "",
                                first_token, what));
      }
      if (axis.indexed) {
        // Indices beyond this are surely typos (and would allocate huge responses).
        constexpr size_t kMaxIndexDigits = 5;
        const long index = token.size() > kMaxIndexDigits ? 0 : std::stol(token);
        if (index < 1 || index > frd_detail::kMaxChannels)
          fail_header(c.column, fmt::format("{} index '{}' in column '{}' is not allowed; give an index from 1 to "
                                            "{}",
                                            what, token, csv_.names[static_cast<size_t>(c.column)],
                                            frd_detail::kMaxChannels));
        axis.size = std::max<Index>(axis.size, index);
      } else if (std::find(axis.names.begin(), axis.names.end(), token) == axis.names.end()) {
        if (!valid_utf8(token))
          fail_header(c.column, fmt::format("{} name {} in column '{}' is not valid UTF-8; save the file as UTF-8",
                                            what, detail::quote_cell(token), csv_.names[static_cast<size_t>(c.column)]));
        if (static_cast<Index>(axis.names.size()) == frd_detail::kMaxChannels)
          fail_header(c.column, fmt::format("column '{}' names a {} beyond the first {}; lpvid reads responses of at "
                                            "most {} outputs and inputs: split the file",
                                            csv_.names[static_cast<size_t>(c.column)], what, frd_detail::kMaxChannels,
                                            frd_detail::kMaxChannels));
        axis.names.push_back(token);
        axis.size = static_cast<Index>(axis.names.size());
      }
    }
  }

  void resolve_axes() {
    resolve_axis(outs_, outs_meta_, true);
    resolve_axis(ins_, ins_meta_, false);
  }

  std::string token(const Axis& axis, Index k) const {
    return axis.indexed ? std::to_string(k + 1) : axis.names[static_cast<size_t>(k)];
  }
  std::string label(Index i, Index j) const {
    if (outs_.indexed && ins_.indexed) return fmt::format("output {}, input {}", i + 1, j + 1);
    auto one = [&](const Axis& axis, Index k, const char* what) {
      return axis.indexed ? fmt::format("{} {}", what, k + 1) : fmt::format("{} '{}'", what, axis.names[static_cast<size_t>(k)]);
    };
    return one(outs_, i, "output") + ", " + one(ins_, j, "input");
  }
  std::string column_name(Index i, Index j, Part part) const {
    return fmt::format("{}_{}_{}_{}", quantity_, token(outs_, i), token(ins_, j), kSuffix[part]);
  }
  const std::string& name_of(Index column) const { return csv_.names[static_cast<size_t>(column)]; }

  void fill_slots() {
    slots_.assign(static_cast<size_t>(outs_.size * ins_.size), Slot{});
    for (const ResponseColumn& c : columns_) {
      Index i = -1, j = -1;
      if (c.extra != Extra::kNone) {
        const bool out_ok = outs_.indexed == all_digits(c.out) && (i = find(outs_, c.out)) >= 0;
        const bool in_ok = ins_.indexed == all_digits(c.in) && (j = find(ins_, c.in)) >= 0;
        if (!out_ok || !in_ok)
          fail_header(c.column, fmt::format("column '{}' is the {} of output {}, input {}, which have no "
                                            "response columns; give {} only for pairs with a response",
                                            name_of(c.column), extra_words(c.extra), shown_token(c.out),
                                            shown_token(c.in), extra_words(c.extra)));
      } else {
        i = find(outs_, c.out);
        j = find(ins_, c.in);
      }
      Slot& slot = slots_[static_cast<size_t>(i * ins_.size + j)];
      Index& at = c.extra == Extra::kCoherence    ? slot.coh
                  : c.extra == Extra::kVariance   ? slot.var
                  : c.extra == Extra::kDistortion ? slot.dvar
                                                  : slot.col[c.part];
      if (at >= 0)
        fail_header(c.column, fmt::format("column '{}' repeats column {} '{}' ({} of {}); give each column once",
                                          name_of(c.column), at + 1, name_of(at),
                                          c.extra != Extra::kNone ? extra_words(c.extra) : part_words(c.part),
                                          label(i, j)));
      at = c.column;
    }
  }

  static std::string shown_token(const std::string& token) {
    return all_digits(token) ? token : "'" + token + "'";
  }

  static const char* extra_words(Extra extra) {
    return extra == Extra::kCoherence ? "coherence" : extra == Extra::kVariance ? "variance" : "distortion variance";
  }

  static const char* part_words(Part part) {
    switch (part) {
      case kRe: return "real part";
      case kIm: return "imaginary part";
      case kDb: return "magnitude in dB";
      case kDeg: return "phase in degrees";
      default: return "";
    }
  }

  void check_slots(bool allow_missing_pairs, std::vector<std::pair<Index, Index>>& pairs) {
    const bool any_coherence = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.coh >= 0; });
    const bool any_variance = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.var >= 0; });
    const bool any_distortion = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.dvar >= 0; });
    Index first_coh = -1, first_var = -1, first_dvar = -1;
    for (const Slot& s : slots_) {
      if (s.coh >= 0 && (first_coh < 0 || s.coh < first_coh)) first_coh = s.coh;
      if (s.var >= 0 && (first_var < 0 || s.var < first_var)) first_var = s.var;
      if (s.dvar >= 0 && (first_dvar < 0 || s.dvar < first_dvar)) first_dvar = s.dvar;
    }
    for (Index i = 0; i < outs_.size; ++i)
      for (Index j = 0; j < ins_.size; ++j) {
        const Slot& s = slots_[static_cast<size_t>(i * ins_.size + j)];
        const bool cartesian = s.col[kRe] >= 0 || s.col[kIm] >= 0;
        const bool polar = s.col[kDb] >= 0 || s.col[kDeg] >= 0;
        const std::string both = fmt::format("give both '{}' and '{}', or '{}' and '{}'", column_name(i, j, kRe),
                                             column_name(i, j, kIm), column_name(i, j, kDb), column_name(i, j, kDeg));
        if (!cartesian && !polar) {
          if (s.coh >= 0)
            fail_header(s.coh, fmt::format("column '{}' is the coherence of {}, which has no response columns; "
                                           "give coherence only for pairs with a response",
                                           name_of(s.coh), label(i, j)));
          if (s.var >= 0)
            fail_header(s.var, fmt::format("column '{}' is the variance of {}, which has no response columns; "
                                           "give variance only for pairs with a response",
                                           name_of(s.var), label(i, j)));
          if (s.dvar >= 0)
            fail_header(s.dvar, fmt::format("column '{}' is the distortion variance of {}, which has no response "
                                            "columns; give it only for pairs with a response",
                                            name_of(s.dvar), label(i, j)));
          if (allow_missing_pairs) continue;
          detail::fail_at(path_, csv_.header_line, 1,
                          fmt::format("no columns for {}; every output/input pair needs a response: {}", label(i, j),
                                      both));
        }
        if (cartesian && polar) {
          const Index a = s.col[kRe] >= 0 ? s.col[kRe] : s.col[kIm];
          const Index b = s.col[kDb] >= 0 ? s.col[kDb] : s.col[kDeg];
          fail_header(std::max(a, b), fmt::format("columns '{}' and '{}' mix re/im with db/deg for {}; {}", name_of(a),
                                                  name_of(b), label(i, j), both));
        }
        const Part have = cartesian ? (s.col[kRe] >= 0 ? kRe : kIm) : (s.col[kDb] >= 0 ? kDb : kDeg);
        const Part partner = static_cast<Part>(have ^ 1);
        if (s.col[partner] < 0)
          fail_header(s.col[have], fmt::format("no column '{}' for the {} of {} (its {} is column '{}'); {}",
                                               column_name(i, j, partner), part_words(partner), label(i, j),
                                               part_words(have), name_of(s.col[have]), both));
        if (any_coherence && s.coh < 0)
          fail_header(first_coh, fmt::format("no column 'coh_{}_{}' for the coherence of {}; give coherence for "
                                             "every pair or for none",
                                             token(outs_, i), token(ins_, j), label(i, j)));
        if (any_variance && s.var < 0)
          fail_header(first_var, fmt::format("no column 'var_{}_{}' for the variance of {}; give variance for "
                                             "every pair or for none",
                                             token(outs_, i), token(ins_, j), label(i, j)));
        if (any_distortion && s.dvar < 0)
          fail_header(first_dvar, fmt::format("no column 'dvar_{}_{}' for the distortion variance of {}; give it for "
                                              "every pair or for none",
                                              token(outs_, i), token(ins_, j), label(i, j)));
        if (s.dvar >= 0 && s.var < 0)
          fail_header(s.dvar, fmt::format("column '{}' gives a distortion variance but there is no column 'var_{}_{}' "
                                          "for the total variance it is part of; give both",
                                          name_of(s.dvar), token(outs_, i), token(ins_, j)));
        pairs.emplace_back(i, j);
      }
  }

  [[noreturn]] void fail_cell(Index row, Index column, const std::string& what) const {
    const int64_t line = csv_.key_position(row).line;
    detail::fail_at(path_, line, detail::cell_column(path_, text_, line, column), what);
  }

  FrequencyResponse build(const std::vector<std::pair<Index, Index>>& pairs) const {
    const Index nf = csv_.data.rows();
    if (nf == 0)
      detail::fail_at(path_, csv_.end_line, 1, "no rows after the header; give one row per frequency");
    const auto f = csv_.data.col(csv_.key);
    for (Index k = 0; k < nf; ++k) {
      if (!(f[k] > 0)) {
        const detail::CellPosition at = csv_.key_position(k);
        detail::fail_at(path_, at.line, at.column,
                        fmt::format("frequency {} Hz is not positive; give freq_hz > 0 in Hz", f[k]));
      }
      if (k > 0 && !(f[k] > f[k - 1])) {
        const detail::CellPosition at = csv_.key_position(k);
        detail::fail_at(path_, at.line, at.column,
                        fmt::format("frequency {} Hz is not above the previous row's {} Hz; freq_hz must increase "
                                    "strictly from row to row",
                                    f[k], f[k - 1]));
      }
    }
    if (nf > frd_detail::kMaxEntries / std::max<Index>(1, outs_.size * ins_.size))
      detail::fail_at(path_, csv_.header_line, 1,
                      fmt::format("{} frequencies of a {}×{} response are more than the {} entries lpvid reads; split "
                                  "the file or use fewer frequencies",
                                  nf, outs_.size, ins_.size, frd_detail::kMaxEntries));
    FrequencyResponse frd;
    frd.omega_rad_s.resize(nf);
    for (Index k = 0; k < nf; ++k) frd.omega_rad_s[k] = frd_detail::omega_from_hz(f[k]);
    frd.response.assign(static_cast<size_t>(nf), Eigen::MatrixXcd::Zero(outs_.size, ins_.size));
    const bool any_coherence = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.coh >= 0; });
    if (any_coherence) frd.coherence.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs_.size, ins_.size));
    const bool any_variance = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.var >= 0; });
    if (any_variance) frd.variance.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs_.size, ins_.size));
    const bool any_distortion = std::any_of(slots_.begin(), slots_.end(), [](const Slot& s) { return s.dvar >= 0; });
    if (any_distortion)
      frd.distortion_variance.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs_.size, ins_.size));
    frd.averages = averages_;
    frd.sample_rate_hz = sample_rate_hz_;
    for (const auto& [i, j] : pairs) {
      const Slot& s = slots_[static_cast<size_t>(i * ins_.size + j)];
      for (Index k = 0; k < nf; ++k) {
        Complex h;
        if (s.col[kRe] >= 0) {
          h = Complex(csv_.data(k, s.col[kRe]), csv_.data(k, s.col[kIm]));
        } else {
          const double magnitude = std::pow(10.0, csv_.data(k, s.col[kDb]) / 20.0);
          h = std::polar(magnitude, csv_.data(k, s.col[kDeg]) * (std::numbers::pi / 180.0));
        }
        frd.response[static_cast<size_t>(k)](i, j) = h;
        if (s.coh >= 0) {
          const double c = csv_.data(k, s.coh);
          if (!(c >= 0 && c <= 1))
            fail_cell(k, s.coh, fmt::format("coherence {} in column '{}' is outside [0, 1]; write a coherence "
                                            "between 0 and 1",
                                            c, name_of(s.coh)));
          frd.coherence[static_cast<size_t>(k)](i, j) = c;
        }
        if (s.var >= 0) {
          const double v = csv_.data(k, s.var);
          if (!(v >= 0))
            fail_cell(k, s.var, fmt::format("variance {} in column '{}' is negative; write a variance >= 0", v,
                                            name_of(s.var)));
          frd.variance[static_cast<size_t>(k)](i, j) = v;
        }
        if (s.dvar >= 0) {
          const double v = csv_.data(k, s.dvar);
          if (!(v >= 0))
            fail_cell(k, s.dvar, fmt::format("distortion variance {} in column '{}' is negative; write a variance >= 0",
                                             v, name_of(s.dvar)));
          if (v > csv_.data(k, s.var) * (1 + 1e-12))
            fail_cell(k, s.dvar, fmt::format("distortion variance {} in column '{}' exceeds the total variance {} in "
                                             "column '{}'; the total (var_) includes the distortion part",
                                             v, name_of(s.dvar), csv_.data(k, s.var), name_of(s.var)));
          frd.distortion_variance[static_cast<size_t>(k)](i, j) = v;
        }
      }
    }
    if (flag_ >= 0) {
      frd.flagged.resize(static_cast<size_t>(nf));
      for (Index k = 0; k < nf; ++k) {
        const double v = csv_.data(k, flag_);
        if (v != 0 && v != 1)
          fail_cell(k, flag_, fmt::format("flag {} is not 0 or 1; write 1 for an untrusted frequency, else 0", v));
        frd.flagged[static_cast<size_t>(k)] = v == 1;
      }
    }
    if (!outs_.indexed) frd.output_names = outs_.names;
    if (!ins_.indexed) frd.input_names = ins_.names;
    return frd;
  }

  const std::string& path_;
  const FrdReadOptions& options_;
  const std::string* text_;
  detail::NumericCsv csv_;
  AxisMeta outs_meta_, ins_meta_;
  std::vector<ResponseColumn> columns_;
  std::vector<std::string> other_quantities_;
  std::string quantity_;
  Index flag_ = -1;
  double averages_ = 0;
  int64_t averages_line_ = 0;
  double sample_rate_hz_ = 0;
  int64_t sample_rate_line_ = 0;
  Axis outs_, ins_;
  std::vector<Slot> slots_;
};

// ---- writing ---------------------------------------------------------------

void check_channel_names(const std::string& path, const std::vector<std::string>& names, Index count,
                         const char* what) {
  if (names.empty()) return;
  if (static_cast<Index>(names.size()) != count)
    throw InputError(fmt::format("cannot write '{}': {} {} names for {} {}s; give one name per {} or none", path,
                                 names.size(), what, count, what, what));
  for (size_t k = 0; k < names.size(); ++k) {
    const std::string& name = names[k];
    if (name.empty() || name.find_first_of(",\"\r\n \t") != std::string::npos)
      throw InputError(fmt::format("cannot write '{}': {} name {} is not allowed; use names without commas, quotes, "
                                   "blanks or line breaks",
                                   path, what, detail::quote_cell(name)));
    if (std::find(names.begin(), names.begin() + static_cast<std::ptrdiff_t>(k), name) !=
        names.begin() + static_cast<std::ptrdiff_t>(k))
      throw InputError(fmt::format("cannot write '{}': {} name '{}' appears twice; give every channel its own name",
                                   path, what, name));
  }
}

}  // namespace

void FrdReadOptions::validate() const {
  if (!quantity.empty() && !frd_detail::quantity_allowed(quantity))
    throw InputError(fmt::format("quantity {} is not allowed; use letters and digits (not 'coh'), e.g. S",
                                 detail::quote_cell(quantity)));
}

void FrdMergeOptions::validate() const {
  if (!std::isfinite(frequency_tolerance) || frequency_tolerance < 0)
    throw InputError(fmt::format("frequency tolerance {} is not allowed; give a finite relative tolerance >= 0, e.g. "
                                 "1e-9",
                                 frequency_tolerance));
}

namespace frd_detail {

void check_frd_for_writing(const std::string& path, const FrequencyResponse& frd) {
  const Index nf = frd.num_frequencies();
  if (nf == 0) throw InputError(fmt::format("cannot write '{}': no frequencies; give at least one", path));
  if (static_cast<Index>(frd.response.size()) != nf)
    throw InputError(fmt::format("cannot write '{}': {} response matrices for {} frequencies; give one per frequency",
                                 path, frd.response.size(), nf));
  const Index ny = frd.num_outputs(), nu = frd.num_inputs();
  if (ny == 0 || nu == 0)
    throw InputError(fmt::format("cannot write '{}': the response is {}×{}; it needs at least one output and one input",
                                 path, ny, nu));
  for (Index k = 0; k < nf; ++k) {
    const double w = frd.omega_rad_s[k];
    if (!std::isfinite(w) || !(w > 0) || (k > 0 && !(w > frd.omega_rad_s[k - 1])))
      throw InputError(fmt::format("cannot write '{}': frequency {} is {} rad/s; frequencies must be finite, positive "
                                   "and strictly increasing",
                                   path, k + 1, w));
    const Eigen::MatrixXcd& h = frd.response[static_cast<size_t>(k)];
    if (h.rows() != ny || h.cols() != nu)
      throw InputError(fmt::format("cannot write '{}': response {} is {}×{}, expected {}×{} (outputs × inputs)", path,
                                   k + 1, h.rows(), h.cols(), ny, nu));
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j)
        if (!std::isfinite(h(i, j).real()) || !std::isfinite(h(i, j).imag()))
          throw InputError(fmt::format("cannot write '{}': response {} ({}, {}) is ({},{}); only finite values can be "
                                       "written",
                                       path, k + 1, i + 1, j + 1, h(i, j).real(), h(i, j).imag()));
  }
  if (!frd.coherence.empty()) {
    if (static_cast<Index>(frd.coherence.size()) != nf)
      throw InputError(fmt::format("cannot write '{}': {} coherence matrices for {} frequencies; give one per "
                                   "frequency or none",
                                   path, frd.coherence.size(), nf));
    for (Index k = 0; k < nf; ++k) {
      const Eigen::MatrixXd& c = frd.coherence[static_cast<size_t>(k)];
      if (c.rows() != ny || c.cols() != nu)
        throw InputError(fmt::format("cannot write '{}': coherence {} is {}×{}, expected {}×{} (outputs × inputs)",
                                     path, k + 1, c.rows(), c.cols(), ny, nu));
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j)
          if (!(c(i, j) >= 0 && c(i, j) <= 1))
            throw InputError(fmt::format("cannot write '{}': coherence {} ({}, {}) is {}; coherence must be in [0, 1]",
                                         path, k + 1, i + 1, j + 1, c(i, j)));
    }
  }
  if (!frd.variance.empty()) {
    if (static_cast<Index>(frd.variance.size()) != nf)
      throw InputError(fmt::format("cannot write '{}': {} variance matrices for {} frequencies; give one per "
                                   "frequency or none",
                                   path, frd.variance.size(), nf));
    for (Index k = 0; k < nf; ++k) {
      const Eigen::MatrixXd& v = frd.variance[static_cast<size_t>(k)];
      if (v.rows() != ny || v.cols() != nu)
        throw InputError(fmt::format("cannot write '{}': variance {} is {}×{}, expected {}×{} (outputs × inputs)",
                                     path, k + 1, v.rows(), v.cols(), ny, nu));
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j)
          if (!(v(i, j) >= 0) || !std::isfinite(v(i, j)))
            throw InputError(fmt::format("cannot write '{}': variance {} ({}, {}) is {}; a variance is finite and >= 0",
                                         path, k + 1, i + 1, j + 1, v(i, j)));
    }
  }
  if (!frd.distortion_variance.empty()) {
    if (frd.variance.empty())
      throw InputError(fmt::format("cannot write '{}': a distortion variance without the total variance", path));
    if (static_cast<Index>(frd.distortion_variance.size()) != nf)
      throw InputError(fmt::format("cannot write '{}': {} distortion variance matrices for {} frequencies; give one "
                                   "per frequency or none",
                                   path, frd.distortion_variance.size(), nf));
    for (Index k = 0; k < nf; ++k) {
      const Eigen::MatrixXd& v = frd.distortion_variance[static_cast<size_t>(k)];
      if (v.rows() != ny || v.cols() != nu)
        throw InputError(fmt::format("cannot write '{}': distortion variance {} is {}×{}, expected {}×{} (outputs × "
                                     "inputs)",
                                     path, k + 1, v.rows(), v.cols(), ny, nu));
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j)
          if (!(v(i, j) >= 0) || !std::isfinite(v(i, j)) || v(i, j) > frd.variance[static_cast<size_t>(k)](i, j))
            throw InputError(fmt::format("cannot write '{}': distortion variance {} ({}, {}) is {}; it is finite, >= 0 "
                                         "and at most the total variance",
                                         path, k + 1, i + 1, j + 1, v(i, j)));
    }
  }
  if (!(frd.averages == 0 || (frd.averages >= 1 && std::isfinite(frd.averages))))
    throw InputError(fmt::format("cannot write '{}': averages {} is not 0 (unknown) or a number >= 1", path,
                                 frd.averages));
  if (!(frd.sample_rate_hz == 0 ||
        (frd.sample_rate_hz > 0 && frd.sample_rate_hz <= kMaxSampleRateHz && std::isfinite(frd.sample_rate_hz))))
    throw InputError(fmt::format("cannot write '{}': sample rate {} Hz is not 0 (not recorded) or a number in (0, {:g}]",
                                 path, frd.sample_rate_hz, kMaxSampleRateHz));
  if (!frd.flagged.empty() && static_cast<Index>(frd.flagged.size()) != nf)
    throw InputError(fmt::format("cannot write '{}': {} flags for {} frequencies; give one per frequency or none", path,
                                 frd.flagged.size(), nf));
  check_channel_names(path, frd.output_names, ny, "output");
  check_channel_names(path, frd.input_names, nu, "input");
}

}  // namespace frd_detail

void write_frd_csv(AtomicFileWriter& out, const FrequencyResponse& frd, const std::string& quantity,
                   const std::vector<std::string>& comments) {
  const std::string path = detail::display_path(out.path());
  if (!frd_detail::quantity_allowed(quantity))
    throw InputError(fmt::format("cannot write '{}': quantity {} is not allowed; use letters and digits "
                                 "(not 'coh'), e.g. S",
                                 path, detail::quote_cell(quantity)));
  frd_detail::check_frd_for_writing(path, frd);
  for (const std::string& comment : comments) {
    size_t start = 0;
    for (;;) {
      const size_t nl = comment.find('\n', start);
      const std::string_view piece(comment.data() + start, (nl == std::string::npos ? comment.size() : nl) - start);
      const size_t colon = piece.find(':');
      const std::string_view key = colon == std::string_view::npos ? std::string_view() : trim(piece.substr(0, colon));
      if (key == "outputs" || key == "inputs" || key == "averages" || key == "sample_rate_hz")
        throw InputError(fmt::format("cannot write '{}': comment {} would be read as '# {}:' metadata; reword it", path,
                                     detail::quote_cell(piece), key));
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
  const Index nf = frd.num_frequencies(), ny = frd.num_outputs(), nu = frd.num_inputs();
  auto tokens = [](const std::vector<std::string>& names, Index n) {
    std::vector<std::string> out;
    for (Index k = 0; k < n; ++k) out.push_back(names.empty() ? std::to_string(k + 1) : names[static_cast<size_t>(k)]);
    return out;
  };
  const std::vector<std::string> outs = tokens(frd.output_names, ny), ins = tokens(frd.input_names, nu);
  AxisMeta outs_meta{!frd.output_names.empty(), frd.output_names, 0};
  AxisMeta ins_meta{!frd.input_names.empty(), frd.input_names, 0};
  std::vector<std::string> names{"freq_hz"};
  for (Index i = 0; i < ny; ++i)
    for (Index j = 0; j < nu; ++j) {
      const std::string& o = outs[static_cast<size_t>(i)];
      const std::string& n = ins[static_cast<size_t>(j)];
      std::pair<std::string, std::string> split, other;
      if (split_pair(o + "_" + n, outs_meta, ins_meta, &split, &other) != 1)
        throw InputError(fmt::format("cannot write '{}': output '{}' and input '{}' give '{}_{}', which does not "
                                     "split one way into an output and an input; rename the channels",
                                     path, o, n, o, n));
      names.push_back(fmt::format("{}_{}_{}_re", quantity, o, n));
      names.push_back(fmt::format("{}_{}_{}_im", quantity, o, n));
    }
  if (!frd.coherence.empty())
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j)
        names.push_back(fmt::format("coh_{}_{}", outs[static_cast<size_t>(i)], ins[static_cast<size_t>(j)]));
  if (!frd.variance.empty())
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j)
        names.push_back(fmt::format("var_{}_{}", outs[static_cast<size_t>(i)], ins[static_cast<size_t>(j)]));
  if (!frd.distortion_variance.empty())
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j)
        names.push_back(fmt::format("dvar_{}_{}", outs[static_cast<size_t>(i)], ins[static_cast<size_t>(j)]));
  if (!frd.flagged.empty()) names.push_back("flag");
  detail::check_header_names(out.path(), names);

  Eigen::MatrixXd rows(nf, static_cast<Index>(names.size()));
  for (Index k = 0; k < nf; ++k) {
    const auto kk = static_cast<size_t>(k);
    Index c = 0;
    rows(k, c++) = frd_detail::hz_from_omega(frd.omega_rad_s[k]);
    for (Index i = 0; i < ny; ++i)
      for (Index j = 0; j < nu; ++j) {
        rows(k, c++) = frd.response[kk](i, j).real();
        rows(k, c++) = frd.response[kk](i, j).imag();
      }
    if (!frd.coherence.empty())
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j) rows(k, c++) = frd.coherence[kk](i, j);
    if (!frd.variance.empty())
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j) rows(k, c++) = frd.variance[kk](i, j);
    if (!frd.distortion_variance.empty())
      for (Index i = 0; i < ny; ++i)
        for (Index j = 0; j < nu; ++j) rows(k, c++) = frd.distortion_variance[kk](i, j);
    if (!frd.flagged.empty()) rows(k, c++) = frd.flagged[kk] ? 1.0 : 0.0;
  }
  std::string head;
  detail::append_comments(head, comments);
  if (frd.averages > 0) head += fmt::format("# averages: {}\n", frd.averages);
  if (frd.sample_rate_hz > 0) head += fmt::format("# sample_rate_hz: {}\n", frd.sample_rate_hz);
  if (!frd.output_names.empty()) head += fmt::format("# outputs: {}\n", fmt::join(frd.output_names, ","));
  if (!frd.input_names.empty()) head += fmt::format("# inputs: {}\n", fmt::join(frd.input_names, ","));
  head += fmt::format("{}\n", fmt::join(names, ","));
  const int64_t first_data_line = static_cast<int64_t>(std::count(head.begin(), head.end(), '\n')) + 1;
  detail::write_numeric_rows(out, std::move(head), rows, names, first_data_line);
}

void write_frd_csv(const std::string& path, const FrequencyResponse& frd, const std::string& quantity,
                   const std::vector<std::string>& comments) {
  AtomicFileWriter out(path);
  write_frd_csv(out, frd, quantity, comments);
  out.commit();
}

FrdPart read_frd_part(const std::string& path, const FrdReadOptions& options) {
  return FrdCsvReader(path, options).read(true);
}

FrequencyResponse read_frd_csv(const std::string& path, const FrdReadOptions& options) {
  return FrdCsvReader(path, options).read(false).frd;
}

FrequencyResponse parse_frd_csv(const std::string& text, const std::string& path, const FrdReadOptions& options) {
  return FrdCsvReader(path, options, &text).read(false).frd;
}

// ---- merging ---------------------------------------------------------------

FrequencyResponse merge_frd_parts(const std::vector<FrdPart>& parts, const FrdMergeOptions& options) {
  options.validate();
  constexpr const char* kFail = "cannot merge FRD parts";
  if (parts.empty()) throw InputError(fmt::format("{}: no parts; give at least one file", kFail));
  auto shown = [](const FrdPart& p) { return detail::display_path(p.path); };
  const FrdPart& first = parts.front();
  const Index nf = first.frd.num_frequencies();
  for (const FrdPart& p : parts) {
    if (p.quantity != first.quantity)
      throw InputError(fmt::format("{}: '{}' holds quantity '{}' but '{}' holds '{}'; give files of one quantity",
                                   kFail, shown(first), first.quantity, shown(p), p.quantity));
    if (p.frd.num_frequencies() != nf)
      throw InputError(fmt::format("{}: '{}' has {} frequencies but '{}' has {}; give files measured on the same "
                                   "frequency grid",
                                   kFail, shown(first), nf, shown(p), p.frd.num_frequencies()));
    for (Index k = 0; k < nf; ++k) {
      const double a = first.frd.omega_rad_s[k], b = p.frd.omega_rad_s[k];
      if (std::abs(a - b) > options.frequency_tolerance * std::max(std::abs(a), std::abs(b)))
        throw InputError(fmt::format("{}: frequency {} is {} Hz in '{}' but {} Hz in '{}' (relative difference {:.3g}, "
                                     "above the tolerance {}); give files measured on the same frequency grid",
                                     kFail, k + 1, frd_detail::hz_from_omega(a), shown(first),
                                     frd_detail::hz_from_omega(b), shown(p), std::abs(a - b) / std::max(a, b),
                                     options.frequency_tolerance));
    }
    if (p.frd.coherence.empty() != first.frd.coherence.empty()) {
      const FrdPart& with = first.frd.coherence.empty() ? p : first;
      const FrdPart& without = first.frd.coherence.empty() ? first : p;
      throw InputError(fmt::format("{}: '{}' has coherence columns but '{}' has none; give coherence in every file or "
                                   "in none",
                                   kFail, shown(with), shown(without)));
    }
    if (p.frd.variance.empty() != first.frd.variance.empty()) {
      const FrdPart& with = first.frd.variance.empty() ? p : first;
      const FrdPart& without = first.frd.variance.empty() ? first : p;
      throw InputError(fmt::format("{}: '{}' has variance columns but '{}' has none; give variance in every file or "
                                   "in none",
                                   kFail, shown(with), shown(without)));
    }
    if (p.frd.distortion_variance.empty() != first.frd.distortion_variance.empty()) {
      const FrdPart& with = first.frd.distortion_variance.empty() ? p : first;
      const FrdPart& without = first.frd.distortion_variance.empty() ? first : p;
      throw InputError(fmt::format("{}: '{}' has distortion variance (dvar_) columns but '{}' has none; give them in "
                                   "every file or in none",
                                   kFail, shown(with), shown(without)));
    }
    if (p.frd.averages != first.frd.averages)
      throw InputError(fmt::format("{}: '{}' states {} averages but '{}' states {}; give files measured with the "
                                   "same number of averages (0 = not stated)",
                                   kFail, shown(first), first.frd.averages, shown(p), p.frd.averages));
    if (p.frd.sample_rate_hz != first.frd.sample_rate_hz)
      throw InputError(fmt::format("{}: '{}' was estimated from a log sampled at {} Hz but '{}' at {} Hz (0 = not "
                                   "recorded); give files estimated from logs of one sample rate",
                                   kFail, shown(first), first.frd.sample_rate_hz, shown(p), p.frd.sample_rate_hz));
  }
  // Axes: named in all parts (match by name) or indexed in all parts (by index).
  struct MergedAxis {
    bool named = false;
    std::vector<std::string> names;
    Index size = 0;
    std::vector<std::vector<Index>> map;  // per part: part index -> merged index
  };
  auto merge_axis = [&](bool outputs) {
    MergedAxis axis;
    const char* what = outputs ? "output" : "input";
    auto names_of = [&](const FrdPart& p) -> const std::vector<std::string>& {
      return outputs ? p.frd.output_names : p.frd.input_names;
    };
    axis.named = !names_of(first).empty();
    for (const FrdPart& p : parts) {
      const std::vector<std::string>& names = names_of(p);
      if (names.empty() == axis.named)
        throw InputError(fmt::format("{}: '{}' {} its {}s but '{}' {}; name the {}s in every file or in none", kFail,
                                     shown(first), axis.named ? "names" : "indexes", what, shown(p),
                                     axis.named ? "indexes them" : "names them", what));
      const Index n = outputs ? p.frd.num_outputs() : p.frd.num_inputs();
      std::vector<Index> map;
      for (Index k = 0; k < n; ++k) {
        if (!axis.named) {
          map.push_back(k);
          axis.size = std::max(axis.size, k + 1);
          continue;
        }
        const std::string& name = names[static_cast<size_t>(k)];
        auto it = std::find(axis.names.begin(), axis.names.end(), name);
        if (it == axis.names.end()) it = axis.names.insert(axis.names.end(), name);
        map.push_back(it - axis.names.begin());
      }
      axis.map.push_back(std::move(map));
      if (axis.named) axis.size = static_cast<Index>(axis.names.size());
    }
    return axis;
  };
  const MergedAxis outs = merge_axis(true), ins = merge_axis(false);
  auto label = [&](Index i, Index j) {
    auto one = [](const MergedAxis& axis, Index k, const char* what) {
      return axis.named ? fmt::format("{} '{}'", what, axis.names[static_cast<size_t>(k)])
                        : fmt::format("{} {}", what, k + 1);
    };
    return one(outs, i, "output") + ", " + one(ins, j, "input");
  };

  FrequencyResponse merged;
  merged.omega_rad_s = first.frd.omega_rad_s;
  merged.response.assign(static_cast<size_t>(nf), Eigen::MatrixXcd::Zero(outs.size, ins.size));
  if (!first.frd.coherence.empty())
    merged.coherence.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs.size, ins.size));
  if (!first.frd.variance.empty())
    merged.variance.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs.size, ins.size));
  if (!first.frd.distortion_variance.empty())
    merged.distortion_variance.assign(static_cast<size_t>(nf), Eigen::MatrixXd::Zero(outs.size, ins.size));
  merged.averages = first.frd.averages;
  merged.sample_rate_hz = first.frd.sample_rate_hz;
  std::vector<Index> owner(static_cast<size_t>(outs.size * ins.size), -1);
  for (size_t p = 0; p < parts.size(); ++p) {
    const FrdPart& part = parts[p];
    for (const auto& [pi, pj] : part.pairs) {
      LPVID_ASSERT(pi >= 0 && pi < part.frd.num_outputs() && pj >= 0 && pj < part.frd.num_inputs());
      const Index i = outs.map[p][static_cast<size_t>(pi)], j = ins.map[p][static_cast<size_t>(pj)];
      Index& who = owner[static_cast<size_t>(i * ins.size + j)];
      if (who >= 0)
        throw InputError(fmt::format("{}: {} is in both '{}' and '{}'; give every pair in exactly one file", kFail,
                                     label(i, j), shown(parts[static_cast<size_t>(who)]), shown(part)));
      who = static_cast<Index>(p);
      for (Index k = 0; k < nf; ++k) {
        const auto kk = static_cast<size_t>(k);
        merged.response[kk](i, j) = part.frd.response[kk](pi, pj);
        if (!merged.coherence.empty()) merged.coherence[kk](i, j) = part.frd.coherence[kk](pi, pj);
        if (!merged.variance.empty()) merged.variance[kk](i, j) = part.frd.variance[kk](pi, pj);
        if (!merged.distortion_variance.empty())
          merged.distortion_variance[kk](i, j) = part.frd.distortion_variance[kk](pi, pj);
      }
    }
    if (!part.frd.flagged.empty()) {
      if (merged.flagged.empty()) merged.flagged.assign(static_cast<size_t>(nf), false);
      for (size_t k = 0; k < static_cast<size_t>(nf); ++k)
        merged.flagged[k] = merged.flagged[k] || part.frd.flagged[k];
    }
  }
  for (Index i = 0; i < outs.size; ++i)
    for (Index j = 0; j < ins.size; ++j)
      if (owner[static_cast<size_t>(i * ins.size + j)] < 0) {
        std::vector<std::string> paths;
        for (const FrdPart& p : parts) paths.push_back("'" + shown(p) + "'");
        throw InputError(fmt::format("{}: {} is in none of the files {}; give every pair in exactly one file", kFail,
                                     label(i, j), fmt::join(paths, ", ")));
      }
  if (outs.named) merged.output_names = outs.names;
  if (ins.named) merged.input_names = ins.names;
  return merged;
}

}  // namespace lpvid
