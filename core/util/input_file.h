// Opening a file the user or a store names, for reading. A FIFO, socket or device where a file belongs
// would block open() or read() forever (a FIFO with no writer) or never end (/dev/zero), so every input
// is opened without blocking and refused unless it is a regular file, with the path and what it is
// named. Symlink loops and other open failures are input errors naming the path, not internal ones.
#pragma once

#include <cstdio>
#include <string>

namespace sl {

// A read-only descriptor of the regular file at `path` (close-on-exec, blocking mode restored), or -1
// when it does not exist (ENOENT). Throws InputError(path, why) when it is a directory, a FIFO, a
// socket or a device, or cannot be opened (a symlink loop: "too many levels of symbolic links").
int open_input_fd(const std::string& path);

// The same, as a FILE* opened "rb"; a missing file throws InputError(path, "no such file").
std::FILE* open_input_file(const std::string& path);

// Throws as open_input_fd does (and for a missing file) unless `path` is a regular file; for readers
// that open the path themselves (libtiff, libnifti).
void check_input_file(const std::string& path);

// What the file type in `mode` (st_mode) is, for messages: "a FIFO", "a directory", ...
std::string file_type_text(unsigned mode);

}  // namespace sl
