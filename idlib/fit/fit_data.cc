// lpvid — the frequency-domain fit's data: the noise model (σ and the relative scale
// per entry), the band and the controller's lines made ready for the engine, the
// per-channel score, and the model's response with its bands.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "idlib/fit/fit_detail.h"
#include "idlib/lti/frequency_response.h"

namespace lpvid {
namespace fit_detail {
namespace {

std::vector<CMat> controller_at(const StateSpace& c, const std::vector<double>& omega) {
  Eigen::VectorXd w(static_cast<Index>(omega.size()));
  for (std::size_t k = 0; k < omega.size(); ++k) w(static_cast<Index>(k)) = omega[k];
  const auto r = evaluate_response(c, w);
  std::vector<CMat> out;
  for (const auto& m : r) out.emplace_back(m);
  return out;
}

bool same_line(double a, double b) { return std::abs(a - b) <= kControllerLineRelTolerance * std::abs(b); }

}  // namespace

void check_controller(const FitOptions& o, const BaseInfo* base) {
  if (o.target == FitTarget::kPlant) return;
  if (!o.controller && !o.measured_controller)
    throw InputError(fmt::format("target {} needs the controller C (e = -q -> u_c); give it (--controller C.json, or "
                                 "its measured response C.csv)",
                                 target_name(o.target)));
  if (o.controller && o.measured_controller)
    throw InputError("both a controller model and a measured controller are given; give one");
  Index c_in = 0, c_out = 0;
  if (o.controller) {
    o.controller->validate();
    c_in = o.controller->num_inputs();
    c_out = o.controller->num_outputs();
  } else {
    const FrequencyResponse& c = *o.measured_controller;
    if (c.num_frequencies() == 0 || c.response.size() != static_cast<std::size_t>(c.num_frequencies()))
      throw InputError("the measured controller holds no frequencies; give its response on the data's frequency lines");
    c_in = c.num_inputs();
    c_out = c.num_outputs();
    for (std::size_t k = 0; k < c.response.size(); ++k) {
      const double w = c.omega_rad_s(static_cast<Index>(k));
      if (!std::isfinite(w) || !(w > 0.0) || c.response[k].rows() != c_out || c.response[k].cols() != c_in ||
          !c.response[k].allFinite())
        throw InputError(fmt::format("the measured controller's line {} ({} rad/s) is not a finite {}x{} response at a "
                                     "frequency > 0; give its response on the data's frequency lines",
                                     k + 1, w, c_out, c_in));
    }
  }
  if (base == nullptr) return;
  const Index ni = static_cast<Index>(base->input_names.size()), no = static_cast<Index>(base->output_names.size());
  if (c_in != no || c_out != ni)
    throw InputError(fmt::format("the controller has {} inputs and {} outputs; base '{}' needs {} (e = -q) and {} "
                                 "(u_c)",
                                 c_in, c_out, base->name, no, ni));
}

namespace {

// s_ij(ω_k) >= kLocalLevelRatio × the largest s_ij within ±kLocalLevelDecades of ω_k
// (fit.h, "noise model"): the bottom of a narrow notch is not the size of its channel
// there.  ω in increasing order (the FRD formats' rule); otherwise left as it is.
void floor_at_local_level(const Eigen::VectorXd& omega, std::vector<Eigen::MatrixXd>& s) {
  const Index F = omega.size();
  if (F < 2 || static_cast<Index>(s.size()) != F) return;
  for (Index k = 1; k < F; ++k)
    if (!(omega(k) > omega(k - 1)) || !(omega(k - 1) > 0)) return;
  const double ratio = std::pow(10.0, kLocalLevelDecades);
  std::vector<Eigen::MatrixXd> out = s;
  Index lo = 0, hi = 0;
  for (Index k = 0; k < F; ++k) {
    while (omega(lo) * ratio < omega(k)) ++lo;
    while (hi + 1 < F && omega(hi + 1) <= omega(k) * ratio) ++hi;
    Eigen::MatrixXd local = s[static_cast<std::size_t>(lo)];
    for (Index j = lo + 1; j <= hi; ++j) local = local.cwiseMax(s[static_cast<std::size_t>(j)]);
    out[static_cast<std::size_t>(k)] = s[static_cast<std::size_t>(k)].cwiseMax(kLocalLevelRatio * local);
  }
  s = std::move(out);
}

// Per frequency: s_ij floored, σ per real part (header cases), the case's name.
struct NoiseTable {
  std::vector<RMat> scale, sigma;
  bool known = false;
  std::string source;
};

NoiseTable noise_table(const FrequencyResponse& f, const NoiseOptions& noise, double scale_floor,
                       const std::string& label) {
  NoiseTable t;
  const Index F = f.num_frequencies();
  std::vector<Eigen::MatrixXd> scales = response_scales(f.response, scale_floor);
  floor_at_local_level(f.omega_rad_s, scales);
  const bool var = !f.variance.empty();
  const bool coh = !f.coherence.empty();
  const double n_d = f.averages > 0 ? f.averages : noise.averages;
  if (var) {
    t.known = true;
    t.source = "variance";
  } else if (coh && n_d > 0) {
    t.known = true;
    t.source = fmt::format("coherence ({:g} averages{})", n_d, f.averages > 0 ? "" : ", given");
  } else if (noise.noise_level > 0) {
    t.known = true;
    t.source = fmt::format("noise level {:g} %", 100.0 * noise.noise_level);
  } else {
    t.known = false;
    t.source = coh ? "unknown (coherence without the number of averages)" : "unknown";
  }
  if (var && static_cast<Index>(f.variance.size()) != F)
    throw InputError(fmt::format("{}: {} variance matrices for {} frequencies", label, f.variance.size(), F));
  if (coh && static_cast<Index>(f.coherence.size()) != F)
    throw InputError(fmt::format("{}: {} coherence matrices for {} frequencies", label, f.coherence.size(), F));
  for (Index k = 0; k < F; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    const Eigen::MatrixXcd& h = f.response[kk];
    RMat s = scales[kk];
    RMat sg(h.rows(), h.cols());
    for (Index i = 0; i < h.rows(); ++i)
      for (Index j = 0; j < h.cols(); ++j) {
        double sigma;
        if (var) {
          // a variance beyond kNoInformationVariance stands for "no information" (the
          // FRD format holds finite numbers only; lpvid frf writes 1e300 there)
          constexpr double kNoInformationVariance = 1e250;
          const double v = f.variance[kk](i, j);
          sigma = v >= kNoInformationVariance ? kInf : std::sqrt(std::max(v, 0.0) / 2.0);
        } else if (coh && n_d > 0) {
          const double g2 = std::clamp(f.coherence[kk](i, j), 0.0, 1.0);
          sigma = g2 > 0 ? std::abs(h(i, j)) * std::sqrt((1.0 - g2) / (2.0 * n_d * g2)) : kInf;
        } else if (noise.noise_level > 0) {
          sigma = noise.noise_level * s(i, j) / std::sqrt(2.0);
        } else if (coh) {
          // relative weights from the coherence (n_d unknown: taken as 1 for the weights only)
          const double g2 = std::clamp(f.coherence[kk](i, j), 0.0, 1.0);
          sigma = g2 > 0 ? std::abs(h(i, j)) * std::sqrt((1.0 - g2) / (2.0 * g2)) : kInf;
        } else {
          sigma = s(i, j) / std::sqrt(2.0);
        }
        // Measured noise (variance, coherence): an entry is never measured against
        // less than kNoiseScaleRatio × its own noise rms √2σ.  Below that its relative
        // error measures the noise (the F-16's acc3 at 5.66 Hz, |H| at twice its noise;
        // fit.h, "noise model", with the local-level floor that does most of the work).
        if ((var || (coh && n_d > 0)) && std::isfinite(sigma))
          s(i, j) = std::max(s(i, j), kNoiseScaleRatio * std::sqrt(2.0) * sigma);
        sg(i, j) = std::max(sigma, noise.sigma_floor * s(i, j));
      }
    t.scale.push_back(std::move(s));
    t.sigma.push_back(std::move(sg));
  }
  return t;
}

bool in_band(double w, const FitOptions& o) { return w >= o.band_min_rad_s && w <= o.band_max_rad_s; }

Prepared prepare(const FitDataset& ds, const PhysicalModel& model, const FitOptions& o, bool* noise_known,
                 std::string* noise_source) {
  const FrequencyResponse& f = ds.response;
  const BaseInfo& base = model.base_info();
  if (f.num_frequencies() == 0 || f.response.size() != static_cast<std::size_t>(f.num_frequencies()))
    throw InputError(fmt::format("{}: no frequencies (or as many responses as frequencies are missing); give FRD data",
                                 ds.label));
  const auto [rows, cols] = target_shape(base, o.target);
  if (f.num_outputs() != rows || f.num_inputs() != cols)
    throw InputError(fmt::format("{}: the response is {}×{}; the {} target of base '{}' is {}×{}", ds.label,
                                 f.num_outputs(), f.num_inputs(), target_name(o.target), base.name, rows, cols));
  check_schedule(model, ds.beam_position_m);
  const Index F = f.num_frequencies();
  for (Index k = 0; k < F; ++k) {
    const double w = f.omega_rad_s(k);
    if (!std::isfinite(w) || !(w > 0.0))
      throw InputError(fmt::format("{}: frequency {} rad/s; frequencies must be finite and > 0", ds.label, w));
    if (!f.response[static_cast<std::size_t>(k)].allFinite())
      throw InputError(fmt::format("{}: a response value at {} rad/s is not finite", ds.label, w));
  }
  const NoiseTable nt = noise_table(f, o.noise, o.scale_floor, ds.label);
  if (noise_known) *noise_known = nt.known;
  if (noise_source) *noise_source = nt.source;
  Prepared d;
  d.sched = ds.beam_position_m;
  for (Index k = 0; k < F; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    if (!f.flagged.empty() && f.flagged[kk]) continue;
    if (!in_band(f.omega_rad_s(k), o)) continue;
    RMat inv_scale = nt.scale[kk].cwiseInverse(), weight(rows, cols);
    for (Index i = 0; i < rows; ++i)
      for (Index j = 0; j < cols; ++j) {
        // the weight: the data's noise, plus a model error of o.noise.model_error × the
        // entry's scale when given (FitOptions::model_error_weighting); sigma stays the
        // data's own, so the noise floor is the data's
        const double sg = nt.sigma[kk](i, j), me = o.noise.model_error * nt.scale[kk](i, j);
        weight(i, j) = std::isinf(sg) ? 0.0 : 1.0 / std::sqrt(sg * sg + 0.5 * me * me);
      }
    d.omega.push_back(f.omega_rad_s(k));
    d.data.emplace_back(f.response[kk]);
    d.inv_scale.push_back(inv_scale);
    d.weight.push_back(weight);
    d.sigma.push_back(nt.sigma[kk]);
  }
  if (d.omega.empty())
    throw InputError(fmt::format("{}: no frequency in the band [{:g}, {:g}] rad/s (after flagged ones); widen the "
                                 "band or check the data's frequencies",
                                 ds.label, o.band_min_rad_s, o.band_max_rad_s));
  if (o.target != FitTarget::kPlant) {
    if (o.controller) {
      d.ctrl = controller_at(*o.controller, d.omega);
    } else {
      check_controller_lines(*o.measured_controller, f.omega_rad_s, "the measured controller", ds.label);
      for (Index k = 0; k < F; ++k) {
        const auto kk = static_cast<std::size_t>(k);
        if ((f.flagged.empty() || !f.flagged[kk]) && in_band(f.omega_rad_s(k), o))
          d.ctrl.emplace_back(o.measured_controller->response[kk]);
      }
    }
  }
  return d;
}

}  // namespace

Prepared subsample(const Prepared& d, int count) {
  const std::size_t F = d.omega.size();
  if (static_cast<std::size_t>(count) >= F) return d;
  Prepared s;
  s.sched = d.sched;
  // Evenly spaced indices over the (log-spaced, typically) grid.
  for (int i = 0; i < count; ++i) {
    const auto k = static_cast<std::size_t>(std::llround(static_cast<double>(i) * static_cast<double>(F - 1) /
                                                         static_cast<double>(count - 1)));
    s.omega.push_back(d.omega[k]);
    s.data.push_back(d.data[k]);
    s.weight.push_back(d.weight[k]);
    s.inv_scale.push_back(d.inv_scale[k]);
    s.sigma.push_back(d.sigma[k]);
    if (!d.ctrl.empty()) s.ctrl.push_back(d.ctrl[k]);
  }
  return s;
}

// Channel names: the data's (first set) when complete, else the base's.
void channel_names(const std::vector<FitDataset>& data, const BaseInfo& b, FitTarget t, std::vector<std::string>& outs,
                   std::vector<std::string>& ins) {
  const auto [rows, cols] = target_shape(b, t);
  const FrequencyResponse& f = data.front().response;
  outs = static_cast<Index>(f.output_names.size()) == rows ? f.output_names : std::vector<std::string>{};
  ins = static_cast<Index>(f.input_names.size()) == cols ? f.input_names : std::vector<std::string>{};
  if (outs.empty()) {
    if (t == FitTarget::kInputSensitivity)
      for (const auto& n : b.input_names) outs.push_back("u_" + n);
    else
      outs = b.output_names;
  }
  if (ins.empty()) {
    if (t == FitTarget::kPlant)
      ins = b.input_names;
    else
      for (const auto& n : b.input_names) ins.push_back("v_" + n);
  }
}

// Per-channel error and noise floor over the sets at the engine's current values.
void score_channels(Engine& engine, const std::vector<Prepared>& sets, bool noise_known,
                    std::vector<ChannelFit>& channels, double& error, double& floor) {
  const Index rows = sets.front().data.front().rows(), cols = sets.front().data.front().cols();
  channels.clear();
  for (Index i = 0; i < rows; ++i)
    for (Index j = 0; j < cols; ++j) channels.push_back(ChannelFit{i, j, 0.0, 0.0, {}});
  std::vector<double> sum(static_cast<std::size_t>(rows * cols), 0.0), nsum(sum);
  Index count = 0;
  for (const Prepared& d : sets) {
    std::vector<CMat> T;
    engine.evaluate(d, T, nullptr);
    for (Index c = 0; c < rows * cols; ++c) {
      const Index i = c / cols, j = c % cols;
      double s = 0.0, ns = 0.0;
      for (std::size_t k = 0; k < d.omega.size(); ++k) {
        s += std::norm((T[k](i, j) - d.data[k](i, j)) * d.inv_scale[k](i, j));
        const double r = d.sigma[k](i, j) * d.inv_scale[k](i, j);
        ns += std::isfinite(r) ? 2.0 * r * r : 0.0;
      }
      sum[static_cast<std::size_t>(c)] += s;
      nsum[static_cast<std::size_t>(c)] += ns;
      channels[static_cast<std::size_t>(c)].per_dataset.push_back(
          std::sqrt(s / static_cast<double>(std::max<std::size_t>(d.omega.size(), 1))));
    }
    count += static_cast<Index>(d.omega.size());
  }
  double e2 = 0.0, f2 = 0.0;
  for (Index c = 0; c < rows * cols; ++c) {
    auto& ch = channels[static_cast<std::size_t>(c)];
    ch.relative_rms_error = std::sqrt(sum[static_cast<std::size_t>(c)] / static_cast<double>(std::max<Index>(count, 1)));
    ch.noise_floor = noise_known ? std::sqrt(nsum[static_cast<std::size_t>(c)] / static_cast<double>(std::max<Index>(count, 1)))
                                 : kNaN;
    e2 += ch.relative_rms_error * ch.relative_rms_error;
    f2 += noise_known ? ch.noise_floor * ch.noise_floor : 0.0;
  }
  error = std::sqrt(e2 / static_cast<double>(rows * cols));
  floor = noise_known ? std::sqrt(f2 / static_cast<double>(rows * cols)) : kNaN;
}

PreparedAll prepare_all(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options) {
  if (data.empty()) throw InputError("no data to fit; give at least one response with its scheduling value");
  PreparedAll all;
  for (const auto& ds : data) {
    bool known = false;
    std::string source;
    all.sets.push_back(prepare(ds, model, options, &known, &source));
    all.noise_known = all.noise_known && known;
    if (all.noise_source.empty())
      all.noise_source = source;
    else if (all.noise_source != source)
      all.noise_source += "; " + source;
  }
  return all;
}

}  // namespace fit_detail

using fit_detail::check_controller;
using fit_detail::CMat;
using fit_detail::Cx;
using fit_detail::Engine;
using fit_detail::noise_table;
using fit_detail::NoiseTable;
using fit_detail::Prepared;
using fit_detail::prepare_all;
using fit_detail::PreparedAll;
using fit_detail::RMat;
using fit_detail::same_line;
using fit_detail::score_channels;
using fit_detail::target_shape;

std::string target_name(FitTarget target) {
  switch (target) {
    case FitTarget::kPlant:
      return "plant";
    case FitTarget::kClosedLoopOutput:
      return "G";
    case FitTarget::kInputSensitivity:
      return "S";
  }
  return "plant";
}

FitTarget parse_target(const std::string& text) {
  if (text == "plant" || text == "P") return FitTarget::kPlant;
  if (text == "G") return FitTarget::kClosedLoopOutput;
  if (text == "S") return FitTarget::kInputSensitivity;
  throw InputError(fmt::format("target '{}': give plant (P data), G (closed loop v -> q) or S (input sensitivity "
                               "v -> u)",
                               text));
}

void NoiseOptions::validate() const {
  if (!std::isfinite(averages) || averages < 0 || (averages > 0 && averages < 1))
    throw InputError(fmt::format("averages {}: give the independent averages behind the coherence, a number >= 1 "
                                 "(or 0 to take it from the data)",
                                 averages));
  if (!std::isfinite(noise_level) || noise_level < 0 || noise_level >= 1)
    throw InputError(fmt::format("noise level {}: give the relative rms error of the measurement, in [0, 1) (e.g. "
                                 "0.01 for 1 %)",
                                 noise_level));
  if (!std::isfinite(sigma_floor) || sigma_floor < 0 || sigma_floor >= 1)
    throw InputError(fmt::format("sigma floor {}: must be in [0, 1)", sigma_floor));
  if (!std::isfinite(model_error) || model_error < 0 || model_error > 100)
    throw InputError(fmt::format("model error {}: the relative rms model error the weights allow for, in [0, 100] "
                                 "(e.g. 0.1 for 10 %)",
                                 model_error));
}

void FitOptions::validate() const {
  auto bad = [](const char* name, double v, const char* rule) {
    throw InputError(fmt::format("fit option {} = {}: {}", name, v, rule));
  };
  if (!std::isfinite(sample_period_s) || sample_period_s < 0) bad("sample_period_s", sample_period_s, "must be >= 0");
  if (!(band_min_rad_s >= 0) || !(band_max_rad_s > band_min_rad_s) || std::isnan(band_max_rad_s))
    throw InputError(fmt::format("frequency band [{}, {}] rad/s: give 0 <= low < high (e.g. --band-min 1 "
                                 "--band-max 400)",
                                 band_min_rad_s, band_max_rad_s));
  noise.validate();
  if (global_starts < 1) bad("global_starts", global_starts, "must be >= 1");
  if (!(global_search_factor > 1.0) || !std::isfinite(global_search_factor))
    bad("global_search_factor", global_search_factor, "must be finite and > 1");
  if (global_subsample < 2) bad("global_subsample", global_subsample, "must be >= 2");
  if (global_max_evaluations < 10) bad("global_max_evaluations", global_max_evaluations, "must be >= 10");
  if (restarts < 0) bad("restarts", restarts, "must be >= 0");
  if (max_iterations < 1) bad("max_iterations", max_iterations, "must be >= 1");
  if (!(function_tolerance > 0.0) || !(function_tolerance < 1.0))
    bad("function_tolerance", function_tolerance, "must be in (0, 1)");
  if (!(scale_floor > 0.0) || !(scale_floor < 1.0)) bad("scale_floor", scale_floor, "must be in (0, 1)");
  if (!(correlation_flag > 0.0) || !(correlation_flag <= 1.0))
    bad("correlation_flag", correlation_flag, "must be in (0, 1]");
  if (!(singular_value_flag > 0.0) || !(singular_value_flag < 1.0))
    bad("singular_value_flag", singular_value_flag, "must be in (0, 1)");
  check_controller(*this, nullptr);
}

std::vector<Eigen::MatrixXd> data_sigma(const FrequencyResponse& data, const NoiseOptions& noise,
                                        std::string* source, bool* known, std::vector<Eigen::MatrixXd>* scales) {
  noise.validate();
  const NoiseTable t = noise_table(data, noise, 1e-6, "data");
  if (source) *source = t.source;
  if (known) *known = t.known;
  if (scales) scales->assign(t.scale.begin(), t.scale.end());
  std::vector<Eigen::MatrixXd> out;
  for (const RMat& s : t.sigma) out.emplace_back(s);
  return out;
}

ModelScore score_model(const PhysicalModel& model, const std::vector<FitDataset>& data, const FitOptions& options) {
  options.validate();
  model.validate();
  check_controller(options, &model.base_info());
  const PreparedAll all = prepare_all(model, data, options);
  Engine engine(model, options);
  ModelScore s;
  s.noise_known = all.noise_known;
  score_channels(engine, all.sets, all.noise_known, s.channels, s.error, s.noise_floor);
  std::vector<CMat> T;
  for (const Prepared& d : all.sets) {
    if (!engine.evaluate(d, T, nullptr))
      throw InputError("the model cannot be evaluated at a data set's scheduling value (mass matrix not positive "
                       "definite); check the model");
    for (std::size_t k = 0; k < d.omega.size(); ++k)
      for (Index i = 0; i < d.data[k].rows(); ++i)
        for (Index j = 0; j < d.data[k].cols(); ++j) {
          s.cost += std::norm((T[k](i, j) - d.data[k](i, j)) * d.weight[k](i, j));
          s.residual_count += 2;
        }
  }
  return s;
}

void check_controller_lines(const FrequencyResponse& controller, const Eigen::VectorXd& omega,
                            const std::string& controller_name, const std::string& data_name) {
  const Index nc = controller.num_frequencies(), nd = omega.size();
  Index k = 0;
  while (k < std::min(nc, nd) && same_line(controller.omega_rad_s(k), omega(k))) ++k;
  if (k == nc && k == nd) return;
  constexpr double kHz = 1.0 / (2.0 * std::numbers::pi);
  const std::string what = "; measure the controller at the data's frequency lines (or give it as a model)";
  if (k < std::min(nc, nd))
    throw InputError(fmt::format("{}: line {} is {:.10g} Hz but line {} of {} is {:.10g} Hz (relative difference "
                                 "{:.3g} > {:g}){}",
                                 controller_name, k + 1, controller.omega_rad_s(k) * kHz, k + 1, data_name,
                                 omega(k) * kHz, std::abs(controller.omega_rad_s(k) - omega(k)) / std::abs(omega(k)),
                                 kControllerLineRelTolerance, what));
  throw InputError(fmt::format("{}: {} lines but {} has {}; line {} ({:.10g} Hz) is in {} only{}", controller_name,
                               nc, data_name, nd, k + 1,
                               (nc > nd ? controller.omega_rad_s(k) : omega(k)) * kHz,
                               nc > nd ? controller_name : data_name, what));
}

std::vector<Eigen::MatrixXcd> controller_response_at(const FitOptions& options, const Eigen::VectorXd& omega_rad_s) {
  if (options.controller) return evaluate_response(*options.controller, omega_rad_s);
  if (!options.measured_controller)
    throw InputError("no controller given; give the controller (--controller C.json, or its measured response C.csv)");
  const FrequencyResponse& c = *options.measured_controller;
  // The lines in increasing order, to look each frequency up (FRD files need not be sorted).
  std::vector<Index> order(static_cast<std::size_t>(c.num_frequencies()));
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<Index>(k);
  std::sort(order.begin(), order.end(), [&](Index a, Index b) { return c.omega_rad_s(a) < c.omega_rad_s(b); });
  std::vector<Eigen::MatrixXcd> out;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    const double w = omega_rad_s(k);
    const auto it = std::lower_bound(order.begin(), order.end(), w,
                                     [&](Index a, double x) { return c.omega_rad_s(a) < x; });
    Index hit = -1;
    for (auto j = it == order.begin() ? it : it - 1; j != order.end() && j <= it; ++j)
      if (same_line(c.omega_rad_s(*j), w)) hit = *j;
    if (hit < 0)
      throw InputError(fmt::format("the measured controller has no line at {:.10g} Hz (relative {:g}); the response "
                                   "through a measured controller is known only at its lines: measure the controller "
                                   "at the data's frequency lines (or give it as a model)",
                                   w / (2.0 * std::numbers::pi), kControllerLineRelTolerance));
    out.push_back(c.response[static_cast<std::size_t>(hit)]);
  }
  return out;
}

