/* An LD_PRELOAD fault-injection shim for the I/O fault tests (issue #25): it makes reads of a
 * chosen input fail with EIO in the middle of the file and writes of a chosen output fail with
 * ENOSPC, as a failing disk or a full one would, without either. Driven by the environment:
 *
 *   PHOTOMILL_FAULT_READ=NAME      reads of a regular file whose name (last path component)
 *                                  contains NAME fail with EIO once PHOTOMILL_FAULT_READ_AT bytes
 *                                  of it were read (default: half its size): the read that would
 *                                  cross that offset is shortened to end there (a short read is
 *                                  legal), the next one fails. An EIO in the middle of the file.
 *   PHOTOMILL_FAULT_READ_NTH=N     the N-th read (counted from 1) of any regular file other than
 *                                  standard input, output and error fails with EIO.
 *   PHOTOMILL_FAULT_WRITE=NAME     writes to a regular file whose name contains NAME fail with
 *                                  ENOSPC once the file would grow past PHOTOMILL_FAULT_WRITE_AT
 *                                  bytes (default 0: the first write), the write that crosses it
 *                                  shortened to end there. An output's temporary name
 *                                  (.NAME.tmp.PID.N) contains NAME.
 *   PHOTOMILL_FAULT_WRITE_NTH=N    the N-th write of any regular file other than standard
 *                                  output and error fails with ENOSPC.
 *   PHOTOMILL_FAULT_FSYNC=NAME     fsync/fdatasync of a file whose name contains NAME fail with EIO.
 *   PHOTOMILL_FAULT_CLOSE=NAME     close of a file whose name contains NAME closes it but returns
 *                                  EIO (as NFS reports a write-back error).
 *   PHOTOMILL_FAULT_KILL_RENAME=N  the process kills itself with SIGKILL at its N-th rename(2)
 *                                  (counted from 1), before making it: the outputs renamed
 *                                  before are new, the others previous. A kill between two
 *                                  renames, which a kill at a random moment almost never hits.
 *   PHOTOMILL_FAULT_LOG=PATH       appends one line per injected fault ("write ENOSPC NAME"), so
 *                                  a test can tell that the fault was injected at all.
 *
 * Covered calls: read, readv, pread(64), __read_chk, write, writev, pwrite(64), fsync, fdatasync,
 * close, rename. stdio's internal reads and writes (fread, fwrite) do not go through these symbols and
 * are not reached: photomill reads and writes its files through file descriptors (open_input,
 * std::fstream). Under AddressSanitizer the shim is not first in the library list:
 * ASAN_OPTIONS=verify_asan_link_order=0 lets the process start. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

typedef ssize_t (*read_fn)(int, void*, size_t);
typedef ssize_t (*write_fn)(int, const void*, size_t);
typedef ssize_t (*readv_fn)(int, const struct iovec*, int);
typedef ssize_t (*writev_fn)(int, const struct iovec*, int);
typedef ssize_t (*pread_fn)(int, void*, size_t, off_t);
typedef ssize_t (*pwrite_fn)(int, const void*, size_t, off_t);
typedef int (*int_fd_fn)(int);
typedef int (*rename_fn)(const char*, const char*);

/* The next definition of a call (libc's, or AddressSanitizer's interceptor). A function pointer
 * copied out of dlsym's object pointer: ISO C has no cast between the two. */
#define DEFINE_REAL(type, name)                \
  static type real_##name(void) {                \
    type f;                                      \
    void* p = dlsym(RTLD_NEXT, #name);           \
    memcpy(&f, &p, sizeof f);                    \
    return f;                                    \
  }
DEFINE_REAL(read_fn, read)
DEFINE_REAL(write_fn, write)
DEFINE_REAL(readv_fn, readv)
DEFINE_REAL(writev_fn, writev)
DEFINE_REAL(pread_fn, pread)
DEFINE_REAL(pwrite_fn, pwrite)
DEFINE_REAL(int_fd_fn, fsync)
DEFINE_REAL(int_fd_fn, fdatasync)
DEFINE_REAL(int_fd_fn, close)
DEFINE_REAL(rename_fn, rename)

static long env_long(const char* name, long fallback) {
  const char* v = getenv(name);
  return v != NULL && *v != '\0' ? strtol(v, NULL, 10) : fallback;
}

