// lpvid hankel — singular values of the block Hankel matrix of Markov
// parameters (seed 000, eq 10 and Fig. 9), with the order the rule would choose.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/common.h"
#include "cli/output_set.h"
#include "cli/registry.h"
#include "formats/io/atomic_file.h"
#include "formats/io/markov_csv.h"
#include "formats/io/table_csv.h"
#include "formats/plot/sv_plot.h"
#include "idlib/core/error.h"
#include "idlib/realization/era.h"

namespace lpvid::cli {
namespace {

constexpr const char* kHankelExample = R"(
Example:
  lpvid hankel g.csv --out hankel_sv.csv --png hankel_sv.png --count 12
The Hankel matrix is built from channel-scaled Markov parameters (each excitation and
output divided by its spread), sized from the data exactly as 'realize' does; the CSV
lists index, singular value and whether it stands above the noise floor.)";

struct HankelOptions {
  std::string markov, out, png;
  Index count = 20;
  bool json = false;
};

void run(const HankelOptions& o) {
  OutputSet outputs;
  outputs.input(o.markov);
  outputs.file("--out", o.out);
  outputs.file("--png", o.png);
  outputs.check();
  const MarkovFile file = read_markov_csv(o.markov);
  EraOptions options = era_options_from(file);
  options.max_order = std::max<Index>(o.count, options.max_order);
  // hankel shows the singular values even when none stands above the noise
  // floor (then realize would fail): the values are computed with order 1 and
  // the chosen order is reported as 0.
  EraResult era;
  std::string no_order;
  try {
    era = realize_era(file.g, options);
  } catch (const NumericalError& e) {
    options.order = 1;
    era = realize_era(file.g, options);
    era.selection.order = 0;
    era.selection.reason = e.what();
    no_order = e.what();
  }
  const Eigen::VectorXd& sv = era.selection.singular_values;
  const Index n = std::min<Index>(sv.size(), std::max<Index>(o.count, era.selection.order + 1));
  Eigen::MatrixXd table(n, 3);
  for (Index i = 0; i < n; ++i) {
    table(i, 0) = static_cast<double>(i + 1);
    table(i, 1) = sv(i);
    table(i, 2) = sv(i) > era.selection.noise_floor ? 1.0 : 0.0;
  }
  write_table_csv(outputs.stage(o.out), {"index", "singular_value", "above_noise_floor"}, table,
                  {fmt::format("lpvid hankel {}", o.markov),
                   fmt::format("block_rows={} block_cols={} stride={} noise_floor={:.6g} chosen_order={}",
                               era.block_rows, era.block_cols, era.stride, era.selection.noise_floor,
                               era.selection.order),
                   "rule: " + era.selection.reason});
  if (!o.png.empty()) {
    SingularValuePlotOptions plot;
    plot.count = std::min<Index>(o.count, sv.size());
    plot.chosen_order = era.selection.order;
    plot.noise_floor = era.selection.noise_floor;
    plot.title = "Largest Hankel singular values (scaled channels)";
    const auto bytes = singular_values_png(sv, plot);
    outputs.stage(o.png, bytes);
  }
  nlohmann::json summary = {{"order", era.selection.order},
                            {"reason", era.selection.reason},
                            {"noise_floor", era.selection.noise_floor},
                            {"block_rows", era.block_rows},
                            {"block_cols", era.block_cols},
                            {"stride", era.stride},
                            {"singular_values", std::vector<double>(sv.data(), sv.data() + n)},
                            {"warnings", no_order.empty() ? std::vector<std::string>{}
                                                          : std::vector<std::string>{"no model order stands above the noise floor"}}};
  std::string text = fmt::format("hankel: {} x {} blocks, stride {}; order {}: {}\n", era.block_rows, era.block_cols,
                                 era.stride, era.selection.order, era.selection.reason);
  if (!no_order.empty()) text += "warning: no model order stands above the noise floor; realize would fail on these data\n";
  outputs.commit();
  if (!outputs.to_stdout()) print_summary(o.json, summary, text);
}

}  // namespace

Command make_hankel_command() {
  return {"hankel", "Hankel singular values (CSV + PNG) of Markov parameters", [](CLI::App& parent) {
            auto o = std::make_shared<HankelOptions>();
            auto* app = parent.add_subcommand("hankel", "Block Hankel singular values of Markov parameters" +
                                                            std::string(kHankelExample));
            app->add_option("markov", o->markov, "Markov parameter CSV written by 'lpvid markov'")->required();
            app->add_option("--out", o->out, "singular-value CSV to write ('-' = stdout)")->required();
            app->add_option("--png", o->png, "also write a PNG of the largest singular values");
            app->add_option("--count", o->count, "how many singular values to list and plot")
                ->check(integer_in(1, kMaxListed, "how many singular values to list"));
            app->add_flag("--json", o->json, "print the summary as JSON");
            app->callback([o] { run(*o); });
          }};
}

}  // namespace lpvid::cli
