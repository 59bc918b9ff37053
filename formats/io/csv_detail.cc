#include "formats/io/csv_detail.h"

#include <fast_float/fast_float.h>
#include <fcntl.h>
#include <fmt/compile.h>
#include <fmt/format.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <thread>
#include <unordered_map>

#include "idlib/core/error.h"

namespace lpvid::detail {

std::string display_path(const std::string& path) { return path == "-" ? "<stdin>" : path; }

std::string one_line_message(std::string_view what) {
  // Bounds of the readers' messages (fuzz/readers.h allows 1000 bytes with the path).
  constexpr size_t kMaxWhat = 900, kHead = 450, kTail = 400;
  std::string shown;
  for (const char c : what) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F)
      shown += fmt::format("\\x{:02X}", static_cast<unsigned>(static_cast<unsigned char>(c)));
    else
      shown += c;
  }
  if (shown.size() > kMaxWhat) shown = shown.substr(0, kHead) + " ... " + shown.substr(shown.size() - kTail);
  return shown;
}

void fail_at(const std::string& path, int64_t line, int64_t column, const std::string& what) {
  throw InputError(fmt::format("{}:{}:{}: {}", display_path(path), line, column, one_line_message(what)));
}

std::string quote_cell(std::string_view text) {
  constexpr size_t kMaxShown = 40;  // keeps the message on one readable line
  std::string shown = "'";
  for (const char c : text.substr(0, kMaxShown)) {
    // Control bytes (NUL, line breaks, escapes) would cut or break the line: shown as \xNN.
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F)
      shown += fmt::format("\\x{:02X}", static_cast<unsigned>(static_cast<unsigned char>(c)));
    else
      shown += c;
  }
  shown += text.size() > kMaxShown ? "...'" : "'";
  return shown;
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

[[noreturn]] void changed_while_reading(const std::string& path) {
  throw InputError(fmt::format("{}: the file changed while it was read; read it again once it is complete",
                               display_path(path)));
}

// Threads that read one regular file at most (each with its own read buffer).
constexpr size_t kMaxThreads = 4;

// Per-column growable arrays of doubles in their own anonymous mappings, for
// input of unknown length (stdin, pipes): growing is an mremap (no copy), and
// the pages are backed by huge pages where the kernel allows (malloc/realloc
// would copy whenever glibc's adaptive mmap threshold puts a buffer on the heap).
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

// Owns the file descriptor being read.  A regular file is read with pread at
// explicit offsets (so several threads can read parts of it); anything else
// (stdin, a pipe) sequentially.
class Source {
 public:
  explicit Source(const std::string& path) : path_(path) {
    if (path == "-") {
      fd_ = STDIN_FILENO;
    } else {
      fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
      if (fd_ < 0)
        throw InputError(fmt::format("cannot open '{}': {}; check the path", path, std::strerror(errno)));
    }
    struct stat st;
    if (::fstat(fd_, &st) != 0) return;
    if (S_ISDIR(st.st_mode)) {
      if (fd_ > STDIN_FILENO) ::close(fd_);
      fd_ = -1;
      throw InputError(fmt::format("cannot open '{}': {}; give a file, not a directory", path, std::strerror(EISDIR)));
    }
    if (S_ISREG(st.st_mode) && path != "-") {
      regular_ = true;
      size_ = static_cast<uint64_t>(st.st_size);
    }
  }
  // Text already in memory (stdin read whole to detect its content): read as
  // a regular file of that size.
  Source(const std::string& path, std::string_view text)
      : path_(path), memory_(text), in_memory_(true), regular_(true), size_(text.size()) {}
  ~Source() {
    if (fd_ > STDIN_FILENO) ::close(fd_);
  }
  Source(const Source&) = delete;
  Source& operator=(const Source&) = delete;

  bool regular() const { return regular_; }
  uint64_t size() const { return size_; }  // of a regular file, at open

