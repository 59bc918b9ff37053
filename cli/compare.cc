// lpvid compare — where does a model fail?  Two forms:
//   lpvid compare --model M --data FRD [--data FRD ...] [--out-png p.png] [--json]
//     the model-error model (idlib/validate/model_error.h): E = P_data − P_model per
//     channel with its noise band from coherence, the failing bands (significant
//     beyond the noise) listed with size and signature, and a PNG;
//   lpvid compare ESTIMATE REFERENCE
//     the first version: distance between two responses per channel and band.
// (A time-domain form, --log, is dispatched to cli/compare_time.cc.)
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "cli/beam_commands.h"
#include "cli/common.h"
#include "cli/fit_inputs.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "cli/responses.h"
#include "formats/io/atomic_file.h"
#include "formats/io/physical_model_json.h"
#include "formats/plot/compare_plot.h"
#include "idlib/diagnose/diagnose.h"
#include "idlib/fit/fit.h"
#include "idlib/core/error.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/validate/compare.h"
#include "idlib/validate/model_error.h"

namespace lpvid::cli {
namespace {

constexpr const char* kCompareExample = R"(
Example:
  lpvid compare --model plant.json --data P_left.csv --data P_right.csv --out-png compare.png
  lpvid compare --model left.json --model right.json --data P_left.csv --data P_right.csv --json
With --model and --data: the model-error model E = P_data - P_model of every channel, its
99 % noise band from the data (their variance, or coherence with the averages the files
state or --averages, or --noise-level: the relative rms error of the measurement; without
any of them compare stops and says so), and the failing bands: frequencies where |E| is
beyond the noise, at least --min-points of them together.  The table (or --json) lists
each failure: data set, channel, band rad/s, size in dB, degrees and percent of |P_data|,
and a signature in plain words ("phase lag growing with frequency", "narrow peak at 612
rad/s", "off-diagonal coupling", "low-frequency gain error", "differs between data sets"),
then the distinct phenomena.  One --model for all data, or one per --data (in order).
A physical model file (lpvid model/fit) is compared as fit and diagnose see it:
  lpvid compare --model fit2.json --datasets data.json --out-png where.png
  lpvid compare --model fit2.json --target S --controller C.json --data S_left.csv@-0.1 ...
with the error figure and its noise floor.  Failures are results: the exit code is 0.

  lpvid compare P_from_S.csv truth_plant.json --band-min 1 --band-max 400 --weights 0.1,0.1,1
  lpvid compare P_from_S.csv P_from_G.csv --json
ESTIMATE and REFERENCE are models (.json) or FRD files (.csv, .mat); a model is evaluated on
the data's frequencies, two models on a log grid.  For each channel and band: the
largest error as a share of the weighted matrix gain (percent), the mean gain error (dB)
and the mean phase error (degrees); per band the weighted matrix error
|W(A - R)W| / |WRW| (mean, max).  Flagged frequencies of the data are skipped.
  lpvid compare --log data/sweep_1000hz/run.csv --params model.json --controller data/sweep_1000hz/controller.json \
      --out-png overlay.png --json
time domain: simulates the platform model's closed loop on the logged excitation and beam
trajectory; NRMSE fit % per output, residual whiteness and residual-input tests (99 %),
and the time windows where the model fails (channel, t_start, t_end, size).
  lpvid compare --log validation.csv --model axis_fitted.json --out-png where.png
a mechanical model (base mechanical): the force error of the model as given on the log
(nothing refitted), against its noise floor, and the windows where it fails; smoothed as
the fit that wrote the model (its fit.smoothing: window and input convention), or with the
route's defaults (0.02 s, the input held) for a model no force-error fit wrote.)";

struct CompareCliOptions {
  std::string estimate, reference, weights, out;
  double band_min = 0, band_max = 0, per_decade = 1;
  Index top = 9, points = 400;
  bool json = false;
  // Model-error form.
  std::vector<std::string> models, data;
  std::string out_png, labels;
  ModelErrorOptions mem;
  NoiseOptions noise;
  // A physical model: the inputs of fit/diagnose.
  std::string datasets, target, controller;
  double rate_hz = kUnset;
};


std::string channel_name(const std::vector<std::string>& names, Index i) {
  return i < static_cast<Index>(names.size()) && !names[static_cast<std::size_t>(i)].empty()
             ? names[static_cast<std::size_t>(i)]
             : std::to_string(i + 1);
}

// The model-error report of per-data-set model-error models (shared by both model kinds).
struct ErrorReport {
  std::vector<ModelErrorModel> mems;
  std::vector<std::vector<FailingBand>> failures;
  std::vector<std::string> data_names, labels, models, noise;
  std::vector<std::string> out_names, in_names;
  nlohmann::json extra;  // added to the summary (physical model: error figure, floor)
  std::string extra_text;
};

void report(const CompareCliOptions& o, ErrorReport& r, OutputSet& outputs) {
  mark_differences_between_data(r.failures);
  nlohmann::json jdata = nlohmann::json::array(), jfail = nlohmann::json::array();
  std::string text = fmt::format("compare: model-error model of {} data set(s) against {}; {:.3g} % noise band (k = {:.3f} sigma)\n",
                                 r.data_names.size(), fmt::join(r.models, ", "), 100 * o.mem.confidence, r.mems.front().k);
  text += r.extra_text;
  std::size_t total = 0;
  for (std::size_t d = 0; d < r.data_names.size(); ++d) {
    Index skipped = 0;
    for (bool s : r.mems[d].skipped) skipped += s ? 1 : 0;
    jdata.push_back({{"file", r.data_names[d]},
                     {"label", r.labels[d]},
                     {"frequencies", r.mems[d].omega_rad_s.size()},
                     {"skipped", skipped},
                     {"noise", r.noise[d]},
                     {"failing_bands", r.failures[d].size()}});
    text += fmt::format("  data {} '{}': {} frequencies ({} flagged or outside the band, skipped); noise from {}; {} failing band(s)\n",
                        d + 1, r.labels[d], r.mems[d].omega_rad_s.size(), skipped, r.noise[d], r.failures[d].size());
    total += r.failures[d].size();
  }
  if (total == 0) {
    text += "  no failing band: every difference is within the measurement's noise\n";
  } else {
    text += "  data  output    input     band [rad/s]         points  gain dB mean/max   phase deg mean/max  error % mean/max  signature\n";
  }
  for (const auto& set : r.failures)
    for (const FailingBand& b : set) {
      const std::string out = channel_name(r.out_names, b.output), in = channel_name(r.in_names, b.input);
      jfail.push_back({{"data", b.data_index + 1},
                       {"data_file", r.data_names[static_cast<std::size_t>(b.data_index)]},
                       {"output", out},
                       {"input", in},
                       {"band_rad_s", {b.lo_rad_s, b.hi_rad_s}},
                       {"points", b.points},
                       {"gain_db", {{"mean", number_or_null(b.gain_db_mean)}, {"max", number_or_null(b.gain_db_max)}}},
                       {"phase_deg", {{"mean", number_or_null(b.phase_deg_mean)}, {"max", number_or_null(b.phase_deg_max)}}},
                       {"relative_percent",
                        {{"mean", number_or_null(b.relative_percent_mean)}, {"max", number_or_null(b.relative_percent_max)}}},
                       {"omega_at_max_rad_s", b.omega_at_max_rad_s},
                       {"sigma_max", number_or_null(b.max_sigma_ratio)},
                       {"signature", b.signature},
                       {"hint", b.hint},
                       {"differs_between_data", b.differs_between_data}});
      auto num = [](double v, const char* f) { return std::isfinite(v) ? fmt::format(fmt::runtime(f), v) : std::string("-"); };
      text += fmt::format("  {:<5} {:<9} {:<9} {:>8.4g} - {:<8.4g}  {:6d}  {:>7} / {:<7}  {:>7} / {:<7}   {:>6} / {:<7} {}\n",
                          b.data_index + 1, out, in, b.lo_rad_s, b.hi_rad_s, b.points, num(b.gain_db_mean, "{:+.2f}"),
                          num(b.gain_db_max, "{:+.2f}"), num(b.phase_deg_mean, "{:+.1f}"), num(b.phase_deg_max, "{:+.1f}"),
                          num(b.relative_percent_mean, "{:.1f}"), num(b.relative_percent_max, "{:.1f}"), b.hint);
    }
  const std::vector<Phenomenon> phenomena = ranked_by_error_share(group_phenomena(r.failures, r.out_names, r.in_names));
  nlohmann::json jph = nlohmann::json::array();
  if (!phenomena.empty()) text += fmt::format("  {} distinct phenomena, largest share of the error first:\n", phenomena.size());
  for (std::size_t k = 0; k < phenomena.size(); ++k) {
    const Phenomenon& p = phenomena[k];
    std::vector<std::string> sets;
    for (Index d : p.data_sets) sets.push_back(r.labels[static_cast<std::size_t>(d)]);
    jph.push_back({{"omega_rad_s", p.omega_rad_s}, {"where", p.where}, {"data", sets}, {"bands", p.bands.size()},
                   {"max_sigma_ratio", p.max_sigma_ratio}, {"error_share", p.error_share},
                   {"scaled_percent_max", p.bands.front().scaled_percent_max}, {"hint", p.bands.front().hint}});
    if (k < 8)
      text += fmt::format("    {}. near {:.4g} rad/s in {} ({}): {:.2g} % of the error, up to {:.3g} %, {:.0f}x the "
                          "noise; {}\n",
                          k + 1, p.omega_rad_s, p.where, fmt::join(sets, ", "), 100.0 * p.error_share,
                          p.bands.front().scaled_percent_max, p.max_sigma_ratio, p.bands.front().hint);
  }
  nlohmann::json summary = {{"models", r.models},
                            {"data", jdata},
                            {"confidence", o.mem.confidence},
                            {"k_sigma", r.mems.front().k},
                            {"min_points", o.mem.min_band_points},
                            {"failing_bands", total},
                            {"failures", jfail},
                            {"phenomena", jph}};
  for (auto it = r.extra.begin(); it != r.extra.end(); ++it) summary[it.key()] = it.value();

  // --- outputs, staged and committed together ---
  if (!o.out_png.empty()) {
    std::vector<CompareSeries> series;
    std::vector<CompareBandMark> marks;
    for (std::size_t d = 0; d < r.mems.size(); ++d) {
      series.push_back({r.mems.size() > 1 ? r.labels[d] : "", r.mems[d].omega_rad_s, r.mems[d].data, r.mems[d].model,
                        r.mems[d].radius, r.mems[d].scale, r.mems[d].skipped});
      for (const auto& b : r.failures[d]) marks.push_back({b.output, b.input, b.lo_rad_s, b.hi_rad_s});
    }
    ComparePlotOptions po;
    po.same_model = r.models.size() == 1 && !r.extra.contains("error");
    po.band_label = fmt::format("{:g} % noise band", 100 * o.mem.confidence);
    po.title = fmt::format("Model {} vs measurement: {} failing band{}", fmt::join(r.models, ", "), total,
                           total == 1 ? "" : "s");
    if (static_cast<Index>(r.out_names.size()) == r.mems.front().data.front().rows()) po.output_labels = r.out_names;
    if (static_cast<Index>(r.in_names.size()) == r.mems.front().data.front().cols()) po.input_labels = r.in_names;
    const auto png = compare_png(series, marks, po);
    outputs.stage(o.out_png, png);
    summary["png"] = o.out_png;
  }
  if (!o.out.empty()) outputs.stage(o.out, json_text(summary));
  outputs.commit();
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

// --model is a physical model file: the inputs of fit/diagnose, the fit's error figure.
void run_physical_model_error(const CompareCliOptions& o) {
  FitInputOptions f;
  f.model = o.models.front();
  f.data = o.data;
  f.datasets = o.datasets;
  f.target = o.target;
  f.controller = o.controller;
  f.rate_hz = o.rate_hz;
  f.averages = o.noise.averages > 0 ? o.noise.averages : kUnset;
  f.noise_level = o.noise.noise_level > 0 ? o.noise.noise_level : kUnset;
  f.band_min = o.band_min > 0 ? o.band_min : kUnset;
  f.band_max = o.band_max > 0 ? o.band_max : kUnset;
  OutputSet outputs;
  outputs.file("--out-png", o.out_png);
  outputs.file("--out", o.out);
  const FitInputs in = load_fit_inputs(f, outputs);
  for (const FitDataset& ds : in.data) {
    bool known = false;
    std::string source;
    data_sigma(ds.response, in.options.noise, &source, &known);
    if (!known)
      throw InputError(fmt::format("compare: {}: the noise of the data is not known ({}); give --averages N or "
                                   "--noise-level X, or data that carry their variance",
                                   ds.label, source));
  }
  const ModelScore score = score_model(in.start, in.data, in.options);
  const ModelErrorSet mes = model_errors(in.start, in.data, in.options, o.mem);
  ErrorReport r;
  r.mems = mes.models;
  r.failures = mes.failures;
  r.models = {f.model};
  for (const FitDataset& ds : in.data) {
    r.data_names.push_back(ds.label);
    // a base without a scheduling variable: the data set's own name
    r.labels.push_back(std::isnan(ds.beam_position_m) ? ds.label : fmt::format("x_b = {:g} m", ds.beam_position_m));
    std::string source;
    data_sigma(ds.response, in.options.noise, &source);
    r.noise.push_back(source);
  }
  const FrequencyResponse named = target_response(in.start, in.data.front().beam_position_m,
                                                  in.data.front().response.omega_rad_s, in.options);
  const FrequencyResponse& first = in.data.front().response;
  r.out_names = first.output_names.size() == named.output_names.size() ? first.output_names : named.output_names;
  r.in_names = first.input_names.size() == named.input_names.size() ? first.input_names : named.input_names;
  r.extra = {{"error", score.error}, {"noise_floor", number_or_null(score.noise_floor)},
             {"effective_floor", mes.effective_floor}, {"target", target_name(in.options.target)}};
  r.extra_text = fmt::format("  error {:.4g} % (rms over the channels of the relative rms error); noise floor {} "
                             "({:.4g} % with lpvid's resolution){}\n",
                             100 * score.error,
                             std::isfinite(score.noise_floor) ? fmt::format("{:.4g} %", 100 * score.noise_floor) : "unknown",
                             100 * mes.effective_floor,
                             score.error <= 1.5 * mes.effective_floor ? ": within the noise" : "");
  report(o, r, outputs);
}

void run_model_error(const CompareCliOptions& o) {
  o.mem.validate();
  o.noise.validate();
  if (o.models.empty()) throw InputError("compare: --data needs --model; give the model to compare the data with (--model M.json)");
  if (!o.estimate.empty())
    throw InputError(fmt::format("compare: '{}' given with --model/--data; use either ESTIMATE REFERENCE or "
                                 "--model M --data FRD",
                                 o.estimate));
  if (o.models.size() == 1 && is_physical_model_file(o.models.front())) return run_physical_model_error(o);
  if (!o.datasets.empty())
    throw InputError("compare: --datasets needs a physical model file as --model (lpvid model/fit); a state-space "
                     "or FRD model takes --data FRD");
  if (o.models.size() != 1 && o.models.size() != o.data.size())
    throw InputError(fmt::format("compare: {} --model for {} --data; give one model for all data or one per data set",
                                 o.models.size(), o.data.size()));
  std::vector<std::string> labels;
  if (!o.labels.empty()) {
    labels = split_names(o.labels, "--labels");
    if (labels.size() != o.data.size())
      throw InputError(fmt::format("--labels: {} labels for {} --data; give one per data set", labels.size(),
                                   o.data.size()));
  }
  OutputSet outputs;
  outputs.inputs(o.models);
  outputs.inputs(o.data);
  outputs.file("--out-png", o.out_png);
  outputs.file("--out", o.out);
  outputs.check();

  std::vector<LoadedResponse> models;
  for (const auto& m : o.models) models.push_back(load_response(m));
  ErrorReport r;
  r.models = o.models;
  std::vector<FrequencyResponse> datas;
  for (std::size_t d = 0; d < o.data.size(); ++d) {
    LoadedResponse data = load_response(o.data[d]);
    if (!data.frd)
      throw InputError(fmt::format("--data '{}' is a model; give measured frequency-response data (FRD .csv "
                                   "or .mat) to --data and the model to --model",
                                   o.data[d]));
    const LoadedResponse& model = models[models.size() == 1 ? 0 : d];
    const FrequencyResponse on = response_on(model, data.frd->omega_rad_s);
    if (on.num_outputs() != data.frd->num_outputs() || on.num_inputs() != data.frd->num_inputs())
      throw InputError(fmt::format("compare: '{}' is {}x{} but the model '{}' is {}x{}; give data and model of one plant",
                                   o.data[d], data.frd->num_outputs(), data.frd->num_inputs(), model.path,
                                   on.num_outputs(), on.num_inputs()));
    std::string source;
    bool known = false;
    std::vector<Eigen::MatrixXd> scales;
    const std::vector<Eigen::MatrixXd> sigma = data_sigma(*data.frd, o.noise, &source, &known, &scales);
    if (!known)
      throw InputError(fmt::format("compare: '{}': the noise of the data is not known ({}); give --averages N (the "
                                   "independent averages behind its coherence) or --noise-level X (the relative rms "
                                   "error of the measurement, e.g. 0.01)",
                                   o.data[d], source));
    FrequencyResponse banded = *data.frd;
    if (o.band_min > 0 || o.band_max > 0) {
      if (banded.flagged.empty()) banded.flagged.assign(static_cast<std::size_t>(banded.num_frequencies()), false);
      for (Index k = 0; k < banded.num_frequencies(); ++k) {
        const double w = banded.omega_rad_s(k);
        if ((o.band_min > 0 && w < o.band_min) || (o.band_max > 0 && w > o.band_max))
          banded.flagged[static_cast<std::size_t>(k)] = true;
      }
    }
    r.mems.push_back(model_error(banded, on.response, sigma, o.mem, &scales));
    r.failures.push_back(failing_bands(r.mems.back(), o.mem, static_cast<Index>(d)));
    r.noise.push_back(source);
    r.data_names.push_back(o.data[d]);
    r.labels.push_back(labels.empty() ? o.data[d] : labels[d]);
    datas.push_back(std::move(*data.frd));
  }
  const FrequencyResponse& first = datas.front();
  r.out_names = !first.output_names.empty()
                    ? first.output_names
                    : (models.front().model ? models.front().model->output_names : std::vector<std::string>{});
  r.in_names = !first.input_names.empty()
                   ? first.input_names
                   : (models.front().model ? models.front().model->input_names : std::vector<std::string>{});
  report(o, r, outputs);
}

void run(const CompareCliOptions& o) {
  if (!o.data.empty() || !o.datasets.empty()) return run_model_error(o);
  if (!o.models.empty()) throw InputError("compare: --model needs --data; give the measured FRD to compare it with (--data P.csv)");
  if (o.estimate.empty() || o.reference.empty())
    throw InputError("compare: give --model M --data FRD (where the model fails), ESTIMATE REFERENCE (distance "
                     "between two responses), or --log RUN.csv (the time domain)");
  if (!o.out_png.empty()) throw InputError("compare: --out-png needs --model and --data; give both, or drop --out-png");
  CompareOptions options;
  options.band_min_rad_s = o.band_min;
  options.band_max_rad_s = o.band_max;
  options.bands_per_decade = o.per_decade;
  options.validate();
  OutputSet outputs;
  outputs.input(o.estimate);
  outputs.input(o.reference);
  outputs.file("--out", o.out);
  outputs.check();
  std::vector<double> weights;
  if (!o.weights.empty()) weights = split_numbers(o.weights, "--weights", "weight");
  const LoadedResponse a = load_response(o.estimate), b = load_response(o.reference);
  Eigen::VectorXd omega;
  std::vector<bool> flagged;
  if (a.frd) {
    omega = a.frd->omega_rad_s;
    flagged = a.frd->flagged;
  } else if (b.frd) {
    omega = b.frd->omega_rad_s;
    flagged = b.frd->flagged;
  } else {
    const double lo = o.band_min > 0 ? o.band_min : 1.0;
    double hi = o.band_max > 0 ? o.band_max : 1e3;
    for (const auto* m : {&*a.model, &*b.model})
      if (m->is_discrete()) hi = std::min(hi, 0.999 * M_PI / m->sample_period_s);
    omega = log_frequency_grid(lo, hi, o.points);
  }
  const FrequencyResponse fa = response_on(a, omega), fb = response_on(b, omega);
  // A frequency flagged in either data set is skipped (both are on one grid here).
  if (a.frd && b.frd && !b.frd->flagged.empty()) {
    if (flagged.empty()) flagged.assign(b.frd->flagged.size(), false);
    for (std::size_t k = 0; k < flagged.size(); ++k) flagged[k] = flagged[k] || b.frd->flagged[k];
  }
  if (!weights.empty()) {
    const Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(weights.data(), static_cast<Index>(weights.size()));
    // W (A - R) W: the same weights on outputs and inputs (square responses).
    options.left_weight = v;
    options.right_weight = v;
  }
  const CompareResult r = compare_responses(fa.response, fb.response, omega, flagged, options);
  auto name = [](const std::vector<std::string>& names, Index i) {
    return i < static_cast<Index>(names.size()) ? names[i] : std::to_string(i + 1);
  };
  nlohmann::json channels = nlohmann::json::array(), bands = nlohmann::json::array();
  for (const auto& c : r.channels)
    channels.push_back({{"output", name(fb.output_names, c.output)},
                        {"input", name(fb.input_names, c.input)},
                        {"band_rad_s", {c.band_lo_rad_s, c.band_hi_rad_s}},
                        {"share_percent", c.share_percent},
                        {"gain_db", std::isnan(c.gain_db) ? nlohmann::json(nullptr) : nlohmann::json(c.gain_db)},
                        {"phase_deg", std::isnan(c.phase_deg) ? nlohmann::json(nullptr) : nlohmann::json(c.phase_deg)}});
  for (const auto& b2 : r.bands)
    bands.push_back({{"band_rad_s", {b2.band_lo_rad_s, b2.band_hi_rad_s}},
                     {"points", b2.points},
                     {"flagged", b2.flagged},
                     {"weighted_error_mean", b2.weighted_mean},
                     {"weighted_error_max", b2.weighted_max}});
  nlohmann::json summary = {{"estimate", o.estimate},     {"reference", o.reference},
                            {"weighted_error_mean", r.weighted_mean}, {"weighted_error_max", r.weighted_max},
                            {"omega_at_max_rad_s", r.omega_at_max_rad_s}, {"bands", bands},
                            {"channels", channels}};
  std::string text = fmt::format("compare {} against {}: weighted matrix error mean {:.3f} %, max {:.3f} % at {:.4g} rad/s\n",
                                 o.estimate, o.reference, 100 * r.weighted_mean, 100 * r.weighted_max,
                                 r.omega_at_max_rad_s);
  text += "  band [rad/s]            points  flagged  mean err  max err\n";
  for (const auto& b2 : r.bands)
    text += fmt::format("  {:9.4g} - {:<9.4g}  {:7d}  {:7d}  {:7.3f} %  {:6.3f} %\n", b2.band_lo_rad_s, b2.band_hi_rad_s,
                        b2.points, b2.flagged, 100 * b2.weighted_mean, 100 * b2.weighted_max);
  text += fmt::format("  worst channels (of {}):\n  output    input     band [rad/s]           share    gain     phase\n",
                      r.channels.size());
  for (std::size_t i = 0; i < r.channels.size() && static_cast<Index>(i) < o.top; ++i) {
    const auto& c = r.channels[i];
    const std::string gp = std::isnan(c.gain_db) ? std::string("   (reference ~ 0)")
                                                 : fmt::format("{:5.2f} dB  {:5.1f} deg", c.gain_db, c.phase_deg);
    text += fmt::format("  {:<9} {:<9} {:9.4g} - {:<9.4g} {:6.3f} %  {}\n", name(fb.output_names, c.output),
                        name(fb.input_names, c.input), c.band_lo_rad_s, c.band_hi_rad_s, c.share_percent, gp);
  }
  if (!o.out.empty()) outputs.stage(o.out, json_text(summary));
  outputs.commit();
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_compare_command() {
  return {"compare", "where a model fails against measurements (model-error model, failing bands, PNG)", [](CLI::App& parent) {
            auto o = std::make_shared<CompareCliOptions>();
            auto* app = parent.add_subcommand("compare", "Where a model fails: model-error model with noise band and failing bands" +
                                                             std::string(kCompareExample));
            app->add_option("--model", o->models, "model (.json) or FRD; once, or once per --data")
                ->take_all()
                ->expected(1);
            app->add_option("--data", o->data, "measured FRD (.csv, .mat), repeatable")->take_all()->expected(1);
            app->add_option("--out-png", o->out_png, "figure: measurement and model overlaid with error panels (with --log: the time-domain overlay)");
            app->add_option("--labels", o->labels, "one label per --data for the table and figure (comma separated)");
            app->add_option("--averages", o->noise.averages,
                            "independent averages behind the data's coherence, when the files do not state it")
                ->check(number_in(1, 1e9, "the number of averages"));
            app->add_option("--confidence", o->mem.confidence, "confidence of the noise band (default 0.99)")
                ->check(number_in(0, 1, "the confidence", true, true));
            app->add_option("--noise-level", o->noise.noise_level,
                            "relative rms error of the measurement (e.g. 0.01) for data with neither variance nor coherence")
                ->check(number_in(0, 1, "the relative noise level (0.01 for 1 %)", true, true));
            app->add_option("--datasets", o->datasets, "physical model: the dataset manifest (as for fit)");
            app->add_option("--target", o->target, "physical model: what the data are (plant, G, S)");
            app->add_option("--rate-hz", o->rate_hz, "physical model: sample rate of the experiment")
                ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz (omit it to use the data's or controller's)"));
            app->add_option("--min-points", o->mem.min_band_points,
                            "significant frequencies a failing band needs (default 3)")
                ->check(integer_in(1, kMaxFrequencyPoints, "the number of frequencies"));
            app->add_option("estimate", o->estimate, "model (.json) or FRD (.csv, .mat)");
            app->add_option("reference", o->reference, "model (.json) or FRD (.csv, .mat)");
            app->add_option("--band-min", o->band_min, "lowest frequency, rad/s (default: from the data)")
                ->check(positive_up_to(kMaxFrequency, "the lowest frequency in rad/s"));
            app->add_option("--band-max", o->band_max, "highest frequency, rad/s (default: from the data)")
                ->check(positive_up_to(kMaxFrequency, "the highest frequency in rad/s"));
            app->add_option("--bands-per-decade", o->per_decade, "log-spaced bands per decade")
                ->check(positive_up_to(1000, "the bands per decade"));
            app->add_option("--weights", o->weights, "weights W on outputs and inputs (comma separated)");
            app->add_option("--top", o->top, "how many channel rows to print")
                ->check(integer_in(1, kMaxListed, "the number of rows"));
            app->add_option("--points", o->points, "frequencies when both are models")
                ->check(integer_in(2, kMaxFrequencyPoints, "the number of frequencies"));
            app->add_option("--out", o->out, "also write the JSON summary to this file");
            app->add_flag("--json", o->json, "print the summary as JSON");
            auto t = std::make_shared<TimeCompareCliOptions>();
            add_time_compare_options(app, *t);
            app->callback([o, t] {
              o->controller = t->controller;  // one --controller for both forms
              if (!t->active()) return run(*o);
              // `compare --model M.json --log RUN.csv`: the model file is the time route's model.
              if (t->params.empty() && o->models.size() == 1) t->params = o->models.front();
              else if (!o->models.empty())
                throw InputError("compare --log: give the model once (--model M.json or --params M.json)");
              t->out_png = o->out_png;  // one --out-png for both forms
              run_time_compare(*t, o->out, o->json);
            });
          }};
}

}  // namespace lpvid::cli