/* The name of the file behind `fd` when it is a regular file, else 0. */
static int regular_file_name(int fd, char* name, size_t size) {
  struct stat st;
  if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return 0;
  char link[64];
  snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
  char path[4096];
  const ssize_t n = readlink(link, path, sizeof path - 1);
  if (n <= 0) return 0;
  path[n] = '\0';
  const char* base = strrchr(path, '/');
  base = base != NULL ? base + 1 : path;
  snprintf(name, size, "%s", base);
  return 1;
}

static int matches(int fd, const char* variable, char* name, size_t size) {
  const char* want = getenv(variable);
  if (want == NULL || *want == '\0') return 0;
  return regular_file_name(fd, name, size) && strstr(name, want) != NULL;
}

static void log_fault(const char* what, const char* name) {
  const char* log = getenv("PHOTOMILL_FAULT_LOG");
  if (log == NULL || *log == '\0') return;
  const int fd = open(log, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return;
  char line[512];
  const int n = snprintf(line, sizeof line, "%s %s\n", what, name);
  if (n > 0) {
    /* The real write: this file is not a target of the faults. */
    const ssize_t w = real_write()(fd, line, (size_t)n < sizeof line ? (size_t)n : sizeof line - 1);
    (void)w;
  }
  real_close()(fd);
}

static long g_reads = 0;   /* regular-file reads so far (PHOTOMILL_FAULT_READ_NTH) */
static long g_writes = 0;  /* regular-file writes so far (PHOTOMILL_FAULT_WRITE_NTH) */

/* How many of `count` bytes a read of `fd` at `offset` may deliver: `count`, fewer (the read
 * stops at the fault's offset), or -1 (it fails with EIO). */
static ssize_t read_allowance(int fd, size_t count, off_t offset) {
  char name[4096];
  if (fd > 2 && getenv("PHOTOMILL_FAULT_READ_NTH") != NULL && regular_file_name(fd, name, sizeof name)) {
    if (__atomic_add_fetch(&g_reads, 1, __ATOMIC_SEQ_CST) == env_long("PHOTOMILL_FAULT_READ_NTH", 0)) {
      log_fault("read EIO", name);
      return -1;
    }
  }
  if (!matches(fd, "PHOTOMILL_FAULT_READ", name, sizeof name)) return (ssize_t)count;
  struct stat st;
  if (fstat(fd, &st) != 0) return (ssize_t)count;
  const long at = env_long("PHOTOMILL_FAULT_READ_AT", (long)(st.st_size / 2));
  if (offset < 0) offset = lseek(fd, 0, SEEK_CUR);
  if (offset >= at) {
    log_fault("read EIO", name);
    return -1;
  }
  return (off_t)count > at - offset ? (ssize_t)(at - offset) : (ssize_t)count;
}

/* The same for a write of `count` bytes at `offset` (-1: at the current offset): ENOSPC. */
static ssize_t write_allowance(int fd, size_t count, off_t offset) {
  char name[4096];
  if (fd > 2 && getenv("PHOTOMILL_FAULT_WRITE_NTH") != NULL && regular_file_name(fd, name, sizeof name)) {
    if (__atomic_add_fetch(&g_writes, 1, __ATOMIC_SEQ_CST) == env_long("PHOTOMILL_FAULT_WRITE_NTH", 0)) {
      log_fault("write ENOSPC", name);
      return -1;
    }
  }
  if (count == 0 || !matches(fd, "PHOTOMILL_FAULT_WRITE", name, sizeof name)) return (ssize_t)count;
  const long at = env_long("PHOTOMILL_FAULT_WRITE_AT", 0);
  if (offset < 0) offset = lseek(fd, 0, SEEK_CUR);
  if (offset >= at) {
    log_fault("write ENOSPC", name);
    return -1;
  }
  return (off_t)count > at - offset ? (ssize_t)(at - offset) : (ssize_t)count;
}

ssize_t read(int fd, void* buf, size_t count) {
  const ssize_t allowed = read_allowance(fd, count, -1);
  if (allowed < 0) {
    errno = EIO;
    return -1;
  }
  return real_read()(fd, buf, (size_t)allowed);
}

ssize_t __read_chk(int fd, void* buf, size_t count, size_t buflen) {
  (void)buflen;
  return read(fd, buf, count);
}

ssize_t pread(int fd, void* buf, size_t count, off_t offset) {
  const ssize_t allowed = read_allowance(fd, count, offset);
  if (allowed < 0) {
    errno = EIO;
    return -1;
  }
  return real_pread()(fd, buf, (size_t)allowed, offset);
}

ssize_t pread64(int fd, void* buf, size_t count, off_t offset) { return pread(fd, buf, count, offset); }

static size_t iov_total(const struct iovec* iov, int n) {
  size_t total = 0;
  for (int i = 0; i < n; ++i) total += iov[i].iov_len;
  return total;
}

ssize_t readv(int fd, const struct iovec* iov, int iovcnt) {
  const size_t total = iov_total(iov, iovcnt);
  const ssize_t allowed = read_allowance(fd, total, -1);
  if (allowed < 0) {
    errno = EIO;
    return -1;
  }
  if ((size_t)allowed == total) return real_readv()(fd, iov, iovcnt);
  /* Shortened: into the first buffers only (a short read). */
  ssize_t done = 0;
  for (int i = 0; i < iovcnt && done < allowed; ++i) {
    const size_t want = iov[i].iov_len < (size_t)(allowed - done) ? iov[i].iov_len : (size_t)(allowed - done);
    const ssize_t n = real_read()(fd, iov[i].iov_base, want);
    if (n < 0) return done > 0 ? done : n;
    done += n;
    if ((size_t)n < want) break;
  }
  return done;
}

ssize_t write(int fd, const void* buf, size_t count) {
  const ssize_t allowed = write_allowance(fd, count, -1);
  if (allowed < 0) {
    errno = ENOSPC;
    return -1;
  }
  return real_write()(fd, buf, (size_t)allowed);
}

ssize_t pwrite(int fd, const void* buf, size_t count, off_t offset) {
  const ssize_t allowed = write_allowance(fd, count, offset);
  if (allowed < 0) {
    errno = ENOSPC;
    return -1;
  }
  return real_pwrite()(fd, buf, (size_t)allowed, offset);
}

ssize_t pwrite64(int fd, const void* buf, size_t count, off_t offset) { return pwrite(fd, buf, count, offset); }

ssize_t writev(int fd, const struct iovec* iov, int iovcnt) {
  const size_t total = iov_total(iov, iovcnt);
  const ssize_t allowed = write_allowance(fd, total, -1);
  if (allowed < 0) {
    errno = ENOSPC;
    return -1;
  }
  if ((size_t)allowed == total) return real_writev()(fd, iov, iovcnt);
  ssize_t done = 0;
  for (int i = 0; i < iovcnt && done < allowed; ++i) {
    const size_t want = iov[i].iov_len < (size_t)(allowed - done) ? iov[i].iov_len : (size_t)(allowed - done);
    const ssize_t n = real_write()(fd, iov[i].iov_base, want);
    if (n < 0) return done > 0 ? done : n;
    done += n;
    if ((size_t)n < want) break;
  }
  return done;
}

static int sync_fault(int fd) {
  char name[4096];
  if (!matches(fd, "PHOTOMILL_FAULT_FSYNC", name, sizeof name)) return 0;
  log_fault("fsync EIO", name);
  errno = EIO;
  return 1;
}

int fsync(int fd) { return sync_fault(fd) ? -1 : real_fsync()(fd); }
int fdatasync(int fd) { return sync_fault(fd) ? -1 : real_fdatasync()(fd); }

int close(int fd) {
  char name[4096];
  const int fault = matches(fd, "PHOTOMILL_FAULT_CLOSE", name, sizeof name);
  const int rc = real_close()(fd);
  if (fault && rc == 0) {
    log_fault("close EIO", name);
    errno = EIO;
    return -1;
  }
  return rc;
}

static long g_renames = 0; /* renames so far (PHOTOMILL_FAULT_KILL_RENAME) */

int rename(const char* from, const char* to) {
  const long kill_at = env_long("PHOTOMILL_FAULT_KILL_RENAME", 0);
  if (kill_at > 0 && __atomic_add_fetch(&g_renames, 1, __ATOMIC_SEQ_CST) == kill_at) {
    log_fault("kill before rename", to);
    raise(SIGKILL);
  }
  return real_rename()(from, to);
}
