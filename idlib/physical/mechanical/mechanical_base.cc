#include "idlib/physical/mechanical/mechanical_base.h"

#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>

#include "idlib/core/error.h"
#include "idlib/physical/evaluate.h"

namespace lpvid {
namespace {

bool is_identifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

// Terms of one parameter (or of the constant) summed, zero terms dropped, sorted by name.
LinearExpression normalised(const LinearExpression& e) {
  std::map<std::string, double> sum;
  for (const LinearTerm& t : e) sum[t.parameter] += t.coefficient;
  LinearExpression out;
  for (const auto& [name, c] : sum)
    if (c != 0.0) out.push_back({c, name});
  return out;
}

// The force unit on a DOF of that unit, and its suffix in parameter names.
std::pair<std::string, std::string> force_unit(const std::string& dof_unit) {
  if (dof_unit == "m") return {"N", "_N"};
  if (dof_unit == "rad") return {"N·m", "_Nm"};
  return {"force on " + dof_unit, ""};
}

// A force ripple periodic in position on each DOF, the k-th (k = 1: position_ripple,
// parameters ripple_sin_<dof>_N, ...; k = 2: position_ripple_2, ripple2_...): the sine's
// and the cosine's amplitudes per DOF, then the periods (read so by
// idlib/fit/force_error.cc).
EffectInfo ripple_effect(const BaseInfo& b, int k) {
  const std::string tag = k == 1 ? "ripple" : fmt::format("ripple{}", k);
  EffectInfo ripple{k == 1 ? "position_ripple" : fmt::format("position_ripple_{}", k),
                    k == 1 ? "a force ripple periodic in position on each DOF (cogging, a screw's lead error, a "
                             "commutation error)"
                           : "a second force ripple periodic in position on each DOF, of another period (a motor's "
                             "cogging beside a screw's lead error, or a harmonic of the first)",
                    "adds a sin(2 pi q/p) + b cos(2 pi q/p) to the DOF's force balance (time domain only); the "
                    "period p is found by a periodogram of the residual over position, then a profile search",
                    "a force residual that repeats with position (a peak in its periodogram over q)",
                    {},
                    {},
                    false,
                    {},
                    true};
  for (const char* part : {"sin", "cos"})
    for (std::size_t i = 0; i < b.dof_names.size(); ++i) {
      const auto [unit, suffix] = force_unit(b.dof_units[i]);
      ripple.parameters.push_back({tag + "_" + part + "_" + b.dof_names[i] + suffix, unit, 0.0, -1e9, 1e9, true});
    }
  for (std::size_t i = 0; i < b.dof_names.size(); ++i) {
    const std::string& u = b.dof_units[i];
    const std::string suffix = u == "m" ? "_m" : u == "rad" ? "_rad" : "";
    ripple.parameters.push_back({tag + "_period_" + b.dof_names[i] + suffix, u, k == 1 ? 0.01 : 0.005, 1e-12, 1e9, true});
  }
  return ripple;
}

// The nonlinear time-domain effects of a mechanical base (EffectInfo::time_only):
// one parameter per DOF, entering M q'' + D q' + K q + f = B_w w as a generalised
// force (idlib/fit/force_error.h).
std::vector<EffectInfo> mechanical_time_effects(const BaseInfo& b) {
  EffectInfo coulomb{"coulomb_friction",
                     "Coulomb (dry) friction on each DOF: a force of constant size against the motion",
                     "adds F_c sign(q') to the DOF's force balance (time domain only: no frequency response)",
                     "a force residual that steps with the sign of the velocity (correlated with sign(q'))",
                     {},
                     {},
                     false,
                     {},
                     true};
  EffectInfo offset{"force_offset",
                    "a constant force on each DOF (gravity on an inclined axis, a cable carrier, an amplifier "
                    "offset)",
                    "adds F_0 to the DOF's force balance (time domain only)",
                    "a force residual with a nonzero mean, whatever the motion",
                    {},
                    {},
                    false,
                    {},
                    true};
  EffectInfo stribeck{"stribeck_friction",
                      "Stribeck friction on each DOF: the friction rises towards standstill above the Coulomb level "
                      "(static friction, breakaway)",
                      "adds F_s exp(-(q'/v_s)^2) sign(q') to the DOF's force balance (time domain only); v_s is found "
                      "by a profile search over the log's low speeds",
                      "a force residual against the motion that is largest at low speed and fades with speed",
                      {},
                      {},
                      false,
                      {},
                      true};
  EffectInfo saturation{"input_saturation",
                        "a drive that saturates: each input applies at most ±w_max, while the log holds the "
                        "controller's unlimited command",
                        "replaces each input w by clip(w, ±w_max) in the force balance (time domain only); w_max is "
                        "found by a profile search between the median and the largest |w| of the log",
                        "a force residual that grows where the command is largest (its top few per cent)",
                        {},
                        {},
                        false,
                        {},
                        true};
  for (std::size_t j = 0; j < b.input_names.size(); ++j) {
    // the input's unit in the name when it is a plain symbol (V, A, N)
    const std::string& u = j < b.input_units.size() ? b.input_units[j] : std::string();
    const bool plain = !u.empty() && std::all_of(u.begin(), u.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) != 0;
    });
    // no limit until the fit finds one (the search range comes from the log)
    saturation.parameters.push_back(
        {"saturation_" + b.input_names[j] + (plain ? "_" + u : ""), u, 1e12, 1e-12, 1e12, true});
  }
  for (std::size_t i = 0; i < b.dof_names.size(); ++i) {
    const auto [unit, suffix] = force_unit(b.dof_units[i]);
    PhysicalParameter c{"coulomb_" + b.dof_names[i] + suffix, unit, 0.0, 0.0, 1e9, true};
    PhysicalParameter f{"offset_" + b.dof_names[i] + suffix, unit, 0.0, -1e9, 1e9, true};
    PhysicalParameter s{"stribeck_" + b.dof_names[i] + suffix, unit, 0.0, 0.0, 1e9, true};
    coulomb.parameters.push_back(c);
    offset.parameters.push_back(f);
    stribeck.parameters.push_back(s);
  }
  // the velocity scales after the forces (idlib/fit/force_error.cc reads them so)
  for (std::size_t i = 0; i < b.dof_names.size(); ++i) {
    const std::string& u = b.dof_units[i];
    const std::string suffix = u == "m" ? "_m_per_s" : u == "rad" ? "_rad_per_s" : "";
    stribeck.parameters.push_back({"stribeck_v_" + b.dof_names[i] + suffix, u + "/s", 0.01, 1e-9, 1e6, true});
  }
  return {coulomb, offset, stribeck, saturation, ripple_effect(b, 1), ripple_effect(b, 2)};
}

}  // namespace

