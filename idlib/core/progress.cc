#include "idlib/core/progress.h"

#include <algorithm>
#include <exception>

namespace lpvid {

void NestedProgress::report(const ProgressStep& step) noexcept {
  if (parent_ == nullptr) return;
  try {
    std::string task = prefix_;
    if (!step.task.empty()) {
      task += ", ";
      task += step.task;
    }
    ProgressStep nested = step;
    nested.task = task;
    parent_->report(nested);
  } catch (const std::exception&) {
    // out of memory for a few characters: the report is dropped, the computation goes on
  }
}

void ParallelSteps::start(const std::string& name) noexcept {
  if (progress_ == nullptr) return;
  try {
    std::lock_guard<std::mutex> lock(m_);
    ++started_;
    running_.push_back(name);
    emit();
  } catch (const std::exception&) {
  }
}

void ParallelSteps::finish(const std::string& name) noexcept {
  if (progress_ == nullptr) return;
  try {
    std::lock_guard<std::mutex> lock(m_);
    ++finished_;
    const auto it = std::find(running_.begin(), running_.end(), name);
    if (it != running_.end()) running_.erase(it);
    emit();
  } catch (const std::exception&) {
  }
}

void ParallelSteps::emit() {
  std::string names;
  for (auto it = running_.rbegin(); it != running_.rend(); ++it) {
    if (!names.empty()) names += ", ";
    names += *it;
  }
  ProgressStep s;
  s.task = task_;
  s.step = step_;
  s.index = started_;
  s.count = count_;
  s.detail = names;
  s.fraction = count_ > 0 ? static_cast<double>(finished_) / static_cast<double>(count_) : -1.0;
  progress_->report(s);
}

}  // namespace lpvid
