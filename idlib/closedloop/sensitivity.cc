#include "idlib/closedloop/sensitivity.h"
#include "idlib/core/eigen_decompositions.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <Eigen/SVD>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include "idlib/lti/frequency_response.h"

namespace lpvid {
namespace {

// A frequency may exceed π / Ts by this relative amount (round-off of a grid that
// ends exactly at Nyquist, or of a period read from a file).
constexpr double kNyquistRelTolerance = 1e-9;

std::string shape(const Eigen::MatrixXcd& a) { return fmt::format("{}x{}", a.rows(), a.cols()); }

// Shape, count and finiteness checks shared by the three functions.
void check_frd(const FrequencyResponse& frd, const char* fn, const char* what, Index rows, Index cols) {
  const Index F = frd.num_frequencies();
  if (F == 0)
    throw InputError(fmt::format("{}: {} has no frequencies; pass at least one", fn, what));
  if (static_cast<Index>(frd.response.size()) != F)
    throw InputError(fmt::format("{}: {} has {} frequencies but {} response matrices; they must match", fn,
                                 what, F, frd.response.size()));
  if (!frd.coherence.empty() && static_cast<Index>(frd.coherence.size()) != F)
    throw InputError(fmt::format("{}: {} has {} coherence matrices for {} frequencies; give one per "
                                 "frequency or none",
                                 fn, what, frd.coherence.size(), F));
  if (!frd.flagged.empty() && static_cast<Index>(frd.flagged.size()) != F)
    throw InputError(fmt::format("{}: {} has {} flags for {} frequencies; give one per frequency or none",
                                 fn, what, frd.flagged.size(), F));
  for (Index k = 0; k < F; ++k) {
    const Eigen::MatrixXcd& r = frd.response[static_cast<size_t>(k)];
    if (r.rows() != rows || r.cols() != cols)
      throw InputError(fmt::format("{}: {} at frequency {} ({} rad/s) is {}, the controller needs {}x{}", fn,
                                   what, k, frd.omega_rad_s(k), shape(r), rows, cols));
    if (!std::isfinite(frd.omega_rad_s(k)))
      throw InputError(fmt::format("{}: {} frequency {} is {} rad/s; every frequency must be finite", fn, what,
                                   k, frd.omega_rad_s(k)));
    if (!r.allFinite())
      throw InputError(fmt::format("{}: {} at frequency {} ({} rad/s) holds NaN or Inf; every entry must be "
                                   "finite (drop or interpolate that frequency)",
                                   fn, what, k, frd.omega_rad_s(k)));
    if (!frd.coherence.empty()) {
      const Eigen::MatrixXd& c = frd.coherence[static_cast<size_t>(k)];
      if (c.rows() != rows || c.cols() != cols)
        throw InputError(fmt::format("{}: {} coherence at frequency {} is {}x{}, the response is {}x{}", fn,
                                     what, k, c.rows(), c.cols(), rows, cols));
      if (!c.allFinite())
        throw InputError(fmt::format("{}: {} coherence at frequency {} holds NaN or Inf", fn, what, k));
    }
  }
}

// C(ω) at every frequency; pole_hit[k] when ω is exactly at a controller pole (the
// response is infinite there: evaluate_response throws).
struct ControllerResponse {
  std::vector<Eigen::MatrixXcd> value;
  std::vector<bool> pole_hit;
};

ControllerResponse controller_response(const StateSpace& controller, const Eigen::VectorXd& omega,
                                       const char* fn);

// The measured controller's response on the data's frequencies (KnownController).
ControllerResponse controller_response(const KnownController& known, const Eigen::VectorXd& omega, const char* fn) {
  if (known.model()) return controller_response(*known.model(), omega, fn);
  known.validate();
  const FrequencyResponse& c = *known.measured();
  if (c.num_frequencies() != omega.size())
    throw InputError(fmt::format("{}: the measured controller has {} frequencies but the data {}; measure the "
                                 "controller on the data's frequency lines (or give it as a model)",
                                 fn, c.num_frequencies(), omega.size()));
  for (Index k = 0; k < omega.size(); ++k)
    if (!(std::abs(c.omega_rad_s(k) - omega(k)) <= kMeasuredControllerFrequencyRelTolerance * std::abs(omega(k))))
      throw InputError(fmt::format("{}: frequency {} of the measured controller is {} Hz but the data's is {} Hz "
                                   "(relative difference {:.3g} > {}); measure the controller on the data's frequency "
                                   "lines (or give it as a model)",
                                   fn, k + 1, c.omega_rad_s(k) / (2 * std::numbers::pi), omega(k) / (2 * std::numbers::pi),
                                   std::abs(c.omega_rad_s(k) - omega(k)) / std::abs(omega(k)),
                                   kMeasuredControllerFrequencyRelTolerance));
  ControllerResponse out;
  out.value = c.response;
  out.pole_hit.assign(static_cast<size_t>(omega.size()), false);
  return out;
}

ControllerResponse controller_response(const StateSpace& controller, const Eigen::VectorXd& omega,
                                       const char* fn) {
  controller.validate();
  if (controller.is_discrete()) {
    const double nyquist = std::numbers::pi / controller.sample_period_s;
    for (Index k = 0; k < omega.size(); ++k)
      if (std::abs(omega(k)) > nyquist * (1.0 + kNyquistRelTolerance))
        throw InputError(fmt::format(
            "{}: frequency {} is {} rad/s, above the Nyquist frequency {} rad/s of the discrete controller "
            "(Ts = {} s); drop the frequencies above Nyquist or use the controller's sample period",
            fn, k, omega(k), nyquist, controller.sample_period_s));
  }
  ControllerResponse out;
  out.pole_hit.assign(static_cast<size_t>(omega.size()), false);
  try {
    out.value = evaluate_response(controller, omega);
  } catch (const InputError&) {
    // Some ω sits exactly on a controller pole: evaluate one by one, flag those.
    out.value.assign(static_cast<size_t>(omega.size()),
                     Eigen::MatrixXcd::Zero(controller.num_outputs(), controller.num_inputs()));
    for (Index k = 0; k < omega.size(); ++k) {
      try {
        out.value[static_cast<size_t>(k)] = evaluate_response(controller, omega.segment(k, 1)).front();
      } catch (const InputError&) {
        out.pole_hit[static_cast<size_t>(k)] = true;
      }
    }
  }
  return out;
}

double condition(const Eigen::VectorXd& sv) {
  const double lo = sv(sv.size() - 1);
  return lo > 0.0 ? sv(0) / lo : std::numeric_limits<double>::infinity();
}

// a⁻¹ from its SVD (callers ensure σ_min > 0).
Eigen::MatrixXcd inverse_from(const Eigen::JacobiSVD<Eigen::MatrixXcd>& svd) {
  return svd.matrixV() * svd.singularValues().cwiseInverse().asDiagonal() * svd.matrixU().adjoint();
}

void append(std::string& reasons, const std::string& r) {
  if (!reasons.empty()) reasons += "; ";
  reasons += r;
}

}  // namespace

void KnownController::validate() const {
  if (model_) {
    model_->validate();
    return;
  }
  const FrequencyResponse& c = *measured_;
  if (c.num_frequencies() == 0 || static_cast<Index>(c.response.size()) != c.num_frequencies())
    throw InputError("the measured controller holds no frequencies; give its response on the data's frequency lines");
  for (size_t k = 0; k < c.response.size(); ++k)
    if (c.response[k].rows() != c.num_outputs() || c.response[k].cols() != c.num_inputs() || !c.response[k].allFinite())
      throw InputError(fmt::format("the measured controller's response at frequency {} is not a finite {}x{} matrix",
                                   k + 1, c.num_outputs(), c.num_inputs()));
}

void SensitivityUnloopOptions::validate() const {
  if (!(max_condition > 1.0))
    throw InputError(fmt::format(
        "sensitivity unloop options: max_condition = {}; it must be > 1 (e.g. 1e6)", max_condition));
  if (!(min_coherence >= 0.0 && min_coherence <= 1.0))
    throw InputError(fmt::format(
        "sensitivity unloop options: min_coherence = {}; it must be in [0, 1] (0 disables the check)",
        min_coherence));
  if (!(min_loop_gain >= 0.0) || !std::isfinite(min_loop_gain))
    throw InputError(fmt::format(
        "sensitivity unloop options: min_loop_gain = {}; it must be finite and >= 0 (0 disables the check)",
        min_loop_gain));
}

SensitivityUnloopResult plant_from_sensitivity(const FrequencyResponse& S, const KnownController& controller,
                                               const SensitivityUnloopOptions& options) {
  constexpr const char* fn = "plant_from_sensitivity";
  options.validate();
  controller.validate();
  const Index m = controller.num_outputs();
  const Index p = controller.num_inputs();
  if (p != m)
    throw InputError(fmt::format(
        "{}: the controller has {} inputs and {} outputs; P = C⁻¹ (S⁻¹ − I) needs a square controller "
        "(as many plant outputs as inputs): use plant_from_closed_loop_frd with v → q data instead",
        fn, p, m));
  check_frd(S, fn, "S (v → u)", m, m);
  const ControllerResponse C = controller_response(controller, S.omega_rad_s, fn);
  const Index F = S.num_frequencies();

  SensitivityUnloopResult out;
  out.plant.omega_rad_s = S.omega_rad_s;
  out.plant.response.assign(static_cast<size_t>(F), Eigen::MatrixXcd::Zero(p, m));
  out.plant.flagged.assign(static_cast<size_t>(F), false);
  out.plant.input_names = S.output_names;
  out.plant.output_names = controller.input_names();
  out.flag_reasons.assign(static_cast<size_t>(F), std::string());
  std::map<std::string, Index> counts;
  const auto flag = [&](Index k, const std::string& kind, const std::string& detail) {
    append(out.flag_reasons[static_cast<size_t>(k)], detail.empty() ? kind : kind + " " + detail);
    ++counts[kind];
  };

  const Eigen::MatrixXcd I = Eigen::MatrixXcd::Identity(m, m);
  for (Index k = 0; k < F; ++k) {
    const size_t kk = static_cast<size_t>(k);
    if (!S.flagged.empty() && S.flagged[kk]) flag(k, "input flagged", "");
    if (!S.coherence.empty() && options.min_coherence > 0.0) {
      const Eigen::MatrixXd& c = S.coherence[kk];
      const double worst = std::min(c.rowwise().maxCoeff().minCoeff(), c.colwise().maxCoeff().minCoeff());
      if (worst < options.min_coherence)
        flag(k, "low coherence", fmt::format("({:.3g} < {})", worst, options.min_coherence));
    }
    bool computable = true;
    Eigen::MatrixXcd Cinv;
    if (C.pole_hit[kk]) {
      flag(k, "C ill-conditioned", "(controller pole at this frequency)");
      computable = false;
    } else {
      const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(C.value[kk], Eigen::ComputeFullU | Eigen::ComputeFullV);
      const double cond = condition(svd.singularValues());
      if (!(cond <= options.max_condition)) flag(k, "C ill-conditioned", fmt::format("(cond {:.3g})", cond));
      if (std::isfinite(cond))
        Cinv = inverse_from(svd);
      else
        computable = false;
    }
    const Eigen::JacobiSVD<Eigen::MatrixXcd> svd_s(S.response[kk], Eigen::ComputeFullU | Eigen::ComputeFullV);
    const double cond_s = condition(svd_s.singularValues());
    if (!(cond_s <= options.max_condition)) flag(k, "S ill-conditioned", fmt::format("(cond {:.3g})", cond_s));
    if (!std::isfinite(cond_s)) computable = false;
    if (computable) {
      const Eigen::MatrixXcd M = inverse_from(svd_s) - I;  // = C P
      const Eigen::JacobiSVD<Eigen::MatrixXcd> svd_m(M);
      const double cond_m = condition(svd_m.singularValues());
      if (!(cond_m <= options.max_condition))
        flag(k, "S^-1 - I ill-conditioned", fmt::format("(cond {:.3g})", cond_m));
      const double loop_gain = svd_m.singularValues()(svd_m.singularValues().size() - 1);
      if (loop_gain < options.min_loop_gain)
        flag(k, "low loop gain", fmt::format("(sigma_min(C P) {:.3g} < {})", loop_gain, options.min_loop_gain));
      out.plant.response[kk] = Cinv * M;
    }
    if (!out.flag_reasons[kk].empty()) {
      out.plant.flagged[kk] = true;
      ++out.flagged_count;
    }
  }
  out.report.usable = out.flagged_count < F;
  out.report.termination = fmt::format("plant at {} frequencies, {} flagged", F, out.flagged_count);
  for (const auto& [kind, n] : counts)
    out.report.warnings.push_back(fmt::format("{}: {} of {} frequencies", kind, n, F));
  return out;
}

std::vector<Eigen::MatrixXd> plant_variance_from_sensitivity(const FrequencyResponse& S,
                                                             const std::vector<Eigen::MatrixXd>& s_variance,
                                                             const KnownController& controller) {
  constexpr const char* fn = "plant_variance_from_sensitivity";
  controller.validate();
  const Index m = controller.num_outputs();
  if (controller.num_inputs() != m)
    throw InputError(fmt::format("{}: the controller has {} inputs and {} outputs; P = C⁻¹ (S⁻¹ − I) needs a square "
                                 "controller",
                                 fn, controller.num_inputs(), m));
  check_frd(S, fn, "S (v → u)", m, m);
  const Index F = S.num_frequencies();
  if (static_cast<Index>(s_variance.size()) != F)
    throw InputError(fmt::format("{}: {} variance matrices for {} frequencies of S", fn, s_variance.size(), F));
  for (Index k = 0; k < F; ++k) {
    const Eigen::MatrixXd& v = s_variance[static_cast<std::size_t>(k)];
    if (v.rows() != m || v.cols() != m)
      throw InputError(fmt::format("{}: the variance at frequency {} is {}x{}; S is {}x{}", fn, k, v.rows(), v.cols(), m, m));
    if ((v.array() < 0.0).any())
      throw InputError(fmt::format("{}: the variance at frequency {} holds a negative value", fn, k));
  }
  const ControllerResponse C = controller_response(controller, S.omega_rad_s, fn);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Eigen::MatrixXd> out(static_cast<std::size_t>(F), Eigen::MatrixXd::Constant(m, m, inf));
  for (Index k = 0; k < F; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    if (C.pole_hit[kk] || !s_variance[kk].allFinite()) continue;
    const Eigen::FullPivLU<Eigen::MatrixXcd> lu_s(S.response[kk]), lu_c(C.value[kk]);
    if (!lu_s.isInvertible() || !lu_c.isInvertible()) continue;
    const Eigen::MatrixXcd Si = lu_s.inverse();
    const Eigen::MatrixXd left = (lu_c.inverse() * Si).cwiseAbs2();  // |(C⁻¹ S⁻¹)_ak|²
    const Eigen::MatrixXd right = Si.cwiseAbs2();                    // |(S⁻¹)_lb|²
    // Σ_kl left_ak v_kl right_lb = (left · v · right)_ab
    out[kk] = left * s_variance[kk] * right;
  }
  return out;
}

FrequencyResponse plant_from_sensitivity_printed_eq15(const FrequencyResponse& S, const StateSpace& controller) {
  constexpr const char* fn = "plant_from_sensitivity_printed_eq15";
  controller.validate();
  const Index m = controller.num_outputs();
  const Index p = controller.num_inputs();
  if (p != m)
    throw InputError(fmt::format("{}: the controller has {} inputs and {} outputs; eq (15) needs a square "
                                 "controller",
                                 fn, p, m));
  check_frd(S, fn, "S (v → u)", m, m);
  const ControllerResponse C = controller_response(controller, S.omega_rad_s, fn);
  const Index F = S.num_frequencies();
  FrequencyResponse out;
  out.omega_rad_s = S.omega_rad_s;
  out.response.assign(static_cast<size_t>(F), Eigen::MatrixXcd::Zero(p, m));
  out.flagged.assign(static_cast<size_t>(F), false);
  out.input_names = S.output_names;
  out.output_names = controller.input_names;
  const Eigen::MatrixXcd I = Eigen::MatrixXcd::Identity(m, m);
  for (Index k = 0; k < F; ++k) {
    const size_t kk = static_cast<size_t>(k);
    if (C.pole_hit[kk]) {
      out.flagged[kk] = true;
      continue;
    }
    const Eigen::FullPivLU<Eigen::MatrixXcd> lu_c(C.value[kk]);
    const Eigen::FullPivLU<Eigen::MatrixXcd> lu_s(S.response[kk] - I);
    if (!lu_c.isInvertible() || !lu_s.isInvertible()) {
      out.flagged[kk] = true;
      continue;
    }
    out.response[kk] = lu_c.solve(lu_s.inverse());
  }
  return out;
}

FrequencyResponse plant_from_closed_loop_frd(const FrequencyResponse& G, const KnownController& controller) {
  constexpr const char* fn = "plant_from_closed_loop_frd";
  const double max_condition = SensitivityUnloopOptions{}.max_condition;
  controller.validate();
  const Index m = controller.num_outputs();
  const Index p = controller.num_inputs();
  check_frd(G, fn, "G (v → q)", p, m);
  const ControllerResponse C = controller_response(controller, G.omega_rad_s, fn);
  const Index F = G.num_frequencies();
  FrequencyResponse out;
  out.omega_rad_s = G.omega_rad_s;
  out.response.assign(static_cast<size_t>(F), Eigen::MatrixXcd::Zero(p, m));
  out.flagged.assign(static_cast<size_t>(F), false);
  out.input_names = G.input_names;
  out.output_names = G.output_names;
  const Eigen::MatrixXcd I = Eigen::MatrixXcd::Identity(m, m);
  for (Index k = 0; k < F; ++k) {
    const size_t kk = static_cast<size_t>(k);
    if (!G.flagged.empty() && G.flagged[kk]) out.flagged[kk] = true;
    if (C.pole_hit[kk]) {
      out.flagged[kk] = true;
      continue;
    }
    const Eigen::MatrixXcd& g = G.response[kk];
    const Eigen::JacobiSVD<Eigen::MatrixXcd> svd(I - C.value[kk] * g, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const double cond = condition(svd.singularValues());
    if (!(cond <= max_condition)) out.flagged[kk] = true;
    if (std::isfinite(cond)) out.response[kk] = g * inverse_from(svd);
  }
  return out;
}

}  // namespace lpvid
