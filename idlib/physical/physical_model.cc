#include "idlib/physical/physical_model.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>

#include "idlib/core/error.h"
#include "idlib/physical/mechanical/mechanical_base.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/physical/stage6/stage6_base.h"

namespace lpvid {
namespace {

PhysicalParameter par(std::string name, std::string unit, double value, double lower, double upper, bool free) {
  return PhysicalParameter{std::move(name), std::move(unit), value, lower, upper, free};
}

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}

// The shape unit of a collocated mode for a DOF measured in `unit`: the modal
// coordinate is in kg^0.5·m, so phi maps it to the DOF's unit.
std::string shape_unit(const std::string& dof_unit) { return dof_unit == "m" ? "1/kg^0.5" : "1/(kg^0.5·m)"; }

// Ratio unit "to/from" for a static coupling, "1" when equal.
std::string ratio_unit(const std::string& to, const std::string& from) {
  if (to == from) return "1";
  return to + "/" + from;
}

}  // namespace

namespace physical_detail {

std::vector<EffectInfo> shared_block_effects(const BaseInfo& b) {
  std::vector<EffectInfo> out;
  const std::size_t n = b.dof_names.size();
  // structural_mode, then (a base with b.max_modes > 1) structural_mode_2 ... _N with
  // parameters mode_2_frequency_rad_s ...: the k-th mode is proposed once the (k−1)-th
  // is in the model (PhysicalModel::absent_effects)
  for (int k = 1; k <= b.max_modes; ++k) {
    const std::string tag = k == 1 ? "mode_" : fmt::format("mode_{}_", k);
    EffectInfo e{k == 1 ? "structural_mode" : fmt::format("structural_mode_{}", k),
                 k == 1 ? "an extra lightly damped (non-rigid) mode above the rigid-body band"
                        : fmt::format("a further lightly damped (non-rigid) mode (number {} of the model)", k),
                 "adds phi phiᵀ / (s² + 2 zeta w s + w²) to P (collocated: driven by the same wrench it is seen in); "
                 "2 states",
                 "a narrow peak/notch pair in several channels at one frequency, above the rigid-body band",
                 {par(tag + "frequency_rad_s", "rad/s", std::clamp(600.0, b.mode_lower_rad_s, b.mode_upper_rad_s),
                      b.mode_lower_rad_s, b.mode_upper_rad_s, true),
                  par(tag + "damping", "1", 0.02, 1e-4, 0.7, true)},
                 {},
                 false, {}};
    Block blk{BlockKind::kMode, BlockSide::kBody, {}, {tag + "frequency_rad_s", tag + "damping"}};
    for (std::size_t i = 0; i < n; ++i) {
      const std::string name = tag + "shape_" + b.dof_names[i];
      // a tilt-like shape of 1/sqrt(J)-size and a translation of 0.3/sqrt(m)-size
      e.parameters.push_back(par(name, shape_unit(b.dof_units[i]), b.dof_units[i] == "m" ? 0.3 : 1.0, -100.0,
                                 100.0, true));
      blk.parameters.push_back(name);
    }
    e.blocks.push_back(blk);
    out.push_back(e);
  }
  out.push_back({"input_delay", "pure delay tau on all inputs (computation time + the ZOH's half sample)",
                 "multiplies P by exp(-s tau); in sampled form exact for fractional samples (the input switches tau "
                 "after each sample)",
                 "a phase lag growing linearly with frequency in every channel, magnitude fits",
                 {par("input_delay_s", "s", 5e-4, 0.0, 0.02, true)},
                 {{BlockKind::kDelay, BlockSide::kInput, {}, {"input_delay_s"}}},
                 false, {}});
  out.push_back({"actuator_lag", "first-order actuator (coil current) lag 1/(tau_a s + 1), tau_a = L/R (seed 001 eqs "
                 "10–13)",
                 "inserts 1/(tau_a s + 1) on every input; one state per input",
                 "magnitude roll-off and phase lag near and above 1/tau_a in every channel",
                 {par("actuator_time_constant_s", "s", 5e-4, 1e-6, 0.1, true)},
                 {{BlockKind::kFirstOrder, BlockSide::kInput, {}, {"actuator_time_constant_s"}}},
                 false, {}});
  {
    EffectInfo e{"gain_error", "per-input actuator gain (e.g. the 1.5 of eq 9's printed z row, a coil constant)",
                 "multiplies input j of P by g_j: P -> P diag(g)",
                 "a frequency-independent magnitude ratio in the columns of one input",
                 {},
                 {},
                 false, {}};
    Block blk{BlockKind::kGain, BlockSide::kInput, b.input_names, {}};
    for (std::size_t j = 0; j < n; ++j) {
      const std::string name = "gain_" + b.dof_names[j];
      e.parameters.push_back(par(name, "1", 1.0, 0.05, 20.0, true));
      blk.parameters.push_back(name);
    }
    e.blocks.push_back(blk);
    out.push_back(e);
  }
  {
    EffectInfo e{"sensor_gain", "per-output sensor gain (a sensor's sensitivity, the measurement transformation T)",
                 "multiplies output i of P by g_i: P -> diag(g) P",
                 "a frequency-independent magnitude ratio in the rows of one output",
                 {},
                 {},
                 false, {}};
    Block blk{BlockKind::kGain, BlockSide::kOutput, b.output_names, {}};
    for (std::size_t i = 0; i < n; ++i) {
      const std::string name = "sensor_gain_" + b.dof_names[i];
      e.parameters.push_back(par(name, "1", 1.0, 0.05, 20.0, true));
      blk.parameters.push_back(name);
    }
    e.blocks.push_back(blk);
    out.push_back(e);
  }
  {
    EffectInfo e{"sensor_crosstalk", "static cross-talk between the measured outputs (sensor or transformation)",
                 "y_to += c y_from for every ordered pair of outputs, applied pair after pair: P -> (I + X) P to first order in the couplings",
                 "off-diagonal errors that follow the shape of another output's row",
                 {},
                 {},
                 false, {}};
    for (std::size_t a = 0; a < n; ++a)
      for (std::size_t t = 0; t < n; ++t) {
        if (a == t) continue;
        const std::string name = "crosstalk_" + b.dof_names[a] + "_to_" + b.dof_names[t];
        const std::string unit = ratio_unit(b.output_units[t], b.output_units[a]);
        // ±0.5 of the ratio of units: far beyond any plausible cross-talk
        e.parameters.push_back(par(name, unit, 0.0, -0.5, 0.5, true));
        e.blocks.push_back({BlockKind::kCoupling, BlockSide::kOutput, {b.output_names[a], b.output_names[t]}, {name}});
      }
    out.push_back(e);
  }
  return out;
}

}  // namespace physical_detail

