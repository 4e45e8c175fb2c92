// Where a run's outputs go, so that results are never lost or mixed (issue 13):
//
// - Outputs never overwrite inputs: CheckOutputFile / CheckOutputFolder throw OutputError (bad
//   input, exit 2) when an output resolves to an input of the run (same file through any path,
//   symlink or hard link), or when a folder output would hold an input.
// - A result folder is one run: a fit holds DIR's lock (FolderLock, the file DIR.lock beside DIR),
//   writes everything into the staging folder DIR.partial beside DIR, and PublishFolder swaps the
//   complete staging folder with DIR in one atomic rename (renameat2 RENAME_EXCHANGE) and deletes
//   the previous result. A kill at any moment leaves DIR as the previous complete result or the
//   new complete one; DIR.partial then holds the unfinished run (its checkpoint) or the replaced
//   previous result, and the next fit into DIR deletes it.
// - A fit never deletes another run: an output folder (or its DIR.partial) holding another run's
//   result or checkpoint at any depth is refused (OtherRunInside), whatever --force.
// - Every file of a run carries its run id (NewRunId): see sysid/io/result.h.
//
// Failure: OutputError for paths the user gave (exit 2), io::FileError for the file system
// refusing a write (the message names the file and the system's reason).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace mjsysid::run {

// an output path that must not be used (it is an input, it is foreign, it is locked)
class OutputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// true when `a` and `b` name the same file: the same inode when both exist, else the same
// absolute normal path
bool SamePath(const std::string& a, const std::string& b);

// `out` (a file to be written, given by `option`, e.g. "--out") is none of `inputs`
void CheckOutputFile(const std::string& out, const std::vector<std::string>& inputs,
                     const std::string& option);

// another run's folder found inside an output folder: its path and what it is
struct OtherRun {
  std::string path;  // "" when none
  std::string what;  // e.g. "a fit's result folder (it has result.yaml)"
};

// The first folder of another run strictly inside `dir`, at any depth (symlinks not followed):
// a folder holding result.yaml, result.h5, checkpoint.yaml or checkpoint.h5, or a staging folder
// (a folder named *.partial). `dir`'s own result files do not count.
OtherRun OtherRunInside(const std::string& dir);

// `dir` (an output folder) is none of `inputs` and holds none of them (at any depth, through
// symlinked folders too) nor the current directory; when it exists it is a folder that holds no
// other run's folder (OtherRunInside, whatever `force`), and unless `force` it is empty or an
// mjsysid result folder (it has result.yaml or is a previous fit's folder); its staging folder
// DIR.partial holds no other run's folder either
void CheckOutputFolder(const std::string& dir, const std::vector<std::string>& inputs, bool force);

// a new run id: UTC time, process id and 32 random bits, e.g. "20261122T180501Z-12345-9f3a07c1"
std::string NewRunId();

// The lock of output folder `dir`: the file DIR.lock beside it, held with flock() for the life of
// this object (the kernel drops it when the process dies, even by SIGKILL) and naming the holder
// (pid and start time). Throws OutputError naming the other process when it is held.
class FolderLock {
 public:
  // `what` names the holder in the lock file and in the other process's message ("sysid fit")
  FolderLock(const std::string& dir, const std::string& what);
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  std::string path_;
  int fd_ = -1;
};

// DIR.partial: the staging folder of output folder `dir`
std::string StagingFolder(const std::string& dir);

// the staging folder for `dir`, empty (a leftover one deleted first) or, with keep_checkpoint,
// holding only the checkpoint.yaml and checkpoint.h5 it had; the caller holds the lock
std::string CreateStagingFolder(const std::string& dir, bool keep_checkpoint = false);

// Makes the complete staging folder `staging` the folder `dir`: flushes every file and the folder
// to disk, swaps it with `dir` in one rename (or renames it when `dir` does not exist), deletes
// the previous result and flushes the parent folder. Throws io::FileError. The previous folder is
// not deleted when another run's folder got into it during the fit (CheckOutputFolder refused one
// before: a broken invariant): it stays at `staging`, named in the FileError.
void PublishFolder(const std::string& staging, const std::string& dir);

}  // namespace mjsysid::run
