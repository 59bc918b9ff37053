// lpvid — progress of long computations: idlib says what it is doing and how far it
// is; the caller decides whether and how to show it (idlib never prints: the command
// line draws one line on a terminal, cli/progress_line.h).
//
// A long computation takes a `Progress*` in its options (FitOptions::progress,
// DiagnoseOptions, IdentifyOptions, LpmOptions, LrmOptions).  nullptr, the default,
// means no reports; a report site inside a loop then costs one pointer test (a
// once-per-stage site may still format its short text).  The computation's result
// never depends on the observer.
//
// What a report says (ProgressStep), e.g. "diagnose: candidate 3 of 8: actuator_lag":
//
// | field    | meaning                                                             |
// |----------|---------------------------------------------------------------------|
// | task     | what runs: "fit round 1", "diagnose", "identify", "frf lrm"         |
// | step     | the unit counted: "global start", "candidate", "frequency line"     |
// | index    | the one running, 1-based; 0: no number                              |
// | count    | of how many; 0: not known in advance (then no "of")                 |
// | detail   | free text: the candidate's name, "cost 1.234e+04"; may be empty     |
// | fraction | of the task done, in [0, 1]; < 0: (index − 1) / count when count>0, |
// |          | else none (then no bar is drawn)                                    |
//
// The strings are views: valid during the call only (a renderer copies them).
//
// Contract for observers: report() may be called from several threads at once
// (diagnose's candidates and residual models run in parallel), must be safe for that,
// must not throw, and should return quickly (it is called inside solver loops: per
// Levenberg–Marquardt iteration, per global start, a few hundred times over an LPM or
// LRM run).
#pragma once

#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "idlib/core/types.h"

namespace lpvid {

struct ProgressStep {
  std::string_view task;
  std::string_view step;
  Index index = 0;
  Index count = 0;
  std::string_view detail;
  double fraction = -1.0;
};

class Progress {
 public:
  virtual ~Progress() = default;
  virtual void report(const ProgressStep& step) noexcept = 0;
};

// Reports `step` to `progress` unless it is nullptr.
inline void report_progress(Progress* progress, const ProgressStep& step) noexcept {
  if (progress != nullptr) progress->report(step);
}

// A nested computation's reports under the caller's name: each task becomes
// "prefix, task" ("diagnose baseline, fit round 1: global start 3 of 8").
// get() is nullptr when the parent is, so that nesting keeps the null default free.
class NestedProgress final : public Progress {
 public:
  NestedProgress(Progress* parent, std::string prefix) : parent_(parent), prefix_(std::move(prefix)) {}
  Progress* get() { return parent_ != nullptr ? this : nullptr; }
  void report(const ProgressStep& step) noexcept override;

 private:
  Progress* parent_;
  std::string prefix_;
};

// Progress of n tasks run in parallel (parallel_for and diagnose's pool): start(name)
// and finish(name) from any thread; each reports
//   task: step K of n: NAMES   (bar: the share finished)
// K the number started so far, NAMES the ones running now, newest first.
// Does nothing when progress is nullptr; never throws (a report that cannot be made
// for want of memory is dropped).
class ParallelSteps {
 public:
  ParallelSteps(Progress* progress, std::string task, std::string step, Index count)
      : progress_(progress), task_(std::move(task)), step_(std::move(step)), count_(count) {}
  void start(const std::string& name) noexcept;
  void finish(const std::string& name) noexcept;

 private:
  void emit();  // with m_ held
  Progress* progress_;
  std::string task_, step_;
  Index count_;
  std::mutex m_;
  Index started_ = 0, finished_ = 0;
  std::vector<std::string> running_;
};

}  // namespace lpvid
