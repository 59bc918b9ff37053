#include "idlib/core/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace lpvid {
namespace {

// The pool never grows past this many workers (identify's tasks come in twos and
// threes; more threads would only wait).
constexpr unsigned kMaxWorkers = 7;

class Pool {
 public:
  Pool() {
    unsigned hw = std::max(1u, std::thread::hardware_concurrency());
    if (const char* env = std::getenv("LPVID_THREADS")) {
      const long want = std::strtol(env, nullptr, 10);
      if (want >= 1) hw = static_cast<unsigned>(std::min<long>(want, kMaxWorkers + 1));
    }
    const unsigned workers = std::min(hw - 1, kMaxWorkers);
    for (unsigned w = 0; w < workers; ++w) threads_.emplace_back([this] { work(); });
  }
  ~Pool() {
    {
      std::lock_guard<std::mutex> lock(m_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& t : threads_) t.join();
  }
  Index threads() const { return 1 + static_cast<Index>(threads_.size()); }

  // false: the pool is busy (or has no workers); the caller runs the tasks itself.
  bool run(Index n, const std::function<void(Index)>& task) {
    if (threads_.empty()) return false;
    // A flag, not a mutex: a nested call comes from a thread that may hold it already.
    if (busy_.exchange(true)) return false;
    struct Release {
      std::atomic<bool>& flag;
      ~Release() { flag = false; }
    } release{busy_};
    errors_.assign(static_cast<std::size_t>(n), nullptr);
    {
      std::lock_guard<std::mutex> lock(m_);
      task_ = &task;
      n_ = n;
      next_ = 0;
      pending_ = n;
      ++generation_;
    }
    wake_.notify_all();
    drain();
    {
      std::unique_lock<std::mutex> lock(m_);
      done_.wait(lock, [&] { return pending_ == 0 && active_ == 0; });
      task_ = nullptr;
    }
    for (auto& e : errors_)
      if (e) std::rethrow_exception(e);
    return true;
  }

 private:
  // Takes task indices until none are left.
  void drain() {
    for (;;) {
      const Index i = next_.fetch_add(1);
      if (i >= n_) return;
      try {
        (*task_)(i);
      } catch (...) {
        errors_[static_cast<std::size_t>(i)] = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(m_);
      if (--pending_ == 0) done_.notify_all();
    }
  }
  void work() {
    std::uint64_t seen = 0;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(m_);
        wake_.wait(lock, [&] { return stop_ || (generation_ != seen && task_ != nullptr); });
        if (stop_) return;
        seen = generation_;
        ++active_;
      }
      drain();
      std::lock_guard<std::mutex> lock(m_);
      if (--active_ == 0 && pending_ == 0) done_.notify_all();
    }
  }

  std::vector<std::thread> threads_;
  std::atomic<bool> busy_{false};  // one parallel_for at a time
  std::mutex m_;
  std::condition_variable wake_, done_;
  bool stop_ = false;
  std::uint64_t generation_ = 0;
  const std::function<void(Index)>* task_ = nullptr;
  Index n_ = 0, pending_ = 0;
  int active_ = 0;
  std::atomic<Index> next_{0};
  std::vector<std::exception_ptr> errors_;
};

Pool& pool() {
  static Pool p;
  return p;
}

}  // namespace

Index parallel_threads() { return pool().threads(); }

void parallel_for(Index n, const std::function<void(Index)>& task) {
  if (n <= 0) return;
  if (n > 1 && pool().run(n, task)) return;
  std::exception_ptr first;
  for (Index i = 0; i < n; ++i) {
    try {
      task(i);
    } catch (...) {
      if (!first) first = std::current_exception();
    }
  }
  if (first) std::rethrow_exception(first);
}

}  // namespace lpvid
