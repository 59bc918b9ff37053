#include "idlib/stage6/stage6_time.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

// theta index -> model parameter (kStageThetaNames order).
constexpr const char* kThetaParameter[stage6::kStageThetaSize] = {
    "mass_kg", "inertia_xx_kgm2", "inertia_yy_kgm2", "inertia_zz_kgm2", "force_constant_scale", "com_x_m", "com_y_m",
    "com_z_m", "gap_decay_per_m", "electrical_time_constant_s", "back_emf_damping_Ns_per_m"};

double value_of(const PhysicalModel& m, const char* name) { return m.parameter(name).value; }

}  // namespace

const std::vector<std::string>& stage6_time_effects() {
  static const std::vector<std::string> e = {"com_offset", "gap_dependence", "electrical_lag"};
  return e;
}

std::string stage6_time_parameter_name(int theta_index) {
  LPVID_ASSERT(theta_index >= 0 && theta_index < stage6::kStageThetaSize);
  return kThetaParameter[theta_index];
}

Stage6TimeSetup stage6_time_setup(const PhysicalModel& model) {
  if (model.base != "stage6")
    throw InputError(fmt::format("the time-domain fit (--log) is for models of base stage6, and this model's base is "
                                 "'{}'; fit a {} model to responses (--data), or check it against a log with "
                                 "lpvid compare --log",
                                 model.base, model.base));
  model.validate();
  std::vector<std::string> unsupported;
  for (const auto& e : model.effects)
    if (std::find(stage6_time_effects().begin(), stage6_time_effects().end(), e) == stage6_time_effects().end())
      unsupported.push_back(e);
  if (!unsupported.empty())
    throw InputError(fmt::format(
        "effect{} {} of the model ha{} no time-domain form (the time-domain route simulates {}); remove {} "
        "(lpvid model remove), or fit the model to the plant's frequency response instead (lpvid frf --input "
        "u1,u2,u3,u6,u5,u4 ... on the log, then lpvid fit --data P.csv@0)",
        unsupported.size() > 1 ? "s" : "", fmt::join(unsupported, ", "), unsupported.size() > 1 ? "ve" : "s",
        fmt::join(stage6_time_effects(), ", "), unsupported.size() > 1 ? "them" : "it"));
  for (const char* h : {"inertia_xx_kgm2", "inertia_yy_kgm2", "inertia_zz_kgm2"})
    if (!model.parameter(h).free)
      throw InputError(fmt::format("{} is held in the model, but the time-domain fit estimates every inertia; free "
                                   "it (\"free\": true in the model file) or use the frequency route",
                                   h));
  const bool mass_free = model.parameter("mass_kg").free, kappa_free = model.parameter("force_constant_scale").free;
  if (mass_free == kappa_free)
    throw InputError(fmt::format(
        "mass_kg and force_constant_scale are both {}: a log of commanded wrench and motion determines only their "
        "ratio, so exactly one must be free (by default the weighed mass is held and the force constant fitted)",
        mass_free ? "free" : "held"));
  if (std::abs(value_of(model, "gravity_m_per_s2") - stage6::kGravity_m_per_s2) > 1e-12)
    throw InputError(fmt::format("gravity_m_per_s2 is {} in the model, but the time-domain route uses the stage's "
                                 "{} m/s²; set it back to {}",
                                 value_of(model, "gravity_m_per_s2"), stage6::kGravity_m_per_s2,
                                 stage6::kGravity_m_per_s2));
  Stage6TimeSetup s;
  s.fix_mass = !mass_free;
  s.nominal.mass_kg = value_of(model, "mass_kg");
  s.nominal.inertia_kgm2 = Eigen::Vector3d(value_of(model, "inertia_xx_kgm2"), value_of(model, "inertia_yy_kgm2"),
                                           value_of(model, "inertia_zz_kgm2"))
                               .asDiagonal();
  for (int i = 0; i < 4; ++i)
    for (int a = 0; a < 3; ++a)
      s.nominal.lever_arms_m(a, i) = value_of(model, fmt::format("lever_arm_{}_{}_m", i + 1, "xyz"[a]).c_str());
  if (model.has_effect("gap_dependence"))  // gamma = 2 pi / pitch: the start value of the fit
    s.nominal.magnet_pitch_m = 2.0 * std::numbers::pi / value_of(model, "gap_decay_per_m");
  s.nominal.validate();
  s.model.com_offset = model.has_effect("com_offset");
  s.model.gap_dependence = model.has_effect("gap_dependence");
  s.model.electrical_lag = model.has_effect("electrical_lag");
  return s;
}

