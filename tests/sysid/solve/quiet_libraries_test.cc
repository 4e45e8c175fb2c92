// QuietThirdPartyLibraries (sysid/solve/quiet_libraries.h): SuiteSparse's printf captured instead
// of printed, and a fit taking the captured lines into its warnings.
#include "sysid/solve/quiet_libraries.h"

#include <SuiteSparse_config.h>
#include <cholmod.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/problem.h"
#include "tests/file_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

// what `run` writes on the process's stdout and stderr (file descriptors 1 and 2)
template <typename F>
std::string Printed(const F& run) {
  const std::string path = test::FreshTempDir("quiet_libraries") + "/out.txt";
  std::fflush(stdout);
  std::fflush(stderr);
  FILE* sink = std::fopen(path.c_str(), "w");
  const int out = dup(1), err = dup(2);
  dup2(fileno(sink), 1);
  dup2(fileno(sink), 2);
  run();
  std::fflush(stdout);
  std::fflush(stderr);
  dup2(out, 1);
  dup2(err, 2);
  close(out);
  close(err);
  std::fclose(sink);
  const std::string printed = test::ReadFile(path);
  std::filesystem::remove_all(std::filesystem::path(path).parent_path());
  return printed;
}

// a CHOLMOD error (a matrix too large to allocate: CHOLMOD prints "CHOLMOD error: problem too
// large. file: ... line: ..." on stdout when not quieted, measured with a plain program): nothing
// on stdout or stderr, the line captured once, the next take empty
TEST(QuietLibrariesTest, CholmodErrorsAreCapturedNotPrinted) {
  QuietThirdPartyLibraries("quiet_libraries_test");
  TakeThirdPartyMessages();  // nothing left from before
  const std::string printed = Printed([] {
    cholmod_common c;
    cholmod_start(&c);
    const size_t huge = size_t{1} << 62;
    cholmod_sparse* s = cholmod_allocate_sparse(huge, huge, huge, 1, 1, 0, CHOLMOD_REAL, &c);
    EXPECT_EQ(s, nullptr);
    EXPECT_EQ(c.status, CHOLMOD_TOO_LARGE);
    cholmod_finish(&c);
  });
  EXPECT_EQ(printed, "");
  const std::vector<std::string> lines = TakeThirdPartyMessages();
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].rfind("CHOLMOD error: problem too large. file: ", 0), 0u) << lines[0];
  EXPECT_TRUE(TakeThirdPartyMessages().empty());
}

// a line SuiteSparse printed before a fit ends up in that fit's warnings, once (the pendulum's
// damping from 0.4, truth 0.2, noise-free, 500 steps)
TEST(QuietLibrariesTest, AFitTakesTheCapturedLinesIntoItsWarnings) {
  QuietThirdPartyLibraries("quiet_libraries_test");
  TakeThirdPartyMessages();
  ModelPtr m = LoadModel(std::string(MJSYSID_MODELS_DIR) + "/pendulum.xml");
  const test::Truth damping{"damping", test::Spec("joint_damping", "hinge"), 0.2};
  InitialState x0;
  const RowMatrix u = test::Excitation(*m, 500, 1.0, 1);
  const RowMatrix y = test::Measure(*m, {damping}, x0, u, 0, 0);
  Problem problem;
  problem.AddModel("pendulum", *m);
  problem.AddParameter(FitParameter("damping", damping.spec, 0.4).Bounds(1e-4, 10).Log());
  problem.AddSequence(FitSequence("seq0", "pendulum", x0, u, y));
  SuiteSparse_config.printf_func("CHOLMOD warning: %s\n", "a test line");
  const FitResult r = problem.Fit(FitOptions());
  int found = 0;
  for (const std::string& w : r.warnings) {
    found += w ==
             "the sparse linear algebra library (SuiteSparse) said: CHOLMOD warning: a test "
             "line";
  }
  EXPECT_EQ(found, 1);
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
}

}  // namespace
}  // namespace mjsysid
