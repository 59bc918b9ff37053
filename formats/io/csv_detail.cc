#include "formats/io/csv_detail.h"

#include <fast_float/fast_float.h>
#include <fcntl.h>
#include <fmt/compile.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>

#include "idlib/core/error.h"

namespace lpvid::detail {

std::string display_path(const std::string& path) { return path == "-" ? "<stdin>" : path; }

void fail_at(const std::string& path, int64_t line, int64_t column, const std::string& what) {
  throw InputError(fmt::format("{}:{}:{}: {}", display_path(path), line, column, what));
}

std::string quote_cell(std::string_view text) {
  constexpr size_t kMaxShown = 40;  // keeps the message on one readable line
  if (text.size() <= kMaxShown) return fmt::format("'{}'", text);
  return fmt::format("'{}...'", text.substr(0, kMaxShown));
}

void advise_huge_pages(void* data, size_t bytes) {
  constexpr size_t kMinBytes = size_t{2} << 20;  // one huge page
  if (bytes < kMinBytes) return;
  const uintptr_t page = 4096;
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(data) + page - 1) & ~(page - 1);
  const uintptr_t end = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(page - 1);
#ifdef MADV_HUGEPAGE
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)begin;
  (void)end;
#endif
}

CellPosition NumericCsv::key_position(Index row) const {
  LPVID_ASSERT(!runs.empty() && row >= 0);
  auto it = std::upper_bound(runs.begin(), runs.end(), row, [](Index r, const Run& run) { return r < run.row; });
  LPVID_ASSERT(it != runs.begin());
  --it;
  return {it->line + (row - it->row), it->column};
}

namespace {

inline bool is_blank(char c) { return c == ' ' || c == '\t'; }

inline const char* skip_blanks(const char* p, const char* e) {
  while (p < e && is_blank(*p)) ++p;
  return p;
}

std::string_view trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && is_blank(s[b])) ++b;
  while (e > b && is_blank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

// The text of the cell starting at p (up to the next comma), trimmed.
std::string_view cell_text(const char* p, const char* e) {
  const char* q = p;
  while (q < e && *q != ',') ++q;
  return trim(std::string_view(p, static_cast<size_t>(q - p)));
}

// Per-column growable arrays of doubles in their own anonymous mappings:
// growing is an mremap (no copy), and the pages are backed by huge pages where
// the kernel allows (malloc/realloc would copy whenever glibc's adaptive mmap
// threshold puts a buffer on the heap).
class ColumnStore {
 public:
  explicit ColumnStore(size_t columns) : cols_(columns, nullptr) {}
  ~ColumnStore() {
    for (size_t j = 0; j < cols_.size(); ++j) release(j);
  }
  ColumnStore(const ColumnStore&) = delete;
  ColumnStore& operator=(const ColumnStore&) = delete;

  void grow() {
    // 2 MiB first (one huge page), then doubling.
    const size_t cap = capacity_ == 0 ? (size_t{2} << 20) / sizeof(double) : capacity_ * 2;
    for (double*& p : cols_) {
      void* q = p == nullptr ? ::mmap(nullptr, cap * sizeof(double), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0)
                             : ::mremap(p, capacity_ * sizeof(double), cap * sizeof(double), MREMAP_MAYMOVE);
      if (q == MAP_FAILED) throw std::bad_alloc();
      p = static_cast<double*>(q);
      advise_huge_pages(p, cap * sizeof(double));
    }
    capacity_ = cap;
  }
  double* column(size_t j) { return cols_[j]; }
  size_t capacity() const { return capacity_; }
  void release(size_t j) {
    if (cols_[j] != nullptr) ::munmap(cols_[j], capacity_ * sizeof(double));
    cols_[j] = nullptr;
  }

 private:
  std::vector<double*> cols_;
  size_t capacity_ = 0;
};

// Owns the file descriptor being read.
class Source {
 public:
  explicit Source(const std::string& path) : path_(path) {
    if (path == "-") {
      fd_ = STDIN_FILENO;
      return;
    }
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0)
      throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
    struct stat st;
    if (::fstat(fd_, &st) == 0 && S_ISDIR(st.st_mode)) {
      ::close(fd_);
      fd_ = -1;
      throw InputError(fmt::format("cannot open '{}': {}; give a file, not a directory", path, std::strerror(EISDIR)));
    }
  }
  ~Source() {
    if (fd_ > STDIN_FILENO) ::close(fd_);
  }
  Source(const Source&) = delete;
  Source& operator=(const Source&) = delete;

  // Reads up to size bytes; 0 at end of file.
  size_t read(char* into, size_t size) {
    for (;;) {
      const ssize_t n = ::read(fd_, into, size);
      if (n >= 0) return static_cast<size_t>(n);
      if (errno == EINTR) continue;
      throw InputError(fmt::format("cannot read '{}': {}; check the file", display_path(path_), std::strerror(errno)));
    }
  }

 private:
  std::string path_;
  int fd_ = -1;
};

