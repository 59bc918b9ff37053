// lpvid — independent tasks on the machine's cores, with results that do not depend on
// the schedule.
//
//   parallel_for(n, task)  runs task(0), ..., task(n − 1), each exactly once, on the
//   calling thread and the workers of one process-wide pool (hardware_concurrency − 1
//   threads, at most kMaxWorkers, started on first use), and returns when all are done.
//
// Contract for callers: task(i) writes only outputs that belong to i (its own slot of a
// vector, its own buffers) and reads shared data only; any reduction over i is done by
// the caller afterwards in a fixed order.  The number of tasks must not depend on the
// number of threads.  Then the result is bit-identical for every schedule and thread
// count (including one: LPVID_THREADS=1 in the environment runs everything on the
// caller, for comparison and profiling).
//
// A parallel_for started while the pool is busy (nested in a task, or from another
// thread) runs its tasks on the calling thread, in order.
//
// Exceptions: every task runs even if another throws; then the exception of the task
// with the smallest index is rethrown on the caller.
#pragma once

#include <functional>

#include "idlib/core/types.h"

namespace lpvid {

void parallel_for(Index n, const std::function<void(Index)>& task);

// The threads parallel_for uses (the caller included): 1 + the pool's workers.
Index parallel_threads();

}  // namespace lpvid