  // Reads up to size bytes at offset (a regular file) or the next bytes (else);
  // 0 at end of file.
  size_t fetch(char* into, size_t size, uint64_t offset) {
    if (in_memory_) {
      if (offset >= memory_.size()) return 0;
      const size_t n = std::min<size_t>(size, memory_.size() - offset);
      std::memcpy(into, memory_.data() + offset, n);
      return n;
    }
    for (;;) {
      const ssize_t n = regular_ ? ::pread(fd_, into, size, static_cast<off_t>(offset)) : ::read(fd_, into, size);
      if (n >= 0) return static_cast<size_t>(n);
      if (errno == EINTR) continue;
      throw InputError(fmt::format("cannot read '{}': {}; check the file", display_path(path_), std::strerror(errno)));
    }
  }

 private:
  std::string path_;
  std::string_view memory_;
  bool in_memory_ = false;
  int fd_ = -1;
  bool regular_ = false;
  uint64_t size_ = 0;
};

// Read buffers are reused across calls and threads: their pages are already
// mapped after the first file (BUILD-NOTES.md: first touch is expensive).
constexpr size_t kChunkBytes = size_t{4} << 20;
// Bytes kept free after the data in a read buffer, so that number parsing may
// load 8 bytes at any position up to the end of the data.
constexpr size_t kPadBytes = 64;
constexpr size_t kMaxPooledBuffers = 4;  // one per reading thread (kMaxThreads)

class PooledBuffer {
 public:
  PooledBuffer() {
    {
      std::lock_guard<std::mutex> lock(mutex());
      if (!pool().empty()) {
        buffer_ = std::move(pool().back());
        pool().pop_back();
      }
    }
    if (buffer_.size() < kChunkBytes) buffer_.resize(kChunkBytes);
  }
  ~PooledBuffer() {
    if (buffer_.size() != kChunkBytes) return;  // grown for a very long line: let it go
    std::lock_guard<std::mutex> lock(mutex());
    if (pool().size() < kMaxPooledBuffers) pool().push_back(std::move(buffer_));
  }
  PooledBuffer(const PooledBuffer&) = delete;
  PooledBuffer& operator=(const PooledBuffer&) = delete;
  std::vector<char>& get() { return buffer_; }

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static std::vector<std::vector<char>>& pool() {
    static std::vector<std::vector<char>> p;
    return p;
  }
  std::vector<char> buffer_;
};

constexpr uint64_t kToEnd = std::numeric_limits<uint64_t>::max();

// Thrown by scan_lines for a line longer than kMaxCsvLineBytes; the caller
// knows the line number and turns it into an InputError.
struct LineTooLong {
  uint64_t line_start;  // file offset of the line's first byte
};

[[noreturn]] void fail_line_too_long(const std::string& path, int64_t line) {
  fail_at(path, line, 1,
          fmt::format("line longer than {} MiB; a CSV line holds one row of numbers: check that this is the right "
                      "file (not a binary or a device)",
                      kMaxCsvLineBytes >> 20));
}

// Calls on_line(b, e) for every line of the bytes [begin, end) of source, without
// its '\n' (a last line without '\n' included), reading in chunks through buffer.
// on_line returns false to stop.  Returns the offset just after the line where
// it stopped, or after the last byte read.
template <typename OnLine>
uint64_t scan_lines(Source& source, uint64_t begin, uint64_t end, std::vector<char>& buffer, OnLine&& on_line) {
  uint64_t base_offset = begin;  // file offset of buffer[0]
  uint64_t next = begin;         // file offset of the next byte to fetch
  size_t have = 0;               // bytes in buffer
  for (;;) {
    const size_t want = static_cast<size_t>(std::min<uint64_t>(buffer.size() - kPadBytes - have, end - next));
    const size_t n = want == 0 ? 0 : source.fetch(buffer.data() + have, want, next);
    next += n;
    have += n;
    const char* const base = buffer.data();
    const char* const stop = base + have;
    const char* p = base;
    for (;;) {
      const char* nl = static_cast<const char*>(std::memchr(p, '\n', static_cast<size_t>(stop - p)));
      if (nl == nullptr) break;
      if (static_cast<size_t>(nl - p) > kMaxCsvLineBytes) throw LineTooLong{base_offset + static_cast<uint64_t>(p - base)};
      if (!on_line(p, nl)) return base_offset + static_cast<uint64_t>(nl + 1 - base);
      p = nl + 1;
    }
    const size_t rest = static_cast<size_t>(stop - p);
    if (n == 0) {  // end of file (or of the range)
      if (rest > kMaxCsvLineBytes) throw LineTooLong{base_offset + static_cast<uint64_t>(p - base)};
      if (rest > 0) on_line(p, stop);
      return base_offset + have;
    }
    std::memmove(buffer.data(), p, rest);
    base_offset += have - rest;
    have = rest;
    if (have == buffer.size() - kPadBytes) {  // a line longer than the buffer
      if (have > kMaxCsvLineBytes) throw LineTooLong{base_offset};
      buffer.resize(buffer.size() * 2);
    }
  }
}