namespace {

struct Registry {
  std::vector<BaseInfo> bases;
  std::map<std::string, std::vector<EffectInfo>> libraries;
};

const Registry& registry() {
  static const Registry r = [] {
    Registry reg;
    reg.bases.push_back(make_platform_base());
    reg.bases.push_back(make_stage6_base());
    for (const BaseInfo& b : reg.bases) {
      std::vector<EffectInfo> lib = b.physics_effects;
      for (EffectInfo& e : physical_detail::shared_block_effects(b)) lib.push_back(std::move(e));
      reg.libraries[b.name] = std::move(lib);
    }
    return reg;
  }();
  return r;
}

std::string base_names() {
  std::vector<std::string> names;
  for (const BaseInfo& b : base_library()) names.push_back("\"" + b.name + "\"");
  names.push_back("\"mechanical\" (described by the user: lpvid model init --base mechanical --from DESCRIPTION.json)");
  return join(names);
}

Index channel_index(const std::vector<std::string>& names, const std::string& name) {
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : it - names.begin();
}

}  // namespace

std::string block_kind_name(BlockKind kind) {
  switch (kind) {
    case BlockKind::kDelay: return "delay";
    case BlockKind::kFirstOrder: return "first_order";
    case BlockKind::kSecondOrder: return "second_order";
    case BlockKind::kResonance: return "resonance";
    case BlockKind::kGain: return "gain";
    case BlockKind::kCoupling: return "coupling";
    case BlockKind::kMode: return "mode";
  }
  return "?";
}

std::string block_side_name(BlockSide side) {
  switch (side) {
    case BlockSide::kInput: return "input";
    case BlockSide::kOutput: return "output";
    case BlockSide::kBody: return "body";
  }
  return "?";
}

