// The progress interface's helpers (idlib/core/progress.h): a nested computation's
// task under its caller's name, and the reports of tasks run in parallel.
#include "idlib/core/progress.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "idlib/core/parallel.h"

namespace lpvid {
namespace progress_test {

// Keeps copies of every report.
struct Recorded {
  std::string task, step, detail;
  Index index = 0, count = 0;
  double fraction = 0;
};
class Recorder final : public Progress {
 public:
  void report(const ProgressStep& s) noexcept override {
    std::lock_guard<std::mutex> lock(m);
    seen.push_back({std::string(s.task), std::string(s.step), std::string(s.detail), s.index, s.count, s.fraction});
  }
  std::mutex m;
  std::vector<Recorded> seen;
};

TEST(NestedProgress, PrefixesTheTaskAndKeepsTheRest) {
  Recorder r;
  NestedProgress nested(&r, "diagnose baseline");
  ASSERT_EQ(nested.get(), &nested);
  nested.get()->report({"fit", "global start", 2, 8, "x", 0.25});
  ASSERT_EQ(r.seen.size(), 1u);
  EXPECT_EQ(r.seen[0].task, "diagnose baseline, fit");
  EXPECT_EQ(r.seen[0].step, "global start");
  EXPECT_EQ(r.seen[0].index, 2);
  EXPECT_EQ(r.seen[0].count, 8);
  EXPECT_EQ(r.seen[0].detail, "x");
  EXPECT_EQ(r.seen[0].fraction, 0.25);
}

TEST(NestedProgress, UnderNoParentIsNullSoThatNestingStaysFree) {
  NestedProgress nested(nullptr, "diagnose baseline");
  EXPECT_EQ(nested.get(), nullptr);
  report_progress(nested.get(), {"fit", "", 0, 0, "", -1.0});  // no-op, no crash
}

TEST(ParallelSteps, CountsStartsNamesTheRunningNewestFirstAndBarsTheFinished) {
  Recorder r;
  ParallelSteps steps(&r, "diagnose", "candidate", 4);
  steps.start("a");
  steps.start("b");
  steps.finish("a");
  steps.start("c");
  ASSERT_EQ(r.seen.size(), 4u);
  EXPECT_EQ(r.seen[1].detail, "b, a");
  EXPECT_EQ(r.seen[1].index, 2);
  EXPECT_EQ(r.seen[1].fraction, 0.0);
  EXPECT_EQ(r.seen[2].detail, "b");
  EXPECT_EQ(r.seen[2].fraction, 0.25);
  EXPECT_EQ(r.seen[3].task, "diagnose");
  EXPECT_EQ(r.seen[3].step, "candidate");
  EXPECT_EQ(r.seen[3].index, 3);
  EXPECT_EQ(r.seen[3].count, 4);
  EXPECT_EQ(r.seen[3].detail, "c, b");
}

TEST(ParallelSteps, FromThePoolsThreadsEveryStartAndFinishIsReportedOnce) {
  Recorder r;
  constexpr Index kTasks = 64;
  ParallelSteps steps(&r, "t", "s", kTasks);
  parallel_for(kTasks, [&](Index i) {
    steps.start(std::to_string(i));
    steps.finish(std::to_string(i));
  });
  ASSERT_EQ(r.seen.size(), static_cast<std::size_t>(2 * kTasks));
  EXPECT_EQ(r.seen.back().fraction, 1.0);
  EXPECT_EQ(r.seen.back().index, kTasks);
  EXPECT_EQ(r.seen.back().detail, "");
}

TEST(ParallelSteps, WithoutAnObserverDoesNothing) {
  ParallelSteps steps(nullptr, "t", "s", 2);
  steps.start("a");
  steps.finish("a");
}

}  // namespace progress_test
}  // namespace lpvid
