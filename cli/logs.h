// Reading experiment logs for the identification subcommands: every log must
// carry the named excitation and output columns and share one sample period.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "formats/io/csv_log.h"
#include "idlib/signal/markov.h"

namespace CLI {
class App;
}

namespace lpvid::cli {

struct ExperimentSet {
  std::vector<Eigen::MatrixXd> excitations;  // per log: N x m
  std::vector<Eigen::MatrixXd> outputs;      // per log: N x p
  double sample_period_s = 0;
  std::vector<std::string> paths;
  // What idlib/signal/log_checks.h found in the named columns ("PATH: channel y sits at
  // ..."), one sentence each (print_log_findings).
  std::vector<std::string> findings;
  std::vector<ExperimentView> views() const;
};

// Reads each log, keeps only the named columns (the rest is freed at once), and
// checks that all logs share the sample period (relative 1e-6; the message names
// both files and periods).  Saturated or drifting columns (idlib/signal/log_checks.h)
// are collected in `findings`, never changed.
ExperimentSet read_experiments(const std::vector<std::string>& paths, const std::vector<std::string>& excitation,
                               const std::vector<std::string>& output, const LogReadOptions& read = {});

// --log-columns NAMES and --log-rate HZ: the channel names (in the file's order; "a1..a28"
// ranges allowed) and the sample rate of a .mat log that has neither (a DaISy file: one
// unnamed N × k matrix).  Refused for a file that has its own (formats.md).
struct LogLayoutCli {
  std::string columns;
  double rate_hz = 0;
  LogReadOptions read_options() const;  // @throws InputError  a bad name list
};
void add_log_layout_options(CLI::App* app, LogLayoutCli* o);

// Prints each finding as "lpvid: warning: ..." on stderr: called by a command once its
// work succeeded (a refused command's error stays one line).
void print_log_findings(const ExperimentSet& set);

}  // namespace lpvid::cli