// Reads the digits at q (at most 8, not past e) as an integer m; returns how
// many.  Reads 8 bytes at q: the read buffer has kPadBytes after its data.
// SWAR digit test and conversion as in fast_float's parse_eight_digits_unrolled.
inline size_t take_digits(const char* q, const char* e, uint64_t& m) {
  uint64_t w;
  std::memcpy(&w, q, sizeof w);
  const uint64_t x = w ^ 0x3030303030303030;  // digit bytes become 0..9
  // High bit of a byte set iff x >= 10 there (no carries between bytes).
  const uint64_t non_digit = (((x & 0x7F7F7F7F7F7F7F7F) + 0x7676767676767676) | x) & 0x8080808080808080;
  size_t n = non_digit == 0 ? 8 : static_cast<size_t>(std::countr_zero(non_digit)) / 8;  // little-endian
  n = std::min(n, static_cast<size_t>(e - q));
  if (n == 0) {
    m = 0;
    return 0;
  }
  uint64_t v = x << (8 * (8 - n));  // the n digits as the last of 8, after leading zeros
  v = v * 10 + (v >> 8);
  v = (((v & 0x000000FF000000FF) * (100 + (uint64_t{1000000} << 32))) +
       (((v >> 16) & 0x000000FF000000FF) * (1 + (uint64_t{10000} << 32)))) >> 32;
  m = static_cast<uint32_t>(v);
  return n;
}

inline bool is_digit(const char* q, const char* e) { return q < e && static_cast<unsigned>(*q - '0') < 10; }

// The common cell "[-]digits[.digits]" (no exponent) with at most 8 digits
// before and 8 after the point, all digits as an integer m <= 2^53: then m and
// 10^k are exact doubles and one division gives the correctly rounded value,
// bit-identical to fast_float (whose fast path is the same: Clinger 1990).
// Returns the end of the number, or nullptr to use the general parser.
inline const char* parse_plain_decimal(const char* p, const char* e, double& value) {
  static constexpr uint64_t kPow10Int[] = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000};
  static constexpr double kPow10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8};
  const char* q = p;
  const bool negative = q < e && *q == '-';
  if (negative) ++q;
  uint64_t m = 0;
  const size_t whole = take_digits(q, e, m);
  q += whole;
  size_t fraction = 0;
  if (q < e && *q == '.') {
    ++q;
    uint64_t f = 0;
    fraction = take_digits(q, e, f);
    q += fraction;
    m = m * kPow10Int[fraction] + f;
  }
  constexpr uint64_t kMaxExact = uint64_t{1} << 53;
  if (whole + fraction == 0 || m > kMaxExact || is_digit(q, e) || (q < e && (*q == 'e' || *q == 'E'))) return nullptr;
  const double x = static_cast<double>(m) / kPow10[fraction];
  value = negative ? -x : x;
  return q;
}

// Whether a line after the header holds a row (not blank, not a comment): the
// same test as RowParser::line.
inline bool is_row_line(const char* b, const char* e) {
  if (e > b && e[-1] == '\r') --e;
  const char* p = skip_blanks(b, e);
  return p != e && *p != '#';
}

// The lines up to and including the header row.
class HeaderParser {
 public:
  HeaderParser(NumericCsv& out, const std::string& key_name, const std::string& key_hint)
      : out_(out), key_name_(key_name), key_hint_(key_hint) {}

