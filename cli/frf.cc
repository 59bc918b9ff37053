// lpvid frf — nonparametric frequency responses (H1, Welch averaging) with
// coherence from time-domain logs: v -> u gives the input sensitivity S, v -> q
// the closed loop G, so both identification approaches run on one experiment.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/logs.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/frd_csv.h"
#include "idlib/core/error.h"
#include "idlib/signal/frf.h"

namespace lpvid::cli {
namespace {

constexpr const char* kExample = R"(
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
base's order, --excitation v1,v2,v3,v6,v5,v4 --input u1,u2,u3,u6,u5,u4 --output q1,...,q6.)";

struct FrfCliOptions {
  std::vector<std::string> logs;
  std::string excitation, input, output, out, quantity = "H", window = "hann";
  Index segment = 0;
  double overlap = 0.5;
  bool json = false;
};

void run(const FrfCliOptions& o) {
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
  const ExperimentSet set = read_experiments(o.logs, excitation, read);
  options.sample_period_s = set.sample_period_s;
  FrequencyResponse frd = plant ? estimate_plant_frf(set.views(), options) : estimate_frf(set.views(), options);
  frd.input_names = plant ? input : excitation;
  frd.output_names = output;
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
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_frf_command() {
  return {"frf", "nonparametric frequency response (H1, Welch) with coherence", [](CLI::App& parent) {
            auto o = std::make_shared<FrfCliOptions>();
            auto* app = parent.add_subcommand("frf", "H1 frequency-response estimate with coherence from logs" +
                                                         std::string(kExample));
            app->add_option("logs", o->logs, "logs (CSV or .mat), one experiment each")->required();
            app->add_option("--excitation", o->excitation, "excitation columns v (comma separated)")->required();
            app->add_option("--output", o->output, "response columns (u for S, q for G), comma separated")->required();
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
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