// The read buffer is reused across calls on one thread: its pages are already
// mapped after the first file (BUILD-NOTES.md: first touch is expensive).
constexpr size_t kChunkBytes = size_t{4} << 20;

std::vector<char>& read_buffer() {
  thread_local std::vector<char> buffer;
  if (buffer.size() < kChunkBytes) buffer.resize(kChunkBytes);
  return buffer;
}

class Parser {
 public:
  Parser(NumericCsv& out, const std::string& key_name, const std::string& key_hint)
      : out_(out), key_name_(key_name), key_hint_(key_hint) {}

  // One line without its '\n'.  line_ is its 1-based number.
  void line(const char* b, const char* e) {
    ++line_;
    if (line_ == 1 && e - b >= 3 && std::memcmp(b, "\xEF\xBB\xBF", 3) == 0) b += 3;  // UTF-8 byte-order mark
    if (e > b && e[-1] == '\r') --e;
    if (have_header_) {
      row(b, e);
      return;
    }
    const char* p = skip_blanks(b, e);
    if (p == e) return;  // blank line
    if (*p == '#') {
      out_.leading_comments.push_back({line_, p + 1 - b + 1, std::string(p + 1, e)});
      return;
    }
    header(b, e);
  }

  void finish(bool file_empty) {
    out_.end_line = line_ + 1;
    if (!have_header_) {
      if (file_empty)
        fail_at(out_.path, 1, 1, "the file is empty; it must start with a header row naming the columns, e.g. 't,v1,q1'");
      fail_at(out_.path, out_.end_line, 1,
              "no header row, only comments and blank lines; the first other line must name the columns, e.g. 't,v1,q1'");
    }
    const size_t n = rows_;
    const size_t c = out_.names.size();
    out_.data.resize(static_cast<Index>(n), static_cast<Index>(c));
    advise_huge_pages(out_.data.data(), n * c * sizeof(double));
    for (size_t j = 0; j < c; ++j) {
      if (n > 0) std::memcpy(out_.data.data() + j * n, store_->column(j), n * sizeof(double));
      store_->release(j);
    }
  }

 private:
  void header(const char* b, const char* e) {
    have_header_ = true;
    out_.header_line = line_;
    const char* p = b;
    for (;;) {
      const char* q = p;
      while (q < e && *q != ',') ++q;
      std::string_view name = trim(std::string_view(p, static_cast<size_t>(q - p)));
      const char* first = skip_blanks(p, q);
      const int64_t column = first - b + 1;
      if (name.size() >= 2 && name.front() == '"' && name.back() == '"') name = name.substr(1, name.size() - 2);
      if (name.empty())
        fail_at(out_.path, line_, column,
                fmt::format("column {} of the header has no name; name every column", out_.names.size() + 1));
      if (name.find('"') != std::string_view::npos)
        fail_at(out_.path, line_, column,
                fmt::format("column name {} holds a quote; write names without quotes (or quote a whole name)", quote_cell(name)));
      for (size_t k = 0; k < out_.names.size(); ++k)
        if (out_.names[k] == name)
          fail_at(out_.path, line_, column,
                  fmt::format("duplicate column name '{}' (also column {}); give every column its own name", name, k + 1));
      out_.names.emplace_back(name);
      out_.name_columns.push_back(column);
      if (q == e) break;
      p = q + 1;
    }
    if (out_.names.size() == 1 &&
        out_.names[0].find_first_of(";\t") != std::string::npos)
      fail_at(out_.path, line_, 1,
              fmt::format("the header {} has a single column; separate columns with commas", quote_cell(out_.names[0])));
    auto it = std::find(out_.names.begin(), out_.names.end(), key_name_);
    if (it == out_.names.end())
      fail_at(out_.path, line_, 1, fmt::format("no column '{}' in the header; {}", key_name_, key_hint_));
    out_.key = it - out_.names.begin();
    columns_ = out_.names.size();
    store_ = std::make_unique<ColumnStore>(columns_);
  }