BlockKind parse_block_kind(const std::string& text) {
  for (BlockKind k : {BlockKind::kDelay, BlockKind::kFirstOrder, BlockKind::kSecondOrder, BlockKind::kResonance,
                      BlockKind::kGain, BlockKind::kCoupling, BlockKind::kMode})
    if (block_kind_name(k) == text) return k;
  throw InputError(fmt::format("block kind '{}' is unknown; use delay, first_order, second_order, resonance, gain, "
                               "coupling or mode",
                               text));
}

BlockSide parse_block_side(const std::string& text) {
  for (BlockSide s : {BlockSide::kInput, BlockSide::kOutput, BlockSide::kBody})
    if (block_side_name(s) == text) return s;
  throw InputError(fmt::format("block side '{}' is unknown; use input, output or body (modes)", text));
}

std::vector<std::string> block_parameter_units(const BaseInfo& b, const Block& blk) {
  const std::string kind = block_kind_name(blk.kind);
  const bool input = blk.side == BlockSide::kInput, output = blk.side == BlockSide::kOutput;
  const auto& names = input ? b.input_names : b.output_names;
  const auto& units = input ? b.input_units : b.output_units;
  auto check_side = [&](bool ok, const char* allowed) {
    if (!ok)
      throw InputError(fmt::format("a {} block cannot sit on the {} side; it belongs on the {} side", kind,
                                   block_side_name(blk.side), allowed));
  };
  auto check_channels = [&]() {
    for (const std::string& c : blk.channels)
      if (channel_index(names, c) < 0)
        throw InputError(fmt::format("{} block: channel '{}' is not an {} of base '{}'; its {}s are {}", kind, c,
                                     block_side_name(blk.side), b.name, block_side_name(blk.side), join(names)));
    for (std::size_t a = 0; a < blk.channels.size(); ++a)
      for (std::size_t c = a + 1; c < blk.channels.size(); ++c)
        if (blk.channels[a] == blk.channels[c])
          throw InputError(fmt::format("{} block: channel '{}' is listed twice; list each channel once", kind,
                                       blk.channels[a]));
  };
  switch (blk.kind) {
    case BlockKind::kDelay:
      check_side(input, "input");
      check_channels();
      return {"s"};
    case BlockKind::kFirstOrder:
      check_side(input || output, "input or output");
      check_channels();
      return {"s"};
    case BlockKind::kSecondOrder:
      check_side(input || output, "input or output");
      check_channels();
      return {"rad/s", "1"};
    case BlockKind::kResonance:
      check_side(input || output, "input or output");
      check_channels();
      return {"rad/s", "1", "rad/s", "1"};
    case BlockKind::kGain: {
      check_side(input || output, "input or output");
      check_channels();
      if (blk.channels.empty())
        throw InputError("gain block: list its channels (one gain parameter per channel, in the same order)");
      return std::vector<std::string>(blk.channels.size(), "1");
    }
    case BlockKind::kCoupling: {
      check_side(input || output, "input or output");
      check_channels();
      if (blk.channels.size() != 2)
        throw InputError(fmt::format("coupling block: give two channels [from, to], got {}", blk.channels.size()));
      return {ratio_unit(units[static_cast<std::size_t>(channel_index(names, blk.channels[1]))],
                         units[static_cast<std::size_t>(channel_index(names, blk.channels[0]))])};
    }
    case BlockKind::kMode: {
      check_side(blk.side == BlockSide::kBody, "body");
      if (!blk.channels.empty()) throw InputError("mode block: a mode has no channels (its shape has one entry per DOF)");
      std::vector<std::string> u{"rad/s", "1"};
      for (const std::string& unit : b.dof_units) u.push_back(shape_unit(unit));
      return u;
    }
  }
  return {};
}

const std::vector<BaseInfo>& base_library() { return registry().bases; }

const BaseInfo* find_base(const std::string& name) {
  for (const BaseInfo& b : base_library())
    if (b.name == name) return &b;
  return nullptr;
}

const BaseInfo& base_info(const std::string& name) {
  const BaseInfo* b = find_base(name);
  if (b == nullptr) throw InputError(fmt::format("unknown base model '{}'; the bases are {}", name, base_names()));
  return *b;
}

const std::vector<EffectInfo>& effect_library(const std::string& base) {
  base_info(base);  // throws for an unknown base
  return registry().libraries.at(base);
}

const EffectInfo* find_effect(const std::string& base, const std::string& name) {
  if (find_base(base) == nullptr) return nullptr;
  for (const EffectInfo& e : effect_library(base))
    if (e.name == name) return &e;
  return nullptr;
}

