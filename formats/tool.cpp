#include "formats/tool.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <clocale>
#include <cmath>
#include <cstdlib>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <locale>
#include <mutex>
#include <vector>
#include <sstream>
#include <stdexcept>

#include <fcntl.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sys/stat.h>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include "formats/error.hpp"
#include "formats/log.hpp"
#include "formats/run.hpp"

namespace photomill::tool {
namespace {

// Temporary files of unfinished or staged outputs, removed by the signal handler. A signal
// handler may only call async-signal-safe functions (unlink) and must not walk a container that
// another thread is changing, so the table is a list of nodes that are never freed: a node is
// claimed (0 -> 1), filled, then armed (2); the handler unlinks armed nodes only. It grows
// without bound (detect stages one features file per photo) and reuses released nodes.
struct PendingNode {
  std::atomic<int> state{0};  // 0 free, 1 being filled, 2 armed
  std::size_t capacity = 0;
  char* path = nullptr;
  PendingNode* next = nullptr;
};
std::atomic<PendingNode*> g_pending_head{nullptr};

void register_pending(const std::string& path) {
  for (PendingNode* n = g_pending_head.load(); n != nullptr; n = n->next) {
    int expected = 0;
    if (n->capacity > path.size() && n->state.compare_exchange_strong(expected, 1)) {
      std::memcpy(n->path, path.c_str(), path.size() + 1);
      n->state = 2;
      return;
    }
  }
  auto* n = new PendingNode;  // lives as long as the process (see above)
  n->capacity = std::max<std::size_t>(path.size() + 1, 256);
  n->path = new char[n->capacity];
  std::memcpy(n->path, path.c_str(), path.size() + 1);
  n->state = 2;
  n->next = g_pending_head.load();
  while (!g_pending_head.compare_exchange_weak(n->next, n)) {
  }
}

void unregister_pending(const std::string& path) {
  for (PendingNode* n = g_pending_head.load(); n != nullptr; n = n->next) {
    int armed = 2;
    if (n->state.load() == 2 && path == n->path) {
      n->state.compare_exchange_strong(armed, 0);
      return;
    }
  }
}

extern "C" void remove_pending_and_reraise(int sig) {
  for (PendingNode* n = g_pending_head.load(); n != nullptr; n = n->next) {
    if (n->state.load() == 2) ::unlink(n->path);
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

// The signals whose default action ends the process: each would leave temporary files behind.
constexpr std::array<int, 10> kFatalSignals = {SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGPIPE,
                                               SIGALRM, SIGUSR1, SIGUSR2, SIGXCPU, SIGXFSZ};

// Outputs committed inside run(): complete temporaries waiting for their rename, which run() does
// for all of them only after the body returned (an output is renamed only when every output of
// the run is complete). Outside run() (tests, library users) commit() renames at once.
struct Staged {
  std::string temp;
  std::string target;
  std::string name;  // as the user gave it, for messages
};
std::mutex g_staged_mutex;
bool g_staging = false;
std::vector<Staged> g_staged;

void discard_staged() {
  const std::lock_guard<std::mutex> lock(g_staged_mutex);
  for (const auto& s : g_staged) {
    std::remove(s.temp.c_str());
    unregister_pending(s.temp);
  }
  g_staged.clear();
}

// Durability before the rename (the pattern of SQLite and of git's core.fsync): the temporary's
// data reach the disk before its name replaces the previous output, so that a crash or a power
// cut after the rename cannot leave an output of zero length or of stale blocks where the
// previous complete file was (ext4 with delalloc, XFS). fsync(2) on the temporary; its failure
// (EIO from the device, a quota written back) fails the output, naming it.
void sync_file(const std::string& temp, const std::string& name) {
  const int fd = ::open(temp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(name, 0, std::string("cannot sync: ") + std::strerror(errno));
  const int rc = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (rc != 0) throw InputError(name, 0, std::string("write failed: ") + std::strerror(error));
}

// After the rename, the folder's entry itself is made durable (fsync of the directory). Best
// effort: the output is complete and in place either way (a crash before the entry reaches the
// disk leaves the previous complete output), and some file systems refuse fsync on a directory.
void sync_folder_of(const std::string& target) {
  std::string folder = std::filesystem::path(target).parent_path().string();
  if (folder.empty()) folder = ".";
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  (void)::fsync(fd);
  ::close(fd);
}

// Renames every staged output onto its target, in the order committed. A rename that fails stops
// the run: the outputs not yet renamed keep their previous content.
void rename_staged() {
  const std::lock_guard<std::mutex> lock(g_staged_mutex);
  for (std::size_t i = 0; i < g_staged.size(); ++i) {
    const Staged& s = g_staged[i];
    if (std::rename(s.temp.c_str(), s.target.c_str()) != 0) {
      const std::string reason = std::strerror(errno);
      for (std::size_t j = i; j < g_staged.size(); ++j) {
        std::remove(g_staged[j].temp.c_str());
        unregister_pending(g_staged[j].temp);
      }
      g_staged.clear();
      throw InputError(s.name, 0, "cannot rename temporary file: " + reason);
    }
    unregister_pending(s.temp);
    sync_folder_of(s.target);
  }
  g_staged.clear();
}

std::atomic<unsigned> g_temp_counter{0};

// Temporary names handed to libraries that write by name (OutputFile::temp_path) and the
// outputs' names as the user gave them: a library's error names the file it was given, and
// run() puts the output's name in its place (a failed STEP write named ".part.step.tmp.41.0").
std::mutex g_names_mutex;
std::vector<std::pair<std::string, std::string>> g_temp_names;

void remember_temp_name(const std::string& temp, const std::string& name) {
  const std::lock_guard<std::mutex> lock(g_names_mutex);
  g_temp_names.emplace_back(temp, name);
}

// A refusal's message as the one line run() prints: the outputs' names in place of temporary
// names, and on one line (OpenCV's exceptions, for one, end in a newline and may hold several).
std::string message_line(std::string message) {
  {
    const std::lock_guard<std::mutex> lock(g_names_mutex);
    for (const auto& [temp, name] : g_temp_names) {
      for (std::size_t at = 0; (at = message.find(temp, at)) != std::string::npos; at += name.size()) {
        message.replace(at, temp.size(), name);
      }
    }
  }
  while (!message.empty() && std::isspace(static_cast<unsigned char>(message.back()))) message.pop_back();
  for (std::size_t at = 0; (at = message.find_first_of("\r\n", at)) != std::string::npos;) {
    const std::size_t end = message.find_first_not_of(" \t\r\n", at);
    message.replace(at, end - at, "; ");
    at += 2;
  }
  return message;
}

// The most bytes of one name in `dir` (NAME_MAX, 255 on Linux's file systems).
std::size_t name_max(const std::filesystem::path& dir) {
  const long n = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  return n > 16 ? static_cast<std::size_t>(n) : 255;
}

// ".NAME.tmp.PID.N" beside the target; NAME is shortened so that the whole stays within the
// folder's name limit (a target name of 250 bytes is legal, its temporary name must be too).
std::string make_temp_name(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string suffix = ".tmp." + std::to_string(::getpid()) + "." + std::to_string(g_temp_counter++);
  std::string stem = p.filename().string();
  const std::size_t room = name_max(dir) - 1 - suffix.size();
  if (stem.size() > room) stem.resize(room);
  return (dir / ("." + stem + suffix)).string();
}

// Where a write to `path` must land: `path` itself, or the file a symbolic link (or a chain of
// them) points to, so that an output given as a link updates the linked file instead of
// replacing the link by a regular file (as `sed -i --follow-symlinks` and editors do).
std::string follow_links(const std::string& path) {
  namespace fs = std::filesystem;
  fs::path p(path);
  for (int hops = 0; hops < 40; ++hops) {  // 40: Linux's limit (MAXSYMLINKS)
    std::error_code ec;
    if (!fs::is_symlink(fs::symlink_status(p, ec))) return p.string();
    const fs::path to = fs::read_symlink(p, ec);
    if (ec) return p.string();
    p = to.is_absolute() ? to : p.parent_path() / to;
  }
  throw InputError(path, 0, "cannot write: Too many levels of symbolic links");
}

// Checks every option of `app` and its subcommands gets. Every floating-point option refuses NaN and the infinities (and
// numbers beyond the double range, which convert to them) at parse time: CLI11 converts "nan" and
// "inf" to a double, and its Range and PositiveNumber checks let a NaN through (every comparison
// with it is false). The option's own check says what range it takes.
void add_common_checks(CLI::App& app) {
  const CLI::Validator finite(
      [](std::string& value) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (end != value.c_str() && !std::isfinite(v)) return "Value " + value + " is not a finite number";
        return "";
      },
      "");
  // A blank positional argument (a file name: '' or spaces, as an empty make variable gives) is
  // bad usage, not a file that cannot be opened (and '' is not stdin: that is '-').
  const CLI::Validator not_blank(
      [](std::string& value) -> std::string {
        if (value.find_first_not_of(" \t\r\n") == std::string::npos) return "a blank name: give a file's name ('-' for stdin)";
        return "";
      },
      "");
  for (CLI::Option* option : app.get_options()) {
    if (option->get_type_name().rfind("FLOAT", 0) == 0) option->check(finite);
    if (option->get_positional()) option->check(not_blank);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) add_common_checks(*sub);
}

// glibc's malloc gives a freed block of 128 KB or more back to the kernel (munmap), and trims
// the heap's free top, so a tool that allocates and frees image-sized buffers over and over
// (SIFT's scale space, OpenCV's thresholded copies of a photo) takes a page fault on every page
// of every new buffer: on the demo that was a third of detect's CPU, in the kernel. Both
// thresholds at 1 GiB keep freed memory for the next buffer of the process instead (mallopt(3));
// the peak resident size is the same (docs/measurements/walkthrough.md).
void keep_freed_memory() {
#if defined(__GLIBC__)
  constexpr int kOneGiB = 1 << 30;
  mallopt(M_MMAP_THRESHOLD, kOneGiB);
  mallopt(M_TRIM_THRESHOLD, kOneGiB);
#endif
}

}  // namespace

int run(int argc, char** argv, const ToolSpec& spec,
        const std::function<void(CLI::App&)>& configure, const std::function<void()>& body) {
  keep_freed_memory();
  std::setlocale(LC_ALL, "C");
  std::locale::global(std::locale::classic());
  for (int sig : kFatalSignals) std::signal(sig, remove_pending_and_reraise);
  log::set_program(spec.name);

  CLI::App app{spec.summary, spec.name};
  app.set_version_flag("--version", std::string(spec.name) + " (photomill) " PHOTOMILL_VERSION);
  app.footer("Example:\n  " + spec.example + "\n\nExit status: 0 ok, 1 bad input or failure, "
             "2 bad usage. Data on stdout, messages on stderr.");
  bool quiet = false;
  bool verbose = false;
  app.add_flag("-q,--quiet", quiet, "Only errors on stderr");
  app.add_flag("-v,--verbose", verbose, "Progress and details on stderr");
  // A refusal of the command line is one line, as every other refusal: "name: problem (see --help)"
  // (CLI11's own adds "Run with --help for more information." on a second line).
  app.failure_message([name = spec.name](const CLI::App*, const CLI::Error& e) {
    return name + ": " + e.what() + " (see --help)\n";
  });
  try {
    configure(app);
    add_common_checks(app);
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  log::set_level(quiet ? log::Level::Quiet : verbose ? log::Level::Verbose : log::Level::Normal);

  // The body's committed outputs are renamed only when it returned and stdout took every byte:
  // a run that fails at any point leaves every previous output as it was.
  g_staging = true;
  struct StagingOff {
    ~StagingOff() {
      g_staging = false;
      discard_staged();
      const std::lock_guard<std::mutex> lock(g_names_mutex);
      g_temp_names.clear();
    }
  } staging_off;
  try {
    body();
    std::cout.flush();
    if (!std::cout) {
      std::cerr << spec.name << ": error writing to stdout\n";
      return 1;
    }
    rename_staged();
    return 0;
  } catch (const UsageError& e) {
    std::cerr << spec.name << ": " << message_line(e.what()) << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << spec.name << ": out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << spec.name << ": " << message_line(e.what()) << "\n";
    return 1;
  }
}

void publish_committed() { rename_staged(); }

void add_presets(CLI::App& app, std::string& chosen, const Presets& presets, const std::string& help) {
  std::vector<std::string> names;
  for (const auto& [name, values] : presets) {
    names.push_back(name);
    for (const PresetValue& v : values) {
      try {
        app.get_option(v.option);
      } catch (const CLI::OptionNotFound&) {
        throw std::logic_error("preset '" + name + "' sets " + v.option + ", which is no option");
      }
    }
  }
  app.add_option("--preset", chosen, help)->check(CLI::IsMember(names));
  app.final_callback([&app, &chosen, presets] {
    for (const auto& [name, values] : presets) {
      if (name != chosen) continue;
      for (const PresetValue& v : values) {
        if (app.count(v.option) == 0) v.set();
      }
    }
  });
}

std::string source_name(const std::string& path) { return path == "-" ? "<stdin>" : path; }

namespace {

// A read buffer over a file descriptor whose read errors name the file: libstdc++'s filebuf
// reports an EIO as "basic_filebuf::underflow error reading the file" without saying which, and
// std::cin's buffer turns it into an end of file. The stream holding it has badbit in its
// exception mask, so the InputError reaches the caller through every istream operation.
class FileReadBuf : public std::streambuf {
public:
  FileReadBuf(int fd, bool owned, std::string source) : fd_(fd), owned_(owned), source_(std::move(source)) {}
  ~FileReadBuf() override {
    if (owned_) ::close(fd_);
  }
  FileReadBuf(const FileReadBuf&) = delete;
  FileReadBuf& operator=(const FileReadBuf&) = delete;

protected:
  int_type underflow() override {
    if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
    ssize_t n = 0;
    do {
      n = ::read(fd_, buffer_.data(), buffer_.size());
    } while (n < 0 && errno == EINTR);
    if (n < 0) {
      // The line the next byte was on, in a text file (a reader that counts lines names its own;
      // one reading the whole file first, read_all, gets it here).
      const std::size_t line = bytes_ > 0 && !binary_ ? lines_ + 1 : 0;
      throw InputError(source_, line, std::string("read error: ") + std::strerror(errno));
    }
    if (n == 0) return traits_type::eof();
    bytes_ += static_cast<std::size_t>(n);
    for (ssize_t i = 0; i < n; ++i) {
      lines_ += buffer_[static_cast<std::size_t>(i)] == '\n' ? 1 : 0;
      binary_ = binary_ || buffer_[static_cast<std::size_t>(i)] == '\0';
    }
    setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
    return traits_type::to_int_type(*gptr());
  }

private:
  int fd_;
  bool owned_;
  std::string source_;
  std::size_t bytes_ = 0;  // read so far
  std::size_t lines_ = 0;  // line ends among them
  bool binary_ = false;    // a NUL byte among them: no lines to name
  std::array<char, 1 << 16> buffer_{};
};

bool is_dev_null(int fd) {
  struct stat a {}, b {};
  return ::fstat(fd, &a) == 0 && ::stat("/dev/null", &b) == 0 && a.st_rdev == b.st_rdev;
}

class FileInput : public std::istream {
public:
  FileInput(int fd, bool owned, const std::string& source) : std::istream(nullptr), buf_(fd, owned, source) {
    rdbuf(&buf_);
    exceptions(std::ios::badbit);
  }

private:
  FileReadBuf buf_;
};

// A write buffer over a file descriptor whose write errors name the output: std::ofstream only
// sets badbit (the body went on writing into a stream that had failed, and the error was found at
// commit without its reason). The stream holding it has badbit in its exception mask, so the
// InputError leaves the first stream operation whose write failed.
class FileWriteBuf : public std::streambuf {
public:
  FileWriteBuf(int fd, std::string name) : fd_(fd), name_(std::move(name)) {
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }
  ~FileWriteBuf() override {
    if (fd_ >= 0) ::close(fd_);
  }
  FileWriteBuf(const FileWriteBuf&) = delete;
  FileWriteBuf& operator=(const FileWriteBuf&) = delete;

  // Writes what is buffered and closes the file, throwing InputError unless all went well (close
  // reports write-back errors: NFS, quotas).
  void close_checked() {
    if (fd_ < 0) return;
    write_buffer();
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail(errno);
  }

protected:
  int_type overflow(int_type c) override {
    write_buffer();
    if (!traits_type::eq_int_type(c, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(c);
      pbump(1);
    }
    return traits_type::not_eof(c);
  }
  int sync() override {
    write_buffer();
    return 0;
  }

private:
  [[noreturn]] void fail(int error) const {
    throw InputError(name_, 0, std::string("write failed: ") + std::strerror(error));
  }
  void write_buffer() {
    const char* p = pbase();
    while (p < pptr()) {
      const ssize_t n = ::write(fd_, p, static_cast<std::size_t>(pptr() - p));
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) {
        const int error = errno;
        setp(buffer_.data(), buffer_.data() + buffer_.size());  // the bytes are lost either way
        fail(error);
      }
      p += n;
    }
    setp(buffer_.data(), buffer_.data() + buffer_.size());
  }

  int fd_;
  std::string name_;
  std::array<char, 1 << 16> buffer_{};
};

class FileOutput : public std::ostream {
public:
  FileOutput(int fd, const std::string& name) : std::ostream(nullptr), buf_(fd, name) {
    rdbuf(&buf_);
    exceptions(std::ios::badbit);
  }
  void close_checked() { buf_.close_checked(); }

private:
  FileWriteBuf buf_;
};

}  // namespace

std::unique_ptr<std::istream> open_input(const std::string& path) {
  if (path == "-" || path.empty()) return std::make_unique<FileInput>(STDIN_FILENO, false, "<stdin>");
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(status)) throw InputError(path, 0, "is a directory");
  // A device other than a terminal (/dev/zero, /dev/urandom, a disk) is endless or not text:
  // refused at once instead of read until the memory runs out. FIFOs and pipes are streams.
  if (std::filesystem::is_block_file(status)) throw InputError(path, 0, "is a block device, not a file");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  if (std::filesystem::is_character_file(status) && ::isatty(fd) == 0 && !is_dev_null(fd)) {
    ::close(fd);
    throw InputError(path, 0, "is a device, not a file (an endless input)");
  }
  return std::make_unique<FileInput>(fd, true, path);
}

std::optional<std::string> file_run_id(const std::string& path) {
  if (path == "-" || path.empty()) return std::nullopt;
  const auto in = open_input(path);
  std::string head(4096, '\0');
  in->read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in->gcount()));
  return find_run_id(head);
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

// Flushes and closes `out`, throwing InputError naming `name` and the system's reason unless
// every byte was written: a write that fails in the flush (a full disk) or a write-back error
// that close reports (NFS, a quota) alike.
void close_checked(std::ofstream& out, const std::string& name) {
  errno = 0;
  out.flush();
  int error = errno;
  bool ok = static_cast<bool>(out);
  out.close();
  if (ok && !out) {
    ok = false;
    error = errno;
  }
  if (!ok) throw InputError(name, 0, std::string("write failed: ") + (error != 0 ? std::strerror(error) : "unknown error"));
}

}  // namespace

OutputFile::OutputFile(std::string path) : path_(std::move(path)), to_stdout_(path_.empty() || path_ == "-") {
  target_ = to_stdout_ ? path_ : follow_links(path_);
  std::error_code ec;
  const auto status = std::filesystem::status(path_, ec);
  direct_ = !to_stdout_ && !ec && std::filesystem::exists(status) && !std::filesystem::is_regular_file(status);
  if (direct_ && std::filesystem::is_directory(status)) throw InputError(path_, 0, "is a directory");
}

OutputFile::~OutputFile() {
  if (!temp_.empty() && !committed_) {
    file_.reset();  // closes the file unchecked: it is removed
    std::remove(temp_.c_str());
    unregister_pending(temp_);
  }
}

const std::string& OutputFile::temp_path() {
  if (temp_.empty() && !to_stdout_ && !direct_) {
    // A library that writes by name would name the temporary file in its error: name the output.
    const auto folder = std::filesystem::path(target_).parent_path();
    std::error_code ec;
    if (!folder.empty() && !std::filesystem::is_directory(folder, ec)) {
      throw InputError(path_, 0, std::string("cannot write: ") +
                                     (std::filesystem::exists(folder, ec) ? "Not a directory" : "No such file or directory"));
    }
  }
  if (temp_.empty()) {
    // stdout and devices: a private temporary file whose contents commit() copies over.
    temp_ = make_temp_name(to_stdout_ || direct_ ? std::filesystem::temp_directory_path() / "photomill-out"
                                                 : std::filesystem::path(target_));
    register_pending(temp_);
    remember_temp_name(temp_, to_stdout_ ? "<stdout>" : path_);
  }
  return temp_;
}

std::ostream& OutputFile::stream() {
  if (to_stdout_) return std::cout;
  if (!file_) {
    const std::string& target = direct_ ? path_ : temp_path();
    const int fd = ::open(target.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) throw InputError(path_, 0, std::string("cannot write: ") + std::strerror(errno));
    file_ = std::make_unique<FileOutput>(fd, path_);
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
    if (file_) static_cast<FileOutput&>(*file_).close_checked();
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
    static_cast<FileOutput&>(*file_).close_checked();
  } else if (!std::filesystem::exists(temp_path())) {
    // Nothing was written through stream() nor by name: create the (empty) file.
    std::ofstream touch(temp_, std::ios::binary);
    if (!touch) throw InputError(path_, 0, std::string("cannot write: ") + std::strerror(errno));
    close_checked(touch, path_);
  }
  sync_file(temp_, path_);
  {
    const std::lock_guard<std::mutex> lock(g_staged_mutex);
    if (g_staging) {  // renamed by run() once every output of the run is complete
      g_staged.push_back({temp_, target_, path_});
      committed_ = true;
      return;
    }
  }
  if (std::rename(temp_.c_str(), target_.c_str()) != 0) {
    throw InputError(path_, 0, std::string("cannot rename temporary file: ") + std::strerror(errno));
  }
  unregister_pending(temp_);
  sync_folder_of(target_);
  committed_ = true;
}

}  // namespace photomill::tool