FrequencyResponse target_response(const PhysicalModel& model, double beam_position_m,
                                  const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  return response_band(model, Eigen::MatrixXd(), beam_position_m, omega_rad_s, options).response;
}

ResponseBand response_band(const PhysicalModel& model, const Eigen::MatrixXd& covariance, double beam_position_m,
                           const Eigen::VectorXd& omega_rad_s, const FitOptions& options) {
  options.validate();
  model.validate();
  const BaseInfo& base = model.base_info();
  check_controller(options, &base);
  check_schedule(model, beam_position_m);
  Engine engine(model, options);
  const Index p = engine.num_free();
  const bool bands = covariance.size() > 0;
  if (bands && (covariance.rows() != p || covariance.cols() != p))
    throw InputError(fmt::format("covariance is {}×{}; the model has {} free parameters", covariance.rows(),
                                 covariance.cols(), p));
  if (bands && p > 48) throw InputError("at most 48 free parameters");
  Prepared d;
  d.sched = beam_position_m;
  for (Index k = 0; k < omega_rad_s.size(); ++k) {
    if (!std::isfinite(omega_rad_s(k))) throw InputError("a frequency is not finite");
    d.omega.push_back(omega_rad_s(k));
  }
  if (options.target != FitTarget::kPlant)
    for (const Eigen::MatrixXcd& c : controller_response_at(options, omega_rad_s)) d.ctrl.emplace_back(c);
  std::vector<CMat> T;
  std::vector<std::vector<CMat>> dT;
  if (!engine.evaluate(d, T, bands && p > 0 ? &dT : nullptr))
    throw InputError(fmt::format("the mass matrix at {} {} is not positive definite; check the model", beam_position_m,
                                 base.schedule_unit));
  ResponseBand out;
  out.response.omega_rad_s = omega_rad_s;
  std::vector<FitDataset> none;
  const auto [rows, cols] = target_shape(base, options.target);
  if (options.target == FitTarget::kInputSensitivity)
    for (const auto& n : base.input_names) out.response.output_names.push_back("u_" + n);
  else
    out.response.output_names = base.output_names;
  if (options.target == FitTarget::kPlant)
    out.response.input_names = base.input_names;
  else
    for (const auto& n : base.input_names) out.response.input_names.push_back("v_" + n);
  for (std::size_t k = 0; k < T.size(); ++k) {
    out.response.response.emplace_back(T[k]);
    Eigen::MatrixXd sm = Eigen::MatrixXd::Zero(rows, cols), sp = Eigen::MatrixXd::Zero(rows, cols);
    if (bands && p > 0) {
      for (Index i = 0; i < rows; ++i)
        for (Index j = 0; j < cols; ++j) {
          const double mag = std::abs(T[k](i, j));
          if (mag == 0.0) continue;
          Eigen::VectorXd g(p), h(p);
          for (Index q = 0; q < p; ++q) {
            const Cx prod = std::conj(T[k](i, j)) * dT[k][static_cast<std::size_t>(q)](i, j);
            g(q) = prod.real() / mag;
            h(q) = prod.imag() / (mag * mag);
          }
          sm(i, j) = std::sqrt(std::max(g.dot(covariance * g), 0.0));
          sp(i, j) = std::sqrt(std::max(h.dot(covariance * h), 0.0));
        }
    }
    out.magnitude_sigma.push_back(sm);
    out.phase_sigma_rad.push_back(sp);
  }
  return out;
}

}  // namespace lpvid
