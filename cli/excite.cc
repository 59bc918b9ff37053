// lpvid excite — excitation signals for the lab and the simulators: periodic
// multisines (random or Schroeder phases, crest factor minimised on request),
// PRBS and white noise, for one input or n inputs (one at a time, Hadamard-coded,
// zippered), written as a CSV log or a .mat file with the design recorded for
// periodic `frf` (docs/formats.md, "Excitation design line").
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/amplitude_spectrum.h"
#include "formats/io/csv_log.h"
#include "formats/io/excitation_design.h"
#include "formats/io/excitation_file.h"
#include "idlib/core/error.h"
#include "idlib/signal/excitation.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExciteExample = R"(
Example:
  lpvid excite --kind multisine --rate-hz 1000 --period-samples 2000 --periods 4 --transient-periods 1 \
    --band-hz 1,200 --channels 3 --mimo hadamard --rms 0.05,0.05,1 --out ms.csv
writes ms.csv (columns t, v1..v3): 4 experiments (Hadamard-coded signs) of 1 + 4 periods of
2000 samples, lines every 0.5 Hz from 1 to 200 Hz on every input, random phases (--seed),
scaled to the RMS of each input; the first comment line records the design for frf.
  lpvid excite --grid log --lines-per-decade 30 --band-hz 0.5,300 --phase schroeder --minimise-crest \
    --period-s 4 --peak 1 --out ms.mat
one input, a logarithmic grid, Schroeder phases then crest-factor minimisation, peak 1.
  lpvid excite --period-samples 4000 --band-hz 0.5,300 --grid log --amplitude shape.csv --minimise-crest \
    --rms 0.1 --out ms.csv
shape.csv (columns f_hz, amplitude) shapes the lines: relative amplitudes interpolated log-log
between its rows, constant beyond its first and last; then the RMS scaling (the design
records every line's amplitude).
  lpvid excite --kind prbs --period-samples 1023 --periods 8 --rms 0.1 --out prbs.csv
  lpvid excite --kind noise --duration-s 60 --channels 3 --rms 0.05,0.05,1 --out noise.csv
Drive a simulator with the file: lpvid simulate platform --excitation ms.csv --out data
(the log copies the design line).)";

struct ExciteCliOptions {
  std::string kind = "multisine";
  double rate_hz = 1000;
  int64_t period_samples = 0;
  double period_s = 0;
  int64_t periods = 4, transient_periods = 1, realisations = 1;
  std::vector<double> band_hz;
  std::string grid = "lin";
  double lines_per_decade = 20;
  int64_t every = 1;
  std::string phase = "random";
  bool minimise_crest = false;
  int64_t crest_iterations = 200;
  std::string rms, peak;
  std::string amplitude;  // --amplitude FILE: relative amplitude spectrum (multisine)
  int64_t channels = 1;
  std::string mimo;
  std::uint64_t seed = 1;
  double duration_s = 0;
  int64_t clock_divider = 1;
  std::string out;
  bool json = false;
};

// Flags given on the command line (to refuse those that do not apply to a kind).
struct Given {
  CLI::Option *period_samples, *period_s, *periods, *transient, *realisations, *band, *grid, *lpd, *every, *phase,
      *minimise, *iterations, *mimo, *duration, *divider, *amplitude;
};

std::string one_of(const std::string& value, const std::string& flag, std::initializer_list<const char*> allowed) {
  for (const char* a : allowed)
    if (value == a) return value;
  throw InputError(fmt::format("{}: '{}' is not one of {}; give one of them", flag, value, fmt::join(allowed, ", ")));
}

void refuse_if(CLI::Option* option, const std::string& why) {
  if (option->count() > 0) throw InputError(fmt::format("{} does not apply {}; leave it out", option->get_name(), why));
}

