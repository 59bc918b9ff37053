#include "formats/io/model_json.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "idlib/core/error.h"
#include "idlib/lti/transfer_function.h"

namespace lpvid {
namespace {

using nlohmann::json;

class ModelReader {
 public:
  ModelReader(const std::string& path, const std::string& text) : path_(path), text_(text) {}

  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    const detail::CellPosition at = detail::text_position(text_, key.empty() ? 0 : detail::find_top_level_key(text_, key));
    detail::fail_at(path_, at.line, at.column, what);
  }

  const json* find(const json& root, const std::string& key) const {
    const auto it = root.find(key);
    return it == root.end() ? nullptr : &*it;
  }

  const json& require(const json& root, const std::string& key, const std::string& hint) const {
    const json* value = find(root, key);
    if (value == nullptr) fail("", fmt::format("missing key '{}'; {}", key, hint));
    return *value;
  }

  std::vector<std::string> names(const json& root, const std::string& key) const {
    std::vector<std::string> out;
    const json* value = find(root, key);
    if (value == nullptr) return out;
    const std::string rule = fmt::format("key '{}' must be an array of unique, non-empty names", key);
    if (!value->is_array()) fail(key, fmt::format("{}, got {}; write e.g. \"{}\": [\"v1\", \"v2\"]", rule, value->type_name(), key));
    if (static_cast<Index>(value->size()) > kMaxModelChannels)
      fail(key, fmt::format("key '{}' lists {} names: lpvid reads models of at most {} inputs and outputs; check the file",
                            key, value->size(), kMaxModelChannels));
    for (const json& item : *value) {
      if (!item.is_string() || item.get_ref<const std::string&>().empty())
        fail(key, fmt::format("{}, got an entry {}; write every name as a string", rule, detail::json_excerpt(item)));
      const std::string& name = item.get_ref<const std::string&>();
      if (std::find(out.begin(), out.end(), name) != out.end())
        fail(key, fmt::format("{}, '{}' appears twice; give every signal its own name", rule, name));
      out.push_back(name);
    }
    return out;
  }

  // Shape of a nested array: rows and columns (columns = -1 when there are no rows).
  Eigen::MatrixXd matrix(const json& value, const std::string& key, const std::string& shape_words, Index& cols) const {
    const std::string rule = fmt::format("key '{}' must be a matrix ({}) written as an array of rows", key, shape_words);
    if (!value.is_array()) fail(key, fmt::format("{}, got {}; write e.g. [[1, 0], [0, 1]]", rule, value.type_name()));
    const Index rows = static_cast<Index>(value.size());
    // Rows and columns of A, B, C, D count states or channels: bounded before
    // anything is allocated (model_json.h).
    const bool rows_are_states = key == "A" || key == "B";
    const bool cols_are_states = key == "A" || key == "C";
    auto check_size = [&](Index size, bool states, const char* dimension) {
      const Index limit = states ? kMaxModelStates : kMaxModelChannels;
      if (size > limit)
        fail(key, fmt::format("key '{}' has {} {}: lpvid reads models of at most {} states and {} inputs and outputs; "
                              "reduce the model first (e.g. realize --order)",
                              key, size, dimension, kMaxModelStates, kMaxModelChannels));
    };
    check_size(rows, rows_are_states, "rows");
    cols = -1;
    for (Index i = 0; i < rows; ++i) {
      const json& row = value[static_cast<size_t>(i)];
      if (!row.is_array())
        fail(key, fmt::format("{}, but row {} is {}; write each row as an array of numbers", rule, i + 1, row.type_name()));
      const Index len = static_cast<Index>(row.size());
      if (cols < 0) {
        check_size(len, cols_are_states, "columns");
        cols = len;
      }
      if (len != cols)
        fail(key, fmt::format("{}, but row {} has {} entries and row 1 has {}; give every row the same length", rule,
                              i + 1, len, cols));
    }
    Eigen::MatrixXd out(rows, std::max<Index>(cols, 0));
    for (Index i = 0; i < rows; ++i) {
      for (Index j = 0; j < out.cols(); ++j) {
        const json& entry = value[static_cast<size_t>(i)][static_cast<size_t>(j)];
        if (!entry.is_number())
          fail(key, fmt::format("{}, but entry ({}, {}) is {}; every entry must be a finite number (JSON has no NaN or "
                                "Inf)",
                                rule, i + 1, j + 1, detail::json_excerpt(entry)));
        out(i, j) = entry.get<double>();
        if (!std::isfinite(out(i, j)))
          fail(key, fmt::format("{}, but entry ({}, {}) is {}; every entry must be a finite number", rule, i + 1, j + 1,
                                out(i, j)));
      }
    }
    return out;
  }