  bool done() const { return have_header_; }
  int64_t lines() const { return line_; }

  // One line without its '\n'; line number lines() + 1.  Returns done().
  bool line(const char* b, const char* e) {
    ++line_;
    if (line_ == 1 && e - b >= 3 && std::memcmp(b, "\xEF\xBB\xBF", 3) == 0) b += 3;  // UTF-8 byte-order mark
    if (e > b && e[-1] == '\r') --e;
    const char* p = skip_blanks(b, e);
    if (p == e) return false;  // blank line
    if (*p == '#') {
      out_.leading_comments.push_back({line_, p + 1 - b + 1, std::string(p + 1, e)});
      return false;
    }
    header(b, e);
    return true;
  }

  // At the end of the input without a header: throws.
  [[noreturn]] void fail_no_header(bool file_empty) const {
    if (file_empty)
      fail_at(out_.path, 1, 1, "the file is empty; give a file that starts with a header row naming the columns, e.g. 't,v1,q1'");
    fail_at(out_.path, line_ + 1, 1,
            "no header row, only comments and blank lines; add a header row naming the columns, e.g. 't,v1,q1'");
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
      if (out_.names.size() == kMaxCsvColumns)
        fail_at(out_.path, line_, column,
                fmt::format("the header has more than {} columns; lpvid reads at most {}: check that this is the "
                            "right file, or split it",
                            kMaxCsvColumns, kMaxCsvColumns));
      const auto [seen, fresh] = seen_.emplace(std::string(name), out_.names.size());
      if (!fresh)
        fail_at(out_.path, line_, column,
                fmt::format("duplicate column name '{}' (also column {}); give every column its own name", name,
                            seen->second + 1));
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
  }

  NumericCsv& out_;
  const std::string& key_name_;
  const std::string& key_hint_;
  std::unordered_map<std::string, size_t> seen_;  // name -> column (duplicates in O(1))
  bool have_header_ = false;
  int64_t line_ = 0;
};

// The lines after the header: rows of numbers written to columns (column j of
// row r at cols[j][r]).  Either into a ColumnStore that grows (input of unknown
// length), or into a fixed capacity of rows counted beforehand.
class RowParser {
 public:
  // Lines from first_line on; runs record rows from first_row on.
  RowParser(const NumericCsv& csv, int64_t first_line, size_t first_row, std::vector<NumericCsv::Run>& runs)
      : csv_(csv), runs_(runs), line_(first_line - 1), first_row_(first_row), columns_(csv.names.size()),
        key_(static_cast<size_t>(csv.key)), cols_(columns_, nullptr) {}

  void grow_into(ColumnStore* store) { store_ = store; }
  void write_into(double* const* cols, size_t capacity) {
    std::copy(cols, cols + columns_, cols_.begin());
    capacity_ = capacity;
  }

  size_t rows() const { return rows_; }
  int64_t last_line() const { return line_; }

  // One line without its '\n'; line number last_line() + 1.
  void line(const char* b, const char* e) {
    ++line_;
    if (e > b && e[-1] == '\r') --e;
    const char* p = skip_blanks(b, e);
    if (p == e) return;     // blank line
    if (*p == '#') return;  // comment line
    row(b, p, e);
  }

 private:
  [[noreturn]] void bad_cell(const char* b, const char* cell, const char* e, size_t j) const {
    const std::string_view text = cell_text(cell, e);
    const int64_t column = cell - b + 1;
    if (text.empty())
      fail_at(csv_.path, line_, column,
              fmt::format("empty cell in column '{}'; write a number there (every cell after the header is a number)", csv_.names[j]));
    fail_at(csv_.path, line_, column,
            fmt::format("cannot parse {} as a number in column '{}'; write a number there (every cell after the header is a number)",
                        quote_cell(text), csv_.names[j]));
  }

  [[noreturn]] void wrong_count(const char* b, const char* e, const char* at) const {
    const size_t cells = static_cast<size_t>(std::count(b, e, ',')) + 1;
    fail_at(csv_.path, line_, at - b + 1,
            fmt::format("row has {} cells but the header names {} columns; give every row one cell per column", cells,
                        columns_));
  }

