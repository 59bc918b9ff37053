// lpvid — physical (grey-box) models: a BASE (the physics of one system, e.g. the
// seed-000 platform) plus a list of EFFECTS, each a small documented unit with
// named parameters (docs/effects.md).  One framework for every base: the
// parameters (value, unit, bounds, free), the effects (library or user-defined),
// their building blocks and the validation are here; each base's physics lives in
// its own folder (idlib/physical/platform/).
//
// A model is
//
//   u ──► [input blocks] ──► w ──► base (M(s) q = B_w w, plus modes) ──► q ──► [output blocks] ──► y
//
// with u the base's inputs (the platform: T_psi T_theta F_z) and y its outputs (psi
// theta z).  The base is a second-order rigid body M q'' + D q' + K q = w whose
// M, D, K depend on the base's parameters, on its scheduling variable (the
// platform: the beam position x_b) and on the PHYSICS effects of that base
// (rod twist, centre-of-mass offsets, beam gravity).  All other effects are made
// of BUILDING BLOCKS that any base shares:
//
// | block        | side          | parameters (in this order)             | transfer function / action |
// |--------------|---------------|----------------------------------------|----------------------------|
// | delay        | input         | tau_s                                  | e^{-s tau} on each listed input |
// | first_order  | input, output | tau_s                                  | 1/(tau s + 1) on each listed channel |
// | second_order | input, output | omega_rad_s, zeta                      | omega²/(s² + 2 zeta omega s + omega²) |
// | resonance    | input, output | omega_p, zeta_p, omega_z, zeta_z       | (omega_p²/omega_z²)(s² + 2 zeta_z omega_z s + omega_z²)/(s² + 2 zeta_p omega_p s + omega_p²) (unit DC gain) |
// | gain         | input, output | g (one per listed channel, in order)   | channel × g |
// | coupling     | input, output | c                                      | channel[1] += c × channel[0] (static cross-talk) |
// | mode         | body          | omega_rad_s, zeta, shape per DOF       | eta'' + 2 zeta omega eta' + omega² eta = phiᵀ w, q += phi eta (collocated) |
//
// "Listed channels" empty means every channel of that side.  A parameter may be
// shared by several blocks (one lag time constant on every input).  Input delays
// are applied exactly in discrete time, including fractional samples
// (idlib/physical/evaluate.h).
//
// Parameters.  A model is a flat list of parameters: the base's, then those of
// each enabled effect in the order the effects were added.  Names are unique in a
// model and carry their unit (STYLE.md item 2); the unit is also stored as text.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct PhysicalParameter {
  std::string name;  // unique in a model, unit suffix included (e.g. "damping_z_Ns_per_m")
  std::string unit;  // as text, e.g. "N·s/m"; "1" for dimensionless
  double value = 0.0;
  double lower = 0.0;  // bounds, lower <= value <= upper, both finite
  double upper = 0.0;
  bool free = false;  // estimated by fit, else held at value
  // A Gaussian prior: a design value known to ±prior_sigma (a weighed mass, a
  // datasheet force constant); fit and diagnose then estimate the maximum a
  // posteriori value (idlib/fit/fit.h).  prior_sigma 0: no prior.
  double prior_mean = 0.0;
  double prior_sigma = 0.0;
  bool has_prior() const { return prior_sigma > 0.0; }
};

enum class BlockKind { kDelay, kFirstOrder, kSecondOrder, kResonance, kGain, kCoupling, kMode };
enum class BlockSide { kInput, kOutput, kBody };

// "delay", "first_order", ... and "input", "output", "body".
std::string block_kind_name(BlockKind kind);
std::string block_side_name(BlockSide side);
// @throws InputError  unknown text (the message lists the allowed names).
BlockKind parse_block_kind(const std::string& text);
BlockSide parse_block_side(const std::string& text);

// One building block (table above).  channels are channel NAMES of the base
// (inputs for side input, outputs for side output); parameters are parameter
// names of the model, in the order the table gives for the kind.  A mode takes
// 2 + (number of DOFs) parameters: omega, zeta, then the shape entry of each DOF.
struct Block {
  BlockKind kind = BlockKind::kGain;
  BlockSide side = BlockSide::kInput;
  std::vector<std::string> channels;
  std::vector<std::string> parameters;
};

