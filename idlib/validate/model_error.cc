#include "idlib/validate/model_error.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "idlib/core/error.h"

namespace lpvid {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Signature thresholds (header comment).
constexpr double kPeakEdgeShare = 0.15;     // the peak is not in the band's first/last 15 %
constexpr double kPeakOverEdges = 3.0;      // peak >= 3 x |E| at both ends
constexpr double kNarrowDecades = 0.5;      // a narrow band spans less than half a decade
constexpr double kDelayFitResidual = 0.3;   // −ωτ leaves < 30 % of the phase RMS
constexpr double kCouplingLacking = 0.3;    // model below 30 % of the data: coupling lacking
// A model below 1e-6 of the data (−120 dB) is numerically zero there (e.g. a
// coupling that cancels only up to rounding): no gain or phase is reported.
constexpr double kModelZeroShare = 1e-6;

bool finite(const Complex& z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

std::string signed_db(double v) { return fmt::format("{}{:.1f} dB", v >= 0 ? "+" : "", v); }

}  // namespace

void ModelErrorOptions::validate() const {
  if (!(confidence > 0 && confidence < 1))
    throw InputError(fmt::format("model error: confidence {}; must lie strictly between 0 and 1 (e.g. 0.99)",
                                 confidence));
  if (!std::isfinite(resolution) || resolution < 0)
    throw InputError(fmt::format("model error: resolution {}; must be finite and >= 0 (e.g. 0.001)", resolution));
  if (min_band_points < 1)
    throw InputError(fmt::format("model error: minimum band of {} points; must be >= 1", min_band_points));
  if (max_gap_points < 0)
    throw InputError(fmt::format("model error: gap of {} points; must be >= 0", max_gap_points));
  if (!std::isfinite(merge_decades) || merge_decades < 0)
    throw InputError(fmt::format("model error: merge distance {} decades; must be finite and >= 0", merge_decades));
}

double confidence_radius(double confidence) {
  LPVID_ASSERT(confidence > 0 && confidence < 1);
  return std::sqrt(-2.0 * std::log(1.0 - confidence));
}

ModelErrorModel model_error(const FrequencyResponse& data, const std::vector<Eigen::MatrixXcd>& model,
                            const std::vector<Eigen::MatrixXd>& sigma, const ModelErrorOptions& options,
                            const std::vector<Eigen::MatrixXd>* given_scales) {
  options.validate();
  const std::size_t F = data.response.size();
  if (F == 0) throw InputError("model error: the data hold no frequencies");
  if (static_cast<std::size_t>(data.omega_rad_s.size()) != F || model.size() != F || sigma.size() != F)
    throw InputError(fmt::format("model error: {} data responses, {} frequencies, {} model responses and {} noise "
                                 "levels; they must match",
                                 F, data.omega_rad_s.size(), model.size(), sigma.size()));
  const Index p = data.num_outputs(), m = data.num_inputs();
  if (!data.flagged.empty() && data.flagged.size() != F)
    throw InputError("model error: the data's flags must have one entry per frequency");
  ModelErrorModel r;
  r.omega_rad_s = data.omega_rad_s;
  r.data = data.response;
  r.model = model;
  r.k = confidence_radius(options.confidence);
  r.skipped.assign(F, false);
  const std::vector<Eigen::MatrixXd> scales = given_scales != nullptr ? *given_scales : response_scales(data.response);
  if (scales.size() != F)
    throw InputError(fmt::format("model error: {} scale matrices for {} frequencies", scales.size(), F));
  for (std::size_t f = 0; f < F; ++f) {
    if (data.response[f].rows() != p || data.response[f].cols() != m || model[f].rows() != p ||
        model[f].cols() != m || sigma[f].rows() != p || sigma[f].cols() != m)
      throw InputError(fmt::format("model error: at {:.6g} rad/s the data are {}x{}, the model {}x{} and the noise "
                                   "{}x{}; they must match",
                                   data.omega_rad_s(f), data.response[f].rows(), data.response[f].cols(),
                                   model[f].rows(), model[f].cols(), sigma[f].rows(), sigma[f].cols()));
    r.skipped[f] = !data.flagged.empty() && data.flagged[f];
    Eigen::MatrixXcd e = data.response[f] - model[f];
    Eigen::MatrixXd s(p, m), sc(p, m), rad(p, m);
    BoolMatrix sig = BoolMatrix::Constant(p, m, false);
    sc = scales[f];
    for (Index i = 0; i < p; ++i) {
      for (Index j = 0; j < m; ++j) {
        if (!r.skipped[f] && (!finite(data.response[f](i, j)) || !finite(model[f](i, j))))
          throw InputError(fmt::format("model error: non-finite response of output {}, input {} at {:.6g} rad/s",
                                       i + 1, j + 1, data.omega_rad_s(f)));
        const double sg = sigma[f](i, j);
        if (!(sg > 0) && !(sg == 0 && options.resolution > 0))
          throw InputError(fmt::format("model error: noise level {} of output {}, input {} at {:.6g} rad/s; it must "
                                       "be > 0",
                                       sg, i + 1, j + 1, data.omega_rad_s(f)));
        s(i, j) = std::max(sg, options.resolution * sc(i, j));
        rad(i, j) = r.k * s(i, j);
        sig(i, j) = !r.skipped[f] && std::abs(e(i, j)) > rad(i, j);
      }
    }
    r.error.push_back(std::move(e));
    r.sigma.push_back(std::move(s));
    r.scale.push_back(std::move(sc));
    r.radius.push_back(std::move(rad));
    r.significant.push_back(std::move(sig));
  }
  return r;
}

namespace {

void describe(const ModelErrorModel& mem, const std::vector<Index>& idx, FailingBand& b) {
  const Index i = b.output, j = b.input;
  // a coupling is an off-diagonal entry of a square response (input k drives output
  // k); a non-square one (a mechanical base with two sensors on one actuator) has none
  const bool off_diagonal =
      i != j && !mem.data.empty() && mem.data.front().rows() == mem.data.front().cols();
  const std::size_t n = idx.size();
  std::vector<double> gain(n), phase(n), err(n), rel(n), w(n);
  bool model_zero = false;
  double sum_model = 0, sum_data = 0;
  for (std::size_t t = 0; t < n; ++t) {
    const std::size_t f = static_cast<std::size_t>(idx[t]);
    const Complex d = mem.data[f](i, j), mo = mem.model[f](i, j), e = mem.error[f](i, j);
    w[t] = mem.omega_rad_s(idx[t]);
    err[t] = std::abs(e);
    rel[t] = std::abs(d) > 0 ? 100.0 * err[t] / std::abs(d) : kInf;
    sum_model += std::abs(mo);
    sum_data += std::abs(d);
    if (std::abs(mo) <= kModelZeroShare * std::abs(d) || std::abs(d) == 0) {
      model_zero = true;
      gain[t] = phase[t] = kNaN;
    } else {
      gain[t] = 20.0 * std::log10(std::abs(d) / std::abs(mo));
      phase[t] = std::arg(d / mo) * 180.0 / M_PI;
    }
    const double ratio = std::isinf(mem.sigma[f](i, j)) ? 0.0 : err[t] / std::max(mem.sigma[f](i, j), 1e-300);
    b.max_sigma_ratio = std::max(b.max_sigma_ratio, ratio);
  }
  auto mean_and_extreme = [&](const std::vector<double>& v, double& mean, double& ext) {
    mean = 0;
    ext = 0;
    for (double x : v) {
      mean += x;
      if (std::abs(x) > std::abs(ext)) ext = x;
    }
    mean /= static_cast<double>(v.size());
  };
  if (model_zero) {
    b.gain_db_mean = b.gain_db_max = b.phase_deg_mean = b.phase_deg_max = kNaN;
  } else {
    mean_and_extreme(gain, b.gain_db_mean, b.gain_db_max);
    mean_and_extreme(phase, b.phase_deg_mean, b.phase_deg_max);
  }
  double dummy = 0;
  mean_and_extreme(rel, b.relative_percent_mean, dummy);
  const std::size_t at_rel = static_cast<std::size_t>(std::max_element(rel.begin(), rel.end()) - rel.begin());
  b.relative_percent_max = rel[at_rel];
  b.omega_at_max_rad_s = w[at_rel];
  for (std::size_t t = 0; t < n; ++t) {
    const double s = mem.scale[static_cast<std::size_t>(idx[t])](i, j);
    if (s > 0) b.scaled_percent_max = std::max(b.scaled_percent_max, 100.0 * err[t] / s);
  }

  // --- signature (header comment: the first rule that holds) ---
  if (off_diagonal && sum_model < kCouplingLacking * sum_data) {
    b.signature = "coupling";
    b.hint = fmt::format("off-diagonal coupling the model lacks (model at {:.0f} % of the measured)",
                         100.0 * sum_model / sum_data);
    return;
  }
  const std::size_t peak = static_cast<std::size_t>(std::max_element(err.begin(), err.end()) - err.begin());
  const double edge = kPeakEdgeShare * static_cast<double>(n - 1);
  const bool interior = static_cast<double>(peak) > edge && static_cast<double>(peak) < static_cast<double>(n - 1) - edge;
  if (n >= 3 && interior && err[peak] >= kPeakOverEdges * std::max(err.front(), err.back()) &&
      std::log10(b.hi_rad_s / b.lo_rad_s) < kNarrowDecades) {
    b.signature = "narrow_peak";
    b.hint = fmt::format("narrow peak at {:.4g} rad/s (a mode missing from the model, or placed wrongly)", w[peak]);
    return;
  }
  // Gain or phase: which explains more of |E| at its largest.
  const bool gain_dominates =
      !model_zero && std::abs(std::pow(10.0, gain[peak] / 20.0) - 1.0) >= std::abs(phase[peak] * M_PI / 180.0);
  if (!model_zero && !gain_dominates && n >= 3) {
    // φ ≈ −ω τ by least squares through the origin.
    double sww = 0, swp = 0, spp = 0;
    bool one_sign = true;
    for (std::size_t t = 0; t < n; ++t) {
      const double ph = phase[t] * M_PI / 180.0;
      sww += w[t] * w[t];
      swp += w[t] * ph;
      spp += ph * ph;
      one_sign = one_sign && (ph * phase[0] > 0);
    }
    const double tau = -swp / sww;
    double res = 0;
    for (std::size_t t = 0; t < n; ++t) {
      const double d = phase[t] * M_PI / 180.0 + w[t] * tau;
      res += d * d;
    }
    if (one_sign && spp > 0 && std::sqrt(res / spp) < kDelayFitResidual) {
      b.signature = "delay";
      b.hint = fmt::format("phase {} growing with frequency (like a delay of {:.3g} ms)", tau > 0 ? "lag" : "lead",
                           1e3 * std::abs(tau));
      return;
    }
  }
  if (off_diagonal) {
    b.signature = "coupling";
    b.hint = "off-diagonal coupling error";
    return;
  }
  Index first_used = -1, last_used = -1;
  for (Index f = 0; f < mem.omega_rad_s.size(); ++f)
    if (!mem.skipped[static_cast<std::size_t>(f)]) {
      if (first_used < 0) first_used = f;
      last_used = f;
    }
  if (gain_dominates && b.first == first_used) {
    b.signature = "low_frequency_gain";
    b.hint = fmt::format("low-frequency gain error ({} at {:.4g} rad/s): static gain or stiffness", signed_db(gain[peak]),
                         w[peak]);
  } else if (gain_dominates && b.last == last_used) {
    b.signature = "high_frequency_gain";
    b.hint = fmt::format("high-frequency gain error ({} at {:.4g} rad/s): mass or inertia", signed_db(gain[peak]),
                         w[peak]);
  } else if (gain_dominates) {
    b.signature = "gain";
    b.hint = fmt::format("gain error ({} at {:.4g} rad/s)", signed_db(gain[peak]), w[peak]);
  } else {
    b.signature = "phase";
    b.hint = model_zero ? "error where the model or the data is zero"
                        : fmt::format("phase error ({:+.1f} deg at {:.4g} rad/s)", phase[peak], w[peak]);
  }
}

}  // namespace

std::vector<FailingBand> failing_bands(const ModelErrorModel& mem, const ModelErrorOptions& options, Index data_index) {
  options.validate();
  std::vector<FailingBand> out;
  if (mem.error.empty()) return out;
  const Index p = mem.error.front().rows(), m = mem.error.front().cols();
  std::vector<Index> used;  // unflagged frequencies in order
  for (std::size_t f = 0; f < mem.skipped.size(); ++f)
    if (!mem.skipped[f]) used.push_back(static_cast<Index>(f));
  // |E/s|² per entry, and its sum over the set: the squared error figure's numerator.
  auto scaled_squared = [&](Index f, Index i, Index j) {
    const std::size_t k = static_cast<std::size_t>(f);
    const double s = mem.scale[k](i, j);
    return s > 0 ? std::norm(mem.error[k](i, j)) / (s * s) : 0.0;
  };
  double total = 0;
  for (Index f : used)
    for (Index i = 0; i < p; ++i)
      for (Index j = 0; j < m; ++j) total += scaled_squared(f, i, j);
  for (Index i = 0; i < p; ++i)
    for (Index j = 0; j < m; ++j) {
      std::vector<Index> run;  // significant frequencies of the current band
      std::vector<std::vector<Index>> kept;
      Index gap = 0;
      auto close = [&] {
        if (static_cast<Index>(run.size()) >= options.min_band_points) {
          const double ratio = kept.empty() ? kInf : mem.omega_rad_s(run.front()) / mem.omega_rad_s(kept.back().back());
          if (ratio <= std::pow(10.0, options.merge_decades))
            kept.back().insert(kept.back().end(), run.begin(), run.end());
          else
            kept.push_back(run);
        }
        run.clear();
        gap = 0;
      };
      for (Index f : used) {
        if (mem.significant[static_cast<std::size_t>(f)](i, j)) {
          run.push_back(f);
          gap = 0;
        } else if (!run.empty() && ++gap > options.max_gap_points) {
          close();
        }
      }
      close();
      for (const auto& band : kept) {
        FailingBand b;
        b.data_index = data_index;
        b.output = i;
        b.input = j;
        b.first = band.front();
        b.last = band.back();
        b.lo_rad_s = mem.omega_rad_s(b.first);
        b.hi_rad_s = mem.omega_rad_s(b.last);
        b.points = static_cast<Index>(band.size());
        describe(mem, band, b);
        double sum = 0;
        for (Index f : band) sum += scaled_squared(f, i, j);
        b.error_share = total > 0 ? sum / total : 0.0;
        out.push_back(std::move(b));
      }
    }
  return out;
}

std::vector<Phenomenon> group_phenomena(const std::vector<std::vector<FailingBand>>& failures,
                                        const std::vector<std::string>& output_names,
                                        const std::vector<std::string>& input_names, double phenomenon_decades) {
  std::vector<FailingBand> all;
  for (const auto& set : failures)
    for (const FailingBand& b : set) all.push_back(b);
  // furthest beyond the noise first: each phenomenon is seeded by its strongest band
  // (where a thing is, is best located by its clearest band)
  std::stable_sort(all.begin(), all.end(),
                   [](const FailingBand& a, const FailingBand& b) { return a.max_sigma_ratio > b.max_sigma_ratio; });
  std::vector<Phenomenon> out;
  auto peak_of = [](const FailingBand& b) {
    // a band's location: where its error is largest (bands that span decades are
    // located by their peak, not their extent)
    return b.omega_at_max_rad_s > 0 ? b.omega_at_max_rad_s : std::sqrt(b.lo_rad_s * b.hi_rad_s);
  };
  for (const FailingBand& b : all) {
    Phenomenon* home = nullptr;
    for (Phenomenon& ph : out)
      if (std::abs(std::log10(peak_of(b) / ph.omega_rad_s)) <= phenomenon_decades) {
        home = &ph;
        break;
      }
    if (home == nullptr) {
      out.push_back({});
      home = &out.back();
      home->omega_rad_s = peak_of(b);
      home->max_sigma_ratio = b.max_sigma_ratio;
    }
    home->bands.push_back(b);
    home->error_share += b.error_share / static_cast<double>(std::max<std::size_t>(failures.size(), 1));
    auto add = [](std::vector<Index>& v, Index x) {
      if (std::find(v.begin(), v.end(), x) == v.end()) v.push_back(x);
    };
    add(home->outputs, b.output);
    add(home->inputs, b.input);
    add(home->data_sets, b.data_index);
  }
  auto oname = [&](Index i) {
    return i < static_cast<Index>(output_names.size()) ? output_names[static_cast<std::size_t>(i)]
                                                        : fmt::format("output {}", i + 1);
  };
  auto iname = [&](Index j) {
    return j < static_cast<Index>(input_names.size()) ? input_names[static_cast<std::size_t>(j)]
                                                       : fmt::format("input {}", j + 1);
  };
  for (Phenomenon& ph : out) {
    std::sort(ph.outputs.begin(), ph.outputs.end());
    std::sort(ph.inputs.begin(), ph.inputs.end());
    std::sort(ph.data_sets.begin(), ph.data_sets.end());
    std::vector<std::string> channels;
    bool diagonal = true;
    for (const FailingBand& b : ph.bands) {
      const std::string c = oname(b.output) + " <- " + iname(b.input);
      if (std::find(channels.begin(), channels.end(), c) == channels.end()) channels.push_back(c);
      diagonal = diagonal && b.output == b.input;
    }
    const std::string list = fmt::format("{}", fmt::join(channels, ", "));
    if (channels.size() == 1)
      ph.where = list;
    else if (ph.outputs.size() == 1)
      ph.where = fmt::format("the {} output row only ({})", oname(ph.outputs[0]), list);
    else if (ph.inputs.size() == 1)
      ph.where = fmt::format("the {} input column only ({})", iname(ph.inputs[0]), list);
    else if (diagonal)
      ph.where = fmt::format("the diagonal ({})", list);
    else
      ph.where = list;
  }
  return out;
}

std::vector<Phenomenon> ranked_by_error_share(std::vector<Phenomenon> phenomena) {
  std::stable_sort(phenomena.begin(), phenomena.end(), [](const Phenomenon& a, const Phenomenon& b) {
    return a.error_share > b.error_share;
  });
  return phenomena;
}

void mark_differences_between_data(std::vector<std::vector<FailingBand>>& failures) {
  const std::size_t sets = failures.size();
  if (sets < 2) return;
  for (std::size_t d = 0; d < sets; ++d)
    for (FailingBand& b : failures[d]) {
      std::vector<std::size_t> in;
      for (std::size_t e = 0; e < sets; ++e) {
        bool found = e == d;
        for (const FailingBand& c : failures[e])
          found = found || (c.output == b.output && c.input == b.input && c.lo_rad_s <= b.hi_rad_s &&
                            c.hi_rad_s >= b.lo_rad_s);
        if (found) in.push_back(e + 1);
      }
      if (in.size() == sets) continue;
      b.differs_between_data = true;
      b.hint += fmt::format("; differs between data sets (only in set {} of {})", fmt::join(in, ", "), sets);
    }
}

}  // namespace lpvid
