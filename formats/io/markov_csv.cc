#include "formats/io/markov_csv.h"

#include <fast_float/fast_float.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "formats/io/csv_detail.h"
#include "formats/io/model_json.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

constexpr const char* kMagic = "lpvid markov 1";

std::string markov_header_name(const std::string& output, const std::string& input) {
  return fmt::format("g_{}_{}", output, input);
}

using detail::is_blank;

// Text with its byte column in the file.
struct Piece {
  std::string_view text;
  int64_t column;
};

Piece trim(Piece piece) {
  std::string_view s = piece.text;
  size_t b = 0, e = s.size();
  while (b < e && is_blank(s[b])) ++b;
  while (e > b && is_blank(s[e - 1])) --e;
  return {s.substr(b, e - b), piece.column + static_cast<int64_t>(b)};
}

std::vector<Piece> split(Piece piece) {
  std::vector<Piece> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = piece.text.find(',', start);
    const size_t end = comma == std::string_view::npos ? piece.text.size() : comma;
    out.push_back(trim({piece.text.substr(start, end - start), piece.column + static_cast<int64_t>(start)}));
    if (comma == std::string_view::npos) return out;
    start = comma + 1;
  }
}

struct Metadata {
  std::optional<Piece> sample_period, inputs, outputs, noise_std, input_rms, output_rms;
  int64_t sample_period_line = 0, inputs_line = 0, outputs_line = 0, noise_line = 0, input_rms_line = 0,
          output_rms_line = 0;
};

class MarkovReader {
 public:
  explicit MarkovReader(const std::string& path) : path_(path) {}

