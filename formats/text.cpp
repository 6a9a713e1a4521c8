#include "formats/text.hpp"

#include <charconv>
#include <cmath>

#include "formats/error.hpp"
#include "formats/run.hpp"

namespace photomill {

LineReader::LineReader(std::istream& in, std::string source, LineReaderOptions options)
    : in_(in), source_(std::move(source)), options_(options),
      line_number_(options.first_line_number - 1) {}

// Reads one raw line into buffer_ without letting it grow past max_line_bytes.
bool LineReader::read_raw_line() {
  buffer_.clear();
  std::streambuf* sb = in_.rdbuf();
  if (sb == nullptr) return false;
  bool any = false;
  for (;;) {
    int c = 0;
    try {
      c = sb->sbumpc();
    } catch (const InputError& e) {  // a read error (tool::open_input): name the line it hit
      if (e.line() != 0) throw;
      throw InputError(e.source(), line_number_ + 1, e.message());
    }
    if (c == std::char_traits<char>::eof()) {
      if (!any) return false;
      last_line_ended_ = false;
      break;
    }
    any = true;
    if (c == '\n') {
      last_line_ended_ = true;
      break;
    }
    if (buffer_.size() >= options_.max_line_bytes) {
      ++line_number_;
      fail("line longer than " + std::to_string(options_.max_line_bytes) + " bytes");
    }
    buffer_.push_back(static_cast<char>(c));
  }
  ++line_number_;
  if (!buffer_.empty() && buffer_.back() == '\r') buffer_.pop_back();
  if (line_number_ == 1 && options_.first_line_number == 1 && buffer_.rfind("\xEF\xBB\xBF", 0) == 0) buffer_.erase(0, 3);
  if (buffer_.find('\0') != std::string::npos) fail("binary data (NUL byte) in a text file");
  return true;
}

std::optional<std::string_view> LineReader::next() {
  if (ended_) return std::nullopt;
  while (read_raw_line()) {
    if (options_.skip_comments_and_blank) {
      const std::string_view t = trim(buffer_);
      if (!t.empty() && t.front() == '#') {
        if (auto stamp = parse_stamp(t)) {
          end_segment();
          stamped_ = true;
          segment_rows_expected_ = stamp->rows;
          segment_rows_ = 0;
          segment_line_ = line_number_;
          segment_run_ = std::move(stamp->run);
        }
        continue;
      }
      if (t.empty()) continue;
      ++segment_rows_;
    }
    return std::string_view(buffer_);
  }
  ended_ = true;
  if (stamped_ && !last_line_ended_) {
    fail("the last line has no line end: the file was cut short (a photomill file ends with one)");
  }
  end_segment();
  return std::nullopt;
}

void LineReader::uncount_row() noexcept {
  if (stamped_ && segment_rows_ > 0) --segment_rows_;
}

// A segment's row count against its stamp's.
void LineReader::end_segment() {
  if (!segment_rows_expected_ || *segment_rows_expected_ == segment_rows_) return;
  const std::size_t want = *segment_rows_expected_;
  const std::string counts = "its stamp announces " + std::to_string(want) + " rows, " +
                             std::to_string(segment_rows_) + " follow";
  throw InputError(source_, segment_line_,
                   segment_rows_ < want ? counts + ": the file was cut short"
                                        : counts + ": rows were added after the stamp (files joined "
                                                   "without their stamps?)");
}

void LineReader::fail(const std::string& message) const {
  throw InputError(source_, line_number_, message);
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split_fields(std::string_view line, char delimiter) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = line.find(delimiter, start);
    if (end == std::string_view::npos) {
      fields.push_back(trim(line.substr(start)));
      return fields;
    }
    fields.push_back(trim(line.substr(start, end - start)));
    start = end + 1;
  }
}

std::vector<std::string_view> split_whitespace(std::string_view line) {
  std::vector<std::string_view> fields;
  const auto is_sep = [](char c) { return c == ' ' || c == '\t' || c == ','; };
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_sep(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_sep(line[i])) ++i;
    if (i > start) fields.push_back(line.substr(start, i - start));
  }
  return fields;
}

std::optional<double> parse_double(std::string_view field) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return std::nullopt;
  double value = 0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || ptr != field.data() + field.size()) return std::nullopt;
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

std::optional<std::int64_t> parse_int(std::string_view field) {
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  if (field.empty()) return std::nullopt;
  std::int64_t value = 0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || ptr != field.data() + field.size()) return std::nullopt;
  return value;
}

void append_double(std::string& out, double value) {
  char buf[32];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof buf, value);
  out.append(buf, ec == std::errc() ? ptr : buf);
}

std::string format_double(double value) {
  std::string s;
  append_double(s, value);
  return s;
}

}  // namespace photomill