PhysicalModel PhysicalModel::bare(const std::string& base) {
  if (base == "mechanical")
    throw InputError("base 'mechanical' is described by the user: give its description (lpvid model init --base "
                     "mechanical --from DESCRIPTION.json; docs/formats.md)");
  PhysicalModel m;
  m.base = base;
  m.parameters = lpvid::base_info(base).parameters;
  return m;
}

PhysicalModel PhysicalModel::bare(std::shared_ptr<const UserBase> user) {
  LPVID_ASSERT(user != nullptr);
  PhysicalModel m;
  m.base = user->info.name;
  m.user_base = std::move(user);
  m.parameters = m.user_base->info.parameters;
  return m;
}

PhysicalModel PhysicalModel::initial(const std::string& base) {
  PhysicalModel m = bare(base);
  for (const std::string& e : lpvid::base_info(base).default_effects) m.add_effect(e);
  return m;
}

const BaseInfo& PhysicalModel::base_info() const {
  if (user_base != nullptr) {
    if (base != user_base->info.name)
      throw InputError(fmt::format("the model names base '{}' but carries a {} description; write \"base\": \"{}\"",
                                   base, user_base->info.name, user_base->info.name));
    return user_base->info;
  }
  if (base == "mechanical")
    throw InputError("base 'mechanical' needs its description (key \"mechanical\" of the model file; lpvid model init "
                     "--base mechanical --from DESCRIPTION.json writes it)");
  return lpvid::base_info(base);
}

const std::vector<EffectInfo>& PhysicalModel::library() const {
  if (user_base != nullptr) {
    base_info();  // the name must match
    return user_base->library;
  }
  return effect_library(base_info().name);
}

const EffectInfo* PhysicalModel::effect_info(const std::string& name) const {
  for (const EffectInfo& e : library())
    if (e.name == name) return &e;
  for (const EffectInfo& d : definitions)
    if (d.name == name) return &d;
  return nullptr;
}

std::vector<std::string> PhysicalModel::absent_time_effects() const {
  std::vector<std::string> out;
  for (const EffectInfo& e : library())
    // position_ripple_2 once the first ripple is in the model (ripples are added one at a
    // time, as modes are)
    if (e.time_only && !has_effect(e.name) && !(e.name == "position_ripple_2" && !has_effect("position_ripple")))
      out.push_back(e.name);
  return out;
}

std::vector<std::string> PhysicalModel::absent_effects() const {
  std::vector<std::string> out;
  for (const EffectInfo& e : library()) {
    if (has_effect(e.name) || e.time_only) continue;
    // structural_mode_k (k >= 2) once the mode before it is in the model: modes are
    // added one at a time, each candidate a new one
    if (e.name.rfind("structural_mode_", 0) == 0) {
      const int k = std::atoi(e.name.c_str() + std::strlen("structural_mode_"));
      const std::string before = k == 2 ? "structural_mode" : fmt::format("structural_mode_{}", k - 1);
      if (!has_effect(before)) continue;
    }
    out.push_back(e.name);
  }
  for (const EffectInfo& d : definitions)
    if (!has_effect(d.name)) out.push_back(d.name);
  return out;
}

void PhysicalModel::add_effect(const std::string& name) {
  const EffectInfo* e = effect_info(name);
  if (e == nullptr) {
    std::vector<std::string> names;
    for (const EffectInfo& x : library()) names.push_back(x.name);
    for (const EffectInfo& d : definitions) names.push_back(d.name + " (user-defined)");
    throw InputError(fmt::format("unknown effect '{}'; the library of base '{}' has {}", name, base, join(names)));
  }
  if (has_effect(name))
    throw InputError(fmt::format("effect '{}' is already in the model; each effect can be added once", name));
  for (const PhysicalParameter& q : e->parameters)
    if (index_of(q.name) >= 0)
      throw InputError(fmt::format("effect '{}' needs parameter '{}', which the model already has (from another "
                                   "effect); rename the user-defined effect's parameters",
                                   name, q.name));
  effects.push_back(name);
  for (const PhysicalParameter& q : e->parameters) {
    // the user's design value for it, if any, replaces the library's default
    const auto known = std::find_if(design_values.begin(), design_values.end(),
                                    [&](const PhysicalParameter& d) { return d.name == q.name; });
    if (known == design_values.end()) {
      parameters.push_back(q);
    } else {
      parameters.push_back(*known);
      design_values.erase(known);
    }
  }
  for (const std::string& h : e->holds)
    for (const PhysicalParameter& design : base_info().parameters)
      if (design.name == h) {
        PhysicalParameter& q = parameter(h);
        q.value = design.value;
        q.free = false;
      }
}

