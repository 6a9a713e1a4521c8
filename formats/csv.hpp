// Reader for photomill's CSV tables: a header row naming the columns, then one record per line.
// Columns are found by name, so extra columns (written by another tool or by hand) are allowed
// and their order does not matter. '#' comment lines and blank lines are skipped.
#pragma once

#include <cstdint>
#include <istream>
#include <string>
#include <string_view>
#include <vector>

#include "formats/text.hpp"

namespace photomill {

class CsvReader {
public:
  // `required` columns must be in the header; `optional` ones may be. Column handles passed to
  // the accessors are indices into required followed by optional.
  CsvReader(std::istream& in, std::string source, std::vector<std::string> required,
            std::vector<std::string> optional = {});

  // Advances to the next record; false at the end of input.
  bool next();

  // Accessors for the current record. Each throws InputError naming the line and column.
  std::string_view text(std::size_t column) const;
  double number(std::size_t column) const;
  std::int64_t integer(std::size_t column) const;
  std::int64_t non_negative_integer(std::size_t column) const;
  // True if the optional column is in the header and the current record's field is not empty.
  bool has(std::size_t column) const;

  std::size_t line_number() const { return lines_.line_number(); }
  const std::string& source() const { return lines_.source(); }
  // The run= of the stamp the current row follows (formats/run.hpp); empty if none.
  const std::string& run_id() const { return lines_.run_id(); }
  [[noreturn]] void fail(const std::string& message) const { lines_.fail(message); }

private:
  std::string_view field(std::size_t column) const;
  LineReader lines_;
  std::vector<std::string> names_;
  std::vector<long> index_;  // header position of each requested column, -1 if absent
  std::size_t header_columns_ = 0;
  std::vector<std::string_view> fields_;
};

// Joins fields with commas and a newline; used by the table writers.
void write_csv_row(std::ostream& out, const std::vector<std::string>& fields);

// Rejects a text field a CSV writer cannot store unambiguously (comma, newline, leading '#',
// leading or trailing blanks, empty). Throws std::invalid_argument naming `what`.
void check_csv_text(std::string_view value, std::string_view what);

}  // namespace photomill