PhysicalModel stage6_model_of(const stage6::StageFitModel& effects, bool fix_mass) {
  PhysicalModel m = PhysicalModel::bare("stage6");
  if (effects.com_offset) m.add_effect("com_offset");
  if (effects.gap_dependence) m.add_effect("gap_dependence");
  if (effects.electrical_lag) m.add_effect("electrical_lag");
  m.parameter("mass_kg").free = !fix_mass;
  m.parameter("force_constant_scale").free = fix_mass;
  return m;
}

Eigen::Matrix<double, stage6::kStageThetaSize, 1> stage6_time_theta(const PhysicalModel& model) {
  Eigen::Matrix<double, stage6::kStageThetaSize, 1> theta = Eigen::Matrix<double, stage6::kStageThetaSize, 1>::Zero();
  const stage6::StageParameters nominal;
  theta(9) = nominal.electrical_time_constant_s();
  for (int i = 0; i < stage6::kStageThetaSize; ++i) {
    const Index k = model.index_of(kThetaParameter[i]);
    if (k >= 0) theta(i) = model.parameters[static_cast<std::size_t>(k)].value;
  }
  return theta;
}

PhysicalModel stage6_apply_time_fit(const PhysicalModel& model,
                                    const Eigen::Matrix<double, stage6::kStageThetaSize, 1>& theta,
                                    std::vector<std::string>* warnings) {
  PhysicalModel out = model;
  for (int i = 0; i < stage6::kStageThetaSize; ++i) {
    const Index k = out.index_of(kThetaParameter[i]);
    if (k < 0) continue;
    PhysicalParameter& p = out.parameters[static_cast<std::size_t>(k)];
    if (!p.free) continue;
    const double v = std::clamp(theta(i), p.lower, p.upper);
    if (v != theta(i) && warnings)
      warnings->push_back(fmt::format("{}: the estimate {:.6g} lies outside the bounds [{:.6g}, {:.6g}] and was "
                                      "written as {:.6g}; widen the bounds if the value is physical",
                                      p.name, theta(i), p.lower, p.upper, v));
    p.value = v;
  }
  out.validate();
  return out;
}

StageErrorFigure stage_error_figure(const Eigen::MatrixXd& residual, const Eigen::MatrixXd& q) {
  LPVID_ASSERT(residual.cols() == 6 && q.cols() == 6 && residual.rows() == q.rows() && q.rows() >= 2);
  StageErrorFigure f;
  const Eigen::Index N = q.rows();
  double sum2 = 0.0, floor2 = 0.0, sum = 0.0;
  for (int c = 0; c < 6; ++c) {
    const double motion = std::max(std::sqrt((q.col(c).array() - q.col(c).mean()).square().sum() / double(N)), 1e-300);
    const double rel = std::sqrt(residual.col(c).squaredNorm() / double(N)) / motion;
    const Eigen::VectorXd de = residual.col(c).tail(N - 1) - residual.col(c).head(N - 1);
    const double floor = std::sqrt(de.squaredNorm() / double(N - 1) / 2.0) / motion;
    f.relative[static_cast<std::size_t>(c)] = rel;
    f.floor[static_cast<std::size_t>(c)] = floor;
    sum += rel;
    sum2 += rel * rel;
    floor2 += floor * floor;
    f.max = std::max(f.max, rel);
  }
  f.mean = sum / 6.0;
  f.error = std::sqrt(sum2 / 6.0);
  f.noise_floor = std::sqrt(floor2 / 6.0);
  return f;
}

}  // namespace lpvid