void PhysicalModel::remove_effect(const std::string& name) {
  if (!has_effect(name))
    throw InputError(fmt::format("the model has no effect '{}' to remove; it has {}", name,
                                 effects.empty() ? std::string("none") : join(effects)));
  const EffectInfo* e = effect_info(name);
  LPVID_ASSERT(e != nullptr);
  effects.erase(std::find(effects.begin(), effects.end(), name));
  for (const PhysicalParameter& q : e->parameters) {
    const Index i = index_of(q.name);
    if (i < 0) continue;
    // a prior is what the user knows about the effect: kept for when it comes back
    if (parameters[static_cast<std::size_t>(i)].has_prior()) design_values.push_back(parameters[static_cast<std::size_t>(i)]);
    parameters.erase(parameters.begin() + i);
  }
  for (const std::string& h : e->holds)
    if (index_of(h) >= 0) parameter(h).free = true;
}

void PhysicalModel::define_effect(const EffectInfo& def) {
  const BaseInfo& b = base_info();
  auto fail = [&](const std::string& what) {
    throw InputError(fmt::format("user-defined effect '{}': {}", def.name, what));
  };
  if (def.name.empty() || def.name.find_first_of(" \t\r\n,\"") != std::string::npos)
    throw InputError(fmt::format("user-defined effect name '{}': give a name without blanks, commas or quotes",
                                 def.name));
  if (std::any_of(library().begin(), library().end(), [&](const EffectInfo& e) { return e.name == def.name; }))
    fail("the library already has an effect of that name; choose another name");
  for (const EffectInfo& d : definitions)
    if (d.name == def.name) fail("it is defined twice; define each effect once");
  if (def.blocks.empty()) fail("it has no blocks; give at least one building block (docs/effects.md)");
  // parameters: unique, not clashing with the base's, finite, bounds ordered
  for (std::size_t k = 0; k < def.parameters.size(); ++k) {
    const PhysicalParameter& q = def.parameters[k];
    if (q.name.empty()) fail("a parameter has an empty name");
    for (std::size_t j = 0; j < k; ++j)
      if (def.parameters[j].name == q.name) fail(fmt::format("parameter '{}' is declared twice", q.name));
    for (const PhysicalParameter& bp : b.parameters)
      if (bp.name == q.name) fail(fmt::format("parameter '{}' is a parameter of the base; choose another name", q.name));
    if (!std::isfinite(q.value) || !std::isfinite(q.lower) || !std::isfinite(q.upper) || q.lower > q.upper ||
        q.value < q.lower || q.value > q.upper)
      fail(fmt::format("parameter '{}': value {} and bounds [{}, {}] must be finite with lower <= value <= upper",
                       q.name, q.value, q.lower, q.upper));
  }
  std::vector<bool> used(def.parameters.size(), false);
  for (const Block& blk : def.blocks) {
    std::vector<std::string> units;
    try {
      units = block_parameter_units(b, blk);
    } catch (const InputError& e) {
      fail(e.what());
    }
    if (blk.parameters.size() != units.size())
      fail(fmt::format("a {} block takes {} parameter(s) ({}), got {}", block_kind_name(blk.kind), units.size(),
                       join(units), blk.parameters.size()));
    for (std::size_t k = 0; k < blk.parameters.size(); ++k) {
      const auto it = std::find_if(def.parameters.begin(), def.parameters.end(),
                                   [&](const PhysicalParameter& q) { return q.name == blk.parameters[k]; });
      if (it == def.parameters.end())
        fail(fmt::format("its {} block uses parameter '{}', which the effect does not declare",
                         block_kind_name(blk.kind), blk.parameters[k]));
      if (it->unit != units[k])
        fail(fmt::format("parameter '{}' has unit '{}' but its place in the {} block takes '{}'", it->name, it->unit,
                         block_kind_name(blk.kind), units[k]));
      used[static_cast<std::size_t>(it - def.parameters.begin())] = true;
      const bool positive = units[k] == "s" || units[k] == "rad/s";
      if (positive && it->lower <= 0 && !(blk.kind == BlockKind::kDelay && it->lower == 0))
        fail(fmt::format("parameter '{}' ({}) must have a lower bound > 0", it->name, units[k]));
      if (blk.kind == BlockKind::kDelay && it->lower < 0)
        fail(fmt::format("delay '{}' must have a lower bound >= 0", it->name));
      if (units[k] == "1" && (blk.kind == BlockKind::kSecondOrder || blk.kind == BlockKind::kResonance ||
                              blk.kind == BlockKind::kMode) && (k == 1 || k == 3) && it->lower <= 0)
        fail(fmt::format("damping '{}' must have a lower bound > 0", it->name));
    }
  }
  for (std::size_t k = 0; k < used.size(); ++k)
    if (!used[k]) fail(fmt::format("parameter '{}' is declared but no block uses it", def.parameters[k].name));
  EffectInfo copy = def;
  copy.user_defined = true;
  definitions.push_back(std::move(copy));
}

