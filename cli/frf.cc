// lpvid frf — nonparametric frequency responses (H1, Welch averaging) with
// coherence from time-domain logs: v -> u gives the input sensitivity S, v -> q
// the closed loop G, so both identification approaches run on one experiment.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <charconv>
#include <numbers>
#include <optional>
#include <string_view>

#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "cli/progress_line.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/frd_csv.h"
#include "idlib/core/error.h"
#include "idlib/signal/frf.h"
#include "idlib/signal/lpm.h"
#include "idlib/signal/lrm.h"
#include "idlib/signal/periodic_frf.h"
#include "formats/io/excitation_design.h"
#include "formats/io/excitation_file.h"

namespace lpvid::cli {
namespace {

constexpr const char* kFrfExample = R"(
Example:
  lpvid frf --excitation v1,v2,v3 --output u1,u2,u3 --quantity S --out S.csv exp_T_psi.csv exp_T_theta.csv exp_F_z.csv
  lpvid frf --excitation v1,v2,v3 --output q1,q2,q3 --quantity G --out G.csv --segment 4096 exp_*.csv
  lpvid frf --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 --quantity P --out P.csv exp_*.csv
H1 estimate S_yv S_vv^-1 averaged over Hann-windowed segments (50 % overlap) of every log;
writes an FRD CSV (columns freq_hz, <Q>_i_j_re/_im, coh_i_j, var_i_j, flag) and flags
frequencies where the excitation's spectral matrix is ill-conditioned.  With --input, the
PLANT u -> y from the closed loop, S_yv S_uv^-1 (v as instrument: unbiased by the loop, any
controller), its variance from the residual y - P u (docs/math.md, "Plant from closed-loop
logs").  6-DOF stage logs (u1..u6 = F_x F_y F_z tau_x tau_y tau_z): name the columns in the
base's order, --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,...,q6.

Periodic (multisine) data, --method periodic: the logs (concatenated in the order given)
hold R realisations x E experiments blocks of (T + P) periods of L samples, T discarded:
  lpvid frf --method periodic --period-samples 4096 --periods 8 --transient-periods 2 \
    --experiments 3 --realisations 4 --excitation v1,v2,v3 --input u1,u2,u3 --output q1,q2,q3 \
    --quantity P --out P.csv multisine.csv
gives the plant (PS) S^-1 at the excited lines with its noise variance (var_) and, with
R >= 2, the nonlinear-distortion variance (dvar_) of the Best Linear Approximation.
Random data, --method lpm: the Local Polynomial Method (transient removal) on each log's
whole-record DFT, same flags as welch plus --lpm-order and --lpm-half-width.  --method lrm: the
Local Rational Method (numerator and denominator degree 2 by default, one common denominator
per output row): follows lightly damped resonances that the LPM's polynomial cannot.
  lpvid frf --method lrm --lrm-stride 4 --excitation v1 --output y1 --quantity G --out G.csv short_log.csv)";

struct FrfCliOptions {
  std::vector<std::string> logs;
  LogLayoutCli layout;
  std::string excitation, input, output, out, quantity = "H", window = "hann";
  Index segment = 0;
  double overlap = 0.5;
  bool json = false;
  std::string method = "welch";
  // periodic
  Index period_samples = 0, periods = 0, transient_periods = 0, realisations = 1, experiments = 1;
  std::string excited_bins;
  // lpm
  int lpm_order = 2;
  Index lpm_half_width = 0, lpm_stride = 1;
  // lrm
  int lrm_numerator_degree = 2, lrm_denominator_degree = 2, lrm_iterations = 1;
  Index lrm_half_width = 0, lrm_stride = 1;
  std::vector<std::string> given;  // long names of the options given
};

bool given(const FrfCliOptions& o, const std::string& name) {
  return std::find(o.given.begin(), o.given.end(), name) != o.given.end();
}

// "41:307,400,410:412" -> 41..307, 400, 410..412 (ranges inclusive).
std::vector<Index> parse_bins(const std::string& text) {
  std::vector<Index> bins;
  if (text.empty()) return bins;
  auto number = [&](const std::string& item, std::string_view digits) {
    Index v = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (digits.empty() || ec != std::errc() || end != digits.data() + digits.size())
      throw InputError(fmt::format("--excited-bins '{}': '{}' is not a bin number or a range first:last; give DFT "
                                   "bins of one period, e.g. --excited-bins 1,2,5 or 41:307",
                                   text, item));
    return v;
  };
  for (const std::string& item : split_names(text, "--excited-bins")) {
    const auto colon = item.find(':');
    if (colon == std::string::npos) {
      bins.push_back(number(item, item));
      continue;
    }
    const std::string_view all(item);
    const Index first = number(item, all.substr(0, colon)), last = number(item, all.substr(colon + 1));
    if (last < first)
      throw InputError(fmt::format("--excited-bins '{}': the range '{}' ends before it starts; give first:last with "
                                   "first <= last",
                                   text, item));
    if (last - first >= kMaxSegment)
      throw InputError(fmt::format("--excited-bins '{}': the range '{}' holds more bins than any period; give bins of "
                                   "one period",
                                   text, item));
    for (Index k = first; k <= last; ++k) bins.push_back(k);
  }
  return bins;
}

// --method periodic / lpm: estimate, write the FRD (excited lines / LPM bins, var_ and
// dvar_ columns), print the noise and distortion summary.
void run_other(const FrfCliOptions& o, const ExperimentSet& set, const std::vector<std::string>& excitation,
               const std::vector<std::string>& output, const std::vector<std::string>& input, OutputSet& outputs,
               PeriodicFrfOptions popt) {
  const bool plant = !input.empty();
  const Index m = static_cast<Index>(excitation.size());
  FrequencyResponse frd;
  std::vector<std::string> comments;
  nlohmann::json summary = {{"method", o.method}, {"sample_period_s", set.sample_period_s}, {"out", o.out}};
  std::string text;
  const std::string what = plant ? fmt::format("plant {} = (PS) S^-1 from v -> [y u] (indirect route, variance "
                                               "propagated)",
                                               o.quantity)
                                 : fmt::format("{} from v -> y", o.quantity);
  const std::string where = set.paths.size() == 1 ? set.paths.front()
                          : o.method == "periodic" ? fmt::format("the {} logs concatenated", set.paths.size())
                                                   : fmt::format("the {} logs", set.paths.size());
  if (o.method == "periodic") {
    Index total = 0;
    for (const auto& x : set.excitations) total += x.rows();
    Eigen::MatrixXd v(total, m), z(total, static_cast<Index>(output.size() + input.size()));
    Index at = 0;
    for (size_t e = 0; e < set.excitations.size(); ++e) {
      v.middleRows(at, set.excitations[e].rows()) = set.excitations[e];
      z.middleRows(at, set.outputs[e].rows()) = set.outputs[e];
      at += set.excitations[e].rows();
    }
    popt.sample_period_s = set.sample_period_s;
    PeriodicFrfResult r;
    try {
      r = estimate_periodic_frf(v, z, plant ? m : 0, popt);
    } catch (const InputError& e) {  // name the file and the columns the message counts
      throw InputError(fmt::format("{}: {} (excitation columns {}; measured {}{}{})", where, e.what(),
                                   fmt::join(excitation, ","), fmt::join(output, ","), plant ? "," : "",
                                   fmt::join(input, ",")));
    }
    frd = r.frd;
    const auto& lay = popt.layout;
    comments.push_back(fmt::format("lpvid frf --method periodic: {} from {} log(s), Ts = {:.6g} s, L = {}, P = {}, "
                                   "T = {}, R = {}, E = {}; var_ = noise{}{} (dof {}{})",
                                   what, set.paths.size(), set.sample_period_s, lay.period_samples, lay.periods,
                                   lay.transient_periods, lay.realisations, lay.experiments,
                                   r.measured_reference ? " of the outputs and the measured excitation" : "",
                                   lay.realisations >= 2 ? " + nonlinear distortion, dvar_ = distortion" : "",
                                   r.noise_dof,
                                   lay.realisations >= 2 ? fmt::format(", realisation dof {}", r.realisation_dof) : ""));
    std::string noise;
    nlohmann::json noise_json = nlohmann::json::object();
    for (size_t c = 0; c < output.size() + input.size(); ++c) {
      const std::string& name = c < output.size() ? output[c] : input[c - output.size()];
      noise += fmt::format("{}{} {:.3g}", c ? ", " : "", name, r.channel_noise_rms(static_cast<Index>(c)));
      noise_json[name] = r.channel_noise_rms(static_cast<Index>(c));
    }
    summary["lines"] = frd.num_frequencies();
    summary["noise_rms"] = noise_json;
    summary["noise_dof"] = r.noise_dof;
    text = fmt::format("frf (periodic): {} excited lines ({:.4g} to {:.4g} Hz), noise rms per sample: {}\n",
                       frd.num_frequencies(), frd.omega_rad_s(0) / (2 * std::numbers::pi),
                       frd.omega_rad_s(frd.num_frequencies() - 1) / (2 * std::numbers::pi), noise);
    summary["measured_excitation"] = r.measured_reference;
    if (r.measured_reference) {
      std::string vnoise;
      nlohmann::json vnoise_json = nlohmann::json::object();
      for (size_t j = 0; j < excitation.size(); ++j) {
        vnoise += fmt::format("{}{} {:.3g}", j ? ", " : "", excitation[j],
                              r.excitation_noise_rms(static_cast<Index>(j)));
        vnoise_json[excitation[j]] = r.excitation_noise_rms(static_cast<Index>(j));
      }
      summary["excitation_noise_rms"] = vnoise_json;
      summary["excitation_periodicity"] = r.excitation_periodicity;
      text += fmt::format("  measured excitation (noise rms per sample: {}): at its lines its period mean carries "
                          "{:.3g}× the noise power of its period-to-period scatter; its noise enters the variance "
                          "(errors in variables)\n",
                          vnoise, r.excitation_periodicity);
    }
    if (lay.realisations >= 2) {
      nlohmann::json jb = nlohmann::json::array();
      std::string tb;
      const auto bands = distortion_bands(r);
      for (const auto& [first, last] : bands) {
        const double lo = r.frd.omega_rad_s(first) / (2 * std::numbers::pi);
        const double hi = r.frd.omega_rad_s(last) / (2 * std::numbers::pi);
        jb.push_back({lo, hi});
        tb += fmt::format("{}{:.4g}-{:.4g} Hz", tb.empty() ? "" : ", ", lo, hi);
      }
      summary["distortion_bands_hz"] = jb;
      text += bands.empty() ? "  nonlinear distortion: not above the noise at any band of the excited lines\n"
                            : fmt::format("  nonlinear distortion above the noise (sigma2_BLA / sigma2_noise beyond "
                                          "{} sd of its linear-system distribution over {} lines) in: {}\n",
                                          kDistortionSigmas, kDistortionWindow, tb);
    } else {
      text += "  one realisation: nonlinear distortions cannot be told from the system (use --realisations >= 2)\n";
    }
    for (const auto& w : r.report.warnings) text += "  warning: " + w + "\n";
  } else {
    Index half_width = 0, dof = 0;
    std::string model;
    std::vector<std::string> warnings;
    try {
      LocalFrfResult r;
      if (o.method == "lpm") {
        LpmOptions lo;
        lo.order = o.lpm_order;
        lo.half_width = o.lpm_half_width;
        lo.stride = o.lpm_stride;
        lo.sample_period_s = set.sample_period_s;
        TerminalProgress progress;  // on a terminal only (cli/progress_line.h)
        lo.progress = progress.get();
        r = estimate_lpm_frf(set.views(), plant ? m : 0, lo);
        model = fmt::format("local polynomial order {}", lo.order);
      } else {
        LrmOptions lo;
        lo.numerator_degree = o.lrm_numerator_degree;
        lo.denominator_degree = o.lrm_denominator_degree;
        lo.sk_iterations = o.lrm_iterations;
        lo.half_width = o.lrm_half_width;
        lo.stride = o.lrm_stride;
        lo.sample_period_s = set.sample_period_s;
        TerminalProgress progress;  // on a terminal only (cli/progress_line.h)
        lo.progress = progress.get();
        r = estimate_lrm_frf(set.views(), plant ? m : 0, lo);
        model = fmt::format("local rational degrees {}/{}, {} reweighting step(s)", lo.numerator_degree,
                            lo.denominator_degree, lo.sk_iterations);
      }
      frd = std::move(r.frd);
      half_width = r.half_width;
      dof = r.dof;
      warnings = r.report.warnings;
    } catch (const InputError& e) {  // name the file(s)
      throw InputError(fmt::format("{}: {}", where, e.what()));
    }
    comments.push_back(fmt::format("lpvid frf --method {}: {} from {} log(s), Ts = {:.6g} s, {}, {} bins per window, {} "
                                   "degrees of freedom; var_ = noise",
                                   o.method, what, set.paths.size(), set.sample_period_s, model, 2 * half_width + 1, dof));
    Index flagged = 0;
    for (bool f : frd.flagged) flagged += f ? 1 : 0;
    summary["frequencies"] = frd.num_frequencies();
    summary["flagged"] = flagged;
    summary["dof"] = dof;
    text = fmt::format("frf ({}): {} frequencies ({:.4g} to {:.4g} rad/s), {} flagged, {} bins per window, {} dof\n",
                       o.method, frd.num_frequencies(), frd.omega_rad_s(0), frd.omega_rad_s(frd.num_frequencies() - 1),
                       flagged, 2 * half_width + 1, dof);
    for (const auto& w : warnings) text += "  warning: " + w + "\n";
  }
  frd.input_names = plant ? input : excitation;
  frd.output_names = output;
  frd.sample_rate_hz = 1.0 / set.sample_period_s;  // '# sample_rate_hz:': the fit's --rate-hz
  write_frd_csv(outputs.stage(o.out), frd, o.quantity, comments);
  text += fmt::format("  written to {}\n", o.out);
  outputs.commit();
  print_log_findings(set);
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

void run(const FrfCliOptions& o) {
  if (o.method != "welch" && o.method != "lpm" && o.method != "lrm" && o.method != "periodic")
    throw InputError(fmt::format("--method '{}': use welch, lpm, lrm or periodic", o.method));
  for (const char* flag : {"--period-samples", "--periods", "--transient-periods", "--realisations", "--experiments",
                           "--excited-bins"})
    if (o.method != "periodic" && given(o, flag))
      throw InputError(fmt::format("{} describes periodic data: use it with --method periodic", flag));
  for (const char* flag : {"--lpm-order", "--lpm-half-width", "--lpm-stride"})
    if (o.method != "lpm" && given(o, flag))
      throw InputError(fmt::format("{} is an option of the Local Polynomial Method: use it with --method lpm", flag));
  for (const char* flag : {"--lrm-numerator-degree", "--lrm-denominator-degree", "--lrm-iterations", "--lrm-half-width",
                           "--lrm-stride"})
    if (o.method != "lrm" && given(o, flag))
      throw InputError(fmt::format("{} is an option of the Local Rational Method: use it with --method lrm", flag));
  for (const char* flag : {"--segment", "--overlap", "--window"})
    if (o.method != "welch" && given(o, flag))
      throw InputError(fmt::format("{} is a Welch option: --method {} does not cut segments", flag, o.method));
  // The layout: the flags, or the design `lpvid excite` writes (and the simulators
  // copy into their logs): the first log's comment line, or a .mat log's variable.
  std::optional<ExcitationDesign> design;
  if (o.method == "periodic" && !given(o, "--period-samples")) {
    for (const char* flag : {"--periods", "--transient-periods", "--realisations", "--experiments", "--excited-bins"})
      if (given(o, flag))
        throw InputError(fmt::format("{} without --period-samples: give the whole layout by flags, or none of it "
                                     "to take it from the log's excitation design line",
                                     flag));
    if (o.logs.front() != "-") design = read_log_excitation_design(o.logs.front());
    if (!design)
      throw InputError(fmt::format(
          "--method periodic needs the layout: {} has no excitation design (the line '# lpvid-excitation:' of a CSV "
          "log, the variable excitation_design of a .mat log, written by lpvid excite and copied by simulate "
          "--excitation); give --period-samples L and --periods P (and --transient-periods, --realisations, "
          "--experiments when not 0, 1, 1)",
          o.logs.front()));
    if (!design->periodic())
      throw InputError(fmt::format("{}: the excitation design is {} (not periodic); use --method welch or lpm for it",
                                   o.logs.front(), design->kind));
    if (design->mimo == "zipper")
      throw InputError(fmt::format("{}: a zipper design excites each input at its own lines, and the periodic FRF "
                                   "needs every input at every line; design with --mimo one-at-a-time or hadamard",
                                   o.logs.front()));
  }
  if (o.method == "periodic" && !design && !given(o, "--periods"))
    throw InputError("--method periodic needs the layout: --period-samples L and --periods P (and "
                     "--transient-periods, --realisations, --experiments when not 0, 1, 1)");
  FrfOptions options;
  options.segment_length = o.segment;
  options.overlap = o.overlap;
  if (o.window == "hann") {
    options.window = FrfOptions::Window::kHann;
  } else if (o.window == "rect" || o.window == "rectangular") {
    options.window = FrfOptions::Window::kRectangular;
  } else {
    throw InputError(fmt::format("--window '{}': use hann or rect", o.window));
  }
  try {
    FrdReadOptions{o.quantity}.validate();  // before any log is read
  } catch (const InputError& e) {
    throw InputError(fmt::format("--quantity: {}", e.what()));
  }
  const auto excitation = split_names(o.excitation, "--excitation");
  const auto output = split_names(o.output, "--output");
  const bool plant = !o.input.empty();
  std::vector<std::string> input;
  if (plant) {
    input = split_names(o.input, "--input");
    if (input.size() != excitation.size())
      throw InputError(fmt::format("--input names {} columns and --excitation {}; give one excitation column per "
                                   "plant input, in the same order",
                                   input.size(), excitation.size()));
  }
  std::vector<std::string> read = output;
  read.insert(read.end(), input.begin(), input.end());
  OutputSet outputs;
  outputs.inputs(o.logs);
  outputs.file("--out", o.out);
  outputs.check();
  PeriodicFrfOptions popt;
  if (o.method == "periodic") {
    if (design) {
      popt.layout = {design->period_samples, design->periods, design->transient_periods, design->realisations,
                     design->experiments};
      // Every input's lines (one-at-a-time and hadamard designs excite the same ones).
      std::vector<Index> bins;
      for (const auto& b : design->excited_bins) bins.insert(bins.end(), b.begin(), b.end());
      std::sort(bins.begin(), bins.end());
      bins.erase(std::unique(bins.begin(), bins.end()), bins.end());
      popt.excited_bins = bins;
    } else {
      popt.layout = {o.period_samples, o.periods, o.transient_periods, o.realisations, o.experiments};
      popt.excited_bins = parse_bins(o.excited_bins);
    }
    popt.sample_period_s = 1;  // replaced by the logs' below; checks the layout before any log is read
    popt.validate();
  }
  const ExperimentSet set = read_experiments(o.logs, excitation, read, o.layout.read_options());
  if (o.method != "welch") {
    run_other(o, set, excitation, output, input, outputs, popt);
    return;
  }
  options.sample_period_s = set.sample_period_s;
  FrequencyResponse frd = plant ? estimate_plant_frf(set.views(), options) : estimate_frf(set.views(), options);
  frd.input_names = plant ? input : excitation;
  frd.output_names = output;
  frd.sample_rate_hz = 1.0 / set.sample_period_s;  // '# sample_rate_hz:': the fit's --rate-hz
  Index flagged = 0;
  for (bool f : frd.flagged) flagged += f ? 1 : 0;
  write_frd_csv(outputs.stage(o.out), frd, o.quantity,
                {plant ? fmt::format("lpvid frf: plant {} = S_yv S_uv^-1 (Welch, excitation as instrument) from {} "
                                     "log(s), Ts = {:.6g} s, variance from the residual y - P u",
                                     o.quantity, set.paths.size(), set.sample_period_s)
                       : fmt::format("lpvid frf: H1 Welch estimate of {} from {} log(s), Ts = {:.6g} s", o.quantity,
                                     set.paths.size(), set.sample_period_s)});
  nlohmann::json summary = {{"frequencies", frd.num_frequencies()},
                            {"flagged", flagged},
                            {"sample_period_s", set.sample_period_s},
                            {"out", o.out}};
  const std::string text = fmt::format("frf: {} frequencies ({:.4g} to {:.4g} rad/s), {} flagged, written to {}\n",
                                       frd.num_frequencies(), frd.omega_rad_s.size() ? frd.omega_rad_s(0) : 0.0,
                                       frd.omega_rad_s.size() ? frd.omega_rad_s(frd.omega_rad_s.size() - 1) : 0.0,
                                       flagged, o.out);
  outputs.commit();
  print_log_findings(set);
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_frf_command() {
  return {"frf", "nonparametric frequency response (H1, Welch) with coherence", [](CLI::App& parent) {
            auto o = std::make_shared<FrfCliOptions>();
            auto* app = parent.add_subcommand("frf", "H1 frequency-response estimate with coherence from logs" +
                                                         std::string(kFrfExample));
            app->add_option("logs", o->logs, "logs (CSV or .mat), one experiment each")->required();
            app->add_option("--excitation", o->excitation, "excitation columns v (comma separated)")->required();
            app->add_option("--output", o->output, "response columns (u for S, q for G), comma separated")->required();
            add_log_layout_options(app, &o->layout);
            app->add_option("--input", o->input,
                            "plant input columns u (comma separated, one per excitation): estimate the plant "
                            "u -> output from the closed loop");
            app->add_option("--out", o->out, "FRD CSV to write ('-' = stdout)")->required();
            app->add_option("--quantity", o->quantity, "column prefix in the FRD file (S, G, P, H)");
            app->add_option("--segment", o->segment, "samples per segment (default: N/16 as a power of two)")
                ->check(integer_in(4, kMaxSegment, "the samples per segment"));
            app->add_option("--overlap", o->overlap, "segment overlap fraction in [0, 0.95)")
                ->check(number_in(0, 0.95, "the segment overlap fraction", false, true));
            app->add_option("--window", o->window, "hann (default) or rect");
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->add_option("--method", o->method,
                            "welch (H1, default), lpm (Local Polynomial Method), lrm (Local Rational Method) or "
                            "periodic");
            app->add_option("--period-samples", o->period_samples, "periodic: samples per period L")
                ->check(integer_in(4, kMaxSegment, "the samples per period"));
            app->add_option("--periods", o->periods, "periodic: measured periods P per block (>= 2)")
                ->check(integer_in(2, 1000000, "the measured periods per block"));
            app->add_option("--transient-periods", o->transient_periods,
                            "periodic: periods T at the start of each block to discard (default 0)")
                ->check(integer_in(0, 1000000, "the transient periods"));
            app->add_option("--realisations", o->realisations, "periodic: random-phase realisations R (default 1)")
                ->check(integer_in(1, 1000000, "the realisations"));
            app->add_option("--experiments", o->experiments, "periodic: experiments E per realisation (default 1)")
                ->check(integer_in(1, 1000000, "the experiments per realisation"));
            app->add_option("--excited-bins", o->excited_bins,
                            "periodic: DFT bins of one period to use, ranges allowed (e.g. 41:307 or 1,2,5:9; "
                            "default: the lines where the excitation's period mean stands above its "
                            "period-to-period scatter)");
            app->add_option("--lpm-order", o->lpm_order, "lpm: local polynomial order R (default 2)")
                ->check(integer_in(0, 4, "the LPM order"));
            app->add_option("--lpm-half-width", o->lpm_half_width,
                            "lpm: n, the window is 2n+1 bins (default: the smallest with >= 6 degrees of freedom)")
                ->check(integer_in(1, 100000, "the LPM half width"));
            app->add_option("--lpm-stride", o->lpm_stride, "lpm: write every k-th bin (default 1)")
                ->check(integer_in(1, 1000000, "the LPM bin stride"));
            app->add_option("--lrm-numerator-degree", o->lrm_numerator_degree,
                            "lrm: degree of the FRF and transient numerators (default 2)")
                ->check(integer_in(0, 4, "the LRM numerator degree"));
            app->add_option("--lrm-denominator-degree", o->lrm_denominator_degree,
                            "lrm: degree of the common denominator (default 2: one mode per window)")
                ->check(integer_in(1, 4, "the LRM denominator degree"));
            app->add_option("--lrm-iterations", o->lrm_iterations,
                            "lrm: Sanathanan-Koerner reweighting steps after the linearised fit (default 1)")
                ->check(integer_in(0, 20, "the LRM reweighting steps"));
            app->add_option("--lrm-half-width", o->lrm_half_width,
                            "lrm: n, the window is 2n+1 bins (default: the smallest with >= 6 degrees of freedom)")
                ->check(integer_in(1, 100000, "the LRM half width"));
            app->add_option("--lrm-stride", o->lrm_stride, "lrm: write every k-th bin (default 1)")
                ->check(integer_in(1, 1000000, "the LRM bin stride"));
            app->callback([o, app] {
              for (const CLI::Option* opt : app->get_options())
                if (opt->count() > 0 && !opt->get_lnames().empty()) o->given.push_back("--" + opt->get_lnames()[0]);
              run(*o);
            });
          }};
}

}  // namespace lpvid::cli