// The spec without the amplitude spectrum (read after the output checks).
ExcitationSpec spec_from(const ExciteCliOptions& o, const Given& g) {
  ExcitationSpec s;
  const std::string kind = one_of(o.kind, "--kind", {"multisine", "prbs", "noise"});
  s.kind = kind == "multisine" ? ExcitationKind::kMultisine : kind == "prbs" ? ExcitationKind::kPrbs : ExcitationKind::kNoise;
  s.sample_rate_hz = o.rate_hz;
  s.channels = o.channels;
  s.seed = o.seed;
  if (o.rms.empty() && o.peak.empty())
    throw InputError("give the amplitude: --rms and/or --peak, one value or one per channel (e.g. --rms 0.05,0.05,1)");
  if (!o.rms.empty()) s.rms = split_numbers(o.rms, "--rms", "RMS value");
  if (!o.peak.empty()) s.peak = split_numbers(o.peak, "--peak", "peak value");
  if (g.period_samples->count() > 0 && g.period_s->count() > 0)
    throw InputError("--period-samples and --period-s both given; give the period once");
  if (g.period_s->count() > 0) {
    const double samples = o.period_s * o.rate_hz;
    const double whole = std::round(samples);
    // 1e-9 relative: a period typed in seconds that is a whole number of samples up to rounding.
    if (!(whole >= 1) || std::abs(samples - whole) > 1e-9 * whole)
      throw InputError(fmt::format("--period-s {} at --rate-hz {} is {} samples, not a whole number; give "
                                   "--period-samples, or a period of {} s",
                                   o.period_s, o.rate_hz, samples, std::max(1.0, whole) / o.rate_hz));
    s.period_samples = static_cast<Index>(whole);
  } else {
    s.period_samples = o.period_samples;
  }
  s.periods = o.periods;
  s.transient_periods = o.transient_periods;
  s.realisations = o.realisations;
  if (s.kind == ExcitationKind::kMultisine) {
    refuse_if(g.duration, "to a multisine (its length is R x E x (T + P) x L samples)");
    refuse_if(g.divider, "to a multisine");
    if (s.period_samples == 0) throw InputError("a multisine needs its period: give --period-samples or --period-s");
    if (g.band->count() > 0) {
      if (o.band_hz.size() != 2) throw InputError("--band-hz: give two frequencies LO,HI in Hz, e.g. 1,200");
      s.band_lo_hz = o.band_hz[0];
      s.band_hi_hz = o.band_hz[1];
    }
    const std::string grid = one_of(o.grid, "--grid", {"lin", "log"});
    s.grid = grid == "lin" ? LineGrid::kLinear : LineGrid::kLog;
    if (s.grid == LineGrid::kLinear) refuse_if(g.lpd, "to a linear grid (it is --grid log's spacing)");
    if (s.grid == LineGrid::kLog) refuse_if(g.every, "to a log grid (it is --grid lin's spacing)");
    s.every = o.every;
    s.lines_per_decade = o.lines_per_decade;
    s.phase = one_of(o.phase, "--phase", {"random", "schroeder"}) == "random" ? PhaseChoice::kRandom
                                                                             : PhaseChoice::kSchroeder;
    s.minimise_crest = o.minimise_crest;
    if (!o.minimise_crest) refuse_if(g.iterations, "without --minimise-crest");
    s.crest_iterations = o.crest_iterations;
  } else {
    const std::string why = fmt::format("to a {} (multisine only)", kind);
    for (CLI::Option* opt : {g.band, g.grid, g.lpd, g.every, g.phase, g.minimise, g.iterations, g.amplitude})
      refuse_if(opt, why);
    const bool periodic_prbs = s.kind == ExcitationKind::kPrbs && s.period_samples > 0;
    if (periodic_prbs) {
      refuse_if(g.duration, "to a periodic PRBS (its length is E x (T + P) x L samples)");
    } else {
      const std::string what = s.kind == ExcitationKind::kNoise ? "white noise" : "a PRBS without --period-samples";
      for (CLI::Option* opt : {g.periods, g.transient, g.realisations})
        refuse_if(opt, fmt::format("to {} (not periodic)", what));
      if (g.duration->count() == 0)
        throw InputError(fmt::format("{} needs its length: give --duration-s{}", what,
                                     s.kind == ExcitationKind::kPrbs ? " (or --period-samples for a periodic PRBS)" : ""));
      const double samples = std::round(o.duration_s * o.rate_hz);
      if (!(samples >= 2) || samples > ExcitationSpec::kMaxValues)
        throw InputError(fmt::format("--duration-s {} at --rate-hz {} gives {} samples; give 2 to {:.0e} samples",
                                     o.duration_s, o.rate_hz, samples, ExcitationSpec::kMaxValues));
      s.samples = static_cast<Index>(samples);
      s.periods = 1;
      s.transient_periods = 0;
    }
    s.clock_divider = o.clock_divider;
    if (s.kind == ExcitationKind::kNoise) refuse_if(g.divider, "to white noise (PRBS only)");
  }
  const std::string mimo = o.mimo.empty() ? (o.channels == 1 || s.kind == ExcitationKind::kNoise ||
                                                     (s.kind == ExcitationKind::kPrbs && s.period_samples == 0)
                                                 ? "single"
                                                 : "one-at-a-time")
                                          : one_of(o.mimo, "--mimo", {"single", "one-at-a-time", "hadamard", "zipper"});
  s.mimo = mimo == "single"          ? MimoDesign::kSingle
           : mimo == "one-at-a-time" ? MimoDesign::kOneAtATime
           : mimo == "hadamard"      ? MimoDesign::kHadamard
                                     : MimoDesign::kZipper;
  s.validate();
  return s;
}