  void check_shape(const std::string& key, const Eigen::MatrixXd& value, Index cols_given, Index rows, Index cols,
                   const std::string& shape_words) const {
    const bool ok = value.rows() == rows && (value.rows() == 0 || cols_given == cols);
    if (!ok) {
      const std::string got =
          value.rows() == 0 ? "an empty array (0 rows)" : fmt::format("{}×{}", value.rows(), cols_given);
      fail(key, fmt::format("key '{}' must be a {}×{} matrix ({}), got {}; check the dimensions of A, B, C, D and "
                            "the inputs/outputs names",
                            key, rows, cols, shape_words, got));
    }
  }

  StateSpace read() const {
    const json root = detail::parse_json(path_, text_);
    if (!root.is_object())
      fail("", fmt::format("the file holds {} where a JSON object is expected; a model file is an object "
                           "{{\"type\": \"state_space\", \"ts\": ..., \"A\": ..., \"B\": ..., \"C\": ..., \"D\": ...}}: check that this is a model file",
                           root.type_name()));
    const json& type = require(root, "type", "a model file starts with \"type\": \"state_space\" (or \"transfer_function\")");
    if (type.is_string() && type.get_ref<const std::string&>() == "transfer_function") return read_transfer_function(root);
    if (!type.is_string() || type.get_ref<const std::string&>() != "state_space")
      fail("type", fmt::format("key 'type' is {}; write \"type\": \"state_space\" or \"transfer_function\" (the types "
                               "lpvid reads)",
                               detail::json_excerpt(type)));
    const json& ts = require(root, "ts", "give the sample period in seconds, \"ts\": 0 for continuous time");
    if (!ts.is_number())
      fail("ts", fmt::format("key 'ts' must be a number of seconds (0 for continuous time), got {}; write a number", ts.type_name()));
    const double sample_period_s = ts.get<double>();
    if (!(sample_period_s >= 0) || !std::isfinite(sample_period_s))
      fail("ts", fmt::format("key 'ts' is {}; write 0 (continuous time) or the positive sample period in seconds",
                             sample_period_s));

    StateSpace model;
    model.sample_period_s = sample_period_s;
    model.input_names = names(root, "inputs");
    model.output_names = names(root, "outputs");
    const std::string hint = "a model needs the matrices A, B, C and D";
    Index cols_a, cols_b, cols_c, cols_d;
    model.A = matrix(require(root, "A", hint), "A", "states × states", cols_a);
    model.B = matrix(require(root, "B", hint), "B", "states × inputs", cols_b);
    model.C = matrix(require(root, "C", hint), "C", "outputs × states", cols_c);
    model.D = matrix(require(root, "D", hint), "D", "outputs × inputs", cols_d);

    const Index n = model.A.rows();
    const bool have_inputs = find(root, "inputs") != nullptr;
    const bool have_outputs = find(root, "outputs") != nullptr;
    const Index p = have_outputs ? static_cast<Index>(model.output_names.size()) : model.D.rows();
    Index m = 0;
    if (have_inputs) m = static_cast<Index>(model.input_names.size());
    else if (model.D.rows() > 0) m = cols_d;
    else if (n > 0) m = std::max<Index>(cols_b, 0);
    check_shape("A", model.A, cols_a, n, n, "states × states");
    check_shape("B", model.B, cols_b, n, m, "states × inputs");
    check_shape("C", model.C, cols_c, p, n, "outputs × states");
    check_shape("D", model.D, cols_d, p, m, "outputs × inputs");
    // Empty matrices carry their implied width.
    model.B.resize(n, m);
    if (n == 0 || m == 0) model.B.setZero();
    if (model.C.cols() != n) model.C.resize(p, n);
    if (model.D.cols() != m) model.D.resize(p, m);
    try {
      model.validate();
    } catch (const InputError& e) {
      fail("", fmt::format("{}; fix the model file", e.what()));
    }
    return model;
  }

