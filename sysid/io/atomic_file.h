// Atomic file replacement: the one way every writer of mjsysid (logs, results, the report) puts a
// file on disk. A reader of PATH sees the old file or the complete new one, never a partial
// write, also after a crash or a power loss.
//
// - The new content is written to PATH.tmp-<pid> in the same folder, flushed to disk (fsync),
//   renamed over PATH, and then the folder is flushed so that the rename itself is durable.
// - On failure PATH is left byte-identical and the temporary file is removed.
// - Errors throw FileError "<PATH>: <what failed>: <the system's reason>", the reason read from
//   errno right after the failing call (e.g. "No space left on device", "Permission denied").
// - Flushing the folder is best effort: some file systems refuse fsync on a folder, and by then
//   the new file is already in place.
// - Thread safety: different paths may be written from different threads; two threads of one
//   process writing the same PATH at once share the temporary name and must not.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

namespace mjsysid::io {

// a file could not be written; the message names the file and the reason
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// `write(tmp)` creates and completely writes the file `tmp` (= path + ".tmp-<pid>") and closes
// it; the file is then flushed to disk and renamed over `path`. Whatever `write` throws
// propagates (the temporary removed, `path` untouched); flush and rename failures throw
// FileError.
void ReplaceAtomically(const std::string& path,
                       const std::function<void(const std::string& tmp)>& write);

// `bytes` as the whole content of `path`, by the pattern above; throws FileError
void WriteFileAtomically(const std::string& path, const std::string& bytes);

}  // namespace mjsysid::io
