/* A write-fault shim for docs/scripts/write_faults.py (LD_PRELOAD): counts every file opened
 * for writing under WF_ROOT (colon-separated folder prefixes) and makes the WF_FAIL_AT-th one
 * fail with WF_ERRNO: EROFS at the open itself, any other errno (ENOSPC, EIO) at its first
 * write and every later one (the open succeeds, as on a full disk). WF_LOG receives one line
 * per counted open ("open <n> <path>") and one when the fault strikes ("fault <n> <path>").
 * The open and write calls (write, pwrite, writev, sendfile, copy_file_range) of every
 * library in the process go through here: Python's files and copies,
 * Arrow's parquet writer, matplotlib's, XLA's compilation cache. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <unistd.h>

#define MAX_FD 65536
static unsigned char faulty[MAX_FD]; /* 1: this descriptor's writes fail */
static long number[MAX_FD];           /* the count of a counted descriptor's open, until written */
static long opened = 0;              /* write-opens counted under WF_ROOT */

static void note(const char *kind, long n, const char *path) {
    const char *log = getenv("WF_LOG");
    if (!log) return;
    char line[4352];
    int len = snprintf(line, sizeof line, "%s %ld %s\n", kind, n, path);
    if (len <= 0) return;
    if (len >= (int)sizeof line) len = sizeof line - 1;
    int fd = (int)syscall(SYS_openat, AT_FDCWD, log, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (fd < 0) return;
    syscall(SYS_write, fd, line, (size_t)len);
    syscall(SYS_close, fd);
}

/* The absolute path of (dirfd, path), in out (empty when it cannot be formed). */
static void absolute(int dirfd, const char *path, char *out, size_t size) {
    out[0] = 0;
    if (!path) return;
    if (path[0] == '/') {
        snprintf(out, size, "%s", path);
        return;
    }
    char base[4096];
    if (dirfd == AT_FDCWD) {
        if (!getcwd(base, sizeof base)) return;
    } else {
        char link[64];
        snprintf(link, sizeof link, "/proc/self/fd/%d", dirfd);
        ssize_t n = readlink(link, base, sizeof base - 1);
        if (n <= 0) return;
        base[n] = 0;
    }
    snprintf(out, size, "%s/%s", base, path);
}

static int watched(const char *path) {
    const char *roots = getenv("WF_ROOT");
    if (!roots || !path[0]) return 0;
    char copy[4096];
    snprintf(copy, sizeof copy, "%s", roots);
    for (char *save = NULL, *root = strtok_r(copy, ":", &save); root;
         root = strtok_r(NULL, ":", &save)) {
        size_t n = strlen(root);
        if (n && strncmp(path, root, n) == 0 && (path[n] == '/' || path[n] == 0)) return 1;
    }
    return 0;
}

/* Before an open: its count (0: not counted) in *n, and 1 if this open is the one to fault
 * (errno chosen by WF_ERRNO). */
static int counted(int dirfd, const char *path, int flags, char *where, size_t size, long *n) {
    *n = 0;
    if (!(flags & (O_WRONLY | O_RDWR | O_CREAT | O_TRUNC))) return 0;
    absolute(dirfd, path, where, size);
    if (!watched(where)) return 0;
    *n = __atomic_add_fetch(&opened, 1, __ATOMIC_SEQ_CST);
    note("open", *n, where);
    const char *at = getenv("WF_FAIL_AT");
    return at && atol(at) == *n;
}

static int fault_errno(void) {
    const char *e = getenv("WF_ERRNO");
    return e ? atoi(e) : ENOSPC;
}

static int opened_fd(int fd, int fault, long n) {
    if (fd >= 0 && fd < MAX_FD) {
        faulty[fd] = fault ? 1 : 0;
        number[fd] = n;
    }
    return fd;
}

static int do_openat(int dirfd, const char *path, int flags, mode_t mode) {
    char where[4096];
    long n;
    int fault = counted(dirfd, path, flags, where, sizeof where, &n);
    if (fault && fault_errno() == EROFS) {
        note("fault", n, where);
        errno = EROFS;
        return -1;
    }
    int fd = (int)syscall(SYS_openat, dirfd, path, flags, mode); /* -1 and errno on failure */
    return opened_fd(fd, fault, n);
}

static mode_t mode_of(int flags, va_list ap) {
    return (flags & (O_CREAT | O_TMPFILE)) ? (mode_t)va_arg(ap, int) : 0;
}

int open(const char *path, int flags, ...) {
    va_list ap;
    va_start(ap, flags);
    mode_t mode = mode_of(flags, ap);
    va_end(ap);
    return do_openat(AT_FDCWD, path, flags, mode);
}
int open64(const char *path, int flags, ...) {
    va_list ap;
    va_start(ap, flags);
    mode_t mode = mode_of(flags, ap);
    va_end(ap);
    return do_openat(AT_FDCWD, path, flags, mode);
}
int openat(int dirfd, const char *path, int flags, ...) {
    va_list ap;
    va_start(ap, flags);
    mode_t mode = mode_of(flags, ap);
    va_end(ap);
    return do_openat(dirfd, path, flags, mode);
}
int openat64(int dirfd, const char *path, int flags, ...) {
    va_list ap;
    va_start(ap, flags);
    mode_t mode = mode_of(flags, ap);
    va_end(ap);
    return do_openat(dirfd, path, flags, mode);
}
int creat(const char *path, mode_t mode) {
    return do_openat(AT_FDCWD, path, O_CREAT | O_WRONLY | O_TRUNC, mode);
}
int creat64(const char *path, mode_t mode) {
    return do_openat(AT_FDCWD, path, O_CREAT | O_WRONLY | O_TRUNC, mode);
}

static void fd_path(int fd, char *path, size_t size) {
    char link[64];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = readlink(link, path, size - 1);
    path[n > 0 ? n : 0] = 0;
}

/* A write to a faulty descriptor fails (the first time it strikes, the log says so); the
 * first write through a counted open is logged ("write <n> <path>"). */
static int strikes(int fd) {
    if (fd < 0 || fd >= MAX_FD) return 0;
    char path[4096];
    if (number[fd]) {
        fd_path(fd, path, sizeof path);
        note("write", number[fd], path);
        if (!faulty[fd]) number[fd] = 0;
    }
    if (!faulty[fd]) return 0;
    if (faulty[fd] == 1) {
        fd_path(fd, path, sizeof path);
        note("fault", number[fd], path);
        number[fd] = 0;
        faulty[fd] = 2;
    }
    errno = fault_errno();
    return 1;
}

ssize_t write(int fd, const void *buf, size_t count) {
    if (strikes(fd)) return -1;
    long r = syscall(SYS_write, fd, buf, count);
    return r; /* syscall(): -1 and errno on failure */
}
ssize_t pwrite(int fd, const void *buf, size_t count, off_t offset) {
    if (strikes(fd)) return -1;
    long r = syscall(SYS_pwrite64, fd, buf, count, offset);
    return r; /* syscall(): -1 and errno on failure */
}
ssize_t pwrite64(int fd, const void *buf, size_t count, off_t offset) {
    return pwrite(fd, buf, count, offset);
}
ssize_t writev(int fd, const struct iovec *iov, int iovcnt) {
    if (strikes(fd)) return -1;
    long r = syscall(SYS_writev, fd, iov, iovcnt);
    return r; /* syscall(): -1 and errno on failure */
}
/* shutil.copyfile writes through sendfile (Python's fast copy on Linux), other copies through
 * copy_file_range: the same writes, the same faults. off_t is 64 bits on x86-64 Linux. */
ssize_t sendfile(int out_fd, int in_fd, off_t *offset, size_t count) {
    if (strikes(out_fd)) return -1;
    return syscall(SYS_sendfile, out_fd, in_fd, offset, count);
}
ssize_t sendfile64(int out_fd, int in_fd, off_t *offset, size_t count) {
    return sendfile(out_fd, in_fd, offset, count);
}
ssize_t copy_file_range(int in_fd, off_t *in_off, int out_fd, off_t *out_off, size_t len,
                        unsigned int flags) {
    if (strikes(out_fd)) return -1;
    return syscall(SYS_copy_file_range, in_fd, in_off, out_fd, out_off, len, flags);
}
int close(int fd) {
    if (fd >= 0 && fd < MAX_FD) {
        faulty[fd] = 0;
        number[fd] = 0;
    }
    return (int)syscall(SYS_close, fd);
}
