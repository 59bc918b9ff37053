#include "cli/registry.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <exception>

#include "idlib/core/error.h"

namespace lpvid::cli {

Command make_simulate_command();
Command make_markov_command();
Command make_hankel_command();
Command make_realize_command();
Command make_unloop_command();
Command make_bode_command();
Command make_identify_command();
Command make_frf_command();
Command make_compare_command();
Command make_model_command();
Command make_fit_command();
Command make_diagnose_command();
Command make_history_command();
Command make_stage6_command();

const std::vector<Command>& commands() {
  static const std::vector<Command> all = {
      make_simulate_command(), make_markov_command(), make_hankel_command(), make_realize_command(),
      make_unloop_command(),   make_bode_command(),   make_identify_command(), make_frf_command(),
      make_compare_command(),  make_model_command(),  make_fit_command(),      make_diagnose_command(),
      make_history_command(), make_stage6_command(),
  };
  return all;
}

int run_main(int argc, char** argv) {
  CLI::App app{
      "lpvid — offline system identification for precision motion stages.\n"
      "Closed-loop logs -> Markov parameters -> Hankel SVD -> state-space model -> plant -> Bode plots.\n"
      "Run 'lpvid SUBCOMMAND --help' for a worked example of each step."};
  app.name("lpvid");
  app.require_subcommand(1);
  app.set_version_flag("--version", "lpvid 0.1.0");
  for (const Command& command : commands()) command.install(app);
  const char* sub = "lpvid";
  try {
    app.parse(argc, argv);
    return 0;
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    for (CLI::App* s : app.get_subcommands()) sub = s->get_name().c_str();
    std::fprintf(stderr, "%s: error: %s; run '%s --help' for usage\n",
                 sub == std::string("lpvid") ? "lpvid" : fmt::format("lpvid {}", sub).c_str(), e.what(),
                 sub == std::string("lpvid") ? "lpvid" : fmt::format("lpvid {}", sub).c_str());
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "lpvid: error: %s\n", e.what());
    return 2;
  } catch (const NumericalError& e) {
    std::fprintf(stderr, "lpvid: computation failed: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "lpvid: computation failed: out of memory; use shorter logs or fewer lags\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lpvid: internal error: %s\n", e.what());
    return 1;
  }
}

}  // namespace lpvid::cli