  [[noreturn]] void bad_cell(const char* b, const char* cell, const char* e, size_t j) {
    const std::string_view text = cell_text(cell, e);
    const int64_t column = cell - b + 1;
    if (text.empty())
      fail_at(out_.path, line_, column,
              fmt::format("empty cell in column '{}'; every cell after the header must be a number", out_.names[j]));
    fail_at(out_.path, line_, column,
            fmt::format("cannot parse {} as a number in column '{}'; every cell after the header must be a number",
                        quote_cell(text), out_.names[j]));
  }

  [[noreturn]] void wrong_count(const char* b, const char* e, const char* at) {
    const size_t cells = static_cast<size_t>(std::count(b, e, ',')) + 1;
    fail_at(out_.path, line_, at - b + 1,
            fmt::format("row has {} cells but the header names {} columns; give every row one cell per column", cells,
                        columns_));
  }

  void row(const char* b, const char* e) {
    const char* p = skip_blanks(b, e);
    if (p == e) return;          // blank line
    if (*p == '#') return;       // comment line
    if (rows_ == store_->capacity()) store_->grow();
    const size_t c = columns_;
    int64_t key_column = 0;
    for (size_t j = 0; j < c; ++j) {
      p = skip_blanks(p, e);
      const char* cell = p;
      if (j == static_cast<size_t>(out_.key)) key_column = cell - b + 1;
      if (p < e && *p == '+' && p + 1 < e && (p[1] == '.' || (p[1] >= '0' && p[1] <= '9'))) ++p;
      double value;
      const auto result = fast_float::from_chars(p, e, value);
      if (result.ec != std::errc()) bad_cell(b, cell, e, j);
      p = skip_blanks(result.ptr, e);
      if (j + 1 < c) {
        if (p == e) wrong_count(b, e, e);
        if (*p != ',') bad_cell(b, cell, e, j);
        ++p;
      } else if (p != e) {
        if (*p == ',') wrong_count(b, e, skip_blanks(p + 1, e));
        bad_cell(b, cell, e, j);
      }
      if (!std::isfinite(value))
        fail_at(out_.path, line_, cell - b + 1,
                fmt::format("{} in column '{}' is not a finite number; NaN/Inf not allowed, every cell must be a finite number",
                            quote_cell(cell_text(cell, e)), out_.names[j]));
      store_->column(j)[rows_] = value;
    }
    const int64_t delta = line_ - static_cast<int64_t>(rows_);
    if (out_.runs.empty() || delta != run_delta_ || key_column != out_.runs.back().column) {
      out_.runs.push_back({static_cast<Index>(rows_), line_, key_column});
      run_delta_ = delta;
    }
    ++rows_;
  }

  NumericCsv& out_;
  const std::string& key_name_;
  const std::string& key_hint_;
  std::unique_ptr<ColumnStore> store_;
  bool have_header_ = false;
  int64_t line_ = 0;
  size_t columns_ = 0;
  size_t rows_ = 0;
  int64_t run_delta_ = 0;
};

}  // namespace