  [[noreturn]] void not_finite(const char* b, const char* cell, const char* e, size_t j) const {
    fail_at(csv_.path, line_, cell - b + 1,
            fmt::format("{} in column '{}' is not a finite number; write a finite number there (NaN/Inf not allowed)",
                        quote_cell(cell_text(cell, e)), csv_.names[j]));
  }

  void make_room() {
    if (store_ == nullptr) changed_while_reading(csv_.path);
    store_->grow();
    for (size_t j = 0; j < columns_; ++j) cols_[j] = store_->column(j);
    capacity_ = store_->capacity();
  }

  // The general number syntax (fast_float, and '+' before a digit or '.').
  const char* parse_general(const char* b, const char* cell, const char* e, size_t j, double& value) const {
    const char* p = cell;
    if (p < e && *p == '+' && p + 1 < e && (p[1] == '.' || (p[1] >= '0' && p[1] <= '9'))) ++p;
    const auto result = fast_float::from_chars(p, e, value);
    if (result.ec != std::errc()) bad_cell(b, cell, e, j);
    return result.ptr;
  }

  // p: the first non-blank byte of the row.
  void row(const char* b, const char* p, const char* e) {
    if (rows_ == capacity_) make_room();
    const size_t c = columns_;
    const size_t r = rows_;
    int64_t key_column = 0;
    for (size_t j = 0; j < c; ++j) {
      const char* cell = p;
      if (j == key_) key_column = cell - b + 1;
      double value;
      const char* q = parse_plain_decimal(p, e, value);
      const bool general = q == nullptr;
      if (general) q = parse_general(b, cell, e, j, value);
      if (j + 1 < c) {
        if (q == e || *q != ',') {
          q = skip_blanks(q, e);
          if (q == e) wrong_count(b, e, e);
          if (*q != ',') bad_cell(b, cell, e, j);
        }
        p = q + 1;
        if (p < e && is_blank(*p)) p = skip_blanks(p, e);
      } else if (q != e) {
        q = skip_blanks(q, e);
        if (q != e) {
          if (*q == ',') wrong_count(b, e, skip_blanks(q + 1, e));
          bad_cell(b, cell, e, j);
        }
      }
      if (general && !std::isfinite(value)) not_finite(b, cell, e, j);
      cols_[j][r] = value;
    }
    const int64_t delta = line_ - static_cast<int64_t>(first_row_ + r);
    if (runs_.empty() || delta != run_delta_ || key_column != runs_.back().column) {
      runs_.push_back({static_cast<Index>(first_row_ + r), line_, key_column});
      run_delta_ = delta;
    }
    rows_ = r + 1;
  }

  const NumericCsv& csv_;
  std::vector<NumericCsv::Run>& runs_;
  int64_t line_;
  size_t first_row_;
  size_t columns_;
  size_t key_;
  std::vector<double*> cols_;
  ColumnStore* store_ = nullptr;
  size_t capacity_ = 0;
  size_t rows_ = 0;
  int64_t run_delta_ = 0;
};

// Input of unknown length (stdin, a pipe): one pass into growing columns, then
// one copy into the matrix.
void read_stream(Source& source, NumericCsv& out, HeaderParser& header) {
  PooledBuffer buffer;
  std::unique_ptr<ColumnStore> store;
  std::optional<RowParser> rows;
  uint64_t read = 0;
  try {
    read = scan_lines(source, 0, kToEnd, buffer.get(), [&](const char* b, const char* e) {
      if (rows) {
        rows->line(b, e);
      } else if (header.line(b, e)) {
        store = std::make_unique<ColumnStore>(out.names.size());
        rows.emplace(out, header.lines() + 1, 0, out.runs);
        rows->grow_into(store.get());
      }
      return true;
    });
  } catch (const LineTooLong&) {
    fail_line_too_long(out.path, (rows ? rows->last_line() : header.lines()) + 1);
  }
  if (!rows) header.fail_no_header(read == 0);
  out.end_line = rows->last_line() + 1;
  const size_t n = rows->rows();
  const size_t c = out.names.size();
  out.data.resize(static_cast<Index>(n), static_cast<Index>(c));
  advise_huge_pages(out.data.data(), n * c * sizeof(double));
  for (size_t j = 0; j < c; ++j) {
    if (n > 0) std::memcpy(out.data.data() + j * n, store->column(j), n * sizeof(double));
    store->release(j);
  }
}

