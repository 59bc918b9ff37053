#include "cli/logs.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <sys/stat.h>

#include <cmath>
#include <cstdio>

#include "cli/common.h"
#include "formats/io/csv_log.h"
#include "idlib/core/error.h"
#include "idlib/signal/log_checks.h"

namespace lpvid::cli {

std::vector<ExperimentView> ExperimentSet::views() const {
  std::vector<ExperimentView> v;
  v.reserve(excitations.size());
  for (std::size_t i = 0; i < excitations.size(); ++i) v.push_back(ExperimentView{excitations[i], outputs[i]});
  return v;
}

ExperimentSet read_experiments(const std::vector<std::string>& paths, const std::vector<std::string>& excitation,
                               const std::vector<std::string>& output, const LogReadOptions& read) {
  if (paths.empty()) throw InputError("no logs given; pass one or more CSV logs (one file per experiment)");
  // One experiment given twice would count twice (and stdin can be read once).
  for (std::size_t i = 0; i < paths.size(); ++i)
    for (std::size_t k = 0; k < i; ++k) {
      struct stat a, b;
      const bool both_stdin = paths[i] == "-" && paths[k] == "-";
      const bool same_file = paths[i] != "-" && paths[k] != "-" && ::stat(paths[i].c_str(), &a) == 0 &&
                             ::stat(paths[k].c_str(), &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino;
      if (both_stdin || same_file)
        throw InputError(fmt::format("log '{}' is given twice (also as '{}'); give each experiment once", paths[i],
                                     paths[k]));
    }
  // Relative difference of sample periods tolerated between logs of one set.
  constexpr double kSamePeriodTolerance = 1e-6;
  ExperimentSet set;
  for (const std::string& path : paths) {
    Log log = read_log(path, read);
    set.excitations.push_back(log.columns(excitation));
    set.outputs.push_back(log.columns(output));
    if (set.paths.empty()) {
      set.sample_period_s = log.sample_period_s;
    } else if (std::abs(log.sample_period_s - set.sample_period_s) > kSamePeriodTolerance * set.sample_period_s) {
      throw InputError(fmt::format(
          "{}: sampled every {:.6g} s but {} every {:.6g} s; give logs of one sample rate (resample, or identify them separately)",
          path, log.sample_period_s, set.paths.front(), set.sample_period_s));
    }
    set.paths.push_back(path);
    // The habits of real logs the methods do not model: said with the place, not corrected.
    const Eigen::MatrixXd& ex = set.excitations.back();
    const Eigen::MatrixXd& ou = set.outputs.back();
    for (const auto* block : {&ex, &ou}) {
      const std::vector<std::string>& names = block == &ex ? excitation : output;
      for (const ChannelFinding& f : inspect_channels(*block, &log.data)) {
        set.findings.push_back(fmt::format("{}: {}", path == "-" ? "<stdin>" : path,
                                           describe_finding(f, names[static_cast<std::size_t>(f.channel)])));
      }
    }
  }
  return set;
}

LogReadOptions LogLayoutCli::read_options() const {
  LogReadOptions r;
  r.sample_rate_hz = rate_hz;
  if (!columns.empty()) r.channel_names = split_names(columns, "--log-columns");
  return r;
}

void add_log_layout_options(CLI::App* app, LogLayoutCli* o) {
  app->add_option("--log-columns", o->columns,
                  "for a .mat log of one unnamed matrix (a DaISy file): its channel names in order, comma separated "
                  "(ranges such as a1..a28 allowed); needs --log-rate");
  app->add_option("--log-rate", o->rate_hz, "for a .mat log without t or a rate variable: its sample rate in Hz")
      ->check(positive_up_to(1e9, "the sample rate in Hz"));
}

void print_log_findings(const ExperimentSet& set) {
  for (const std::string& f : set.findings) std::fprintf(stderr, "lpvid: warning: %s\n", f.c_str());
}

}  // namespace lpvid::cli