// A library or user-defined effect.
struct EffectInfo {
  std::string name;         // e.g. "input_delay"
  std::string description;  // one line
  std::string changes;      // how it changes the model (one or two sentences)
  std::string signature;    // the residual signature it explains
  std::vector<PhysicalParameter> parameters;  // with their defaults and bounds
  std::vector<Block> blocks;  // empty: a physics effect of its base (its terms enter M, D, K)
  bool user_defined = false;  // declared in a model file, not in the library
  // Base parameters the data cannot separate from this effect's own: adding the
  // effect holds them at their design values (the base's defaults, not free), so
  // that the effect carries what goes beyond the design (rod_twist: the tilt
  // stiffness beyond the rods' designed bending).  Removing the effect frees them.
  std::vector<std::string> holds;
  // A nonlinear effect with no frequency response (Coulomb friction, a constant force
  // offset): only the time-domain force-error route uses it (idlib/fit/force_error.h;
  // `lpvid fit --log`, `lpvid diagnose --log` on a mechanical base).  The frequency
  // routes refuse a model that has one (ModelLayout) and never propose one.
  bool time_only = false;
};

// What a base is: its parameters and channels.  The physics is in the base's
// folder (evaluate.h dispatches on the name).
struct PhysicalModel;
struct ModelLayout;  // idlib/physical/evaluate.h

struct BaseInfo {
  std::string name;         // "platform"
  std::string description;  // one line
  std::vector<PhysicalParameter> parameters;             // defaults, bounds, free flags
  std::vector<std::string> input_names, input_units;     // e.g. T_psi N·m
  std::vector<std::string> output_names, output_units;   // e.g. psi rad
  std::vector<std::string> dof_names;                    // q, e.g. psi theta z (outputs are q)
  std::vector<std::string> dof_units;                    // e.g. rad rad m (a mode's shape units follow them)
  std::string schedule_name;  // the scheduling variable, e.g. "beam position x_b"; "" = none
  std::string schedule_unit;  // "m"
  std::string schedule_symbol;  // its short name in tables, e.g. "x_b"; "" = none
  std::vector<std::string> default_effects;  // what `model init` adds
  // The structural_mode's frequency bounds (rad/s): above the rigid-body band of the
  // library's bases; a user's stage may have its modes anywhere.
  double mode_lower_rad_s = 300.0, mode_upper_rad_s = 6000.0;
  // How many structural modes the library offers (structural_mode, structural_mode_2, ...).
  int max_modes = 1;
  std::vector<EffectInfo> physics_effects;   // this base's physics effects
  // Dimensionless tolerances on a design value: {scale, design} means the model uses
  // design × scale, the scale bounded to the build's tolerance (platform: the rods'
  // bending_scale_psi/theta on k_torque_low_Nm_per_rad, 0.5–2x).  A scale the data
  // push onto its bound says the design value itself is off (diagnose's guidance).
  std::vector<std::pair<std::string, std::string>> design_scales;
  // The base's own hooks, so that the framework (evaluate.cc, fit, diagnose) knows
  // no base by name.  compile: records the base's parameter positions in the layout
  // (ModelLayout::platform, ::stage6, ::mechanical — each base's matrices read them).
  // check_schedule: @throws InputError for an operating point outside the base's
  // range (the platform's beam stroke, the stage's gap); empty: finite is enough.
  std::function<void(ModelLayout&, const PhysicalModel&)> compile;
  std::function<void(const PhysicalModel&, double)> check_schedule;
  // How `fit/diagnose/compare --log` reach a model of this base, so that the CLI's
  // time routes dispatch on the kind of physics, not on the base's name:
  //   kNone: no time-domain fit (the platform: compare --log simulates its parameters);
  //   kStageOutputError: the nonlinear rigid-body equations of motion fitted by
  //     equation and output error (stage6: idlib/stage6/stage6_time.h);
  //   kForceError: the equation of motion checked sample by sample on a log of every
  //     DOF's position (a mechanical base: idlib/fit/force_error.h).
  enum class TimeRoute { kNone, kStageOutputError, kForceError };
  TimeRoute time_route = TimeRoute::kNone;
};

// The library's bases ("platform", "stage6").  A model may instead carry a base of
// its own, declared by the user ("mechanical": idlib/physical/mechanical/).
const std::vector<BaseInfo>& base_library();
// The base of that name, or nullptr.
const BaseInfo* find_base(const std::string& name);
// @throws InputError  unknown base (the message lists the bases).
const BaseInfo& base_info(const std::string& name);

// The effect library of a base: its physics effects, then the block effects every
// base shares, instantiated with the base's channel names (structural_mode,
// input_delay, actuator_lag, gain_error, sensor_gain, sensor_crosstalk).
const std::vector<EffectInfo>& effect_library(const std::string& base);
// The library entry of name for base, or nullptr.
const EffectInfo* find_effect(const std::string& base, const std::string& name);

