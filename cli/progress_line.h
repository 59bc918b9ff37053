// The progress line of long subcommands (diagnose, fit, identify, frf --method
// lpm/lrm): what runs and how far, on ONE stderr line rewritten in place
//   diagnose: candidate 3 of 8: actuator_lag, coil_lag [#####---------------] 41 s
// and erased when the work ends, before the command prints its report.
//
// Shown only when stderr is a terminal (and TERM is not "dumb"), so that pipelines,
// Makefiles and golden tests see exactly the bytes they saw before.  LPVID_PROGRESS in the environment overrides:
// 0 never shows it, 1 always does (also into a file or pipe: for tests, or to watch a
// log); anything else, or unset, means "when stderr is a terminal"
// (docs/subcommands.md, "Progress").
//
// Drawing: "\r" + the line + "\x1b[K" (erase to the end of the line); erasing: "\r\x1b[K".
// The first report is drawn at once; later ones at most every kMinIntervalS (a ticker
// redraws the newest state, so the elapsed seconds advance during a long step and the
// last report before a long step is shown).  The line is cut to the terminal's width
// minus one column (TIOCGWINSZ; 80 when it cannot be read) so that it never wraps.
#pragma once

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "idlib/core/progress.h"

namespace lpvid::cli {

// The drawing logic, with its clock, stream and width given (tests give fakes).
class ProgressLine final : public Progress {
 public:
  static constexpr double kMinIntervalS = 0.1;  // at most 10 draws per second
  static constexpr int kBarCells = 20;
  static constexpr int kFallbackColumns = 80;

  struct Io {
    std::function<void(std::string_view)> write;  // bytes to the terminal
    std::function<double()> now_s;                // a monotonic clock in seconds
    std::function<int()> columns;                 // the terminal's width (<= 0: unknown)
  };
  explicit ProgressLine(Io io);

  // Stores the step; draws it when nothing was drawn yet or kMinIntervalS has passed.
  void report(const ProgressStep& step) noexcept override;
  // Draws the newest state (with the elapsed time now) if kMinIntervalS has passed
  // and the line would change.
  void tick() noexcept;
  // Erases the line if one is shown; a later report draws again.
  void clear() noexcept;
  // Erases the line and ignores every later report and tick (the work has ended).
  void close() noexcept;

  // The line for a step after elapsed_s seconds, at most columns − 1 characters
  // (code points; control characters shown as '?'): "task: step i of n: detail",
  // then " [bar] 41 s" (without a bar " (41 s)") kept whole while the text before it
  // is cut ("...").
  static std::string compose(const ProgressStep& step, double elapsed_s, int columns);
  // "41 s", "2 min 05 s", "1 h 02 min".
  static std::string elapsed_text(double seconds);

 private:
  void draw_locked(double now);
  Io io_;
  std::mutex m_;
  double t0_ = 0.0, last_draw_ = 0.0;
  bool have_ = false, shown_ = false, closed_ = false;
  std::string task_, step_, detail_;
  ProgressStep current_;  // views into the strings above
  std::string last_line_;
};

// True when the line is to be shown (LPVID_PROGRESS, else isatty(stderr) and TERM not "dumb").
bool progress_enabled();

// A command's progress: on stderr with a ticker thread when progress_enabled(),
// else nothing (get() is nullptr and no thread starts).  finish() (or the destructor,
// e.g. when an error unwinds) stops the ticker and erases the line; call it before
// printing the report.
class TerminalProgress {
 public:
  TerminalProgress();
  ~TerminalProgress();
  TerminalProgress(const TerminalProgress&) = delete;
  TerminalProgress& operator=(const TerminalProgress&) = delete;
  Progress* get() { return line_.get(); }
  void finish();

 private:
  std::unique_ptr<ProgressLine> line_;
  std::thread ticker_;
  std::mutex m_;
  std::condition_variable wake_;
  bool stop_ = false;
};

}  // namespace lpvid::cli
