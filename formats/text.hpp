// Locale-independent line reading, number parsing and number formatting shared by every text
// reader and writer in formats/. Readers use LineReader so that CRLF line ends, a UTF-8 BOM,
// '#' comments, blank lines and hostile line lengths are handled the same way everywhere.
#pragma once

#include <cstddef>
#include <cstdint>
#include <istream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photomill {

struct LineReaderOptions {
  // A longer line is an error rather than a reason to allocate without bound.
  std::size_t max_line_bytes = 1 << 20;
  // Skip lines whose first non-blank character is '#', and lines that are blank.
  bool skip_comments_and_blank = true;
  // Number of the first line read (a reader that consumed a header itself starts later).
  std::size_t first_line_number = 1;
};

// Reads an istream line by line, counting lines from 1, stripping a trailing '\r' and a UTF-8 BOM
// at the start of the first line. Errors name `source` and the current line.
class LineReader {
public:
  LineReader(std::istream& in, std::string source, LineReaderOptions options = {});

  // Next line (comments/blank skipped if configured); nullopt at end of input.
  std::optional<std::string_view> next();
  // Line number of the line last returned by next() (1-based).
  std::size_t line_number() const noexcept { return line_number_; }
  // Stamps (formats/run.hpp; only when comments are skipped): a "# photomill run=ID rows=N"
  // comment starts a segment of N rows (the lines next() returns up to the next stamp or the
  // end); at a segment's end a count that differs is an error naming the stamp's line, and a file
  // holding a stamp must end with a line end (else it was cut inside its last line). A file
  // without stamps reads as before. uncount_row(): the line last returned was not a row (a CSV's
  // column header). run_id(): the run= of the current segment, empty if none.
  void uncount_row() noexcept;
  const std::string& run_id() const noexcept { return segment_run_; }
  const std::string& source() const noexcept { return source_; }
  // Throws InputError(source, line_number(), message).
  [[noreturn]] void fail(const std::string& message) const;

private:
  bool read_raw_line();
  void end_segment();
  std::istream& in_;
  std::string source_;
  LineReaderOptions options_;
  std::string buffer_;
  std::size_t line_number_ = 0;
  bool last_line_ended_ = true;          // the last raw line ended with '\n'
  bool stamped_ = false;                 // a stamp was seen
  bool ended_ = false;                   // the end of input was reached and checked
  std::optional<std::size_t> segment_rows_expected_;
  std::size_t segment_rows_ = 0;
  std::size_t segment_line_ = 0;         // the stamp's line
  std::string segment_run_;
};

// Splits on a single-character delimiter; fields are trimmed of spaces and tabs. No quoting:
// photomill's CSV never needs commas inside a field (image names with commas are rejected by
// the writers).
std::vector<std::string_view> split_fields(std::string_view line, char delimiter);
// Splits on runs of spaces, tabs or commas (plain "x y z" text and its relatives).
std::vector<std::string_view> split_whitespace(std::string_view line);
std::string_view trim(std::string_view s);

// Strict parsers: the whole field must be the number, in the C locale. NaN and infinity are
// rejected (no photomill quantity is ever infinite). Return nullopt on failure so the caller can
// word the error with its column name.
std::optional<double> parse_double(std::string_view field);
std::optional<std::int64_t> parse_int(std::string_view field);

// Shortest decimal text that reads back to exactly the same double (std::to_chars), in the C
// locale. Finite values only; callers validate before writing.
std::string format_double(double value);
void append_double(std::string& out, double value);

}  // namespace photomill
