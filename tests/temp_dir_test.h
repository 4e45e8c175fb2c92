// A test fixture with a fresh folder per test (temp/mjsysid_<suite>_<pid>_<test>, any '/' of a
// parameterized test's names as '_'), removed afterwards: what every test that writes files derives
// from.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

namespace mjsysid::test {

class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "mjsysid_" + std::string(info->test_suite_name()) + "_" +
                       std::to_string(::getpid()) + "_" + info->name();
    // a parameterized test's names hold '/' (Prefix/Suite, Test/0): one folder, not a tree
    for (char& c : name) c = c == '/' ? '_' : c;
    dir_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    // a test may have made the folder read-only
    std::error_code ec;
    std::filesystem::permissions(dir_, std::filesystem::perms::owner_all, ec);
    std::filesystem::remove_all(dir_, ec);
  }

  std::string Dir() const { return dir_.string(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // the names in the folder other than `keep`
  std::vector<std::string> OtherFiles(const std::string& keep) const {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(dir_)) {
      if (e.path().filename() != keep) out.push_back(e.path().filename().string());
    }
    return out;
  }

  std::filesystem::path dir_;
};

}  // namespace mjsysid::test
