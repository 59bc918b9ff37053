// lpvid simulate stage6: installs the `stage6` subcommand under `simulate`.
#pragma once

#include <CLI/CLI.hpp>

namespace lpvid::cli {

// Adds `simulate stage6` (cli/simulate_stage6.cc) to the `simulate` subcommand.
void install_simulate_stage6(CLI::App& simulate);

}  // namespace lpvid::cli