 private:
  // ---- "type": "transfer_function" (docs/formats.md, idlib/lti/transfer_function.h)
  std::vector<double> coefficients(const json& v, const std::string& key, const std::string& where, const char* what) const {
    if (!v.is_array() || v.empty())
      fail(key, fmt::format("{}: '{}' must be a non-empty array of numbers, got {}; write e.g. [1, -0.5]", where, what,
                            detail::json_excerpt(v)));
    if (static_cast<Index>(v.size()) > kMaxModelStates + 1)
      fail(key, fmt::format("{}: '{}' has {} coefficients: lpvid reads models of at most {} states; reduce the order",
                            where, what, v.size(), kMaxModelStates));
    std::vector<double> out;
    for (size_t k = 0; k < v.size(); ++k) {
      if (!v[k].is_number())
        fail(key, fmt::format("{}: '{}' entry {} is {}; every coefficient must be a finite number", where, what, k + 1,
                              detail::json_excerpt(v[k])));
      out.push_back(v[k].get<double>());
      if (!std::isfinite(out.back()))
        fail(key, fmt::format("{}: '{}' entry {} is {}; every coefficient must be finite", where, what, k + 1, out.back()));
    }
    return out;
  }

  std::vector<Complex> roots(const json& v, const std::string& key, const std::string& where, const char* what) const {
    if (!v.is_array())
      fail(key, fmt::format("{}: '{}' must be an array of values (a number, or [re, im] for a complex one), got {}",
                            where, what, detail::json_excerpt(v)));
    if (static_cast<Index>(v.size()) > kMaxModelStates)
      fail(key, fmt::format("{}: '{}' has {} entries: lpvid reads models of at most {} states; reduce the order", where,
                            what, v.size(), kMaxModelStates));
    std::vector<Complex> out;
    for (size_t k = 0; k < v.size(); ++k) {
      const json& e = v[k];
      if (e.is_number()) {
        out.emplace_back(e.get<double>(), 0.0);
      } else if (e.is_array() && e.size() == 2 && e[0].is_number() && e[1].is_number()) {
        out.emplace_back(e[0].get<double>(), e[1].get<double>());
      } else {
        fail(key, fmt::format("{}: '{}' entry {} is {}; write a real value as a number and a complex one as [re, im]",
                              where, what, k + 1, detail::json_excerpt(e)));
      }
      if (!std::isfinite(out.back().real()) || !std::isfinite(out.back().imag()))
        fail(key, fmt::format("{}: '{}' entry {} is not finite; give finite numbers", where, what, k + 1));
    }
    return out;
  }

  // One element: {"num", "den"} or {"zeros", "poles", "gain"}; 0 or null = a zero element.
  std::optional<SisoTf> element(const json& e, const std::string& key, const std::string& where) const {
    if (e.is_null() || (e.is_number() && e.get<double>() == 0)) return std::nullopt;
    if (!e.is_object())
      fail(key, fmt::format("{} is {}; write {{\"num\": [...], \"den\": [...]}} or {{\"zeros\": [...], \"poles\": "
                            "[...], \"gain\": k}} (0 or null for a zero element)",
                            where, detail::json_excerpt(e)));
    SisoTf tf;
    const bool nd = e.contains("num") || e.contains("den");
    const bool zpk = e.contains("zeros") || e.contains("poles") || e.contains("gain");
    if (nd == zpk)
      fail(key, fmt::format("{} must hold either num and den, or zeros, poles and gain{}", where,
                            nd ? " (not both)" : ""));
    if (nd) {
      if (!e.contains("num") || !e.contains("den")) fail(key, fmt::format("{} needs both 'num' and 'den'", where));
      tf.num = coefficients(e["num"], key, where, "num");
      tf.den = coefficients(e["den"], key, where, "den");
    } else {
      if (!e.contains("zeros") || !e.contains("poles") || !e.contains("gain"))
        fail(key, fmt::format("{} needs 'zeros', 'poles' and 'gain' (an empty list [] for none)", where));
      tf.is_zpk = true;
      tf.zeros = roots(e["zeros"], key, where, "zeros");
      tf.poles = roots(e["poles"], key, where, "poles");
      if (!e["gain"].is_number() || !std::isfinite(e["gain"].get<double>()))
        fail(key, fmt::format("{}: 'gain' must be a finite number, got {}", where, detail::json_excerpt(e["gain"])));
      tf.gain = e["gain"].get<double>();
    }
    return tf;
  }