namespace physical_detail {
// The block effects every base shares, with b's channel names (structural_mode,
// input_delay, actuator_lag, gain_error, sensor_gain, sensor_crosstalk).
std::vector<EffectInfo> shared_block_effects(const BaseInfo& b);
}  // namespace physical_detail

struct UserBase;  // idlib/physical/mechanical/mechanical_base.h

struct PhysicalModel {
  std::string base = "platform";
  // The user-described base when base == "mechanical" (its description travels in
  // the model file); null for the library's bases.
  std::shared_ptr<const UserBase> user_base;
  std::vector<PhysicalParameter> parameters;  // base first, then each enabled effect's
  std::vector<std::string> effects;           // enabled effects, in order
  // User-defined effects declared in the model file (enabled or not); their names
  // differ from the library's.
  std::vector<EffectInfo> definitions;
  // What the user knows about an effect the model does not have yet: a datasheet's
  // coil time constant with its uncertainty (`model set --set
  // actuator_lag_tau_s=5e-5±5e-5` on a model without actuator_lag).  Each is a
  // parameter of an absent effect (library or definition) with its value, bounds,
  // free flag and prior; add_effect starts the effect from it (so diagnose's
  // candidates and `model add` carry the prior), and remove_effect keeps a removed
  // parameter's prior here.  Issue 25: the prior that separates a delay from a lag.
  std::vector<PhysicalParameter> design_values;

  // The base alone (no effect).  @throws InputError unknown base.
  static PhysicalModel bare(const std::string& base = "platform");
  // The base with its default effects (`lpvid model init`).
  static PhysicalModel initial(const std::string& base = "platform");
  // A model of a user-described base (no effect; its defaults are the description's).
  static PhysicalModel bare(std::shared_ptr<const UserBase> user_base);

  // The model's base: the library's entry, or the user's.  @throws InputError
  // unknown base, or "mechanical" without a description.
  const BaseInfo& base_info() const;
  // The effect library of the model's base (effect_library(base) for the library's bases).
  const std::vector<EffectInfo>& library() const;

  // The library entry or user definition of an effect name, or nullptr.
  const EffectInfo* effect_info(const std::string& name) const;
  // Every effect the model could add (library + definitions) that it lacks, the
  // frequency routes' candidates: time-only effects are not among them.
  std::vector<std::string> absent_effects() const;
  // The time-only effects (EffectInfo::time_only) of its library that it lacks.
  std::vector<std::string> absent_time_effects() const;

  // Adds the effect (library or definition) with its default parameters, and holds
  // the base parameters it names in `holds` at their design values.
  // @throws InputError  unknown effect (the message lists what there is); already enabled.
  void add_effect(const std::string& name);
  // Removes an enabled effect and its parameters (everything else kept as it is);
  // the base parameters it held become free again.
  // @throws InputError  the model does not have it.
  void remove_effect(const std::string& name);
  // Declares a user-defined effect (not enabled).  @throws InputError  as validate()
  // for the definition: name clashes with the library, a block's channel or
  // parameter unknown, parameter counts of a kind, units of its kind.
  void define_effect(const EffectInfo& definition);

  bool has_effect(const std::string& name) const;
  Index index_of(const std::string& name) const;  // -1 when absent
  // @throws InputError  unknown parameter name (the message lists the model's names).
  const PhysicalParameter& parameter(const std::string& name) const;
  PhysicalParameter& parameter(const std::string& name);
  // The model's parameter of that name or, for a parameter of an effect the model
  // lacks, its design value (created from the library's default on first use).
  // @throws InputError  a name neither the model nor any absent effect has.
  PhysicalParameter& parameter_or_design_value(const std::string& name);

  Eigen::VectorXd values() const;
  std::vector<Index> free_indices() const;

  // Every rule a model can break, as InputError naming the parameter or effect:
  // base known; effects known (library or definitions) and not repeated; the
  // parameter list is exactly the base's plus each enabled effect's (no unknown,
  // none missing, none twice); unit equals the library's (or the definition's);
  // value and bounds finite; lower <= upper; lower <= value <= upper; each
  // definition valid (define_effect); each design value a parameter of an absent
  // effect, given once, with the rules of a parameter.
  void validate() const;
};

// The unit a building block gives each of its parameters for a base, e.g.
// first_order -> {"s"}; gain on output "z" -> {"1"}; coupling from psi to z on the
// output side -> {"m/rad"}; a mode -> {"rad/s", "1", shape units per DOF}.
// @throws InputError  a channel unknown for that side, wrong channel count, side
//   not allowed for the kind.
std::vector<std::string> block_parameter_units(const BaseInfo& base, const Block& block);

}  // namespace lpvid
