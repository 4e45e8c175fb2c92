#include "sysid/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <system_error>

namespace mjsysid::io {
namespace {

// "<path>: <what>: <strerror(err)>"
[[noreturn]] void Fail(const std::string& path, const std::string& what, int err) {
  throw FileError(path + ": " + what + ": " + std::strerror(err));
}

// the temporary file of one write: removed unless the rename committed it
class TempFile {
 public:
  explicit TempFile(const std::string& path) : path_(path + ".tmp-" + std::to_string(::getpid())) {}
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    if (!committed_) {
      std::error_code ec;
      std::filesystem::remove(path_, ec);
    }
  }
  const std::string& path() const { return path_; }
  void Commit() { committed_ = true; }

 private:
  const std::string path_;
  bool committed_ = false;
};

// flushes the closed file `tmp` (written by someone else) to disk
void SyncFile(const std::string& tmp, const std::string& path) {
  const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) Fail(path, "cannot open " + tmp + " to flush it", errno);
  const int status = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  if (status != 0) Fail(path, "cannot flush " + tmp, err);
}

// best effort: makes a rename in the folder of `path` durable
void SyncFolder(const std::string& path) {
  std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (folder.empty()) folder = ".";
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// the flushed temporary file renamed over `path`, then the folder flushed
void Commit(TempFile& tmp, const std::string& path) {
  if (std::rename(tmp.path().c_str(), path.c_str()) != 0) {
    Fail(path, "cannot rename " + tmp.path() + " to it", errno);
  }
  tmp.Commit();
  SyncFolder(path);
}

}  // namespace

void ReplaceAtomically(const std::string& path,
                       const std::function<void(const std::string& tmp)>& write) {
  TempFile tmp(path);
  write(tmp.path());
  SyncFile(tmp.path(), path);
  Commit(tmp, path);
}

void WriteFileAtomically(const std::string& path, const std::string& bytes) {
  TempFile tmp(path);

  // create, write, flush to the kernel, flush to disk, close: each checked, errno read at once
  std::FILE* f = std::fopen(tmp.path().c_str(), "wb");
  if (f == nullptr) Fail(path, "cannot create " + tmp.path(), errno);
  const char* failed = nullptr;
  int err = 0;
  if (std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size()) {
    failed = "cannot write ";
    err = errno;
  } else if (std::fflush(f) != 0) {
    failed = "cannot write ";
    err = errno;
  } else if (::fsync(::fileno(f)) != 0) {
    failed = "cannot flush ";
    err = errno;
  }
  if (std::fclose(f) != 0 && failed == nullptr) {
    failed = "cannot close ";
    err = errno;
  }
  if (failed != nullptr) Fail(path, failed + tmp.path(), err);

  Commit(tmp, path);
}

}  // namespace mjsysid::io