LinearExpression parse_linear_expression(const std::string& text) {
  LinearExpression out;
  std::size_t i = 0;
  const std::size_t n = text.size();
  auto skip = [&] {
    while (i < n && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  };
  auto fail = [&](const std::string& what) -> void {
    throw InputError(fmt::format("expression \"{}\", at character {}: {}; write a sum of terms such as "
                                 "\"m_carriage_kg + m_load_kg\", \"-k_N_per_m\" or \"0.5*k_f_N_per_A\"",
                                 text, i + 1, what));
  };
  auto number = [&](double& v) {
    const std::size_t start = i;
    while (i < n && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
    if (i < n && (text[i] == 'e' || text[i] == 'E')) {
      ++i;
      if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
      while (i < n && std::isdigit(static_cast<unsigned char>(text[i]))) ++i;
    }
    const std::string s = text.substr(start, i - start);
    char* end = nullptr;
    v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) {
      i = start;
      fail(fmt::format("'{}' is not a number", s));
    }
  };
  auto name = [&] {
    const std::size_t start = i;
    while (i < n && (std::isalnum(static_cast<unsigned char>(text[i])) || text[i] == '_')) ++i;
    return text.substr(start, i - start);
  };
  skip();
  if (i == n) fail("it is empty (write 0 for a zero entry)");
  bool first = true;
  while (true) {
    skip();
    double sign = 1.0;
    if (i < n && (text[i] == '+' || text[i] == '-')) {
      sign = text[i] == '-' ? -1.0 : 1.0;
      ++i;
      skip();
    } else if (!first) {
      fail("expected + or - between terms");
    }
    first = false;
    if (i == n) fail("a term is missing at the end");
    LinearTerm t;
    t.coefficient = sign;
    const char c = text[i];
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
      double v = 0.0;
      number(v);
      t.coefficient *= v;
      skip();
      if (i < n && text[i] == '*') {
        ++i;
        skip();
        if (i == n || !(std::isalpha(static_cast<unsigned char>(text[i])) || text[i] == '_'))
          fail("a parameter name must follow '*'");
        t.parameter = name();
      }
    } else if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      t.parameter = name();
      skip();
      if (i < n && text[i] == '*') {
        ++i;
        skip();
        double v = 0.0;
        if (i == n || !(std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.'))
          fail("a number must follow 'name*' (a product of two parameters is not linear)");
        number(v);
        t.coefficient *= v;
      }
    } else {
      fail(fmt::format("unexpected '{}'", c));
    }
    out.push_back(t);
    skip();
    if (i == n) break;
  }
  return out;
}

std::string linear_expression_text(const LinearExpression& e) {
  if (e.empty()) return "0";
  std::string out;
  for (const LinearTerm& t : e) {
    const double a = std::abs(t.coefficient);
    if (out.empty())
      out += t.coefficient < 0 ? "-" : "";
    else
      out += t.coefficient < 0 ? " - " : " + ";
    if (t.parameter.empty())
      out += fmt::format("{}", a);
    else if (a == 1.0)
      out += t.parameter;
    else
      out += fmt::format("{}*{}", a, t.parameter);
  }
  return out;
}

std::shared_ptr<const UserBase> make_mechanical_base(const MechanicalDescription& d) {
  auto fail = [&](const std::string& what) -> void {
    throw InputError(fmt::format("mechanical base '{}': {}", d.name, what));
  };
  if (!is_identifier(d.name)) fail("give it a name of letters, digits and '_' (e.g. \"ball_screw_axis\")");
  const Index nd = static_cast<Index>(d.dofs.size()), ni = static_cast<Index>(d.inputs.size()),
              no = static_cast<Index>(d.outputs.size());
  if (nd == 0 || nd > kMaxMechanicalDofs)
    fail(fmt::format("it has {} DOFs; give 1 to {} rigid-body DOFs (flexible modes are added as structural_mode "
                     "effects, not as DOFs)",
                     nd, kMaxMechanicalDofs));
  if (ni == 0) fail("it has no input; list the actuator channels under \"inputs\"");
  if (no == 0) fail("it has no output; list the sensor channels under \"outputs\"");
  auto check_channels = [&](const std::vector<MechanicalChannel>& list, const char* what) {
    for (std::size_t k = 0; k < list.size(); ++k) {
      if (!is_identifier(list[k].name))
        fail(fmt::format("{} name '{}': use letters, digits and '_' only", what, list[k].name));
      if (list[k].unit.empty()) fail(fmt::format("{} '{}' has no unit; give it (e.g. \"m\", \"rad\", \"N\")", what, list[k].name));
      for (std::size_t j = 0; j < k; ++j)
        if (list[j].name == list[k].name) fail(fmt::format("{} '{}' is named twice; names must differ", what, list[k].name));
    }
  };
  check_channels(d.dofs, "DOF");
  check_channels(d.inputs, "input");
  check_channels(d.outputs, "output");
  for (const auto& c : d.dofs)
    if (c.derivative != 0) fail(fmt::format("DOF '{}': only outputs measure a velocity or an acceleration", c.name));
  for (const auto& c : d.inputs)
    if (c.derivative != 0) fail(fmt::format("input '{}': only outputs measure a velocity or an acceleration", c.name));
  for (const auto& c : d.outputs)
    if (c.derivative < 0 || c.derivative > 2)
      fail(fmt::format("output '{}': it measures position, velocity or acceleration", c.name));
  for (std::size_t k = 0; k < d.parameters.size(); ++k) {
    const PhysicalParameter& q = d.parameters[k];
    if (!is_identifier(q.name)) fail(fmt::format("parameter name '{}': use letters, digits and '_' only", q.name));
    for (std::size_t j = 0; j < k; ++j)
      if (d.parameters[j].name == q.name) fail(fmt::format("parameter '{}' is declared twice", q.name));
    if (q.unit.empty()) fail(fmt::format("parameter '{}' has no unit", q.name));
    if (!std::isfinite(q.value) || !std::isfinite(q.lower) || !std::isfinite(q.upper) || q.lower > q.upper ||
        q.value < q.lower || q.value > q.upper)
      fail(fmt::format("parameter '{}': value {} and bounds [{}, {}] must be finite with lower <= value <= upper",
                       q.name, q.value, q.lower, q.upper));
  }
  std::vector<bool> used(d.parameters.size(), false);
  auto check_matrix = [&](const std::vector<std::vector<LinearExpression>>& m, Index rows, Index cols,
                          const char* what) {
    if (static_cast<Index>(m.size()) != rows)
      fail(fmt::format("\"{}\" has {} rows; it must be {}×{}", what, m.size(), rows, cols));
    for (const auto& row : m) {
      if (static_cast<Index>(row.size()) != cols)
        fail(fmt::format("\"{}\" has a row of {} entries; it must be {}×{}", what, row.size(), rows, cols));
      for (const LinearExpression& e : row)
        for (const LinearTerm& t : e) {
          if (!std::isfinite(t.coefficient)) fail(fmt::format("\"{}\": a coefficient is not finite", what));
          if (t.parameter.empty()) continue;
          const auto it = std::find_if(d.parameters.begin(), d.parameters.end(),
                                       [&](const PhysicalParameter& q) { return q.name == t.parameter; });
          if (it == d.parameters.end())
            fail(fmt::format("\"{}\" uses '{}', which is not a declared parameter; declare it under \"parameters\"",
                             what, t.parameter));
          used[static_cast<std::size_t>(it - d.parameters.begin())] = true;
        }
    }
  };
  check_matrix(d.mass, nd, nd, "mass");
  check_matrix(d.damping, nd, nd, "damping");
  check_matrix(d.stiffness, nd, nd, "stiffness");
  check_matrix(d.input_map, nd, ni, "input_map");
  check_matrix(d.output_map, no, nd, "output_map");
  for (std::size_t k = 0; k < used.size(); ++k)
    if (!used[k])
      fail(fmt::format("parameter '{}' is declared but no matrix uses it; use it or remove it", d.parameters[k].name));
  for (Index i = 0; i < nd; ++i)
    for (Index j = 0; j < i; ++j)
      if (normalised(d.mass[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]) !=
          normalised(d.mass[static_cast<std::size_t>(j)][static_cast<std::size_t>(i)]))
        fail(fmt::format("the mass matrix is not symmetric: entry ({}, {}) is \"{}\" but ({}, {}) is \"{}\"",
                         d.dofs[static_cast<std::size_t>(i)].name, d.dofs[static_cast<std::size_t>(j)].name,
                         linear_expression_text(d.mass[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]),
                         d.dofs[static_cast<std::size_t>(j)].name, d.dofs[static_cast<std::size_t>(i)].name,
                         linear_expression_text(d.mass[static_cast<std::size_t>(j)][static_cast<std::size_t>(i)])));
  auto base = std::make_shared<UserBase>();
  base->description = d;
  BaseInfo& b = base->info;
  b.name = "mechanical";
  b.time_route = BaseInfo::TimeRoute::kForceError;
  b.description = d.description.empty() ? fmt::format("user-described mechanical stage '{}'", d.name) : d.description;
  b.parameters = d.parameters;
  for (const auto& c : d.inputs) {
    b.input_names.push_back(c.name);
    b.input_units.push_back(c.unit);
  }
  for (const auto& c : d.outputs) {
    b.output_names.push_back(c.name);
    b.output_units.push_back(c.unit);
  }
  for (const auto& c : d.dofs) {
    b.dof_names.push_back(c.name);
    b.dof_units.push_back(c.unit);
  }
  // a user's stage may have its modes anywhere: from 0.1 rad/s (a large structure) to
  // 1e6 rad/s (a stiff precision stage); diagnose seeds them from the failing bands
  b.mode_lower_rad_s = 0.1;
  b.mode_upper_rad_s = 1e6;
  b.max_modes = kMaxMechanicalModes;
  base->library = physical_detail::shared_block_effects(b);
  for (EffectInfo& e : mechanical_time_effects(b)) base->library.push_back(std::move(e));
  // M positive definite at the design values
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(nd, nd);
  for (Index i = 0; i < nd; ++i)
    for (Index j = 0; j < nd; ++j)
      for (const LinearTerm& t : d.mass[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]) {
        double v = t.coefficient;
        if (!t.parameter.empty())
          for (const PhysicalParameter& q : d.parameters)
            if (q.name == t.parameter) v *= q.value;
        M(i, j) += v;
      }
  Eigen::LLT<Eigen::MatrixXd> llt(M);
  if (llt.info() != Eigen::Success)
    fail("the mass matrix is not positive definite at the parameters' values; every DOF needs a mass or inertia "
         "(> 0) and the couplings must be smaller than the diagonal");
  b.compile = [](ModelLayout& layout, const PhysicalModel& model) { layout.mechanical.emplace(model); };
  return base;
}

MechanicalIndices::MechanicalIndices(const PhysicalModel& model) {
  LPVID_ASSERT(model.user_base != nullptr);
  const MechanicalDescription& d = model.user_base->description;
  n_dof = static_cast<Index>(d.dofs.size());
  n_in = static_cast<Index>(d.inputs.size());
  n_out = static_cast<Index>(d.outputs.size());
  auto compile = [&](const std::vector<std::vector<LinearExpression>>& m, std::vector<Entry>& out) {
    for (std::size_t i = 0; i < m.size(); ++i)
      for (std::size_t j = 0; j < m[i].size(); ++j)
        for (const LinearTerm& t : m[i][j]) {
          Entry e{static_cast<Index>(i), static_cast<Index>(j), t.coefficient, -1};
          if (!t.parameter.empty()) {
            e.parameter = model.index_of(t.parameter);
            LPVID_ASSERT(e.parameter >= 0);  // validate() checked the base's parameters
          }
          out.push_back(e);
        }
  };
  compile(d.mass, mass);
  compile(d.damping, damping);
  compile(d.stiffness, stiffness);
  compile(d.input_map, input_map);
  compile(d.output_map, output_map);
  for (const MechanicalChannel& c : d.outputs) output_derivative.push_back(c.derivative);
}

}  // namespace lpvid