  MarkovFile read() {
    csv_ = detail::read_numeric_csv(path_, "lag", "the header must be 'lag,g_<output>_<input>,...'");
    parse_metadata();
    MarkovFile out;
    out.sample_period_s = number(*meta_.sample_period, meta_.sample_period_line, "sample_period_s");
    if (!(out.sample_period_s > 0))
      detail::fail_at(path_, meta_.sample_period_line, meta_.sample_period->column,
                      fmt::format("sample_period_s is {}; write the positive sample period in seconds",
                                  out.sample_period_s));
    out.inputs = names(*meta_.inputs, meta_.inputs_line, "inputs");
    out.outputs = names(*meta_.outputs, meta_.outputs_line, "outputs");
    const size_t m = out.inputs.size(), p = out.outputs.size();
    if (meta_.noise_std) {
      const std::vector<double> v = numbers(*meta_.noise_std, meta_.noise_line, "noise_std", p * m, true);
      out.noise_std = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          v.data(), static_cast<Index>(p), static_cast<Index>(m));
    }
    if (meta_.input_rms) {
      const std::vector<double> v = numbers(*meta_.input_rms, meta_.input_rms_line, "input_rms", m, true);
      out.input_rms = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Index>(m));
    }
    if (meta_.output_rms) {
      const std::vector<double> v = numbers(*meta_.output_rms, meta_.output_rms_line, "output_rms", p, true);
      out.output_rms = Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Index>(p));
    }
    check_header(out.inputs, out.outputs);
    const Index lags = csv_.data.rows();
    if (lags == 0)
      detail::fail_at(path_, csv_.end_line, 1, "no rows after the header; give one row per lag 0, 1, 2, ...");
    out.g.reserve(static_cast<size_t>(lags));
    for (Index k = 0; k < lags; ++k) {
      if (csv_.data(k, 0) != static_cast<double>(k)) {
        const detail::CellPosition at = csv_.key_position(k);
        detail::fail_at(path_, at.line, at.column,
                        fmt::format("lag {} where lag {} is expected; rows must list lags 0, 1, 2, ... in order without "
                                    "gaps",
                                    csv_.data(k, 0), k));
      }
      Eigen::MatrixXd g(static_cast<Index>(p), static_cast<Index>(m));
      for (size_t i = 0; i < p; ++i)
        for (size_t j = 0; j < m; ++j)
          g(static_cast<Index>(i), static_cast<Index>(j)) = csv_.data(k, static_cast<Index>(1 + i * m + j));
      out.g.push_back(std::move(g));
    }
    return out;
  }

 private:
  void parse_metadata() {
    const auto& comments = csv_.leading_comments;
    size_t first = 0;
    while (first < comments.size() && trim({comments[first].text, 0}).text.empty()) ++first;
    if (first == comments.size() || trim({comments[first].text, 0}).text.rfind("lpvid markov", 0) != 0)
      detail::fail_at(path_, first == comments.size() ? 1 : comments[first].line, 1,
                      fmt::format("not an lpvid Markov-parameter file: the first line must be '# {}'; write the file "
                                  "with `lpvid markov`",
                                  kMagic));
    const Piece magic = trim({comments[first].text, comments[first].column});
    if (magic.text != kMagic)
      detail::fail_at(path_, comments[first].line, magic.column,
                      fmt::format("unsupported format '{}'; write the file with this lpvid's `lpvid markov` ('{}')", magic.text, kMagic));
    for (size_t c = first + 1; c < comments.size(); ++c) {
      const auto& comment = comments[c];
      const size_t colon = comment.text.find(':');
      if (colon == std::string::npos) continue;
      const Piece key = trim({std::string_view(comment.text).substr(0, colon), comment.column});
      const Piece value = trim({std::string_view(comment.text).substr(colon + 1),
                                comment.column + static_cast<int64_t>(colon) + 1});
      struct Known {
        const char* name;
        std::optional<Piece>* slot;
        int64_t* line;
      };
      const Known known[] = {{"sample_period_s", &meta_.sample_period, &meta_.sample_period_line},
                             {"inputs", &meta_.inputs, &meta_.inputs_line},
                             {"outputs", &meta_.outputs, &meta_.outputs_line},
                             {"noise_std", &meta_.noise_std, &meta_.noise_line},
                             {"input_rms", &meta_.input_rms, &meta_.input_rms_line},
                             {"output_rms", &meta_.output_rms, &meta_.output_rms_line}};
      for (const Known& k : known) {
        if (key.text != k.name) continue;
        if (k.slot->has_value())
          detail::fail_at(path_, comment.line, key.column,
                          fmt::format("'{}' is given twice (also on line {}); give it once", k.name, *k.line));
        *k.slot = value;
        *k.line = comment.line;
      }
    }
    const std::pair<const std::optional<Piece>*, const char*> required[] = {
        {&meta_.sample_period, "sample_period_s: <seconds>"},
        {&meta_.inputs, "inputs: <names>"},
        {&meta_.outputs, "outputs: <names>"}};
    for (const auto& [slot, line] : required)
      if (!slot->has_value())
        detail::fail_at(path_, csv_.header_line, 1,
                        fmt::format("missing metadata line '# {}' before the header; write the file with `lpvid markov`",
                                    line));
  }

  double number(Piece piece, int64_t line, const char* key) const {
    double value = 0;
    const char* b = piece.text.data();
    const char* e = b + piece.text.size();
    if (!parse_decimal(std::string_view(b, static_cast<size_t>(e - b)), value))
      detail::fail_at(path_, line, piece.column,
                      fmt::format("cannot parse {} as a finite number for '{}'; write a decimal number such as 0.001",
                                  detail::quote_cell(piece.text), key));
    return value;
  }

  std::vector<double> numbers(Piece piece, int64_t line, const char* key, size_t count, bool non_negative) const {
    const std::vector<Piece> items = split(piece);
    if (items.size() != count)
      detail::fail_at(path_, line, piece.column,
                      fmt::format("'{}' has {} values; it needs {} (comma separated, row-major over outputs then "
                                  "inputs): give that many",
                                  key, items.size(), count));
    std::vector<double> out;
    for (const Piece& item : items) {
      out.push_back(number(item, line, key));
      if (non_negative && out.back() < 0)
        detail::fail_at(path_, line, item.column,
                        fmt::format("'{}' holds {}; write values >= 0", key, out.back()));
    }
    return out;
  }

  std::vector<std::string> names(Piece piece, int64_t line, const char* key) const {
    // As many signals as a model may have (formats/io/model_json.h): realize
    // builds a model with these inputs and outputs.
    constexpr size_t kMaxNames = static_cast<size_t>(kMaxModelChannels);
    std::vector<std::string> out;
    for (const Piece& item : split(piece)) {
      if (item.text.empty())
        detail::fail_at(path_, line, item.column,
                        fmt::format("empty name in '{}'; list the names separated by commas, e.g. v1,v2", key));
      if (!valid_utf8(item.text))
        detail::fail_at(path_, line, item.column,
                        fmt::format("name {} in '{}' is not valid UTF-8; save the file as UTF-8",
                                    detail::quote_cell(item.text), key));
      if (out.size() == kMaxNames)
        detail::fail_at(path_, line, item.column,
                        fmt::format("'{}' lists more than {} names; lpvid reads models of at most {} inputs and "
                                    "outputs: use fewer channels",
                                    key, kMaxNames, kMaxNames));
      if (std::find(out.begin(), out.end(), item.text) != out.end())
        detail::fail_at(path_, line, item.column,
                        fmt::format("name '{}' appears twice in '{}'; give every signal its own name", item.text, key));
      out.emplace_back(item.text);
    }
    return out;
  }

  void check_header(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) const {
    std::vector<std::string> expected{"lag"};
    for (const std::string& o : outputs)
      for (const std::string& i : inputs) expected.push_back(markov_header_name(o, i));
    const auto& names = csv_.names;
    for (size_t j = 0; j < std::min(names.size(), expected.size()); ++j)
      if (names[j] != expected[j])
        detail::fail_at(path_, csv_.header_line, csv_.name_columns[j],
                        fmt::format("column {} is '{}' where '{}' is expected; the header is 'lag' then "
                                    "g_<output>_<input> over outputs (outer) and inputs (inner) as listed in the metadata: write the file with `lpvid markov`",
                                    j + 1, names[j], expected[j]));
    if (names.size() != expected.size())
      detail::fail_at(path_, csv_.header_line, 1,
                      fmt::format("the header has {} columns where {} are expected (lag and {} outputs × {} inputs); "
                                  "make the header match the '# inputs' and '# outputs' lines",
                                  names.size(), expected.size(), outputs.size(), inputs.size()));
  }

  const std::string& path_;
  detail::NumericCsv csv_;
  Metadata meta_;
};

