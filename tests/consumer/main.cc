// A program outside the mjsysid source tree, built against an installed mjsysid
// (find_package(mjsysid), tests/consumer/CMakeLists.txt) by tools/run_tests.sh: it simulates a
// pendulum log at a known joint damping with the core Simulator (mjsysid::core), writes it to
// HDF5 and reads it back (mjsysid::io), fits the damping from a wrong start with mjsysid::Problem
// (mjsysid::sysid) and checks the estimate.
//
// usage: mjsysid_consumer MODELS_DIR/pendulum.xml OUT_DIR/log.h5
// exit: 0 when the estimate is within kTolerance (relative) of the truth, 1 otherwise or on error
#include <cmath>
#include <cstdio>
#include <exception>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "mjsysid/version.h"
#include "sysid/io/log.h"
#include "sysid/problem.h"

namespace {
constexpr double kTrueDamping = 0.3;    // N m s / rad; the model file says 0.05
constexpr double kStartDamping = 0.05;  // the fit starts from the model's value
constexpr double kTolerance = 1e-6;     // relative: noise-free data pins the damping down
constexpr int kSteps = 1000;            // 2 s at the model's 2 ms time step
}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s PENDULUM.xml LOG.h5\n", argv[0]);
    return 1;
  }
  try {
    // 1. simulate: a sine torque from a tilted start, damping set to the truth
    mjsysid::ModelPtr model = mjsysid::LoadModel(argv[1]);
    mjsysid::ParameterSpec damping;
    damping.kind = "joint_damping";
    damping.object = "hinge";
    mjsysid::Simulator simulator(*model, {damping});
    simulator.SetParameters(Eigen::VectorXd::Constant(1, kTrueDamping));
    mjsysid::SequenceInput input;
    input.x0.qpos = Eigen::VectorXd::Constant(1, 0.5);
    input.ctrl.resize(kSteps, 1);
    for (int k = 0; k < kSteps; ++k)
      input.ctrl(k, 0) = std::sin(2 * M_PI * k * model->opt.timestep);
    const mjsysid::Trajectory truth = simulator.Rollout(input);

    // 2. the measured sensors through an HDF5 log, written and read back
    mjsysid::io::Log log;
    mjsysid::io::Sequence sequence;
    sequence.name = "run1";
    sequence.time = Eigen::VectorXd::LinSpaced(kSteps, 0, (kSteps - 1) * model->opt.timestep);
    sequence.ctrl = input.ctrl;
    sequence.sensordata = truth.sensors;
    sequence.sensor_names = {"angle", "rate"};
    sequence.sensor_dims = {1, 1};
    sequence.actuator_names = {"torque"};
    log.sequences.push_back(sequence);
    mjsysid::io::WriteLog(argv[2], log);
    const mjsysid::io::Log read = mjsysid::io::ReadLog(argv[2]);

    // 3. fit the damping from the wrong start
    mjsysid::Problem problem;
    problem.AddModel("pendulum", *model);
    problem.AddParameter(mjsysid::FitParameter("damping", damping, kStartDamping).Bounds(1e-4, 10));
    problem.AddSequence(mjsysid::FitSequence("run1", "pendulum", input.x0, read.sequences[0].ctrl,
                                             read.sequences[0].sensordata));
    const mjsysid::FitResult result = problem.Fit(mjsysid::FitOptions());

    // 4. check
    const double estimate = result.parameters.at(0).value;
    const double error = std::abs(estimate - kTrueDamping) / kTrueDamping;
    std::printf(
        "mjsysid %s: damping %.9g (truth %g, start %g), relative error %.2e, %d iterations\n",
        MJSYSID_VERSION, estimate, kTrueDamping, kStartDamping, error, result.iterations);
    if (!(error <= kTolerance)) {
      std::fprintf(stderr, "FAILED: relative error above %g\n", kTolerance);
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "FAILED: %s\n", e.what());
    return 1;
  }
}