  StateSpace read_transfer_function(const json& root) const {
    const json& ts = require(root, "ts", "give the sample period in seconds; a transfer function here is discrete");
    if (!ts.is_number() || !(ts.get<double>() > 0) || !std::isfinite(ts.get<double>()))
      fail("ts", fmt::format("key 'ts' is {}; give the positive sample period in seconds (transfer functions are "
                             "discrete here)",
                             detail::json_excerpt(ts)));
    const double sample_period_s = ts.get<double>();
    const json& var = require(root, "variable",
                              "say how the coefficients are written: \"variable\": \"z\" (descending powers of z, "
                              "MATLAB tf) or \"z^-1\" (ascending powers of z^-1, MATLAB filt)");
    if (!var.is_string() || (var.get_ref<const std::string&>() != "z" && var.get_ref<const std::string&>() != "z^-1"))
      fail("variable", fmt::format("key 'variable' is {}; write \"z\" (descending powers of z, MATLAB tf) or \"z^-1\" "
                                   "(ascending powers of z^-1, MATLAB filt)",
                                   detail::json_excerpt(var)));
    const TfVariable variable = var.get_ref<const std::string&>() == "z" ? TfVariable::kZ : TfVariable::kZInverse;
    const bool has_diag = find(root, "diagonal") != nullptr, has_matrix = find(root, "matrix") != nullptr;
    if (has_diag == has_matrix)
      fail(has_diag ? "matrix" : "",
           has_diag ? "give either 'diagonal' or 'matrix', not both"
                    : "missing key 'diagonal' or 'matrix'; give \"diagonal\": [tf, ...] (one element per channel) or "
                      "\"matrix\": [[tf, ...], ...] (outputs × inputs)");
    const std::string key = has_diag ? "diagonal" : "matrix";
    const json& body = root[key];
    if (!body.is_array() || body.empty())
      fail(key, fmt::format("key '{}' must be a non-empty array, got {}", key, detail::json_excerpt(body)));
    std::vector<std::optional<SisoTf>> entries;
    Index p = 0, m = 0;
    if (has_diag) {
      p = m = static_cast<Index>(body.size());
      if (p > kMaxModelChannels)
        fail(key, fmt::format("key 'diagonal' has {} elements: lpvid reads models of at most {} inputs and outputs", p,
                              kMaxModelChannels));
      entries.assign(static_cast<size_t>(p * m), std::nullopt);
      for (Index i = 0; i < p; ++i)
        entries[static_cast<size_t>(i * m + i)] = element(body[static_cast<size_t>(i)], key, fmt::format("key 'diagonal' element {}", i + 1));
    } else {
      p = static_cast<Index>(body.size());
      for (Index i = 0; i < p; ++i) {
        const json& row = body[static_cast<size_t>(i)];
        if (!row.is_array() || row.empty())
          fail(key, fmt::format("key 'matrix' row {} must be a non-empty array of elements, got {}", i + 1,
                                detail::json_excerpt(row)));
        if (i == 0) m = static_cast<Index>(row.size());
        if (static_cast<Index>(row.size()) != m)
          fail(key, fmt::format("key 'matrix' row {} has {} elements and row 1 has {}; give every row one element per input",
                                i + 1, row.size(), m));
        if (p > kMaxModelChannels || m > kMaxModelChannels)
          fail(key, fmt::format("key 'matrix' is {}×{}: lpvid reads models of at most {} inputs and outputs", p, m,
                                kMaxModelChannels));
        for (Index j = 0; j < m; ++j)
          entries.push_back(element(row[static_cast<size_t>(j)], key, fmt::format("key 'matrix' element ({}, {})", i + 1, j + 1)));
      }
    }
    StateSpace model;
    try {
      model = realize_tf_matrix(entries, p, m, variable, sample_period_s);
    } catch (const InputError& e) {
      fail(key, fmt::format("key '{}' {}", key, e.what()));
    }
    if (model.order() > kMaxModelStates)
      fail(key, fmt::format("the elements realise {} states: lpvid reads models of at most {} states; reduce the order",
                            model.order(), kMaxModelStates));
    model.input_names = names(root, "inputs");
    model.output_names = names(root, "outputs");
    if (!model.input_names.empty() && static_cast<Index>(model.input_names.size()) != m)
      fail("inputs", fmt::format("key 'inputs' names {} inputs but the elements have {}; give one name per input",
                                 model.input_names.size(), m));
    if (!model.output_names.empty() && static_cast<Index>(model.output_names.size()) != p)
      fail("outputs", fmt::format("key 'outputs' names {} outputs but the elements have {}; give one name per output",
                                  model.output_names.size(), p));
    try {
      model.validate();
    } catch (const InputError& e) {
      fail("", fmt::format("{}; fix the model file", e.what()));
    }
    return model;
  }

