#include "cli/progress_line.h"

#include <fmt/format.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <exception>

namespace lpvid::cli {
namespace {

// Code points in UTF-8 text (continuation bytes 10xxxxxx do not start one).
std::size_t code_points(std::string_view s) {
  std::size_t n = 0;
  for (const char c : s) n += (static_cast<unsigned char>(c) & 0xC0) != 0x80 ? 1 : 0;
  return n;
}

// The first `keep` code points of s.
std::string first_code_points(std::string_view s, std::size_t keep) {
  std::size_t n = 0, i = 0;
  for (; i < s.size(); ++i) {
    if ((static_cast<unsigned char>(s[i]) & 0xC0) != 0x80) {
      if (n == keep) break;
      ++n;
    }
  }
  return std::string(s.substr(0, i));
}

// Control characters (a name read from a file) would move the cursor: shown as '?'.
void append_printable(std::string& out, std::string_view s) {
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    out += (u < 0x20 || u == 0x7F) ? '?' : c;
  }
}

void write_stderr(std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t w = ::write(STDERR_FILENO, bytes.data(), bytes.size());
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;  // a closed or full stderr: the progress line is not worth an error
    bytes.remove_prefix(static_cast<std::size_t>(w));
  }
}

int stderr_columns() {
  winsize ws{};
  if (::ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) return ws.ws_col;
  return 0;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string ProgressLine::elapsed_text(double seconds) {
  const long s = std::max(0L, static_cast<long>(std::floor(seconds)));
  if (s < 60) return fmt::format("{} s", s);
  if (s < 3600) return fmt::format("{} min {:02} s", s / 60, s % 60);
  return fmt::format("{} h {:02} min", s / 3600, (s % 3600) / 60);
}

std::string ProgressLine::compose(const ProgressStep& step, double elapsed_s, int columns) {
  std::string text;
  append_printable(text, step.task);
  if (!step.step.empty() || step.index > 0) {
    if (!text.empty()) text += ": ";
    append_printable(text, step.step);
    if (step.index > 0) text += fmt::format("{}{}", step.step.empty() ? "" : " ", step.index);
    if (step.count > 0) text += fmt::format(" of {}", step.count);
  }
  if (!step.detail.empty()) {
    if (!text.empty()) text += ": ";
    append_printable(text, step.detail);
  }
  double fraction = step.fraction;
  if (fraction < 0 && step.count > 0 && step.index > 0)
    fraction = static_cast<double>(step.index - 1) / static_cast<double>(step.count);
  std::string tail;
  if (fraction >= 0) {
    const int filled = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * kBarCells));
    tail = " [" + std::string(static_cast<std::size_t>(filled), '#') +
           std::string(static_cast<std::size_t>(kBarCells - filled), '-') + "]";
  }
  tail += tail.empty() ? " (" + elapsed_text(elapsed_s) + ")" : " " + elapsed_text(elapsed_s);

  // One column short of the width: a line that fills the last column wraps on some terminals.
  const std::size_t limit = static_cast<std::size_t>(std::max(1, (columns > 0 ? columns : kFallbackColumns) - 1));
  const std::size_t need = code_points(text) + code_points(tail);
  if (need <= limit) return text + tail;
  constexpr std::string_view kCut = "...";
  constexpr std::size_t kMinText = 8;  // below this much text, the bar goes first
  if (code_points(tail) + kCut.size() + kMinText <= limit)
    return first_code_points(text, limit - code_points(tail) - kCut.size()) + std::string(kCut) + tail;
  return first_code_points(text + tail, limit);
}

ProgressLine::ProgressLine(Io io) : io_(std::move(io)) { t0_ = io_.now_s(); }

void ProgressLine::report(const ProgressStep& step) noexcept {
  try {
    std::lock_guard<std::mutex> lock(m_);
    if (closed_) return;
    task_.assign(step.task);
    step_.assign(step.step);
    detail_.assign(step.detail);
    current_ = step;
    current_.task = task_;
    current_.step = step_;
    current_.detail = detail_;
    have_ = true;
    const double now = io_.now_s();
    if (!shown_ || now - last_draw_ >= kMinIntervalS) draw_locked(now);
  } catch (const std::exception&) {
    // a report that cannot be stored is dropped; the computation goes on
  }
}

void ProgressLine::tick() noexcept {
  try {
    std::lock_guard<std::mutex> lock(m_);
    if (!have_ || closed_) return;
    const double now = io_.now_s();
    if (now - last_draw_ >= kMinIntervalS) draw_locked(now);
  } catch (const std::exception&) {
  }
}

void ProgressLine::clear() noexcept {
  try {
    std::lock_guard<std::mutex> lock(m_);
    if (shown_) io_.write("\r\x1b[K");
    shown_ = false;
    have_ = false;
    last_line_.clear();
  } catch (const std::exception&) {
  }
}

void ProgressLine::close() noexcept {
  clear();
  std::lock_guard<std::mutex> lock(m_);
  closed_ = true;
}

void ProgressLine::draw_locked(double now) {
  std::string line = compose(current_, now - t0_, io_.columns ? io_.columns() : 0);
  if (shown_ && line == last_line_) return;
  io_.write("\r" + line + "\x1b[K");
  last_line_ = std::move(line);
  last_draw_ = now;
  shown_ = true;
}

bool progress_enabled() {
  if (const char* env = std::getenv("LPVID_PROGRESS")) {
    if (std::string_view(env) == "0") return false;
    if (std::string_view(env) == "1") return true;
  }
  // A terminal that cannot erase a line (TERM=dumb: Emacs' shell, some CI consoles)
  // would show every update one after another.
  const char* term = std::getenv("TERM");
  if (term != nullptr && std::string_view(term) == "dumb") return false;
  return ::isatty(STDERR_FILENO) == 1;
}

TerminalProgress::TerminalProgress() {
  if (!progress_enabled()) return;
  line_ = std::make_unique<ProgressLine>(ProgressLine::Io{write_stderr, steady_seconds, stderr_columns});
  ticker_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(m_);
    const auto period = std::chrono::duration<double>(ProgressLine::kMinIntervalS);
    while (!wake_.wait_for(lock, period, [this] { return stop_; })) line_->tick();
  });
}

TerminalProgress::~TerminalProgress() { finish(); }

void TerminalProgress::finish() {
  if (!line_) return;
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  wake_.notify_all();
  if (ticker_.joinable()) ticker_.join();
  line_->close();
}

}  // namespace lpvid::cli
