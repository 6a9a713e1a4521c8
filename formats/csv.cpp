#include "formats/csv.hpp"

#include <ostream>
#include <stdexcept>

#include "formats/error.hpp"
#include "formats/magnitude.hpp"

namespace photomill {

CsvReader::CsvReader(std::istream& in, std::string source, std::vector<std::string> required,
                     std::vector<std::string> optional)
    : lines_(in, std::move(source)) {
  names_ = std::move(required);
  const std::size_t n_required = names_.size();
  names_.insert(names_.end(), optional.begin(), optional.end());
  index_.assign(names_.size(), -1);

  const auto header = lines_.next();
  if (!header) {
    throw InputError(lines_.source(), 0, "empty input: expected a CSV header naming the columns");
  }
  lines_.uncount_row();  // the column header is not one of the rows a stamp counts
  const auto columns = split_fields(*header, ',');
  header_columns_ = columns.size();
  for (std::size_t c = 0; c < columns.size(); ++c) {
    for (std::size_t k = 0; k < names_.size(); ++k) {
      if (columns[c] == names_[k]) {
        if (index_[k] >= 0) lines_.fail("column '" + names_[k] + "' appears twice in the header");
        index_[k] = static_cast<long>(c);
      }
    }
  }
  for (std::size_t k = 0; k < n_required; ++k) {
    if (index_[k] < 0) {
      std::string expected;
      for (std::size_t j = 0; j < n_required; ++j) expected += (j ? "," : "") + names_[j];
      lines_.fail("header lacks column '" + names_[k] + "' (expected a header with " + expected +
                  ")");
    }
  }
}

bool CsvReader::next() {
  const auto line = lines_.next();
  if (!line) return false;
  fields_ = split_fields(*line, ',');
  if (fields_.size() != header_columns_) {
    lines_.fail("expected " + std::to_string(header_columns_) + " columns, got " +
                std::to_string(fields_.size()));
  }
  return true;
}

std::string_view CsvReader::field(std::size_t column) const {
  const long i = index_.at(column);
  return i < 0 ? std::string_view() : fields_[static_cast<std::size_t>(i)];
}

bool CsvReader::has(std::size_t column) const { return !field(column).empty(); }

std::string_view CsvReader::text(std::size_t column) const {
  const std::string_view f = field(column);
  if (f.empty()) lines_.fail("empty field '" + names_.at(column) + "'");
  return f;
}

double CsvReader::number(std::size_t column) const {
  const std::string_view f = text(column);
  const auto v = parse_bounded(f);
  if (!v) lines_.fail("field '" + names_[column] + "' " + number_problem(f));
  return *v;
}

std::int64_t CsvReader::integer(std::size_t column) const {
  const std::string_view f = text(column);
  const auto v = parse_int(f);
  if (!v) lines_.fail("field '" + names_[column] + "' is not an integer: '" + std::string(f) + "'");
  return *v;
}

std::int64_t CsvReader::non_negative_integer(std::size_t column) const {
  const std::int64_t v = integer(column);
  if (v < 0) lines_.fail("field '" + names_[column] + "' is negative: " + std::to_string(v));
  return v;
}

void write_csv_row(std::ostream& out, const std::vector<std::string>& fields) {
  std::string line;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (i) line += ',';
    line += fields[i];
  }
  line += '\n';
  out << line;
}

void check_csv_text(std::string_view value, std::string_view what) {
  const bool bad = value.empty() || value.find_first_of(",\n\r") != std::string_view::npos ||
                   value.front() == '#' || trim(value).size() != value.size();
  if (bad) {
    throw std::invalid_argument(std::string(what) + " '" + std::string(value) +
                                "' cannot be written to CSV (empty, comma, newline, leading '#' "
                                "or surrounding blanks)");
  }
}

}  // namespace photomill
