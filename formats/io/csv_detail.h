// lpvid — internals shared by the CSV readers and writers of formats/io.
// Not a public interface: include only from formats/io/*.cc (and their tests).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "formats/io/atomic_file.h"
#include "formats/io/text.h"
#include "idlib/core/types.h"

namespace lpvid::detail {

// "-" is shown as "<stdin>" in messages.
std::string display_path(const std::string& path);

// A reader's message made one line of bounded length whatever the file holds:
// control bytes (a name echoed from the file by a rule) shown as \xNN, and a text
// longer than 900 bytes kept to its first 450 and its last 400 bytes (the rule and
// the remedy) around " ... ".
std::string one_line_message(std::string_view what);

// Throws InputError "path:line:column: what" (what through one_line_message).
[[noreturn]] void fail_at(const std::string& path, int64_t line, int64_t column, const std::string& what);

// Quotes a cell for a message: at most 40 bytes, longer text cut with "...",
// control bytes (NUL, line breaks, ESC) shown as \xNN.
std::string quote_cell(std::string_view text);

// A blank between CSV fields: a space or a tab (never a line end).
inline bool is_blank(char c) { return c == ' ' || c == '\t'; }

// What a CSV file may ask of the reader (docs/formats.md, "Limits"): bounded
// so that a wrong file (/dev/zero, a binary, a runaway header) fails at once
// with a message instead of exhausting memory or time.
inline constexpr size_t kMaxCsvLineBytes = size_t{16} << 20;
inline constexpr size_t kMaxCsvColumns = 65536;

// Asks the kernel to back a large buffer with transparent huge pages: on the
// target VMs the first touch of a 4 KiB page costs ~11 us (BUILD-NOTES.md), which
// would otherwise cost more than the parsing itself.  Harmless where unsupported.
void advise_huge_pages(void* data, size_t bytes);

struct CellPosition {
  int64_t line = 0;
  int64_t column = 0;
};

// A CSV file of one header row and numeric rows (the rules of docs/formats.md).
struct NumericCsv {
  std::string path;
  std::vector<std::string> names;
  std::vector<int64_t> name_columns;  // byte column of each header cell
  int64_t header_line = 0;
  // Comment lines before the header.
  struct Comment {
    int64_t line;
    int64_t column;  // byte column of text's first character (just after '#')
    std::string text;
  };
  std::vector<Comment> leading_comments;
  Eigen::MatrixXd data;  // rows x names.size()
  Index key = 0;         // index of the key column
  int64_t end_line = 1;  // the line after the last one (where a next row would start)

  // Line and byte column of the key cell of data row `row`.
  CellPosition key_position(Index row) const;

  struct Run {  // rows from `row` on sit at line + (r - row), key cell at `column`
    Index row;
    int64_t line;
    int64_t column;
  };
  std::vector<Run> runs;
};

// How read_numeric_csv splits a regular file between threads.
struct CsvReadTuning {
  // Files with at least this many bytes of rows are read on up to
  // min(hardware threads, 4) threads.  Below it one thread is faster: starting
  // a thread and the extra row-counting pass cost more than they save.
  uint64_t parallel_min_bytes = uint64_t{8} << 20;
  // For tests: when non-empty, the file is split at the first line start at or
  // after each of these byte offsets (whatever its size) instead.
  std::vector<uint64_t> split_offsets;
};

// Reads path ("-": stdin) in 4 MiB chunks and parses it with fast_float.
// A line longer than kMaxCsvLineBytes or a header of more than kMaxCsvColumns
// columns is an error at its line.
// A regular file is read in two passes: its rows are counted (one memchr per
// line), then parsed straight into `data`; large files are split at line starts
// into parts that are counted and parsed on parallel threads, with the line
// numbers and the first-error-in-file-order of a serial read.  Stdin and pipes
// are read in one pass on one thread, into growing columns copied once into
// `data` (slower).  key_name must be a column of the header, else
// "path:L:1: no column 'key_name' in the header; <key_hint>".  A regular file
// that changes length while it is read gives
// "path: the file changed while it was read; read it again once it is complete".
NumericCsv read_numeric_csv(const std::string& path, const std::string& key_name, const std::string& key_hint,
                            const CsvReadTuning& tuning = {});
// The same from text already in memory (path for messages only).
NumericCsv read_numeric_csv_text(const std::string& text, const std::string& path, const std::string& key_name,
                                 const std::string& key_hint);

// Byte column (1-based) of the first non-blank byte of cell `column` (0-based) on
// line `line` of the CSV, read again from `text` when given, else from the file at
// `path` (error path only; stdin cannot be read twice: 1).  1 when the line or the
// cell is not there.
int64_t cell_column(const std::string& path, const std::string* text, int64_t line, Index column);

// Checks names for a CSV header: non-empty, unique, no ',', '"', '#' at the start,
// or line breaks.  what = "cannot write 'x.csv'" prefix for messages.
void check_header_names(const std::string& path, const std::vector<std::string>& names);

// The checks of a log about to be written, shared by write_log (CSV) and
// write_log_mat: one name per column of data, names valid as a CSV header
// (check_header_names: a .mat log must read back as the same CSV log), a column
// "t".  Throws InputError "cannot write 'path': ...; what to do".
void check_log_columns(const std::string& path, const std::vector<std::string>& names, Index columns);

// Writes "# text" lines (a text with line breaks becomes several lines).
void append_comments(std::string& out, const std::vector<std::string>& comments);

// Writes header + rows of numbers (shortest text that round-trips) to out,
// in blocks.  Throws InputError naming the first non-finite entry.
void write_numeric_rows(AtomicFileWriter& out, std::string head, const Eigen::MatrixXd& rows,
                        const std::vector<std::string>& names, int64_t first_data_line);

}  // namespace lpvid::detail
