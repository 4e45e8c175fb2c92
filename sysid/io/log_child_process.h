// Reading a log in a forked child process (internal to sysid/io/log_read.cc).
//
// HDF5 1.10 is not hardened against corrupt files: on some it crashes (SEGV inside the library),
// on others it allocates gigabytes (docs/bad-input.md). A log is therefore read in a forked child,
// which sends the checked Log back through a pipe: a crash, a timeout or an allocation beyond a
// cap in the child becomes an h5::Error naming the file, and the parent never runs HDF5 on it.
#pragma once

#include <string>

#include "sysid/io/log.h"

namespace mjsysid::io::internal {

// Runs read_locked(path) (which reads and checks the log; the caller's h5::Mutex() is held) in a
// forked child whose address space is capped at max(1 GiB, 64 x the file size) and returns the
// Log it read. Falls back to reading in this process when no child can be made. Throws h5::Error
// naming the file when the child reports an error, crashes, runs out of its memory or time.
Log ReadInChildProcess(const std::string& path, Log (*read_locked)(const std::string& path));

}  // namespace mjsysid::io::internal
