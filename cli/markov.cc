// lpvid markov — Markov parameters g(0..L) of the map excitation -> outputs
// from closed-loop logs (seed 000, section 4; DESIGN.md item 1).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/markov_csv.h"
#include "idlib/core/error.h"
#include "idlib/identify/identify.h"
#include "idlib/signal/markov.h"

namespace lpvid::cli {
namespace {

constexpr const char* kMarkovExample = R"(
Example:
  lpvid markov --excitation v1,v2,v3 --output q1,q2,q3 --out g.csv exp_T_psi.csv exp_T_theta.csv exp_F_z.csv
Correlates the outputs with the injected excitation v (never with the plant input u,
which the loop correlates with the noise) by FFT, and solves the least-squares
(Wiener-Hopf) normal equations, so coloured or simultaneous excitations work.
When least squares cannot be solved to its tolerance (an excitation so coloured that
its normal equations are ill-posed: noise amplified where the input has no power),
the default (--method auto) says so and gives the regularised estimate instead
(--method regularized: a TC-kernel prior, smooth and decaying, tuned per output by
marginal likelihood, as MATLAB's impulseest).  When the response has not died out
within the horizon (a lightly damped or slow mode, a short record: least squares'
last lags then hold its tail), the default compares it on held-out halves of the
records with the impulse response of a high-order ARX model (--method arx, its order
by the corrected Akaike criterion or --arx-order: the observer/OKID idea, a response
to any lag), takes the one that predicts better, and says both figures.
--method correlation gives the paper's plain estimate R_qv(k) / sum v^2, which is
biased: the sample autocorrelation of a finite white record is not a delta (on the
simulated platform, 60 s at 1 kHz, the plant error is 23 % against 0.12 % for least squares).
Each log is one experiment; experiments are combined, never concatenated.)";

struct MarkovCliOptions {
  std::vector<std::string> logs;
  LogLayoutCli layout;
  std::string excitation, output, out;
  Index lags = 0;
  double horizon_s = 0.0;  // 0: not given
  Index arx_order = 0;     // 0: by the criterion
  std::string method = "auto";
  bool json = false;
};

void run(const MarkovCliOptions& o) {
  IdentifyOptions chain;
  chain.num_lags = o.lags;
  chain.markov_horizon_s = o.horizon_s;
  chain.validate();
  MarkovOptions options;
  if (o.arx_order > 0 && o.method != "arx")
    throw InputError(fmt::format("--arx-order {} is for --method arx (the method is '{}'); add --method arx or drop "
                                 "--arx-order",
                                 o.arx_order, o.method));
  options.arx_order = o.arx_order;
  if (o.method == "ls" || o.method == "auto") {
    options.method = MarkovOptions::Method::kLeastSquares;
  } else if (o.method == "regularized") {
    options.method = MarkovOptions::Method::kRegularized;
  } else if (o.method == "arx") {
    options.method = MarkovOptions::Method::kArx;
  } else if (o.method == "correlation") {
    options.method = MarkovOptions::Method::kCorrelation;
  } else {
    throw InputError(fmt::format("--method '{}': use auto (the default), ls (least squares), regularized (TC kernel), "
                                 "arx (a high-order ARX model's response) or correlation (the paper's)",
                                 o.method));
  }
  const auto excitation = split_names(o.excitation, "--excitation");
  const auto output = split_names(o.output, "--output");
  OutputSet outputs;
  outputs.inputs(o.logs);
  outputs.file("--out", o.out);
  outputs.check();
  const ExperimentSet set = read_experiments(o.logs, excitation, output, o.layout.read_options());
  Index shortest = set.excitations.front().rows(), total = 0;
  for (const auto& e : set.excitations) {
    shortest = std::min<Index>(shortest, e.rows());
    total += e.rows();
  }
  // Lags given, or a horizon in seconds; else from the data in samples (Ts may be
  // unknown: a log whose time column is the sample index).
  const bool by_data = o.lags == 0 && o.horizon_s == 0.0;
  options.num_lags = by_data ? default_markov_lags(shortest, total, static_cast<Index>(excitation.size()))
                             : choose_num_lags(chain, set.sample_period_s, shortest);
  const std::string horizon =
      by_data ? fmt::format("default: the longest the records support, min(shortest {} / 4, total {} / (4 x {} "
                            "inputs), {})",
                            shortest, total, excitation.size(), kMaxDefaultMarkovLags)
      : o.lags > 0 ? std::string("--lags")
                   : fmt::format("--horizon-s {:g} s", o.horizon_s);
  // auto keeps the correlations, so a fallback does not compute them again.
  MarkovCorrelations correlations;
  correlations.max_lag = options.num_lags;
  const bool keep = o.method == "auto";
  MarkovResult r = estimate_markov(set.views(), options, keep ? &correlations : nullptr);
  // auto: least squares unless it cannot be solved to its tolerance; then the regularised
  // estimate, with the reason in the summary.
  std::string method = o.method == "auto" ? "ls" : o.method, fallback;
  if (o.method == "auto" && !r.report.usable) {
    fallback = fmt::format("least squares was not solved ({}), so the regularised estimate", r.report.termination);
    options.method = MarkovOptions::Method::kRegularized;
    r = estimate_markov(set.views(), options, &correlations);
    method = "regularized";
  } else if (o.method == "auto") {
    // auto: a response that has not died out within the horizon is truncated by least
    // squares; the ARX estimate describes it to any lag (markov_arx.h).  It replaces least
    // squares only when it also predicts better on data it was not fitted on (each half
    // of the records predicting the other: markov_held_out_error).
    std::vector<Index> lengths;
    for (const auto& e : set.excitations) lengths.push_back(e.rows());
    const MarkovTail tail = markov_tail(r, lengths);
    if (tail.truncated) {
      const std::string cut = fmt::format(
          "least squares' response has not died out within {} lags (its last {} lags hold {:.3g} times the energy "
          "noise alone would leave there)",
          options.num_lags, tail.lags, tail.energy_ratio);
      MarkovOptions arx = options;
      arx.method = MarkovOptions::Method::kArx;
      try {
        const MarkovHeldOut ls_out = markov_held_out_error(set.views(), options);
        const MarkovHeldOut arx_out = markov_held_out_error(set.views(), arx);
        const std::string judged = fmt::format(
            "each half of the records predicted from the other ({} lags) misses {:.4g} % of the output energy with "
            "least squares, {:.4g} % with the ARX estimate",
            ls_out.lags, 100.0 * ls_out.relative_error, 100.0 * arx_out.relative_error);
        if (arx_out.relative_error < ls_out.relative_error) {
          r = estimate_markov(set.views(), arx);
          fallback = cut + " and " + judged + ", so the ARX estimate, whose response runs to any lag";
          method = "arx";
        } else {
          fallback = cut + ", but " + judged + ": least squares kept; a longer record would hold more of the response";
        }
      } catch (const std::runtime_error& e) {  // InputError (halves too short), NumericalError (ARX grows)
        fallback = cut + "; the ARX estimate that would continue it could not be judged or used (" +
                   std::string(e.what()) + "): least squares kept";
      }
    }
  }

  MarkovFile file;
  file.g = r.g;
  file.sample_period_s = set.sample_period_s;
  file.inputs = excitation;
  file.outputs = output;
  file.noise_std = r.noise_std;
  file.input_rms = r.excitation_rms;
  file.output_rms = r.output_rms;
  outputs.stage(o.out, markov_csv_text(file, o.out));
  outputs.commit();
  print_log_findings(set);

  nlohmann::json summary = {{"lags", options.num_lags},
                            {"horizon", horizon},
                            {"sample_period_s", set.sample_period_s},
                            {"method", method},
                            {"method_reason", fallback.empty() ? nlohmann::json(nullptr) : nlohmann::json(fallback)},
                            {"experiments", set.paths.size()},
                            {"samples", r.total_samples},
                            {"iterations", r.iterations},
                            {"arx_order", r.arx_order > 0 ? nlohmann::json(r.arx_order) : nlohmann::json(nullptr)},
                            {"termination", r.report.termination},
                            {"warnings", r.report.warnings},
                            {"out", o.out}};
  std::string text = fmt::format("markov: {} lags ({}) from {} experiments ({} samples, Ts = {:.6g} s), method {}: "
                                 "{}\n",
                                 options.num_lags, horizon, set.paths.size(), r.total_samples, set.sample_period_s,
                                 method, r.report.termination);
  if (!fallback.empty()) text += "note: " + fallback + "\n";
  if (!r.report.usable) text += "warning: the estimate did not converge; check the excitation and the lags\n";
  for (const auto& w : r.report.warnings) text += "warning: " + w + "\n";
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_markov_command() {
  return {"markov", "Markov parameters from closed-loop logs (FFT correlation)", [](CLI::App& parent) {
            auto o = std::make_shared<MarkovCliOptions>();
            auto* app = parent.add_subcommand("markov", "Markov parameters of excitation -> outputs from closed-loop logs" +
                                                            std::string(kMarkovExample));
            app->add_option("logs", o->logs, "logs (CSV or .mat), one experiment each ('-' = stdin, CSV)")->required();
            app->add_option("--excitation", o->excitation, "excitation columns, comma separated (e.g. v1,v2,v3)")
                ->required();
            app->add_option("--output", o->output, "output columns, comma separated (e.g. q1,q2,q3)")->required();
            add_log_layout_options(app, &o->layout);
            app->add_option("--out", o->out, "Markov parameter CSV to write ('-' = stdout)")->required();
            app->add_option("--lags", o->lags,
                            "number of lags L (default: --horizon-s / Ts when given, else the longest the records "
                            "support: min(N shortest / 4, N total / (4 inputs), 2000), in samples)")
                ->check(integer_in(10, kMaxLags, "the number of Markov lags"));
            app->add_option("--horizon-s", o->horizon_s,
                            "impulse-response length in seconds (instead of --lags; needs a known sample time), at "
                            "most a quarter of the shortest record")
                ->check(positive_up_to(kMaxHorizonS, "the impulse-response length in s"));
            app->add_option("--method", o->method,
                            "auto (default: ls; regularized when ls cannot be solved; arx when ls's response has "
                            "not died out within the horizon and arx predicts held-out halves of the records "
                            "better), ls (least squares), regularized (TC-kernel prior, marginal likelihood), arx (a "
                            "high-order ARX model's response) or correlation (the paper's)");
            app->add_option("--arx-order", o->arx_order,
                            "with --method arx: the ARX order (default: by the corrected Akaike criterion)")
                ->check(integer_in(1, 1000, "the ARX order"));
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
