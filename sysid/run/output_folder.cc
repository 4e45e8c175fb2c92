#include "sysid/run/output_folder.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <random>
#include <system_error>

#include "sysid/io/atomic_file.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;

// the absolute normal form of `p`, symlinks resolved as far as the path exists, without a
// trailing separator
fs::path Resolved(const std::string& p) {
  std::error_code ec;
  fs::path r = fs::weakly_canonical(fs::absolute(p), ec);
  if (ec) r = fs::absolute(p).lexically_normal();
  if (!r.has_filename() && r.has_parent_path()) r = r.parent_path();
  return r;
}

// true when `inner` is `outer` or lies under it
bool IsUnder(const fs::path& inner, const fs::path& outer) {
  auto o = outer.begin();
  auto i = inner.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

// "<path>: <what>: <strerror(err)>" as a FileError
[[noreturn]] void Fail(const std::string& path, const std::string& what, int err) {
  throw io::FileError(path + ": " + what + ": " + std::strerror(err));
}

// flushes a file or folder to disk
void Sync(const std::string& path, bool folder) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | (folder ? O_DIRECTORY : 0));
  if (fd < 0) Fail(path, "cannot open to flush it", errno);
  const int status = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  // some file systems refuse fsync on a folder; a file's fsync failing is a write failure
  if (status != 0 && !(folder && (err == EINVAL || err == EBADF))) {
    Fail(path, "cannot flush to disk", err);
  }
}

// the folder without a trailing separator, as given (relative stays relative)
std::string Trimmed(const std::string& dir) {
  fs::path p = fs::path(dir).lexically_normal();
  if (!p.has_filename() && p.has_parent_path()) p = p.parent_path();
  return p.string();
}

// the files that make a folder another run's: its result, or its checkpoint (an unfinished run)
bool IsRunFile(const std::string& name) {
  return name == "result.yaml" || name == "result.h5" || name == "checkpoint.yaml" ||
         name == "checkpoint.h5";
}

}  // namespace

OtherRun OtherRunInside(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(dir, ec))) return {};
  // symlinks are not followed: deleting the folder deletes a symlink, not what it points to
  fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec);
  for (; !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const fs::path& p = it->path();
    const fs::file_status st = it->symlink_status(ec);
    if (ec) break;
    const std::string name = p.filename().string();
    if (fs::is_directory(st) && name.size() > 8 && name.substr(name.size() - 8) == ".partial") {
      return {p.string(), "the staging folder of a fit into " + p.parent_path().string() + "/" +
                              name.substr(0, name.size() - 8)};
    }
    if (it.depth() >= 1 && fs::is_regular_file(st) && IsRunFile(name)) {
      return {p.parent_path().string(),
              "a fit's " + std::string(name.rfind("result", 0) == 0 ? "result" : "checkpoint") +
                  " folder (it has " + name + ")"};
    }
  }
  return {};
}

namespace {

// DIR.partial, which a fit into DIR deletes when it starts, holds no other run (at any depth)
void CheckStagingFolder(const std::string& dir) {
  const std::string staging = StagingFolder(dir);
  if (const OtherRun other = OtherRunInside(staging); !other.path.empty()) {
    throw OutputError("--out " + dir + ": " + staging + ", the staging folder that a fit into " +
                      Trimmed(dir) + " deletes first, holds " + other.path + ", " + other.what +
                      " (hint: move " + other.path + " out)");
  }
}

}  // namespace

bool SamePath(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec) && !ec;
  return Resolved(a) == Resolved(b);
}

void CheckOutputFile(const std::string& out, const std::vector<std::string>& inputs,
                     const std::string& option) {
  for (const std::string& in : inputs) {
    if (SamePath(out, in)) {
      throw OutputError(option + " " + out + " is an input of this run (" + in +
                        "): it would be overwritten (hint: choose another output file)");
    }
  }
}

void CheckOutputFolder(const std::string& dir, const std::vector<std::string>& inputs, bool force) {
  const fs::path d = Resolved(dir);
  for (const std::string& in : inputs) {
    if (IsUnder(Resolved(in), d)) {
      throw OutputError("--out " + dir + ": the output folder holds " + in +
                        ", an input of this run; a fit replaces the whole folder (hint: choose "
                        "a folder of its own, e.g. results/NAME)");
    }
  }
  // replacing the folder that holds the current directory cannot work (the rename fails, busy)
  std::error_code ec;
  const fs::path cwd = Resolved(fs::current_path(ec).string());
  if (!ec && IsUnder(cwd, d)) {
    throw OutputError(
        "--out " + dir + ": the output folder " +
        (cwd == d ? "is the current directory" : "holds the current directory " + cwd.string()) +
        "; a fit replaces the whole folder (hint: choose a folder of its own, "
        "e.g. results/NAME)");
  }
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) {
    CheckStagingFolder(dir);
    return;
  }
  if (!fs::is_directory(st)) {
    throw OutputError("--out " + dir + ": exists and is not a folder (hint: choose another path)");
  }
  // another run's result or checkpoint inside: never deleted, not even with --force
  if (const OtherRun other = OtherRunInside(dir); !other.path.empty()) {
    throw OutputError("--out " + dir + ": the output folder holds " + other.path + ", " +
                      other.what +
                      "; a fit replaces the whole folder and would delete it, --force or not "
                      "(hint: choose a folder of its own, e.g. a new folder beside it, or move " +
                      other.path + " out)");
  }
  CheckStagingFolder(dir);
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw OutputError("--out " + dir +
                      ": the output folder is not writable: " + std::strerror(errno));
  }
  const bool empty = fs::is_empty(dir, ec);
  const bool result =
      fs::exists(fs::path(dir) / "result.yaml", ec) || fs::exists(fs::path(dir) / "result.h5", ec);
  if (!empty && !result && !force) {
    throw OutputError("--out " + dir +
                      ": exists and is not an mjsysid result folder (no result.yaml); a fit "
                      "replaces the whole folder (hint: choose another folder, or --force to "
                      "replace it and delete its files)");
  }
}