  const std::string& path_;
  const std::string& text_;
};

std::string number(double v) { return json(v).dump(); }

void append_matrix(std::string& out, const char* key, const Eigen::MatrixXd& m, bool last) {
  out += fmt::format("  \"{}\": [", key);
  for (Index i = 0; i < m.rows(); ++i) {
    out += i == 0 ? "\n    [" : ",\n    [";
    for (Index j = 0; j < m.cols(); ++j) {
      if (j > 0) out += ", ";
      out += number(m(i, j));
    }
    out += "]";
  }
  out += m.rows() > 0 ? "\n  ]" : "]";
  out += last ? "\n" : ",\n";
}

}  // namespace

StateSpace read_state_space(const std::string& path) {
  const std::string text = detail::read_json_text(path, "a model file");
  return ModelReader(path, text).read();
}

StateSpace parse_state_space(const std::string& text, const std::string& path) { return ModelReader(path, text).read(); }

bool is_state_space_file(const std::string& path) {
  // Only a regular file is probed: a pipe or stdin would be consumed by the probe.
  std::error_code ec;
  if (path == "-" || !std::filesystem::is_regular_file(path, ec)) return false;
  try {
    const json j = detail::parse_json(path, detail::read_json_text(path, "a model file"));
    return j.is_object() && j.contains("type") && (j["type"] == "state_space" || j["type"] == "transfer_function");
  } catch (const InputError&) {
    return false;  // not readable JSON: the caller's other reader says why
  }
}

std::string state_space_to_json(const StateSpace& model, const nlohmann::json& extra) {
  model.validate();
  if (!extra.is_null() && !extra.is_object())
    throw InputError(fmt::format("extra model-file content must be a JSON object, got {}", extra.type_name()));
  static const char* const kSchemaKeys[] = {"type", "ts", "inputs", "outputs", "A", "B", "C", "D"};
  for (const auto* names : {&model.input_names, &model.output_names})
    for (const std::string& name : *names)
      if (!valid_utf8(name))
        throw InputError(fmt::format("cannot write a model with the signal name {}: it is not valid UTF-8; rename the "
                                     "signal (names come from the log's header or the command line)",
                                     detail::quote_cell(name)));
  std::string out = "{\n  \"type\": \"state_space\",\n";
  out += fmt::format("  \"ts\": {},\n", number(model.sample_period_s));
  if (!model.input_names.empty()) out += fmt::format("  \"inputs\": {},\n", json(model.input_names).dump());
  if (!model.output_names.empty()) out += fmt::format("  \"outputs\": {},\n", json(model.output_names).dump());
  append_matrix(out, "A", model.A, false);
  append_matrix(out, "B", model.B, false);
  append_matrix(out, "C", model.C, false);
  const bool has_extra = extra.is_object() && !extra.empty();
  append_matrix(out, "D", model.D, !has_extra);
  if (has_extra) {
    size_t k = 0;
    for (auto it = extra.begin(); it != extra.end(); ++it, ++k) {
      for (const char* key : kSchemaKeys)
        if (it.key() == key)
          throw InputError(fmt::format("extra model-file key '{}' collides with the model schema; rename it", key));
      // Provenance may hold file names that are not UTF-8: shown with U+FFFD.
      std::string value = it.value().dump(2, ' ', false, json::error_handler_t::replace);
      // Indent nested lines by two more spaces.
      for (size_t pos = value.find('\n'); pos != std::string::npos; pos = value.find('\n', pos + 1))
        value.insert(pos + 1, "  ");
      out += fmt::format("  {}: {}{}\n", json(it.key()).dump(-1, ' ', false, json::error_handler_t::replace), value, k + 1 < extra.size() ? "," : "");
    }
  }
  out += "}\n";
  return out;
}

void write_state_space(const std::string& path, const StateSpace& model, const nlohmann::json& extra) {
  write_file_atomic(path, state_space_to_json(model, extra));
}

}  // namespace lpvid
