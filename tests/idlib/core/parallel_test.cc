#include "idlib/core/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

namespace lpvid {
namespace parallel_test {

// Enough tasks that every worker of a many-core machine gets some.
constexpr Index kTasks = 1000;

TEST(ParallelFor, EveryTaskRunsExactlyOnce) {
  std::vector<std::atomic<int>> runs(kTasks);
  for (auto& r : runs) r = 0;
  parallel_for(kTasks, [&](Index i) { ++runs[static_cast<std::size_t>(i)]; });
  for (const auto& r : runs) EXPECT_EQ(r.load(), 1);
}

TEST(ParallelFor, ZeroTasksDoNothing) {
  bool ran = false;
  parallel_for(0, [&](Index) { ran = true; });
  EXPECT_FALSE(ran);
}

TEST(ParallelFor, NestedCallsRunInline) {
  std::vector<long> sums(8, 0);
  parallel_for(8, [&](Index i) {
    std::vector<long> part(10, 0);
    parallel_for(10, [&](Index j) { part[static_cast<std::size_t>(j)] = i * 10 + j; });
    for (long v : part) sums[static_cast<std::size_t>(i)] += v;
  });
  for (Index i = 0; i < 8; ++i) EXPECT_EQ(sums[static_cast<std::size_t>(i)], 100 * i + 45);
}

TEST(ParallelFor, AllTasksRunAndTheSmallestIndexThrows) {
  std::atomic<int> ran{0};
  try {
    parallel_for(50, [&](Index i) {
      ++ran;
      if (i == 7 || i == 30) throw std::runtime_error("task " + std::to_string(i));
    });
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "task 7");
  }
  EXPECT_EQ(ran.load(), 50);
}

TEST(ParallelFor, UsableAgainAfterAnException) {
  EXPECT_THROW(parallel_for(4, [](Index) { throw std::runtime_error("x"); }), std::runtime_error);
  std::vector<int> out(4, 0);
  parallel_for(4, [&](Index i) { out[static_cast<std::size_t>(i)] = static_cast<int>(i) + 1; });
  EXPECT_EQ(out, (std::vector<int>{1, 2, 3, 4}));
}

TEST(ParallelFor, ThreadsIncludeTheCaller) { EXPECT_GE(parallel_threads(), 1); }

}  // namespace parallel_test
}  // namespace lpvid
