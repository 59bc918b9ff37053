#include "formats/io/platform_json.h"

#include <fmt/format.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "formats/io/csv_detail.h"
#include "formats/io/json_detail.h"
#include "formats/io/csv_log.h"
#include "formats/io/text.h"
#include "idlib/core/error.h"

namespace lpvid {
namespace {

using nlohmann::json;

std::string known_names(PlatformParameters& p) {
  std::string known;
  for (auto& [n, f] : platform_parameter_fields(p)) known += (known.empty() ? "" : ", ") + n;
  return known + ", rod_axis_angles_rad";
}

}  // namespace

std::vector<std::pair<std::string, double*>> platform_parameter_fields(PlatformParameters& p) {
  return {{"J_psi_kgm2", &p.J_psi_kgm2},
          {"J_theta_kgm2", &p.J_theta_kgm2},
          {"J_psitheta_kgm2", &p.J_psitheta_kgm2},
          {"platform_mass_kg", &p.platform_mass_kg},
          {"beam_mass_kg", &p.beam_mass_kg},
          {"beam_height_m", &p.beam_height_m},
          {"beam_stroke_m", &p.beam_stroke_m},
          {"coil_arm_m", &p.coil_arm_m},
          {"coil_damping_Ns_per_m", &p.coil_damping_Ns_per_m},
          {"k_linear_N_per_m", &p.k_linear_N_per_m},
          {"k_torque_low_Nm_per_rad", &p.k_torque_low_Nm_per_rad},
          {"k_torque_high_Nm_per_rad", &p.k_torque_high_Nm_per_rad},
          {"com_x_m", &p.com_x_m},
          {"com_y_m", &p.com_y_m},
          {"gravity_m_per_s2", &p.gravity_m_per_s2}};
}

PlatformParameters read_platform_parameters(const std::string& path) {
  const std::string text = detail::read_json_text(path, "a platform parameter file");
  auto fail = [&](const std::string& key, const std::string& what) {
    const detail::CellPosition at = detail::text_position(text, key.empty() ? 0 : detail::find_top_level_key(text, key));
    detail::fail_at(path, at.line, at.column, what);
  };
  const json root = detail::parse_json(path, text);
  if (!root.is_object())
    fail("", fmt::format("the file holds {} where a JSON object of platform parameters is expected, e.g. "
                         "{{\"beam_mass_kg\": 1.0}}: check that this is a parameter file",
                         root.type_name()));
  PlatformParameters p = PlatformParameters::defaults();
  auto fields = platform_parameter_fields(p);
  for (auto it = root.begin(); it != root.end(); ++it) {
    const std::string& key = it.key();
    if (key == "provenance") continue;
    if (key == "type") {
      if (!it->is_string() || it->get<std::string>() != "platform_parameters")
        fail(key, fmt::format("key 'type' is {}; write \"type\": \"platform_parameters\" (or leave it out)", detail::json_excerpt(*it)));
      continue;
    }
    if (key == "rod_axis_angles_rad") {
      if (!it->is_array() || it->size() != 3)
        fail(key, "key 'rod_axis_angles_rad' must be an array of 3 angles in rad: write e.g. [1.5708, 3.6652, 5.7596]");
      for (size_t j = 0; j < 3; ++j) {
        if (!(*it)[j].is_number()) fail(key, "key 'rod_axis_angles_rad' must hold 3 numbers (rad): write e.g. [1.5708, 3.6652, 5.7596]");
        p.rod_axis_angles_rad[j] = (*it)[j].get<double>();
      }
      continue;
    }
    double* field = nullptr;
    for (auto& [n, f] : fields)
      if (n == key) field = f;
    if (!field) fail(key, fmt::format("unknown parameter {}; use one of {}", detail::quote_cell(key), known_names(p)));
    if (!it->is_number())
      fail(key, fmt::format("key '{}' must be a finite number in the units of its name, got {}; write a number", key, detail::json_excerpt(*it)));
    *field = it->get<double>();
  }
  try {
    p.validate();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}; fix the parameter file", detail::display_path(path), e.what()));
  }
  return p;
}

