#include "cli/logs.h"

#include <fmt/format.h>

#include <cmath>

#include "formats/io/csv_log.h"
#include "idlib/core/error.h"

namespace lpvid::cli {

std::vector<ExperimentView> ExperimentSet::views() const {
  std::vector<ExperimentView> v;
  v.reserve(excitations.size());
  for (std::size_t i = 0; i < excitations.size(); ++i) v.push_back(ExperimentView{excitations[i], outputs[i]});
  return v;
}

ExperimentSet read_experiments(const std::vector<std::string>& paths, const std::vector<std::string>& excitation,
                               const std::vector<std::string>& output) {
  if (paths.empty()) throw InputError("no logs given; pass one or more CSV logs (one file per experiment)");
  // Relative difference of sample periods tolerated between logs of one set.
  constexpr double kSamePeriodTolerance = 1e-6;
  ExperimentSet set;
  for (const std::string& path : paths) {
    Log log = read_log(path);
    set.excitations.push_back(log.columns(excitation));
    set.outputs.push_back(log.columns(output));
    if (set.paths.empty()) {
      set.sample_period_s = log.sample_period_s;
    } else if (std::abs(log.sample_period_s - set.sample_period_s) > kSamePeriodTolerance * set.sample_period_s) {
      throw InputError(fmt::format(
          "{}: sampled every {:.6g} s but {} every {:.6g} s; logs of one identification must share the sample rate",
          path, log.sample_period_s, set.paths.front(), set.sample_period_s));
    }
    set.paths.push_back(path);
  }
  return set;
}

}  // namespace lpvid::cli
