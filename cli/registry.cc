#include "cli/registry.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

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
Command make_excite_command();

const std::vector<Command>& commands() {
  static const std::vector<Command> all = {
      make_simulate_command(), make_markov_command(), make_hankel_command(), make_realize_command(),
      make_unloop_command(),   make_bode_command(),   make_identify_command(), make_frf_command(),
      make_compare_command(),  make_model_command(),  make_fit_command(),      make_diagnose_command(),
      make_history_command(), make_stage6_command(), make_excite_command(),
  };
  return all;
}

namespace {

// Every message leaves as one line of bounded length, whatever a file or flag
// put into it: line breaks become spaces and the middle of a very long message
// is cut (each reader already quotes values cut to 40 bytes; this is the net).
std::string one_line(std::string text) {
  constexpr std::size_t kMaxMessage = 2000;
  for (char& c : text)
    if (c == '\n' || c == '\r' || c == '\0') c = ' ';
  if (text.size() > kMaxMessage) text = text.substr(0, kMaxMessage / 2) + " ... " + text.substr(text.size() - kMaxMessage / 2);
  return text;
}

// An empty argument ('' or --out=) would read as "not given" (an optional output
// silently skipped): refused, naming the flag it belongs to.
bool empty_argument(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool empty_value = arg.size() > 2 && arg.rfind("--", 0) == 0 && arg.back() == '=';
    if (!arg.empty() && !empty_value) continue;
    const std::string flag = empty_value ? arg.substr(0, arg.size() - 1)
                             : (i > 1 && argv[i - 1][0] == '-') ? std::string(argv[i - 1])
                                                                : std::string("a file argument");
    std::fprintf(stderr, "lpvid: error: empty value for %s; give a value (a path, a number) or leave the flag out\n",
                 one_line(flag).c_str());
    return true;
  }
  return false;
}

// "lpvid frobnicate" and "lpvid simulate frob": CLI11 would only say that a
// subcommand is required.  Walks the leading words of argv down the command
// tree; prints one line naming the unknown word and the known ones.
bool unknown_subcommand(CLI::App& app, int argc, char** argv) {
  CLI::App* current = &app;
  std::string path = "lpvid";
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (word.empty() || word[0] == '-' || current->get_require_subcommand_min() == 0) return false;
    CLI::App* next = nullptr;
    std::vector<std::string> known;
    for (CLI::App* s : current->get_subcommands([](CLI::App*) { return true; })) {
      known.push_back(s->get_name());
      if (s->check_name(word)) next = s;
    }
    if (next == nullptr) {
      std::fprintf(stderr, "%s: error: unknown subcommand '%s'; the subcommands are %s; run '%s --help' for what each does\n",
                   path.c_str(), (word.size() <= 40 ? word : word.substr(0, 40) + "...").c_str(), fmt::format("{}", fmt::join(known, ", ")).c_str(), path.c_str());
      return true;
    }
    current = next;
    path += " " + next->get_name();
  }
  return false;
}

}  // namespace

int run_main(int argc, char** argv) {
  CLI::App app{
      "lpvid — offline system identification for precision motion stages.\n"
      "Closed-loop logs -> Markov parameters -> Hankel SVD -> state-space model -> plant -> Bode plots.\n"
      "Run 'lpvid SUBCOMMAND --help' for a worked example of each step."};
  app.name("lpvid");
  app.require_subcommand(1);
  app.set_version_flag("--version", "lpvid 0.1.0");
  for (const Command& command : commands()) command.install(app);
  if (unknown_subcommand(app, argc, argv) || empty_argument(argc, argv)) return 2;
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
  } catch (const CLI::ValidationError& e) {
    // Flag ranges (cli/common.h): the message already says what to do.
    for (CLI::App* s : app.get_subcommands()) sub = s->get_name().c_str();
    std::fprintf(stderr, "%s: error: %s\n",
                 sub == std::string("lpvid") ? "lpvid" : fmt::format("lpvid {}", sub).c_str(), one_line(e.what()).c_str());
    return 2;
  } catch (const CLI::ParseError& e) {
    for (CLI::App* s : app.get_subcommands()) sub = s->get_name().c_str();
    std::fprintf(stderr, "%s: error: %s; run '%s --help' for usage\n",
                 sub == std::string("lpvid") ? "lpvid" : fmt::format("lpvid {}", sub).c_str(), one_line(e.what()).c_str(),
                 sub == std::string("lpvid") ? "lpvid" : fmt::format("lpvid {}", sub).c_str());
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "lpvid: error: %s\n", one_line(e.what()).c_str());
    return 2;
  } catch (const NumericalError& e) {
    std::fprintf(stderr, "lpvid: computation failed: %s\n", one_line(e.what()).c_str());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "lpvid: computation failed: out of memory; use shorter logs or fewer lags\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lpvid: internal error: %s\n", one_line(e.what()).c_str());
    return 1;
  }
}

}  // namespace lpvid::cli
