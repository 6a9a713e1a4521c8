// The tool contract every photomill executable follows (see README "Conventions"):
// --help with a pipe example, --version, -q/-v; inputs as files or '-' (stdin); output to -o FILE
// (written to a temporary name and renamed on success) or stdout; exit 0 ok, 1 bad input or
// failure, 2 bad usage; C locale whatever the user's locale.
#pragma once

#include <functional>
#include <iosfwd>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "formats/cli_fwd.hpp"

namespace photomill::tool {

struct ToolSpec {
  std::string name;         // "calib"
  std::string summary;      // one line: what it does
  std::string example;      // one-line pipe example shown in --help
};

// Builds the CLI11 app (adds --version, -q, -v), lets `configure` add the tool's options, parses,
// then runs `body`. Returns the exit code: 0 ok (and for --help/--version), 2 bad usage
// (CLI11 parse errors, photomill::UsageError; NaN or an infinity given to any floating-point
// option), 1 for any other exception, whose message is printed as "name: message" on stderr,
// one line. Outputs committed while `body` runs are renamed onto
// their targets only after it returned and stdout took every byte: a run that fails anywhere
// leaves every previous output as it was. Installs handlers for the signals that end a process
// (SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGPIPE, ...) that remove the temporary files first.
int run(int argc, char** argv, const ToolSpec& spec,
        const std::function<void(CLI::App&)>& configure, const std::function<void()>& body);

// A named preset: option values measured together (docs/measurements/makefile.md), each given
// as the option's long name and what setting it does. `--preset NAME` applies the values of the
// options the command line does not give: an option given explicitly wins, in any order.
struct PresetValue {
  std::string option;          // "--max-features"
  std::function<void()> set;  // sets the option's variable to the preset's value
};
using Presets = std::vector<std::pair<std::string, std::vector<PresetValue>>>;  // name -> values

// Adds `--preset NAME` (one of `presets`' names; `help` says what they are) to `app`, writing the
// name to `chosen`; the values are applied once parsing is complete. Each option must exist in
// `app` (checked here: a misspelt name is a programming error, std::logic_error).
void add_presets(CLI::App& app, std::string& chosen, const Presets& presets, const std::string& help);

// Renames the outputs committed so far in this run at once, for a run that hands its own outputs
// to another program or reads them back (synth_accuracy writes a data set, then runs the stages
// on it). Throws InputError naming the output whose rename failed.
void publish_committed();

// Source name used in messages: "<stdin>" for "-", else the path.
std::string source_name(const std::string& path);

// Opens `path` for reading ("-" = stdin, binary mode). Throws InputError(path, 0, reason) if it
// cannot be opened or is a directory.
std::unique_ptr<std::istream> open_input(const std::string& path);

// Reads a whole input into memory (for readers that need random access, e.g. OCCT), refusing
// inputs larger than max_bytes.
std::string read_all(const std::string& path, std::size_t max_bytes);

// The run id a photomill file carries in its first 4 KB (find_run_id, formats/run.hpp); nullopt
// if it has none, or for stdin ("-"), which cannot be read twice. A read error names the file.
std::optional<std::string> file_run_id(const std::string& path);

// An output that is either stdout ("-" or empty path) or a file written under a temporary name
// in the same folder and renamed onto `path` by commit() (inside run(): once the whole run
// succeeded, see run()). If the object is destroyed without commit() (an exception, a signal),
// the temporary file is removed and `path` is untouched. A `path` that is a symbolic link
// updates the file it links to; the link stays.
// A target that exists and is not a regular file (/dev/null, /dev/stdout, a FIFO) is written
// directly: renaming onto it would replace the device (and as root it would succeed).
class OutputFile {
public:
  explicit OutputFile(std::string path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // The output's stream. A write that fails (a full disk: ENOSPC, an I/O error) throws
  // InputError naming the output and the system's reason at once, from the stream operation.
  std::ostream& stream();
  // A file path that a library writing by name (Open CASCADE) can write to. For stdout outputs a
  // temporary file whose contents commit() copies to stdout.
  const std::string& temp_path();
  // Checks that every byte reached the temporary file (flush and close included: a write-back
  // error that close reports is a failed write) and renames it
  // onto the target; inside run() the rename waits for the end of the run.
  void commit();
  bool is_stdout() const { return to_stdout_; }
  const std::string& path() const { return path_; }

private:
  std::string path_;
  bool to_stdout_;
  std::string target_;  // path_ with symbolic links followed
  std::string temp_;
  std::unique_ptr<std::ostream> file_;  // a FileOutput (tool.cpp): every failed write throws, naming path_
  bool committed_ = false;
  bool direct_ = false;  // write straight to a device or FIFO, no temporary
};

}  // namespace photomill::tool
