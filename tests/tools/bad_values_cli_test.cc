// Values that cannot act or cannot be simulated, through the real CLI (issue 35, items 6 and 7;
// docs/bad-input.md, "Issue 35: values that cannot act"): a mass parameter on a body welded to the
// world, a logged value whose square overflows, a solver that cannot start (no third-party log
// lines, no "-1 iterations"), and the log's path named once.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::CliStreams;
using mjsysid::test::CountOf;
using mjsysid::test::ReadFile;
using mjsysid::test::SysidStreams;
using mjsysid::test::WriteFile;

// the pendulum hung from a jointless base body ("base", welded to the world)
const char kWeldModel[] = R"(<mujoco model="weld">
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <geom name="basegeom" type="box" pos="0 0 0.3" size="0.1 0.1 0.1" mass="1.0"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom name="rod" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="0"/>
        <body name="bob" pos="0 0 -0.5">
          <geom name="bob" type="sphere" size="0.05" mass="1.0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="torque" joint="hinge"/></actuator>
  <sensor>
    <jointpos name="angle" joint="hinge"/>
    <jointvel name="rate" joint="hinge"/>
  </sensor>
</mujoco>
)";

class Values35Test : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = mjsysid::test::FreshTempDir("bad_values_cli"); }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // an experiment on model `model` and log `data`, fitting damping and the parameters in `extra`
  static std::string Experiment(const std::string& model, const std::string& data,
                                const std::string& extra, const std::string& rate_sigma) {
    return "name: v35\nmodel: " + model + "\ndata: " + data +
           "\nsensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: " + rate_sigma +
           "}\nparameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n" +
           extra +
           "solver: {max_iterations: 20, verbose: false}\n"
           "simulate:\n  truth: {damping: 0.08}\n  sequences: 1\n  steps: 200\n"
           "  noise: {angle: 0.001, rate: 0.01}\n";
  }

  static CliStreams Sysid(const std::string& args) { return SysidStreams(args); }

  // a copy of `log` with one element of `dataset` set to `value`
  static std::string PatchedLog(const std::string& log, const std::string& name,
                                const std::string& dataset, hsize_t row, hsize_t col,
                                double value) {
    const std::string path = dir_ + "/" + name;
    fs::copy_file(log, path, fs::copy_options::overwrite_existing);
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    EXPECT_GE(f, 0);
    const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
    EXPECT_GE(d, 0) << dataset;
    const hid_t space = H5Dget_space(d);
    const hsize_t start[2] = {row, col};
    const hsize_t count[2] = {1, 1};
    EXPECT_GE(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
    const hsize_t one = 1;
    const hid_t mem = H5Screate_simple(1, &one, nullptr);
    EXPECT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, &value), 0);
    H5Sclose(mem);
    H5Sclose(space);
    H5Dclose(d);
    H5Fclose(f);
    return path;
  }

  static std::string dir_;
};

std::string Values35Test::dir_;