void apply_parameter_overrides(PlatformParameters& params, const std::vector<std::string>& overrides) {
  auto table = platform_parameter_fields(params);
  for (const std::string& item : overrides) {
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw InputError(fmt::format("--set '{}': expected NAME=VALUE, e.g. --set coil_damping_Ns_per_m=35", item));
    const std::string name = item.substr(0, eq), value = item.substr(eq + 1);
    double* field = nullptr;
    for (auto& [n, f] : table)
      if (n == name) field = f;
    if (!field)
      throw InputError(fmt::format("--set: unknown parameter {}; use one of {}", detail::quote_cell(name), known_names(params)));
    if (!parse_decimal(value, *field))
      throw InputError(fmt::format("--set {}: {} is not a finite number; give a decimal number in the units of its name",
                                   name, detail::quote_cell(value)));
  }
  params.validate();
}

std::string platform_parameters_to_json(const PlatformParameters& params, const nlohmann::json& extra) {
  PlatformParameters p = params;
  p.validate();
  json out = json::object();
  out["type"] = "platform_parameters";
  for (auto& [n, f] : platform_parameter_fields(p)) out[n] = *f;
  out["rod_axis_angles_rad"] = p.rod_axis_angles_rad;
  if (extra.is_object())
    for (auto it = extra.begin(); it != extra.end(); ++it) out[it.key()] = *it;
  // Provenance may hold file names that are not UTF-8: written with U+FFFD.
  return out.dump(2, ' ', false, json::error_handler_t::replace) + "\n";
}

void check_beam_stroke(const std::string& path, const Eigen::VectorXd& x_b_m, double stroke_m,
                       const std::string& column) {
  Index bad = -1;
  for (Index k = 0; k < x_b_m.size() && bad < 0; ++k)
    if (!(std::abs(x_b_m(k)) <= stroke_m)) bad = k;
  if (bad < 0) return;
  // Locate the cell: data row `bad` is the (bad+1)-th non-blank, non-comment
  // line after the header; the cell is the column's field of that line.
  int64_t line_no = 0, col_no = 1;
  Index field = -1;
  if (path != "-") {
    std::ifstream in(path, std::ios::binary);
    std::string line;
    Index data_row = -2;  // the header is row -1
    while (std::getline(in, line)) {
      ++line_no;
      const size_t first = line.find_first_not_of(" \t\r");
      if (first == std::string::npos || line[first] == '#') continue;
      ++data_row;
      if (data_row == -1) {  // header: find the column's index
        Index idx = 0;
        size_t start = 0;
        for (;;) {
          const size_t comma = line.find(',', start);
          std::string cell = line.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
          const size_t a = cell.find_first_not_of(" \t\r\""), b = cell.find_last_not_of(" \t\r\"");
          cell = a == std::string::npos ? "" : cell.substr(a, b - a + 1);
          if (cell == column) field = idx;
          if (comma == std::string::npos) break;
          start = comma + 1;
          ++idx;
        }
        continue;
      }
      if (data_row == bad) {
        size_t start = 0;
        for (Index i = 0; i < field && start != std::string::npos; ++i) {
          const size_t comma = line.find(',', start);
          start = comma == std::string::npos ? comma : comma + 1;
        }
        if (start != std::string::npos) {
          const size_t cell = line.find_first_not_of(" \t", start);
          col_no = static_cast<int64_t>((cell == std::string::npos ? start : cell) + 1);
        }
        break;
      }
    }
  }
  const std::string what = fmt::format(
      "{} = {} m is outside the stroke |x_b| <= {} m (beam_stroke_m); give x_b in metres or raise beam_stroke_m",
      column, x_b_m(bad), stroke_m);
  if (line_no > 0 && field >= 0) detail::fail_at(path, line_no, col_no, what);
  throw InputError(fmt::format("{}: sample {}: {}", detail::display_path(path), bad, what));
}

BeamSamples read_beam_samples(const std::string& path, double stroke_m, const std::string& column) {
  const Log log = read_log(path);
  BeamSamples s;
  s.t_s = log.data.col(log.column("t"));
  s.x_b_m = log.data.col(log.column(column));
  check_beam_stroke(path, s.x_b_m, stroke_m, column);
  return s;
}

}  // namespace lpvid
