#include "idlib/diagnose/diagnose.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"

namespace lpvid {

void DiagnoseOptions::validate() const {
  fit.validate();
  model_error.validate();
  if (!(refit_function_tolerance > 0.0 && refit_function_tolerance < 1.0))
    throw InputError(fmt::format("diagnose: refit_function_tolerance must be in (0, 1), got {}",
                                 refit_function_tolerance));
  if (!(std::isfinite(significance_delta_bic) && significance_delta_bic > 0.0))
    throw InputError(fmt::format("diagnose: significance_delta_bic must be finite and > 0, got {}",
                                 significance_delta_bic));
}

double fit_error(const FitResult& fit) {
  if (fit.channels.empty()) return 0.0;
  double sum = 0.0;
  for (const ChannelFit& c : fit.channels) sum += c.relative_rms_error * c.relative_rms_error;
  return std::sqrt(sum / static_cast<double>(fit.channels.size()));
}

PhysicalModel without_effect(const PhysicalModel& model, const std::string& name) {
  if (!model.has_effect(name))
    throw InputError(fmt::format("diagnose: the model has no effect '{}' to remove", name));
  PhysicalModel out = PhysicalModel::bare_platform();
  for (const std::string& e : model.effects)
    if (e != name) out.add_effect(e);
  // Copy every kept parameter (value, bounds, free flag) from the original.
  for (PhysicalParameter& p : out.parameters) {
    const Index i = model.index_of(p.name);
    if (i >= 0) p = model.parameters[static_cast<std::size_t>(i)];
  }
  out.validate();
  return out;
}

namespace {

std::vector<std::vector<FailingBand>> failures_of(const PhysicalModel& model, const std::vector<FitDataset>& data,
                                                  const DiagnoseOptions& options) {
  std::vector<std::vector<FailingBand>> out;
  out.reserve(data.size());
  for (std::size_t d = 0; d < data.size(); ++d) {
    const FrequencyResponse predicted =
        target_response(model, data[d].beam_position_m, data[d].response.omega_rad_s, options.fit);
    const ModelErrorModel mem = model_error(data[d].response, predicted.response, options.model_error);
    out.push_back(failing_bands(mem, options.model_error, static_cast<Index>(d)));
  }
  mark_differences_between_data(out);
  return out;
}

std::string channel_name(const FitDataset& d, Index i, Index j) {
  const auto& outs = d.response.output_names;
  const auto& ins = d.response.input_names;
  const std::string o = i < static_cast<Index>(outs.size()) ? outs[static_cast<std::size_t>(i)] : fmt::format("y{}", i + 1);
  const std::string u = j < static_cast<Index>(ins.size()) ? ins[static_cast<std::size_t>(j)] : fmt::format("u{}", j + 1);
  return fmt::format("{} <- {}", o, u);
}

// The few largest failing bands, in words.
void describe_failures(const std::vector<std::vector<FailingBand>>& failures, const std::vector<FitDataset>& data,
                       std::vector<std::string>& lines, std::size_t limit) {
  std::vector<const FailingBand*> all;
  for (const auto& set : failures)
    for (const FailingBand& b : set) all.push_back(&b);
  std::sort(all.begin(), all.end(), [](const FailingBand* a, const FailingBand* b) {
    return a->max_sigma_ratio > b->max_sigma_ratio;  // the furthest beyond the noise first
  });
  for (std::size_t k = 0; k < std::min(limit, all.size()); ++k) {
    const FailingBand& b = *all[k];
    const FitDataset& d = data[static_cast<std::size_t>(b.data_index)];
    lines.push_back(fmt::format("  {} at x_b = {:g} m, {:.3g}–{:.3g} rad/s: up to {:.3g} % ({:+.2f} dB, {:+.1f} deg), "
                                "{:.0f}x the noise; {}",
                                channel_name(d, b.output, b.input), d.beam_position_m, b.lo_rad_s, b.hi_rad_s,
                                b.relative_percent_max, b.gain_db_max, b.phase_deg_max, b.max_sigma_ratio, b.hint));
  }
  if (all.size() > limit) lines.push_back(fmt::format("  ... and {} more failing bands", all.size() - limit));
}

std::size_t band_count(const std::vector<std::vector<FailingBand>>& f) {
  std::size_t n = 0;
  for (const auto& s : f) n += s.size();
  return n;
}

}  // namespace

Diagnosis diagnose(const PhysicalModel& model, const std::vector<FitDataset>& data, const DiagnoseOptions& options) {
  options.validate();
  model.validate();
  std::vector<std::string> candidates = options.candidates;
  if (candidates.empty()) {
    for (const EffectInfo& e : effect_library())
      if (!model.has_effect(e.name)) candidates.push_back(e.name);
  } else {
    for (const std::string& c : candidates) {
      if (find_effect(c) == nullptr) {
        std::string known;
        for (const EffectInfo& e : effect_library()) known += (known.empty() ? "" : ", ") + e.name;
        throw InputError(fmt::format("diagnose: unknown effect '{}'; the library has {}", c, known));
      }
      if (model.has_effect(c))
        throw InputError(fmt::format("diagnose: the model already has effect '{}'; try the others", c));
    }
  }

  FitOptions refit = options.fit;
  refit.function_tolerance = std::max(refit.function_tolerance, options.refit_function_tolerance);

  Diagnosis out;
  out.baseline = fit_physical_model(model, data, refit);
  out.baseline_error = fit_error(out.baseline);
  out.baseline_failures = failures_of(out.baseline.model, data, options);

  // The candidates are independent refits: run them on the machine's cores
  // (each fit is single-threaded; results do not depend on the thread count).
  std::vector<CandidateOutcome> outcomes(candidates.size());
  std::atomic<std::size_t> next{0};
  std::mutex input_error_mutex;
  std::exception_ptr first_error;
  auto worker = [&]() {
    for (std::size_t i = next++; i < candidates.size(); i = next++) {
      CandidateOutcome& c = outcomes[i];
      c.effect = candidates[i];
      try {
        PhysicalModel start = out.baseline.model;  // the refitted baseline values as the start
        start.add_effect(c.effect);
        c.fit = fit_physical_model(start, data, refit);
        c.fitted = true;
      } catch (const NumericalError& e) {
        c.failure = e.what();
      } catch (...) {
        std::lock_guard<std::mutex> lock(input_error_mutex);
        if (!first_error) first_error = std::current_exception();
      }
    }
  };
  const std::size_t threads =
      std::min<std::size_t>(candidates.size(), std::max(1u, std::thread::hardware_concurrency()));
  std::vector<std::thread> pool;
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& t : pool) t.join();
  if (first_error) std::rethrow_exception(first_error);

