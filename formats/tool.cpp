#include "formats/tool.hpp"

#include <array>
#include <atomic>
#include <cerrno>
#include <clocale>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <locale>
#include <sstream>

#include <unistd.h>

#include "formats/error.hpp"
#include "formats/log.hpp"

namespace photomill::tool {
namespace {

// Temporary files of unfinished outputs, removed by the signal handler. A fixed table of plain
// char buffers because a signal handler may only call async-signal-safe functions (unlink).
constexpr std::size_t kMaxPending = 16;
constexpr std::size_t kMaxPath = 4096;
std::array<std::array<char, kMaxPath>, kMaxPending> g_pending_paths{};
std::array<std::atomic<bool>, kMaxPending> g_pending_used{};

int register_pending(const std::string& path) {
  if (path.size() + 1 > kMaxPath) return -1;
  for (std::size_t i = 0; i < kMaxPending; ++i) {
    bool expected = false;
    if (g_pending_used[i].compare_exchange_strong(expected, true)) {
      std::memcpy(g_pending_paths[i].data(), path.c_str(), path.size() + 1);
      return static_cast<int>(i);
    }
  }
  return -1;
}

void unregister_pending(const std::string& path) {
  for (std::size_t i = 0; i < kMaxPending; ++i) {
    if (g_pending_used[i] && path == g_pending_paths[i].data()) g_pending_used[i] = false;
  }
}

extern "C" void remove_pending_and_reraise(int sig) {
  for (std::size_t i = 0; i < kMaxPending; ++i) {
    if (g_pending_used[i]) ::unlink(g_pending_paths[i].data());
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

std::atomic<unsigned> g_temp_counter{0};

std::string make_temp_name(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string name = "." + p.filename().string() + ".tmp." + std::to_string(::getpid()) +
                           "." + std::to_string(g_temp_counter++);
  return (dir / name).string();
}

}  // namespace

int run(int argc, char** argv, const ToolSpec& spec,
        const std::function<void(CLI::App&)>& configure, const std::function<void()>& body) {
  std::setlocale(LC_ALL, "C");
  std::locale::global(std::locale::classic());
  std::signal(SIGINT, remove_pending_and_reraise);
  std::signal(SIGTERM, remove_pending_and_reraise);
  log::set_program(spec.name);

  CLI::App app{spec.summary, spec.name};
  app.set_version_flag("--version", std::string(spec.name) + " (photomill) " PHOTOMILL_VERSION);
  app.footer("Example:\n  " + spec.example + "\n\nExit status: 0 ok, 1 bad input or failure, "
             "2 bad usage. Data on stdout, messages on stderr.");
  bool quiet = false;
  bool verbose = false;
  app.add_flag("-q,--quiet", quiet, "Only errors on stderr");
  app.add_flag("-v,--verbose", verbose, "Progress and details on stderr");
  try {
    configure(app);
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  log::set_level(quiet ? log::Level::Quiet : verbose ? log::Level::Verbose : log::Level::Normal);

  try {
    body();
    std::cout.flush();
    if (!std::cout) {
      std::cerr << spec.name << ": error writing to stdout\n";
      return 1;
    }
    return 0;
  } catch (const UsageError& e) {
    std::cerr << spec.name << ": " << e.what() << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << spec.name << ": out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << spec.name << ": " << e.what() << "\n";
    return 1;
  }
}

std::string source_name(const std::string& path) { return path == "-" ? "<stdin>" : path; }

std::unique_ptr<std::istream> open_input(const std::string& path) {
  if (path == "-" || path.empty()) {
    auto in = std::make_unique<std::istream>(std::cin.rdbuf());
    return in;
  }
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, 0, "is a directory");
  auto file = std::make_unique<std::ifstream>(path, std::ios::binary);
  if (!*file) throw InputError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  return file;
}

std::string read_all(const std::string& path, std::size_t max_bytes) {
  auto in = open_input(path);
  std::string data;
  std::array<char, 1 << 16> buf{};
  while (*in) {
    in->read(buf.data(), buf.size());
    data.append(buf.data(), static_cast<std::size_t>(in->gcount()));
    if (data.size() > max_bytes) {
      throw InputError(source_name(path), 0,
                       "larger than " + std::to_string(max_bytes) + " bytes");
    }
  }
  return data;
}

namespace {

// Copies the file `from` into `out` (flushed), true when every byte was written. (operator<< of an
// empty streambuf would set failbit, so the copy is a loop.)
bool copy_contents(const std::string& from, std::ostream& out) {
  std::ifstream in(from, std::ios::binary);
  if (!in) return false;
  char buf[1 << 16];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    out.write(buf, in.gcount());
    if (!out) return false;
  }
  out.flush();
  return static_cast<bool>(out) && in.eof();
}

}  // namespace

OutputFile::OutputFile(std::string path) : path_(std::move(path)), to_stdout_(path_.empty() || path_ == "-") {
  std::error_code ec;
  const auto status = std::filesystem::status(path_, ec);
  direct_ = !to_stdout_ && !ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status);
  if (direct_ && std::filesystem::is_directory(status)) throw InputError(path_, 0, "is a directory");
}

OutputFile::~OutputFile() {
  if (!temp_.empty() && !committed_) {
    if (file_) file_->close();
    std::remove(temp_.c_str());
    unregister_pending(temp_);
  }
}

const std::string& OutputFile::temp_path() {
  if (temp_.empty() && !to_stdout_ && !direct_) {
    // A library that writes by name would name the temporary file in its error: name the output.
    const auto folder = std::filesystem::path(path_).parent_path();
    std::error_code ec;
    if (!folder.empty() && !std::filesystem::is_directory(folder, ec)) {
      throw InputError(path_, 0, std::string("cannot write: ") +
                                     (std::filesystem::exists(folder, ec) ? "Not a directory" : "No such file or directory"));
    }
  }
  if (temp_.empty()) {
    // stdout and devices: a private temporary file whose contents commit() copies over.
    temp_ = make_temp_name(to_stdout_ || direct_ ? std::filesystem::temp_directory_path() / "photomill-out"
                                                 : std::filesystem::path(path_));
    register_pending(temp_);
  }
  return temp_;
}

std::ostream& OutputFile::stream() {
  if (to_stdout_) return std::cout;
  if (!file_) {
    const std::string& target = direct_ ? path_ : temp_path();
    file_ = std::make_unique<std::ofstream>(target, std::ios::binary | std::ios::trunc);
    if (!*file_) {
      throw InputError(path_, 0, std::string("cannot write: ") + std::strerror(errno));
    }
  }
  return *file_;
}

void OutputFile::commit() {
  if (committed_) return;
  if (to_stdout_) {
    if (!temp_.empty()) {  // a library wrote by name: copy it to stdout
      const bool copied = copy_contents(temp_, std::cout);
      std::remove(temp_.c_str());
      unregister_pending(temp_);
      if (!copied) throw InputError("<stdout>", 0, "write failed");
    }
    std::cout.flush();
    if (!std::cout) throw InputError("<stdout>", 0, "write failed");
    committed_ = true;
    return;
  }
  if (direct_) {
    if (file_) {
      file_->flush();
      const bool ok = static_cast<bool>(*file_);
      file_->close();
      if (!ok) throw InputError(path_, 0, "write failed");
    }
    if (!temp_.empty()) {  // a library wrote by name: copy it onto the device
      std::ofstream out(path_, std::ios::binary);
      bool copied = static_cast<bool>(out) && copy_contents(temp_, out);
      out.close();
      copied = copied && static_cast<bool>(out);
      std::remove(temp_.c_str());
      unregister_pending(temp_);
      if (!copied) throw InputError(path_, 0, std::string("write failed: ") + std::strerror(errno));
    }
    committed_ = true;
    return;
  }
  if (file_) {
    file_->flush();
    const bool ok = static_cast<bool>(*file_);
    file_->close();
    if (!ok) throw InputError(path_, 0, "write failed (disk full?)");
  } else if (!std::filesystem::exists(temp_path())) {
    // Nothing was written through stream() nor by name: create the (empty) file.
    std::ofstream touch(temp_, std::ios::binary);
  }
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    throw InputError(path_, 0, std::string("cannot rename temporary file: ") + std::strerror(errno));
  }
  unregister_pending(temp_);
  committed_ = true;
}

}  // namespace photomill::tool