// A body_mass parameter on a body welded to the world (no joint between it and the world, no
// force, torque or subtree sensor): exit 2 from simulate, check and fit, naming the parameter's
// YAML line and why ("body 'base' is welded to the world ... its mass cannot move any state");
// it was a `converged` fit that moved the mass (noise column, std 8e5).
TEST_F(Values35Test, MassOfABodyWeldedToTheWorldIsRefused) {
  const std::string model = dir_ + "/weld.xml";
  WriteFile(model, kWeldModel);
  const std::string log = dir_ + "/weld.h5";
  // a log from the same model without the parameter: the refusal is the parameter's, not the data's
  WriteFile(dir_ + "/plain.yaml", Experiment(model, log, "", "0.01"));
  ASSERT_EQ(Sysid("simulate " + dir_ + "/plain.yaml --out " + log).code, 0);
  const std::string exp = dir_ + "/welded.yaml";
  WriteFile(exp, Experiment(model, log,
                            "  - {name: base_mass, target: body_mass, object: base, initial: 1,\n"
                            "     bounds: [0.05, 10], transform: log}\n",
                            "0.01"));
  for (const std::string sub : {"simulate", "check", "fit"}) {
    SCOPED_TRACE(sub);
    // simulate --force: weld.h5 is plain.yaml's log; the parameter's error must come first
    const CliStreams r = Sysid(sub + " " + exp +
                               (sub == "fit"        ? " --out " + dir_ + "/res"
                                : sub == "simulate" ? " --force"
                                                    : ""));
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("welded.yaml:10:"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("body 'base' is welded to the world"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("its mass cannot move any state"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ + "/res"));
  // the same parameter on the pendulum's moving bob is accepted (the rule is the weld)
  const std::string bob = dir_ + "/bob.yaml";
  WriteFile(bob, Experiment(model, log,
                            "  - {name: bob_mass, target: body_mass, object: bob, initial: 1,\n"
                            "     bounds: [0.05, 10], transform: log}\n",
                            "0.01"));
  const CliStreams ok = Sysid("fit " + bob + " --out " + dir_ + "/res_bob --quiet");
  EXPECT_EQ(ok.code, 0) << ok.err;
}

// The same welded base with a force sensor at a site on it ("mountforce": cfrc_int carries the
// base's weight): a `sensors:` list without it is exit 2 naming the sensor that would read it
// ("none of the fitted sensors reads it (hint: fit a sensor that reads it (mountforce), ...")");
// with it, the fit identifies the mass (exit 0, converged).
TEST_F(Values35Test, MassOfAWeldedBodyNeedsAFittedSensorThatReadsIt) {
  std::string xml = kWeldModel;
  xml.replace(xml.find("<geom name=\"basegeom\""), 0, "<site name=\"mount\"/>");
  xml.replace(xml.find("</sensor>"), 0, "<force name=\"mountforce\" site=\"mount\"/>\n  ");
  const std::string model = dir_ + "/weld_force.xml";
  WriteFile(model, xml);
  const std::string log = dir_ + "/weld_force.h5";
  const std::string base =
      "  - {name: base_mass, target: body_mass, object: base, initial: 0.5,\n"
      "     bounds: [0.05, 10], transform: log}\n";
  const std::string unread = dir_ + "/unread.yaml";
  WriteFile(unread, Experiment(model, log, base, "0.01"));
  const CliStreams r = Sysid("check " + unread);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("unread.yaml:10:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("none of the fitted sensors reads it (hint: fit a sensor that reads it "
                       "(mountforce)"),
            std::string::npos)
      << r.err;
  std::string read = Experiment(model, log, base, "0.01");
  read.replace(read.find("parameters:"), 0, "  - {name: mountforce, sigma: 0.1}\n");
  read.replace(read.find("truth: {damping: 0.08}"), 22, "truth: {damping: 0.08, base_mass: 1}");
  WriteFile(dir_ + "/read.yaml", read);
  ASSERT_EQ(Sysid("simulate " + dir_ + "/read.yaml --out " + log).code, 0);
  const CliStreams fit = Sysid("fit " + dir_ + "/read.yaml --out " + dir_ + "/res_read --quiet");
  EXPECT_EQ(fit.code, 0) << fit.err;
  EXPECT_NE(fit.out.find("converged"), std::string::npos) << fit.out;
  EXPECT_NE(fit.out.find("base_mass"), std::string::npos) << fit.out;
}

// A finite logged value whose square overflows (1e308 in ctrl, 1e200 in sensordata): exit 2,
// "LOG: /seq0/ctrl: row 17, column 0: value 1e+308 is beyond +-1e+150, ...", the log's path
// named once (the child that reads the log prepended it a second time).
TEST_F(Values35Test, LoggedValueBeyond1e150IsBadInputNamingTheFileOnce) {
  const std::string model = std::string(MJSYSID_SOURCE_DIR) + "/models/pendulum.xml";
  const std::string log = dir_ + "/good.h5";
  WriteFile(dir_ + "/good.yaml", Experiment(model, log, "", "0.01"));
  ASSERT_EQ(Sysid("simulate " + dir_ + "/good.yaml --out " + log).code, 0);
  for (const auto& [dataset, value, shown] :
       {std::make_tuple(std::string("ctrl"), 1e308, std::string("1e+308")),
        std::make_tuple(std::string("sensordata"), -1e200, std::string("-1e+200"))}) {
    SCOPED_TRACE(dataset);
    const std::string bad =
        PatchedLog(log, "huge_" + dataset + ".h5", "/seq0/" + dataset, 17, 0, value);
    const std::string exp = dir_ + "/huge_" + dataset + ".yaml";
    WriteFile(exp, Experiment(model, bad, "", "0.01"));
    for (const std::string sub : {"check", "fit"}) {
      const CliStreams r =
          Sysid(sub + " " + exp + (sub == "fit" ? " --out " + dir_ + "/res_huge" : ""));
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_NE(r.err.find("/seq0/" + dataset + ": row 17, column 0: value " + shown +
                           " is beyond +-1e+150"),
                std::string::npos)
          << r.err;
      EXPECT_EQ(CountOf(r.err, "huge_" + dataset + ".h5"), 1) << r.err;
    }
  }
  // 1e150 itself is accepted by the check (the bound is inclusive)
  const std::string edge = PatchedLog(log, "edge.h5", "/seq0/sensordata", 17, 0, 1e150);
  WriteFile(dir_ + "/edge.yaml", Experiment(model, edge, "", "0.01"));
  const CliStreams r = Sysid("check " + dir_ + "/edge.yaml");
  EXPECT_EQ(r.err.find("is beyond"), std::string::npos) << r.err;
}

// The same rule on `import`: a CSV cell of 1e308 is exit 2 naming the CSV file, its line and
// column (issue 35: it named the --out log's dataset, row and column)
TEST_F(Values35Test, ImportRefusesAValueBeyond1e150) {
  const std::string model = std::string(MJSYSID_SOURCE_DIR) + "/models/pendulum.xml";
  std::string csv = "time,torque,angle,rate\n";
  for (int i = 0; i < 20; ++i) {
    csv += std::to_string(0.002 * i) + ",0.1,0.3," + (i == 7 ? "1e308" : "0.0") + "\n";
  }
  WriteFile(dir_ + "/huge.csv", csv);
  const CliStreams r =
      Sysid("import " + model + " " + dir_ + "/huge.csv --out " + dir_ + "/huge.h5");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("huge.csv:9: column 4 ('rate'): value '1e308' is beyond +-1e+150"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("huge.h5"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ + "/huge.h5"));
}

// A cost Ceres cannot evaluate at the start (23 rate values of 1e150 with sigma 1e-4: each
// squared residual 1e308, their sum inf): no glog line of Ceres on the terminal (it printed
// "WARNING: Logging before InitGoogleLogging()" and "E... trust_region_minimizer.cc:71]
// Terminating: ..."), and the summary says what happened instead of "after -1 iterations, cost
// -1 -> -1"; exit 4 (did_not_move).
TEST_F(Values35Test, SolverThatCannotStartPrintsNoLibraryLogAndNoMinusOne) {
  const std::string model = std::string(MJSYSID_SOURCE_DIR) + "/models/pendulum.xml";
  std::string csv = "time,torque,angle,rate\n";
  for (int i = 0; i < 200; ++i) {
    csv += std::to_string(0.002 * i) + ",0.1,0.3," + (i >= 17 && i < 40 ? "1e150" : "0.0") + "\n";
  }
  WriteFile(dir_ + "/edge.csv", csv);
  const std::string log = dir_ + "/edge_csv.h5";
  const CliStreams imp = Sysid("import " + model + " " + dir_ + "/edge.csv --out " + log);
  ASSERT_EQ(imp.code, 0) << imp.err;
  WriteFile(dir_ + "/edge_fit.yaml", Experiment(model, log, "", "0.0001"));
  const CliStreams r = Sysid("fit " + dir_ + "/edge_fit.yaml --out " + dir_ + "/res_edge");
  EXPECT_EQ(r.code, 4) << r.out << r.err;
  EXPECT_EQ(r.err.find("InitGoogleLogging"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find(".cc:"), std::string::npos) << r.err;  // glog's "file.cc:line]" prefix
  EXPECT_EQ(r.out.find("-1 iterations"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("cost -1 -> -1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("solver_failed: the solver stopped before its first iteration (Residual "
                       "and Jacobian evaluation failed.)"),
            std::string::npos)
      << r.out;
}

}  // namespace