  std::vector<CandidateOutcome> failed;
  for (CandidateOutcome& c : outcomes) {
    if (!c.fitted) {
      failed.push_back(std::move(c));
      continue;
    }
    c.error = fit_error(c.fit);
    c.delta_bic = c.fit.bic - out.baseline.bic;
    c.delta_aic = c.fit.aic - out.baseline.aic;
    c.significant = c.delta_bic < -options.significance_delta_bic;
    const EffectInfo* info = find_effect(c.effect);
    for (const ParameterEstimate& p : c.fit.parameters)
      for (const PhysicalParameter& q : info->parameters)
        if (p.name == q.name) c.effect_parameters.push_back(p);
    out.ranked.push_back(std::move(c));
  }
  std::stable_sort(out.ranked.begin(), out.ranked.end(),
                   [](const CandidateOutcome& a, const CandidateOutcome& b) { return a.delta_bic < b.delta_bic; });
  for (CandidateOutcome& c : failed) out.ranked.push_back(std::move(c));

  std::vector<std::string>& s = out.summary;
  s.push_back(fmt::format("model with {} free parameters: error {:.3g} % (rms over the 9 channels of the relative rms "
                          "error), BIC {:.1f}",
                          out.baseline.parameters.size(), 100.0 * out.baseline_error, out.baseline.bic));
  const std::size_t nb = band_count(out.baseline_failures);
  if (nb == 0) {
    s.push_back("where it fails: nowhere beyond the measurement noise (no significant failing band)");
  } else {
    s.push_back(fmt::format("where it fails ({} significant failing bands, furthest beyond the noise first):", nb));
    describe_failures(out.baseline_failures, data, s, 5);
  }
  out.explained = !out.ranked.empty() && out.ranked.front().fitted && out.ranked.front().significant;
  if (out.explained) {
    const CandidateOutcome& w = out.ranked.front();
    const EffectInfo* info = find_effect(w.effect);
    s.push_back(fmt::format("missing: {} — {}", w.effect, info->description));
    s.push_back(fmt::format("  it explains: {}", info->signature));
    s.push_back(fmt::format("  error {:.3g} % -> {:.3g} % ({:.1f}x lower), ΔBIC {:.1f} (significant below −{:g})",
                            100.0 * out.baseline_error, 100.0 * w.error,
                            w.error > 0 ? out.baseline_error / w.error : std::numeric_limits<double>::infinity(),
                            w.delta_bic, options.significance_delta_bic));
    for (const ParameterEstimate& p : w.effect_parameters)
      s.push_back(fmt::format("  {} = {:.6g} ± {:.2g} {}", p.name, p.estimate, p.std_error, p.unit));
    if (out.ranked.size() > 1 && out.ranked[1].fitted)
      s.push_back(fmt::format("  runner-up: {} (ΔBIC {:.1f})", out.ranked[1].effect, out.ranked[1].delta_bic));
    out.remaining_failures = failures_of(w.fit.model, data, options);
    const std::size_t nr = band_count(out.remaining_failures);
    if (nr == 0) {
      s.push_back("  with it, no significant failing band remains");
    } else {
      s.push_back(fmt::format("  with it, {} failing bands remain:", nr));
      describe_failures(out.remaining_failures, data, s, 3);
    }
  } else if (nb == 0) {
    s.push_back("nothing significant: no candidate lowers BIC by more than "
                + fmt::format("{:g}", options.significance_delta_bic) + " and the model fits within the noise");
  } else {
    s.push_back("not explained: no effect in the library lowers BIC by more than " +
                fmt::format("{:g}", options.significance_delta_bic) +
                "; the failing bands above describe the remaining residual");
    if (!out.ranked.empty() && out.ranked.front().fitted)
      s.push_back(fmt::format("  closest candidate: {} (ΔBIC {:.1f}, error {:.3g} %)", out.ranked.front().effect,
                              out.ranked.front().delta_bic, 100.0 * out.ranked.front().error));
  }
  return out;
}

}  // namespace lpvid