bool PhysicalModel::has_effect(const std::string& name) const {
  return std::find(effects.begin(), effects.end(), name) != effects.end();
}

Index PhysicalModel::index_of(const std::string& name) const {
  for (std::size_t i = 0; i < parameters.size(); ++i)
    if (parameters[i].name == name) return static_cast<Index>(i);
  return -1;
}

const PhysicalParameter& PhysicalModel::parameter(const std::string& name) const {
  const Index i = index_of(name);
  if (i < 0) {
    std::vector<std::string> names;
    for (const auto& q : parameters) names.push_back(q.name);
    throw InputError(fmt::format("the model has no parameter '{}'; give one of {}", name, join(names)));
  }
  return parameters[static_cast<std::size_t>(i)];
}

PhysicalParameter& PhysicalModel::parameter(const std::string& name) {
  return const_cast<PhysicalParameter&>(static_cast<const PhysicalModel&>(*this).parameter(name));
}

namespace {
// The library entry of a parameter of an effect (library or definition) the model
// lacks; nullptr when there is none.
const PhysicalParameter* absent_effect_parameter(const PhysicalModel& m, const std::string& name) {
  auto look = [&](const EffectInfo& e) -> const PhysicalParameter* {
    if (m.has_effect(e.name)) return nullptr;
    for (const PhysicalParameter& q : e.parameters)
      if (q.name == name) return &q;
    return nullptr;
  };
  for (const EffectInfo& e : m.library())
    if (const PhysicalParameter* q = look(e)) return q;
  for (const EffectInfo& e : m.definitions)
    if (const PhysicalParameter* q = look(e)) return q;
  return nullptr;
}
}  // namespace

PhysicalParameter& PhysicalModel::parameter_or_design_value(const std::string& name) {
  if (index_of(name) >= 0) return parameter(name);
  for (PhysicalParameter& d : design_values)
    if (d.name == name) return d;
  if (const PhysicalParameter* q = absent_effect_parameter(*this, name)) return design_values.emplace_back(*q);
  std::vector<std::string> names;
  for (const auto& q : parameters) names.push_back(q.name);
  throw InputError(fmt::format("the model has no parameter '{}', and no effect it could add has one; give one of {} "
                               "or a parameter of an effect it lacks (lpvid model effects)",
                               name, join(names)));
}

Eigen::VectorXd PhysicalModel::values() const {
  Eigen::VectorXd v(static_cast<Index>(parameters.size()));
  for (std::size_t i = 0; i < parameters.size(); ++i) v(static_cast<Index>(i)) = parameters[i].value;
  return v;
}

std::vector<Index> PhysicalModel::free_indices() const {
  std::vector<Index> out;
  for (std::size_t i = 0; i < parameters.size(); ++i)
    if (parameters[i].free) out.push_back(static_cast<Index>(i));
  return out;
}

