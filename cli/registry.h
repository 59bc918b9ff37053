// lpvid command registry: the one list of subcommands (a test pins it).
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace lpvid::cli {

// A subcommand: its name, a one-line summary, and a function that adds it to the
// parent app (declaring options into an options struct it owns and setting the
// callback that runs it).  Each lives in cli/<name>.cc.
struct Command {
  std::string name;
  std::string summary;
  std::function<void(CLI::App& parent)> install;
};

const std::vector<Command>& commands();

// Parses argv, runs the chosen subcommand, maps failures to exit codes:
// 0 success, 1 failed computation (NumericalError), 2 bad usage or bad input.
int run_main(int argc, char** argv);

}  // namespace lpvid::cli
