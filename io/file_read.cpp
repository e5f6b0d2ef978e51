#include "io/file_read.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <algorithm>
#include <cstring>

namespace shadowcull {

std::string errnoText(int err) {
    std::string s = std::strerror(err);
    // Only the first letter: "Input/output error" -> "input/output error".
    if (!s.empty() && s[0] >= 'A' && s[0] <= 'Z') s[0] = char(s[0] - 'A' + 'a');
    return s;
}

Expected<std::string> readRegularFile(const std::string& path, const std::string& what, ErrorKind missingKind,
                                      size_t maxBytes) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return makeError(missingKind, path, 0, "cannot open " + what + ": " + errnoText(errno));
    struct Closer {
        int fd;
        ~Closer() { ::close(fd); }
    } closer{fd};
    struct stat st {};
    if (::fstat(fd, &st) != 0)
        return makeError(ErrorKind::Io, path, 0, "cannot inspect " + what + ": " + errnoText(errno));
    if (!S_ISREG(st.st_mode)) {
        const char* kind = S_ISDIR(st.st_mode)    ? "a directory"
                           : S_ISFIFO(st.st_mode) ? "a FIFO"
                           : S_ISSOCK(st.st_mode) ? "a socket"
                           : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device"
                                                                          : "not a regular file";
        return makeError(ErrorKind::BadInput, path, 0, what + " is " + kind + ", not a regular file");
    }
    if (uint64_t(st.st_size) > maxBytes)
        return makeError(ErrorKind::BadInput, path, 0,
                         what + " is " + std::to_string(st.st_size) + " bytes, more than the " +
                             std::to_string(maxBytes) + " accepted");
    // A regular file never returns EAGAIN; clear O_NONBLOCK anyway so reads behave as usual.
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    // One buffer of the size fstat gave, read into once; the end is confirmed by a read
    // into a small scratch buffer, so that a file of the expected size (every file not
    // being written meanwhile) is never reallocated: growing the buffer by a block at its
    // end copied every file whole into a buffer twice its size (a dense mesh's OBJ, 6 MB,
    // into 12 MB of fresh pages).
    std::string out;
    out.resize(size_t(st.st_size));
    size_t done = 0;
    auto fail = [&]() { return makeError(ErrorKind::Io, path, 0, "cannot read " + what + ": " + errnoText(errno)); };
    for (;;) {
        if (done < out.size()) {
            const ssize_t n = ::read(fd, out.data() + done, out.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n < 0) return fail();
            if (n == 0) break;  // shrank since fstat
            done += size_t(n);
            continue;
        }
        // Full: the end of the file, or it grew since fstat (append what follows).
        char more[65536];
        const ssize_t n = ::read(fd, more, std::min(sizeof more, maxBytes - done + 1));
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) return fail();
        if (n == 0) break;
        if (done + size_t(n) > maxBytes)
            return makeError(ErrorKind::BadInput, path, 0,
                             what + " grew past the " + std::to_string(maxBytes) + " bytes accepted while it was read");
        out.append(more, size_t(n));
        done += size_t(n);
    }
    out.resize(done);
    return out;
}

}  // namespace shadowcull
