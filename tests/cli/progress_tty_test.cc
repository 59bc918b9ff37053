// The progress line through the program (cli/progress_line.h): on a pseudo-terminal
// `lpvid fit` and `lpvid frf --method lrm` draw it on stderr and erase it before the
// report; with stderr a file (pipelines, Makefiles, golden tests) nothing is added,
// byte for byte, unless LPVID_PROGRESS=1 asks for it, and then only on stderr.
//
// Robust on fast machines: the renderer draws the first report at once, so the line
// appears however quickly the command ends.
#include <fcntl.h>
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "formats/io/frd_csv.h"
#include "idlib/lti/frequency_response.h"
#include "idlib/physical/evaluate.h"
#include "idlib/physical/platform/platform_base.h"
#include "idlib/plants/platform/platform.h"
#include "tests/support/run_lpvid.h"

extern char** environ;

namespace lpvid {
namespace progress_tty_test {

using ::testing::HasSubstr;
using lpvid::testing::run_lpvid;
using lpvid::testing::RunResult;
using lpvid::testing::slurp;
using lpvid::testing::TempDir;

constexpr int kPtyColumns = 100;
// A command that has not ended by then is hung (the slowest here, under the
// sanitizers, takes a few seconds).
constexpr int kPtyTimeoutMs = 120'000;

struct PtyRun {
  int exit_code = -1;
  std::string bytes;  // everything the program wrote to the terminal (stdout and stderr)
};

// Runs lpvid ARGS with stdin, stdout and stderr on a new pseudo-terminal of
// kPtyColumns columns, LPVID_PROGRESS removed from the environment (so that the
// terminal alone decides) and TERM=xterm.
PtyRun run_on_pty(const std::vector<std::string>& args) {
  // Everything the child needs is built before fork: the test process has threads.
  std::vector<std::string> argv_s{LPVID_BINARY};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::string term = "TERM=xterm";  // a terminal that can erase a line, whatever runs the tests
  std::vector<char*> envp;
  for (char** e = environ; *e != nullptr; ++e)
    if (std::strncmp(*e, "LPVID_PROGRESS=", 15) != 0 && std::strncmp(*e, "TERM=", 5) != 0) envp.push_back(*e);
  envp.push_back(term.data());
  envp.push_back(nullptr);

  winsize ws{};
  ws.ws_col = kPtyColumns;
  ws.ws_row = 24;
  int master = -1;
  const pid_t pid = forkpty(&master, nullptr, nullptr, &ws);
  if (pid == 0) {
    execve(argv[0], argv.data(), envp.data());
    _exit(127);
  }
  PtyRun r;
  if (pid < 0) {
    ADD_FAILURE() << "forkpty: " << std::strerror(errno);
    return r;
  }
  char buf[4096];
  for (;;) {
    pollfd p{master, POLLIN, 0};
    const int ready = poll(&p, 1, kPtyTimeoutMs);
    if (ready == 0) {
      ADD_FAILURE() << "lpvid on the pty did not finish within " << kPtyTimeoutMs << " ms";
      kill(pid, SIGKILL);
      break;
    }
    if (ready < 0 && errno == EINTR) continue;
    const ssize_t n = read(master, buf, sizeof buf);
    if (n > 0) {
      r.bytes.append(buf, static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    break;  // EIO: the child closed the terminal's last slave descriptor
  }
  int status = 0;
  waitpid(pid, &status, 0);
  close(master);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

// The lines drawn: the text between each "\r" and the following "\x1b[K" (an erase is
// "\r\x1b[K", an empty drawn line).
std::vector<std::string> drawn_lines(const std::string& bytes) {
  std::vector<std::string> out;
  std::size_t pos = 0;
  for (;;) {
    const std::size_t end = bytes.find("\x1b[K", pos);
    if (end == std::string::npos) return out;
    const std::size_t cr = bytes.rfind('\r', end);
    if (cr != std::string::npos && cr >= pos && end > cr + 1) out.push_back(bytes.substr(cr + 1, end - cr - 1));
    pos = end + 3;
  }
}

std::size_t code_points(const std::string& s) {
  std::size_t n = 0;
  for (unsigned char c : s) n += (c & 0xC0) != 0x80;
  return n;
}

// y[t] = 0.95 y[t−1] + 0.05 v[t] driven by white noise, with 1e-3 measurement noise:
// 4096 samples at 1 kHz (enough lines for the LRM, a fraction of a second to estimate).
void write_white_noise_log(const std::string& path) {
  std::mt19937_64 rng(23);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::ofstream out(path);
  out.precision(17);
  out << "t,v1,y1\n";
  double y = 0;
  for (int t = 0; t < 4096; ++t) {
    const double v = n01(rng);
    y = 0.95 * y + 0.05 * v;
    out << t * 1e-3 << "," << v << "," << y + 1e-3 * n01(rng) << "\n";
  }
}

// Noise-free plant FRDs of the default platform with its centre of mass moved, at the
// paper's three beam positions (as tests/cli/fit_test.cc); returns the --data arguments.
std::vector<std::string> write_plant_frds(const TempDir& dir) {
  PhysicalModel truth = platform_defaults_model();
  truth.parameter("com_x_m").value = 0.006;
  const Eigen::VectorXd w = log_frequency_grid(2.0, 600.0, 40);
  std::vector<std::string> args;
  for (int i = 0; i < 3; ++i) {
    FrequencyResponse f;
    f.omega_rad_s = w;
    f.response = physical_response(truth, kPaperBeamPositions_m[static_cast<std::size_t>(i)], w, 1e-3);
    f.input_names = {"T_psi", "T_theta", "F_z"};
    f.output_names = {"psi", "theta", "z"};
    const std::string file = dir / fmt::format("P{}.csv", i);
    write_frd_csv(file, f, "P");
    args.push_back("--data");
    args.push_back(fmt::format("{}@{}", file, kPaperBeamPositions_m[static_cast<std::size_t>(i)]));
  }
  return args;
}

std::vector<std::string> fit_args(const TempDir& dir) {
  EXPECT_EQ(run_lpvid("model init --out " + (dir / "start.json")).exit_code, 0);
  std::vector<std::string> args{"fit", "--model", dir / "start.json", "--rate-hz", "1000", "--starts", "2",
                                "--max-iterations", "20", "--out", dir / "fitted.json"};
  for (const auto& a : write_plant_frds(dir)) args.push_back(a);
  return args;
}

std::string shell_args(const std::vector<std::string>& args) {
  std::string s;
  for (const auto& a : args) s += " '" + a + "'";
  return s;
}

TEST(ProgressOnATerminal, FitDrawsOneLineInPlaceAndErasesItBeforeTheReport) {
  TempDir dir("progress_fit");
  const PtyRun r = run_on_pty(fit_args(dir));
  ASSERT_EQ(r.exit_code, 0) << r.bytes;
  const std::vector<std::string> lines = drawn_lines(r.bytes);
  ASSERT_FALSE(lines.empty()) << r.bytes;
  EXPECT_THAT(lines.front(), HasSubstr("fit round 1: global start 1 of 2 [")) << r.bytes;
  bool iterations = false;
  for (const auto& l : lines) {
    iterations = iterations || l.find("Levenberg-Marquardt iteration ") != std::string::npos;
    EXPECT_LE(code_points(l), static_cast<std::size_t>(kPtyColumns - 1)) << l;  // never wraps
    EXPECT_EQ(l.find('\n'), std::string::npos) << l;
  }
  EXPECT_TRUE(iterations) << r.bytes;
  // Erased before the report, and nothing drawn after it.
  const std::size_t erase = r.bytes.rfind("\r\x1b[K");
  const std::size_t report = r.bytes.find("fit: ");
  ASSERT_NE(erase, std::string::npos);
  ASSERT_NE(report, std::string::npos) << r.bytes;
  EXPECT_LT(erase, report);
  EXPECT_EQ(r.bytes.find('\x1b', report), std::string::npos);
}

TEST(ProgressOnATerminal, FrfLrmCountsTheFrequencyLines) {
  TempDir dir("progress_lrm");
  write_white_noise_log(dir / "log.csv");
  const PtyRun r = run_on_pty({"frf", "--method", "lrm", "--excitation", "v1", "--output", "y1", "--quantity", "G",
                               "--out", dir / "G.csv", dir / "log.csv"});
  ASSERT_EQ(r.exit_code, 0) << r.bytes;
  const std::vector<std::string> lines = drawn_lines(r.bytes);
  ASSERT_FALSE(lines.empty()) << r.bytes;
  EXPECT_THAT(lines.front(), ::testing::StartsWith("frf lrm: frequency line 1 of "));
  EXPECT_THAT(r.bytes, HasSubstr("\r\x1b[Kfrf (lrm): "));  // erased, then the report
}

// Runs `env ENV lpvid ARGS` through the shell with stdout and stderr to files (as
// tests/support/run_lpvid.h, with the environment set: "-u LPVID_PROGRESS" removes it).
RunResult run_env(const std::string& env, const std::string& args) {
  return lpvid::testing::run_shell(fmt::format("env {} {} {}", env, LPVID_BINARY, args));
}

TEST(ProgressOffATerminal, OutputIsByteIdenticalAndOnlyTheForcedLineGoesToStderr) {
  TempDir dir("progress_pipe");
  write_white_noise_log(dir / "log.csv");
  auto frf = [&](const std::string& env, const std::string& out) {
    return run_env(env, fmt::format("frf --method lrm --excitation v1 --output y1 --quantity G --out {} {}", out,
                                    dir / "log.csv"));
  };
  const RunResult plain = frf("-u LPVID_PROGRESS", dir / "G_plain.csv");
  const RunResult off = frf("LPVID_PROGRESS=0", dir / "G_off.csv");
  const RunResult forced = frf("LPVID_PROGRESS=1", dir / "G_forced.csv");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  ASSERT_EQ(off.exit_code, 0) << off.err;
  ASSERT_EQ(forced.exit_code, 0) << forced.err;
  // Not a terminal: not one byte more.
  EXPECT_EQ(plain.err, "");
  EXPECT_EQ(off.err, "");
  EXPECT_EQ(plain.out.find_first_of("\r\x1b"), std::string::npos);
  // The same report and file whatever LPVID_PROGRESS says (the file name aside).
  auto report = [&](std::string s, const std::string& name) {
    const std::size_t at = s.find(name);
    if (at != std::string::npos) s.replace(at, name.size(), "G.csv");
    return s;
  };
  EXPECT_EQ(report(off.out, dir / "G_off.csv"), report(plain.out, dir / "G_plain.csv"));
  EXPECT_EQ(report(forced.out, dir / "G_forced.csv"), report(plain.out, dir / "G_plain.csv"));
  EXPECT_EQ(slurp(dir / "G_off.csv"), slurp(dir / "G_plain.csv"));
  EXPECT_EQ(slurp(dir / "G_forced.csv"), slurp(dir / "G_plain.csv"));
  // Forced: the line on stderr only, erased at the end.
  EXPECT_THAT(forced.err, ::testing::StartsWith("\rfrf lrm: frequency line 1 of "));
  EXPECT_THAT(forced.err, ::testing::EndsWith("\r\x1b[K"));
}

TEST(ProgressOffATerminal, FitWritesNothingToStderr) {
  TempDir dir("progress_fit_pipe");
  const std::vector<std::string> args = fit_args(dir);
  const RunResult r = run_env("-u LPVID_PROGRESS", shell_args(args));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(r.out.find_first_of("\r\x1b"), std::string::npos);
  EXPECT_THAT(r.out, HasSubstr("fit: "));
}

}  // namespace progress_tty_test
}  // namespace lpvid