// Runs task(k) for k = 0 .. parts - 1, part 0 on this thread and the others on
// their own threads; rethrows the exception of the lowest-numbered part that
// threw (the first error in file order).
template <typename Task>
void run_parts(size_t parts, Task&& task) {
  std::vector<std::exception_ptr> errors(parts);
  std::vector<std::thread> threads;
  threads.reserve(parts - 1);
  auto guarded = [&](size_t k) {
    try {
      task(k);
    } catch (...) {
      errors[k] = std::current_exception();
    }
  };
  for (size_t k = 1; k < parts; ++k) threads.emplace_back(guarded, k);
  guarded(0);
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

// The start of the first line at or after offset `at` in [begin, end], `begin`
// being a line start; end if there is none.
uint64_t line_start_at(Source& source, uint64_t begin, uint64_t end, uint64_t at) {
  if (at <= begin) return begin;
  char probe[4096];
  for (uint64_t p = at - 1; p < end;) {
    const size_t n = source.fetch(probe, static_cast<size_t>(std::min<uint64_t>(sizeof probe, end - p)), p);
    if (n == 0) break;
    if (const void* nl = std::memchr(probe, '\n', n)) return p + static_cast<uint64_t>(static_cast<const char*>(nl) - probe) + 1;
    p += n;
  }
  return end;
}

// A regular file: the header, then the rows counted in parts (in parallel),
// then each part parsed straight into its rows of the matrix (in parallel).
// Line numbers and the first-error-wins order are those of a serial read.
void read_file(Source& source, NumericCsv& out, HeaderParser& header, const CsvReadTuning& tuning) {
  const uint64_t size = source.size();
  uint64_t data_begin = 0;
  {
    PooledBuffer buffer;
    data_begin = scan_lines(source, 0, size, buffer.get(), [&](const char* b, const char* e) { return !header.line(b, e); });
  }
  if (!header.done()) header.fail_no_header(size == 0);

  // Part boundaries, each the start of a line.
  std::vector<uint64_t> hints = tuning.split_offsets;
  if (hints.empty() && size - data_begin >= tuning.parallel_min_bytes) {
    const size_t threads = std::clamp<size_t>(std::thread::hardware_concurrency(), 1, kMaxThreads);
    for (size_t k = 1; k < threads; ++k) hints.push_back(data_begin + (size - data_begin) * k / threads);
  }
  std::sort(hints.begin(), hints.end());
  std::vector<uint64_t> bounds{data_begin};
  for (const uint64_t hint : hints) {
    const uint64_t at = line_start_at(source, bounds.back(), size, std::max(hint, bounds.back()));
    if (at > bounds.back() && at < size) bounds.push_back(at);
  }
  bounds.push_back(size);
  const size_t parts = bounds.size() - 1;

  struct Part {
    int64_t lines = 0;
    size_t rows = 0;
  };
  std::vector<Part> counted(parts);
  run_parts(parts, [&](size_t k) {
    PooledBuffer buffer;
    Part& part = counted[k];
    scan_lines(source, bounds[k], bounds[k + 1], buffer.get(), [&](const char* b, const char* e) {
      ++part.lines;
      part.rows += is_row_line(b, e) ? 1 : 0;
      return true;
    });
  });

  size_t n = 0;
  int64_t lines = header.lines();
  std::vector<size_t> first_row(parts);
  std::vector<int64_t> first_line(parts);
  for (size_t k = 0; k < parts; ++k) {
    first_row[k] = n;
    first_line[k] = lines + 1;
    n += counted[k].rows;
    lines += counted[k].lines;
  }
  const size_t c = out.names.size();
  out.data.resize(static_cast<Index>(n), static_cast<Index>(c));
  advise_huge_pages(out.data.data(), n * c * sizeof(double));

  std::vector<std::vector<NumericCsv::Run>> runs(parts);
  run_parts(parts, [&](size_t k) {
    PooledBuffer buffer;
    RowParser parser(out, first_line[k], first_row[k], runs[k]);
    std::vector<double*> cols(c);
    for (size_t j = 0; j < c; ++j) cols[j] = out.data.data() + j * n + first_row[k];
    parser.write_into(cols.data(), counted[k].rows);
    scan_lines(source, bounds[k], bounds[k + 1], buffer.get(), [&](const char* b, const char* e) {
      parser.line(b, e);
      return true;
    });
    if (parser.rows() != counted[k].rows || parser.last_line() != first_line[k] + counted[k].lines - 1)
      changed_while_reading(out.path);
  });
  for (std::vector<NumericCsv::Run>& part : runs)
    for (const NumericCsv::Run& run : part) {
      const bool continues = !out.runs.empty() && out.runs.back().column == run.column &&
                             out.runs.back().line - out.runs.back().row == run.line - run.row;
      if (!continues) out.runs.push_back(run);
    }
  out.end_line = lines + 1;
}

// The 1-based line number of the line starting at file offset `at` (error path:
// counts the line breaks before it).
int64_t line_at(Source& source, uint64_t at) {
  int64_t line = 1;
  char probe[65536];
  for (uint64_t p = 0; p < at;) {
    const size_t n = source.fetch(probe, static_cast<size_t>(std::min<uint64_t>(sizeof probe, at - p)), p);
    if (n == 0) break;
    line += std::count(probe, probe + n, '\n');
    p += n;
  }
  return line;
}

}  // namespace