ExcitationDesign design_of(const ExcitationSpec& s, const ExcitationSignal& x) {
  ExcitationDesign d;
  d.kind = to_string(s.kind);
  d.sample_rate_hz = s.sample_rate_hz;
  d.channels = s.channels;
  const bool periodic = s.kind == ExcitationKind::kMultisine || s.period_samples > 0;
  d.period_samples = periodic ? s.period_samples : 0;
  d.periods = s.periods;
  d.transient_periods = s.transient_periods;
  d.realisations = s.realisations;
  d.experiments = x.experiments;
  d.mimo = to_string(s.mimo);
  d.excited_bins = x.excited_bins;
  if (!s.shape_f_hz.empty()) d.amplitudes = x.line_amplitudes;
  d.coding = x.coding;
  d.phase = s.kind == ExcitationKind::kMultisine ? to_string(s.phase) : s.kind == ExcitationKind::kNoise ? "random" : "";
  d.seed = s.seed;
  for (Index j = 0; j < s.channels; ++j) {
    d.crest_factor.push_back(x.crest_factor(j));
    d.rms.push_back(x.rms(j));
    d.peak.push_back(x.peak(j));
  }
  if (s.kind == ExcitationKind::kPrbs) {
    d.prbs_order = x.prbs_order;
    d.clock_divider = s.clock_divider;
  }
  return d;
}