void check_names(const std::string& path, const std::vector<std::string>& names, const char* key) {
  if (names.empty())
    throw InputError(fmt::format("cannot write '{}': no {}; a Markov file needs at least one", path, key));
  for (size_t k = 0; k < names.size(); ++k) {
    const std::string& name = names[k];
    if (name.empty() || name.find_first_of(",\"\r\n ") != std::string::npos)
      throw InputError(fmt::format("cannot write '{}': {} name '{}' is not allowed; use names without commas, quotes, "
                                   "blanks or line breaks",
                                   path, key, name));
    if (std::find(names.begin(), names.begin() + static_cast<std::ptrdiff_t>(k), name) != names.begin() + static_cast<std::ptrdiff_t>(k))
      throw InputError(fmt::format("cannot write '{}': {} name '{}' appears twice; give every signal its own name", path,
                                   key, name));
  }
}

template <typename Matrix>
std::string join_numbers(const Matrix& values, const std::string& path, const char* key) {
  std::string out;
  for (Index i = 0; i < values.rows(); ++i)
    for (Index j = 0; j < values.cols(); ++j) {
      const double v = values(i, j);
      if (!std::isfinite(v) || v < 0)
        throw InputError(fmt::format("cannot write '{}': {} holds {}; it must be finite and >= 0", path, key, v));
      if (!out.empty()) out += ',';
      out += fmt::format("{}", v);
    }
  return out;
}

}  // namespace

std::string markov_csv_text(const MarkovFile& file, const std::string& path) {
  check_names(path, file.inputs, "inputs");
  check_names(path, file.outputs, "outputs");
  const Index m = static_cast<Index>(file.inputs.size()), p = static_cast<Index>(file.outputs.size());
  if (!std::isfinite(file.sample_period_s) || !(file.sample_period_s > 0))
    throw InputError(fmt::format("cannot write '{}': sample period {} s; it must be positive", path, file.sample_period_s));
  if (file.g.empty())
    throw InputError(fmt::format("cannot write '{}': no Markov parameters; give at least g[0]", path));
  if (file.noise_std.size() > 0 && (file.noise_std.rows() != p || file.noise_std.cols() != m))
    throw InputError(fmt::format("cannot write '{}': noise_std is {}×{}, expected {}×{} (outputs × inputs)", path,
                                 file.noise_std.rows(), file.noise_std.cols(), p, m));
  if (file.input_rms.size() > 0 && file.input_rms.size() != m)
    throw InputError(fmt::format("cannot write '{}': input_rms has {} entries for {} inputs", path, file.input_rms.size(), m));
  if (file.output_rms.size() > 0 && file.output_rms.size() != p)
    throw InputError(
        fmt::format("cannot write '{}': output_rms has {} entries for {} outputs", path, file.output_rms.size(), p));
  std::string out = fmt::format("# {}\n# sample_period_s: {}\n# inputs: {}\n# outputs: {}\n", kMagic,
                                file.sample_period_s, fmt::join(file.inputs, ","), fmt::join(file.outputs, ","));
  if (file.noise_std.size() > 0) out += fmt::format("# noise_std: {}\n", join_numbers(file.noise_std, path, "noise_std"));
  if (file.input_rms.size() > 0) out += fmt::format("# input_rms: {}\n", join_numbers(file.input_rms, path, "input_rms"));
  if (file.output_rms.size() > 0)
    out += fmt::format("# output_rms: {}\n", join_numbers(file.output_rms, path, "output_rms"));
  out += "lag";
  for (const std::string& o : file.outputs)
    for (const std::string& i : file.inputs) out += "," + markov_header_name(o, i);
  out += '\n';
  for (size_t k = 0; k < file.g.size(); ++k) {
    const Eigen::MatrixXd& g = file.g[k];
    if (g.rows() != p || g.cols() != m)
      throw InputError(fmt::format("cannot write '{}': g[{}] is {}×{}, expected {}×{} (outputs × inputs)", path, k,
                                   g.rows(), g.cols(), p, m));
    out += fmt::format("{}", k);
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) {
        if (!std::isfinite(g(i, j)))
          throw InputError(fmt::format("cannot write '{}': g[{}]({}, {}) is {}; Markov parameters must be finite", path,
                                       k, i + 1, j + 1, g(i, j)));
        out += fmt::format(",{}", g(i, j));
      }
    out += '\n';
  }
  return out;
}

void write_markov_csv(const std::string& path, const MarkovFile& file) {
  write_file_atomic(path, markov_csv_text(file, detail::display_path(path)));
}

MarkovFile read_markov_csv(const std::string& path) { return MarkovReader(path).read(); }

}  // namespace lpvid