namespace {

NumericCsv read_from(Source& source, const std::string& path, const std::string& key_name,
                     const std::string& key_hint, const CsvReadTuning& tuning) {
  NumericCsv out;
  out.path = path;
  HeaderParser header(out, key_name, key_hint);
  if (source.regular()) {
    try {
      read_file(source, out, header, tuning);
    } catch (const LineTooLong& e) {
      fail_line_too_long(path, line_at(source, e.line_start));
    }
  } else {
    read_stream(source, out, header);
  }
  return out;
}

}  // namespace

NumericCsv read_numeric_csv(const std::string& path, const std::string& key_name, const std::string& key_hint,
                            const CsvReadTuning& tuning) {
  Source source(path);
  return read_from(source, path, key_name, key_hint, tuning);
}

NumericCsv read_numeric_csv_text(const std::string& text, const std::string& path, const std::string& key_name,
                                 const std::string& key_hint) {
  Source source(path, text);
  return read_from(source, path, key_name, key_hint, CsvReadTuning{});
}

int64_t cell_column(const std::string& path, const std::string* text, int64_t line, Index column) {
  std::string row;
  if (text != nullptr) {
    std::istringstream in(*text);
    for (int64_t k = 0; k < line; ++k)
      if (!std::getline(in, row)) return 1;
  } else {
    if (path == "-") return 1;  // stdin cannot be read twice
    std::ifstream in(path, std::ios::binary);
    for (int64_t k = 0; k < line; ++k)
      if (!std::getline(in, row)) return 1;
  }
  if (line == 1 && row.rfind("\xEF\xBB\xBF", 0) == 0) row.erase(0, 3);
  size_t p = 0;
  for (Index c = 0; c < column; ++c) {
    p = row.find(',', p);
    if (p == std::string::npos) return 1;
    ++p;
  }
  while (p < row.size() && is_blank(row[p])) ++p;
  return static_cast<int64_t>(p) + 1;
}

void check_log_columns(const std::string& path, const std::vector<std::string>& names, Index columns) {
  if (static_cast<Index>(names.size()) != columns)
    throw InputError(fmt::format("cannot write '{}': {} column names for {} columns of data; give one name per column",
                                 display_path(path), names.size(), columns));
  check_header_names(path, names);
  if (std::find(names.begin(), names.end(), "t") == names.end())
    throw InputError(fmt::format("cannot write '{}': no column 't'; a log needs a time column 't' in seconds",
                                 display_path(path)));
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