void run(const ExciteCliOptions& o, const Given& g) {
  OutputSet outputs;
  outputs.file("--out", o.out);
  outputs.input(o.amplitude);
  ExcitationSpec spec = spec_from(o, g);
  const bool mat = is_mat_path(o.out);
  outputs.check();
  if (!o.amplitude.empty()) {
    const AmplitudeSpectrum shape = read_amplitude_spectrum(o.amplitude);
    spec.shape_f_hz = shape.f_hz;
    spec.shape_amplitude = shape.amplitude;
    spec.validate();  // the reader's rules are the spec's: cannot fail here
  }

  const ExcitationSignal x = generate_excitation(spec);
  const ExcitationDesign design = design_of(spec, x);
  const Index N = x.samples.rows(), n = spec.channels;
  Eigen::MatrixXd data(N, n + 1);
  for (Index k = 0; k < N; ++k) data(k, 0) = static_cast<double>(k) / spec.sample_rate_hz;
  data.rightCols(n) = x.samples;
  std::vector<std::string> names = {"t"};
  for (Index j = 1; j <= n; ++j) names.push_back(fmt::format("v{}", j));
  const std::string design_line = excitation_design_comment(design);
  // The CSV reader takes lines of up to 16 MiB (formats/io/csv_detail.h); the line
  // lists every excited bin, so a design with millions of lines would not read back.
  constexpr size_t kMaxDesignLineBytes = size_t{8} << 20;
  if (design_line.size() > kMaxDesignLineBytes)
    throw InputError(fmt::format("the design excites {} lines in all: its design line would be {} MB, more than the "
                                 "8 MiB a log's line may hold; use a coarser grid (--every, --grid log) or a shorter "
                                 "period",
                                 [&] {
                                   size_t lines = 0;
                                   for (const auto& b : x.excited_bins) lines += b.size();
                                   return lines;
                                 }(),
                                 static_cast<double>(design_line.size()) / 1e6));
  if (mat)
    write_excitation_mat(outputs.stage(o.out), names, data, design);
  else
    write_log(outputs.stage(o.out), names, data, {design_line});
  outputs.commit();

  // Summary.
  const double fs = spec.sample_rate_hz;
  std::string text = fmt::format("wrote {}: {}, {} input{}, {} sample{} ({} s at {} Hz)\n", o.out, design.kind, n,
                                 n == 1 ? "" : "s", N, N == 1 ? "" : "s", static_cast<double>(N) / fs, fs);
  nlohmann::json summary = {{"out", o.out},
                            {"kind", design.kind},
                            {"channels", n},
                            {"samples", N},
                            {"duration_s", static_cast<double>(N) / fs},
                            {"sample_rate_hz", fs},
                            {"mimo", design.mimo},
                            {"experiments", design.experiments}};
  if (design.periodic()) {
    const double resolution = fs / static_cast<double>(design.period_samples);
    text += fmt::format("  period L = {} samples ({} s), resolution fs/L = {:.6g} Hz; {} transient + {} periods per "
                        "block; {} experiment{} ({}) x {} realisation{}\n",
                        design.period_samples, static_cast<double>(design.period_samples) / fs, resolution,
                        design.transient_periods, design.periods, design.experiments,
                        design.experiments == 1 ? "" : "s", design.mimo, design.realisations,
                        design.realisations == 1 ? "" : "s");
    summary["period_samples"] = design.period_samples;
    summary["resolution_hz"] = resolution;
    summary["periods"] = design.periods;
    summary["transient_periods"] = design.transient_periods;
    summary["realisations"] = design.realisations;
    if (design.kind == "prbs")
      text += fmt::format("  PRBS order m = {} ({} levels of {} sample{})\n", x.prbs_order,
                          (Index{1} << x.prbs_order) - 1, spec.clock_divider, spec.clock_divider == 1 ? "" : "s");
  } else if (design.kind == "prbs") {
    text += fmt::format("  PRBS order m = {} (not periodic: {} levels of {} sample{})\n", x.prbs_order,
                        (Index{1} << x.prbs_order) - 1, spec.clock_divider, spec.clock_divider == 1 ? "" : "s");
  }
  if (design.kind == "prbs") summary["prbs_order"] = x.prbs_order;
  text += fmt::format("  {:<6} {:>7} {:>22} {:>12} {:>12} {:>10}\n", "input", "lines", "band [Hz]", "rms", "peak",
                      spec.minimise_crest ? "crest (before -> after)" : "crest");
  nlohmann::json inputs = nlohmann::json::array();
  for (Index j = 0; j < n; ++j) {
    const auto& bins = x.excited_bins[static_cast<std::size_t>(j)];
    const double resolution = design.periodic() ? fs / static_cast<double>(design.period_samples) : 0.0;
    const std::string band = bins.empty() ? std::string("-")
                                          : fmt::format("{:.6g}..{:.6g}", static_cast<double>(bins.front()) * resolution,
                                                        static_cast<double>(bins.back()) * resolution);
    const std::string crest = spec.minimise_crest
                                  ? fmt::format("{:.3f} -> {:.3f}", x.crest_factor_initial(j), x.crest_factor(j))
                                  : fmt::format("{:.3f}", x.crest_factor(j));
    text += fmt::format("  v{:<5} {:>7} {:>22} {:>12.6g} {:>12.6g} {:>10}\n", j + 1,
                        bins.empty() ? std::string("-") : std::to_string(bins.size()), band, x.rms(j), x.peak(j), crest);
    nlohmann::json in = {{"name", fmt::format("v{}", j + 1)},
                         {"lines", bins.size()},
                         {"rms", x.rms(j)},
                         {"peak", x.peak(j)},
                         {"crest_factor", x.crest_factor(j)},
                         {"crest_factor_before", x.crest_factor_initial(j)}};
    if (!bins.empty()) in["band_hz"] = {static_cast<double>(bins.front()) * resolution, static_cast<double>(bins.back()) * resolution};
    inputs.push_back(in);
  }
  summary["inputs"] = inputs;
  if (!o.amplitude.empty()) {
    text += fmt::format("  amplitude spectrum {} ({} points; log-log between them, constant beyond):", o.amplitude,
                        spec.shape_f_hz.size());
    for (Index j = 0; j < n; ++j) {
      const auto& a = x.line_amplitudes[static_cast<std::size_t>(j)];
      text += fmt::format(" v{} lines {:.4g}..{:.4g}", j + 1, *std::min_element(a.begin(), a.end()),
                          *std::max_element(a.begin(), a.end()));
    }
    text += "\n";
    summary["amplitude_file"] = o.amplitude;
  }
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_excite_command() {
  return {"excite", "excitation signals: multisine, PRBS, noise (CSV or .mat)", [](CLI::App& parent) {
            auto o = std::make_shared<ExciteCliOptions>();
            auto g = std::make_shared<Given>();
            auto* app = parent.add_subcommand(
                "excite", "Write an excitation signal with its design (multisine, PRBS, noise)" + std::string(kExciteExample));
            app->add_option("--kind", o->kind, "multisine (default), prbs or noise");
            app->add_option("--rate-hz", o->rate_hz, "sample rate in Hz (default 1000)")
                ->check(positive_up_to(kMaxRateHz, "the sample rate in Hz"));
            g->period_samples = app->add_option("--period-samples", o->period_samples,
                                                "samples per period L (multisine; PRBS: d (2^m - 1))")
                                    ->check(integer_in(1, 100'000'000, "the period in samples"));
            g->period_s = app->add_option("--period-s", o->period_s, "period in s (a whole number of samples)")
                              ->check(positive_up_to(kMaxDurationS, "the period in s"));
            g->periods = app->add_option("--periods", o->periods, "periods P kept per block (default 4)")
                             ->check(integer_in(1, 1'000'000, "the number of periods"));
            g->transient = app->add_option("--transient-periods", o->transient_periods,
                                           "periods T before them, for transients to die out (default 1)")
                               ->check(integer_in(0, 1'000'000, "the number of transient periods"));
            g->realisations = app->add_option("--realisations", o->realisations,
                                              "random-phase realisations R (multisine; default 1)")
                                  ->check(integer_in(1, 100'000, "the number of realisations"));
            g->band = app->add_option("--band-hz", o->band_hz, "excited band LO,HI in Hz (default: 0 < f < fs/2)")
                          ->delimiter(',')
                          ->check(number_in(0, kMaxFrequency, "a band edge in Hz"));
            g->grid = app->add_option("--grid", o->grid, "line grid: lin (default) or log");
            g->lpd = app->add_option("--lines-per-decade", o->lines_per_decade, "log grid density (default 20)")
                         ->check(positive_up_to(1e6, "the lines per decade"));
            g->every = app->add_option("--every", o->every, "linear grid: every m-th DFT line (default 1)")
                           ->check(integer_in(1, 1'000'000'000, "the line spacing in DFT bins"));
            g->phase = app->add_option("--phase", o->phase, "random (default) or schroeder");
            g->minimise = app->add_flag("--minimise-crest", o->minimise_crest,
                                        "lower the crest factor by clipping iterations (amplitudes kept exactly)");
            g->iterations = app->add_option("--crest-iterations", o->crest_iterations,
                                            "iterations of --minimise-crest (default 200)")
                                ->check(integer_in(1, 100'000, "the number of iterations"));
            app->add_option("--rms", o->rms, "RMS per channel (one value or one per channel), input units");
            app->add_option("--peak", o->peak, "peak |v| per channel (one value or one per channel); with --rms the "
                                               "tighter limit wins");
            g->amplitude = app->add_option("--amplitude", o->amplitude,
                                           "multisine: CSV of f_hz,amplitude, the relative amplitude of the lines "
                                           "(log-log interpolated, constant beyond the ends)");
            app->add_option("--channels", o->channels, "number of inputs n (default 1)")
                ->check(integer_in(1, 256, "the number of inputs"));
            g->mimo = app->add_option("--mimo", o->mimo,
                                      "single, one-at-a-time (default for n > 1), hadamard or zipper");
            app->add_option("--seed", o->seed, "random seed (same seed, same bytes)")->check(seed_value());
            g->duration = app->add_option("--duration-s", o->duration_s, "length in s (noise; PRBS without a period)")
                              ->check(positive_up_to(kMaxDurationS, "the length in s"));
            g->divider = app->add_option("--clock-divider", o->clock_divider, "PRBS: samples per level (default 1)")
                             ->check(integer_in(1, 1'000'000, "the samples per level"));
            app->add_option("--out", o->out, "output file: .csv (a log, '-' = stdout) or .mat")->required();
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o, g] { run(*o, *g); });
          }};
}

}  // namespace lpvid::cli
