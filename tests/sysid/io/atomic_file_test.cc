#include "sysid/io/atomic_file.h"

#include <grp.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/temp_dir_test.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;

// a fresh folder per test, removed afterwards
class AtomicFileTest : public test::TempDirTest {};

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// the message of the FileError that `f` throws ("" when it throws none)
template <typename F>
std::string FileErrorOf(F f) {
  try {
    f();
  } catch (const FileError& e) {
    return e.what();
  }
  return "";
}

TEST_F(AtomicFileTest, WritesBytesThatReadBack) {
  const std::string path = Path("a.bin");
  const std::string bytes("line 1\n\0\xff binary", 16);
  WriteFileAtomically(path, bytes);
  EXPECT_EQ(ReadBytes(path), bytes);

  // replaced whole: shorter content leaves nothing of the old behind
  WriteFileAtomically(path, "ok");
  EXPECT_EQ(ReadBytes(path), "ok");
  WriteFileAtomically(path, "");
  EXPECT_TRUE(fs::exists(path));
  EXPECT_EQ(fs::file_size(path), 0u);
  EXPECT_TRUE(OtherFiles("a.bin").empty());
}

TEST_F(AtomicFileTest, ReplaceAtomicallyWritesThroughATemporaryInTheSameFolder) {
  const std::string path = Path("b.txt");
  std::string seen;
  ReplaceAtomically(path, [&](const std::string& tmp) {
    seen = tmp;
    EXPECT_FALSE(fs::exists(path));  // nothing at path until the rename
    std::ofstream(tmp) << "written by the callback";
  });
  EXPECT_EQ(seen, path + ".tmp-" + std::to_string(::getpid()));
  EXPECT_EQ(ReadBytes(path), "written by the callback");
  EXPECT_TRUE(OtherFiles("b.txt").empty());
}

TEST_F(AtomicFileTest, AFailingWriteLeavesTheOldFileAndNoTemporary) {
  const std::string path = Path("c.txt");
  const std::string old = "the old content\n";
  WriteFileAtomically(path, old);
  EXPECT_THROW(ReplaceAtomically(path,
                                 [](const std::string& tmp) {
                                   std::ofstream(tmp) << "half of the new con";
                                   throw std::runtime_error("the writer failed");
                                 }),
               std::runtime_error);
  EXPECT_EQ(ReadBytes(path), old);
  EXPECT_TRUE(OtherFiles("c.txt").empty());
}

TEST_F(AtomicFileTest, AFolderAtThePathIsAnErrorThatNamesIt) {
  // fails for root too: rename(2) will not put a file over a folder
  const std::string path = Path("target");
  fs::create_directories(fs::path(path) / "inside");
  const std::string msg = FileErrorOf([&] { WriteFileAtomically(path, "x"); });
  EXPECT_EQ(msg.rfind(path + ": cannot rename " + path + ".tmp-", 0), 0u) << msg;
  EXPECT_NE(msg.find("Is a directory"), std::string::npos) << msg;
  EXPECT_TRUE(fs::is_directory(fs::path(path) / "inside"));
  EXPECT_TRUE(OtherFiles("target").empty());
}

TEST_F(AtomicFileTest, AMissingFolderIsAnErrorThatNamesTheFile) {
  const std::string path = Path("missing/d.txt");
  const std::string msg = FileErrorOf([&] { WriteFileAtomically(path, "x"); });
  EXPECT_EQ(msg.rfind(path + ": cannot create " + path + ".tmp-", 0), 0u) << msg;
  EXPECT_NE(msg.find("No such file or directory"), std::string::npos) << msg;
}

TEST_F(AtomicFileTest, AReadOnlyFolderIsPermissionDenied) {
  const std::string path = Path("ro/e.txt");
  fs::create_directories(Path("ro"));
  ::chmod(Path("ro").c_str(), 0555);

  // root writes into read-only folders: the write runs in a child process that gives root up
  int pipe_fd[2];
  ASSERT_EQ(::pipe(pipe_fd), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipe_fd[0]);
    std::string msg;
    if (::geteuid() == 0 &&
        (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0)) {
      msg = "cannot give up root";
    } else {
      msg = FileErrorOf([&] { WriteFileAtomically(path, "x"); });
    }
    const ssize_t n = ::write(pipe_fd[1], msg.data(), msg.size());
    ::_exit(n == static_cast<ssize_t>(msg.size()) ? 0 : 1);
  }
  ::close(pipe_fd[1]);
  std::string msg;
  char buf[512];
  for (ssize_t n; (n = ::read(pipe_fd[0], buf, sizeof(buf))) > 0;) msg.append(buf, n);
  ::close(pipe_fd[0]);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);

  EXPECT_EQ(msg.rfind(path + ": cannot create " + path + ".tmp-", 0), 0u) << msg;
  EXPECT_NE(msg.find("Permission denied"), std::string::npos) << msg;
  EXPECT_FALSE(fs::exists(path));
}

}  // namespace
}  // namespace mjsysid::io