namespace {
// A parameter's own rules against its library entry: unit, finite, bounds, prior.
void check_parameter_rules(const PhysicalParameter& q, const PhysicalParameter& lib) {
  if (q.unit != lib.unit)
    throw InputError(fmt::format("parameter '{}' has unit '{}'; its unit is '{}'; convert the value and write that "
                                 "unit",
                                 q.name, q.unit, lib.unit));
  if (!std::isfinite(q.value) || !std::isfinite(q.lower) || !std::isfinite(q.upper))
    throw InputError(fmt::format("parameter '{}': value {}, bounds [{}, {}]; all must be finite numbers", q.name,
                                 q.value, q.lower, q.upper));
  if (q.lower > q.upper)
    throw InputError(fmt::format("parameter '{}': bounds reversed, lower {} > upper {}; swap them", q.name, q.lower,
                                 q.upper));
  if (q.value < q.lower || q.value > q.upper)
    throw InputError(fmt::format("parameter '{}': value {} is outside its bounds [{}, {}]; change the value or the "
                                 "bounds",
                                 q.name, q.value, q.lower, q.upper));
  if (!std::isfinite(q.prior_mean) || !std::isfinite(q.prior_sigma) || q.prior_sigma < 0.0)
    throw InputError(fmt::format("parameter '{}': prior {} ± {}; give a finite design value and an uncertainty > 0",
                                 q.name, q.prior_mean, q.prior_sigma));
}
}  // namespace

void PhysicalModel::validate() const {
  const BaseInfo& b = base_info();
  // Definitions: re-check each against the base (a copy defines them one by one).
  {
    PhysicalModel check;
    check.base = base;
    check.user_base = user_base;
    for (const EffectInfo& d : definitions) check.define_effect(d);
  }
  std::vector<const PhysicalParameter*> expected;
  for (const auto& q : b.parameters) expected.push_back(&q);
  for (std::size_t k = 0; k < effects.size(); ++k) {
    const EffectInfo* e = effect_info(effects[k]);
    if (e == nullptr) {
      std::vector<std::string> names;
      for (const EffectInfo& x : library()) names.push_back(x.name);
      throw InputError(fmt::format("unknown effect '{}'; the library of base '{}' has {}{}", effects[k], base,
                                   join(names),
                                   definitions.empty() ? std::string() : " (and the user-defined effects of the file)"));
    }
    for (std::size_t j = 0; j < k; ++j)
      if (effects[j] == effects[k])
        throw InputError(fmt::format("effect '{}' is listed twice; list each effect once", effects[k]));
    for (const auto& q : e->parameters) expected.push_back(&q);
  }
  for (const auto& q : parameters) {
    const PhysicalParameter* lib = nullptr;
    for (const auto* x : expected)
      if (x->name == q.name) lib = x;
    if (lib == nullptr) {
      std::string owner;
      for (const auto& e : library())
        for (const auto& x : e.parameters)
          if (x.name == q.name) owner = e.name;
      for (const auto& e : definitions)
        for (const auto& x : e.parameters)
          if (x.name == q.name) owner = e.name;
      throw InputError(owner.empty()
                           ? fmt::format("unknown parameter '{}'; see 'lpvid model effects' for the parameter names",
                                         q.name)
                           : fmt::format("parameter '{}' belongs to effect '{}', which the model does not list; add "
                                         "\"{}\" to \"effects\" or remove the parameter",
                                         q.name, owner, owner));
    }
    check_parameter_rules(q, *lib);
  }
  for (std::size_t k = 0; k < design_values.size(); ++k) {
    const PhysicalParameter& q = design_values[k];
    const PhysicalParameter* lib = absent_effect_parameter(*this, q.name);
    if (lib == nullptr)
      throw InputError(index_of(q.name) >= 0
                           ? fmt::format("design value '{}' is a parameter the model has; set it under \"parameters\" "
                                         "and remove it from \"design_values\"",
                                         q.name)
                           : fmt::format("design value '{}' is no parameter of an effect the model could add; see "
                                         "'lpvid model effects' for the parameter names",
                                         q.name));
    for (std::size_t j = 0; j < k; ++j)
      if (design_values[j].name == q.name)
        throw InputError(fmt::format("design value '{}' is given twice; give it once", q.name));
    check_parameter_rules(q, *lib);
  }
  for (const auto* x : expected) {
    int count = 0;
    for (const auto& q : parameters) count += q.name == x->name ? 1 : 0;
    if (count == 0)
      throw InputError(fmt::format("missing parameter '{}' (unit {}); give it, e.g. its default {}", x->name, x->unit,
                                   x->value));
    if (count > 1) throw InputError(fmt::format("parameter '{}' is given {} times; give it once", x->name, count));
  }
}

}  // namespace lpvid