std::string NewRunId() {
  const std::time_t t = std::time(nullptr);
  char when[32];
  std::strftime(when, sizeof(when), "%Y%m%dT%H%M%SZ", std::gmtime(&t));
  std::random_device random;
  char buf[96];
  std::snprintf(buf, sizeof(buf), "%s-%ld-%08x", when, static_cast<long>(::getpid()),
                static_cast<unsigned>(random()));
  return buf;
}

FolderLock::FolderLock(const std::string& dir, const std::string& what)
    : path_(Trimmed(dir) + ".lock") {
  // a lock file unlinked by its previous holder between our open and flock is not the lock:
  // retry until the locked file is the one at path_
  for (int attempt = 0; attempt < 100; ++attempt) {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) Fail(path_, "cannot create the lock file", errno);
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      char holder[256] = {0};
      const ssize_t n = ::pread(fd_, holder, sizeof(holder) - 1, 0);
      ::close(fd_);
      fd_ = -1;
      if (err != EWOULDBLOCK) Fail(path_, "cannot lock", err);
      std::string who = n > 0 ? std::string(holder, static_cast<size_t>(n)) : "another process";
      while (!who.empty() && who.back() == '\n') who.pop_back();
      throw OutputError(Trimmed(dir) + " is in use: " + who + " (lock " + path_ +
                        "); wait for it to finish or stop it, or choose another --out");
    }
    struct stat held {};
    struct stat named {};
    if (::fstat(fd_, &held) == 0 && ::stat(path_.c_str(), &named) == 0 &&
        held.st_ino == named.st_ino && held.st_dev == named.st_dev) {
      break;
    }
    ::close(fd_);
    fd_ = -1;
  }
  if (fd_ < 0) throw OutputError(path_ + ": cannot take the lock (it keeps being replaced)");
  // name the holder for the message of a second process
  const std::time_t t = std::time(nullptr);
  char when[32];
  std::strftime(when, sizeof(when), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  const std::string text =
      what + " (pid " + std::to_string(::getpid()) + ", started " + when + ")\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, text.data(), text.size(), 0) < 0) {
    // the lock holds without the text; the other process's message is then generic
  }
}

FolderLock::~FolderLock() {
  if (fd_ < 0) return;
  ::unlink(path_.c_str());  // while still held: a waiting process re-checks the path
  ::close(fd_);
}

std::string StagingFolder(const std::string& dir) { return Trimmed(dir) + ".partial"; }

std::string CreateStagingFolder(const std::string& dir, bool keep_checkpoint) {
  const std::string staging = StagingFolder(dir);
  std::error_code ec;
  // CheckOutputFolder refused this before the fit; checked again before deleting anything
  CheckStagingFolder(dir);
  if (keep_checkpoint && fs::is_directory(staging, ec)) {
    for (const fs::directory_entry& e : fs::directory_iterator(staging)) {
      const std::string name = e.path().filename().string();
      if (name != "checkpoint.yaml" && name != "checkpoint.h5") fs::remove_all(e.path(), ec);
    }
    return staging;
  }
  fs::remove_all(staging, ec);
  if (ec) {
    throw OutputError(staging + ": cannot delete the unfinished run left there: " + ec.message());
  }
  fs::create_directory(staging, ec);
  if (ec) {
    throw OutputError(staging + ": cannot create the staging folder of --out " + dir + ": " +
                      ec.message() + " (hint: the folder that holds --out must be writable)");
  }
  return staging;
}

void PublishFolder(const std::string& staging, const std::string& dir) {
  // every file, then the folder itself, on disk
  for (const fs::directory_entry& e : fs::directory_iterator(staging)) {
    if (e.is_regular_file()) Sync(e.path().string(), false);
  }
  Sync(staging, true);

  // swap in one rename, or rename when there is no previous result
  const std::string target = Trimmed(dir);
  std::error_code ec;
  if (fs::exists(target, ec)) {
    if (::renameat2(AT_FDCWD, staging.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) != 0) {
      Fail(target, "cannot swap the new result " + staging + " in", errno);
    }
    // staging is now the previous folder: deleted unless another run's folder got into it
    // during the fit (CheckOutputFolder refused one before), which is kept and named
    if (const OtherRun other = OtherRunInside(staging); !other.path.empty()) {
      fs::path parent = fs::path(target).parent_path();
      Sync(parent.empty() ? "." : parent.string(), true);
      throw io::FileError(target + ": the new result is in place, but the previous folder, now " +
                          staging + ", holds " + other.path + ", " + other.what +
                          ", put there during the fit; it was not deleted (move it out, then "
                          "delete " +
                          staging + ")");
    }
    fs::remove_all(staging, ec);  // the previous result; left behind it is harmless
  } else if (std::rename(staging.c_str(), target.c_str()) != 0) {
    Fail(target, "cannot rename the new result " + staging + " to it", errno);
  }
  fs::path parent = fs::path(target).parent_path();
  if (parent.empty()) parent = ".";
  Sync(parent.string(), true);
}

}  // namespace mjsysid::run