NumericCsv read_numeric_csv(const std::string& path, const std::string& key_name, const std::string& key_hint) {
  NumericCsv out;
  out.path = path;
  Source source(path);
  Parser parser(out, key_name, key_hint);
  std::vector<char>& buffer = read_buffer();
  size_t have = 0;  // bytes in buffer
  bool any = false;
  for (;;) {
    const size_t n = source.read(buffer.data() + have, buffer.size() - have);
    if (n > 0) any = true;
    have += n;
    const char* p = buffer.data();
    const char* end = p + have;
    for (;;) {
      const char* nl = static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(end - p)));
      if (nl == nullptr) break;
      parser.line(p, nl);
      p = nl + 1;
    }
    const size_t rest = static_cast<size_t>(end - p);
    if (n == 0) {  // end of file
      if (rest > 0) parser.line(p, end);
      break;
    }
    std::memmove(buffer.data(), p, rest);
    have = rest;
    if (have == buffer.size()) buffer.resize(buffer.size() * 2);  // a line longer than the buffer
  }
  parser.finish(!any);
  return out;
}

void check_header_names(const std::string& path, const std::vector<std::string>& names) {
  for (size_t j = 0; j < names.size(); ++j) {
    const std::string& name = names[j];
    const bool bad = name.empty() || name != trim(name) || name.front() == '#' ||
                     name.find_first_of(",\"\r\n") != std::string::npos;
    if (bad)
      throw InputError(fmt::format(
          "cannot write '{}': column name {} is not allowed; a name is non-empty, has no comma, quote or line break, "
          "no surrounding blanks and does not start with '#'",
          display_path(path), quote_cell(name)));
    for (size_t k = 0; k < j; ++k)
      if (names[k] == name)
        throw InputError(fmt::format("cannot write '{}': duplicate column name '{}'; give every column its own name",
                                     display_path(path), name));
  }
}

void append_comments(std::string& out, const std::vector<std::string>& comments) {
  for (const std::string& comment : comments) {
    size_t start = 0;
    for (;;) {
      const size_t nl = comment.find('\n', start);
      std::string_view piece(comment.data() + start, (nl == std::string::npos ? comment.size() : nl) - start);
      if (!piece.empty() && piece.back() == '\r') piece.remove_suffix(1);
      out += piece.empty() ? "#" : "# ";
      out += piece;
      out += '\n';
      if (nl == std::string::npos) break;
      start = nl + 1;
    }
  }
}

void write_numeric_rows(AtomicFileWriter& out, std::string head, const Eigen::MatrixXd& rows,
                        const std::vector<std::string>& names, int64_t first_data_line) {
  LPVID_ASSERT(static_cast<Index>(names.size()) == rows.cols());
  const Index n = rows.rows();
  const Index c = rows.cols();
  out.write(head);
  // Longest shortest-round-trip double: "-2.2250738585072014e-308" (24 bytes).
  constexpr size_t kMaxNumber = 32;
  constexpr size_t kBlock = size_t{1} << 20;
  const size_t row_bytes = static_cast<size_t>(c) * (kMaxNumber + 1) + 1;
  const size_t capacity = kBlock + row_bytes;
  std::unique_ptr<char[]> block(new char[capacity]);
  char* const begin = block.get();
  char* p = begin;
  for (Index i = 0; i < n; ++i) {
    if (static_cast<size_t>(p - begin) + row_bytes > capacity) {
      out.write(std::string_view(begin, static_cast<size_t>(p - begin)));
      p = begin;
    }
    for (Index j = 0; j < c; ++j) {
      const double v = rows(i, j);
      if (!std::isfinite(v))
        throw InputError(fmt::format("cannot write '{}': row {} (line {}), column '{}' holds {}; only finite numbers "
                                     "can be written, check the computation that produced it",
                                     display_path(out.path()), i + 1, first_data_line + i,
                                     names[static_cast<size_t>(j)], v));
      if (j > 0) *p++ = ',';
      p = fmt::format_to(p, FMT_COMPILE("{}"), v);
    }
    *p++ = '\n';
  }
  out.write(std::string_view(begin, static_cast<size_t>(p - begin)));
}

}  // namespace lpvid::detail
