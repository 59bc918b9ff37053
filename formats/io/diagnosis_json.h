// lpvid — the start a diagnosis report offers: `lpvid diagnose --json` lists every
// candidate (and combination) it refitted with all its fitted parameter values
// ("values"); `lpvid model add EFFECT[,EFFECT] --from-diagnosis REPORT.json` starts
// the user's refit from them, so that the refit reaches the error diagnose reported
// (docs/subcommands.md, "diagnose").
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace lpvid {

struct DiagnosisStart {
  std::string candidate;  // as the report names it ("com_offset + actuator_lag")
  double error = 0.0;     // the error figure diagnose reached with it
  bool significant = false;
  std::string verdict;
  std::vector<std::pair<std::string, double>> values;  // every parameter of the refitted model
};

// The candidate whose members are `effects` (in any order) in a diagnose JSON
// report.
// @throws InputError  the file unreadable or not a diagnose report (file:line:column
//   where it applies); no candidate with those members (the message lists the
//   report's candidates); its refit failed; a value not a finite number.
DiagnosisStart read_diagnosis_start(const std::string& path, const std::vector<std::string>& effects);

}  // namespace lpvid
