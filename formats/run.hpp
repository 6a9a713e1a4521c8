// Run ids and stamps: every file a photomill run writes carries the run's id, and its own text
// formats announce how many rows they hold, so that a reader can tell a complete file from one cut
// short (an interrupted copy, a full disk) and outputs of one run from a mix of two (a run killed
// between the renames of its outputs). Issue #25; docs/formats.md, "Stamps".
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace photomill {

// This process's run id, made once: UTC time, process id and 32 random bits
// ("20261204T031522Z-4711-9f3a0c1e"), or the environment's PHOTOMILL_RUN_ID when that is set to
// 1-64 characters of [A-Za-z0-9._:-] (reproducible outputs: two runs then write the same bytes).
const std::string& run_id();

// A stamp comment: "# photomill run=ID rows=N" (rows: the data rows that follow it, a CSV's
// column header not counted, up to the next stamp or the end of the file).
struct Stamp {
  std::string run;                  // empty: not given
  std::optional<std::size_t> rows;  // nullopt: not given
};

// The stamp line this run writes, newline included; `rows` nullopt for formats that count their
// records themselves (features, surfaces).
std::string stamp_line(std::optional<std::size_t> rows);

// The stamp in a comment line ("# photomill " followed by key=value words, at least one of run=
// and rows=); nullopt for any other line. Unknown keys are ignored (later versions may add some);
// a rows= that is not a count, or a run= that is empty, is not a stamp.
std::optional<Stamp> parse_stamp(std::string_view line);

// The run id in a file's first bytes (`head`): what follows the first "photomill run=" up to a
// blank, a quote or a line end; in any of photomill's files (a CSV or YAML stamp, a PLY comment,
// an APT '$$' comment, a JSON report's "run_id" is not found this way). nullopt if none.
std::optional<std::string> find_run_id(std::string_view head);

}  // namespace photomill
