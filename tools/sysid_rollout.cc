// sysid rollout MODEL.xml: roll a model out under a sine control and print its sensors.
#include <cmath>
#include <cstdio>
#include <string>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tools/sysid_cli.h"

namespace mjsysid::cli {
namespace {

struct RolloutArgs {
  std::string model_path;
  int steps = 1000;
  double amplitude = 1.0;
};

// the --help page of `sysid rollout`: description and arguments (into args)
void DeclareRollout(CLI::App* sub, RolloutArgs* args) {
  sub->description(
      "Roll a model out from its reference state under a sine control and print the final sensor "
      "readings");
  sub->add_option("model", args->model_path, "MJCF (or MJB) model file")->required();
  sub->add_option("--steps", args->steps, "number of steps")
      ->check(WholeNumberAtLeast(1))
      ->capture_default_str();
  sub->add_option("--amplitude", args->amplitude, "control amplitude, in control units")
      ->check(FiniteNumber())
      ->capture_default_str();
}

// rolls a model out from its reference state under a sinusoidal control and prints a summary
int RunRollout(const RolloutArgs& args) {
  mjsysid::ModelPtr m = mjsysid::LoadModel(args.model_path);
  mjsysid::DataPtr d = mjsysid::MakeData(*m);
  std::printf("model %s: nq=%d nv=%d nu=%d nsensordata=%d timestep=%g\n", args.model_path.c_str(),
              static_cast<int>(m->nq), static_cast<int>(m->nv), static_cast<int>(m->nu),
              static_cast<int>(m->nsensordata), m->opt.timestep);
  for (int k = 0; k < args.steps; ++k) {
    for (int i = 0; i < m->nu; ++i) {
      d->ctrl[i] = args.amplitude * std::sin(2.0 * M_PI * (0.5 + 0.3 * i) * d->time);
    }
    mj_step(m.get(), d.get());
    const std::string warnings = mjsysid::SimulationWarnings(*d);
    if (!warnings.empty()) {
      std::fprintf(stderr, "sysid rollout: simulation warning at step %d: %s\n", k,
                   warnings.c_str());
      return kExitFailed;
    }
  }
  std::printf("rolled out %d steps to t=%.4f s\n", args.steps, d->time);
  for (int i = 0; i < m->nsensor; ++i) {
    const char* name = mj_id2name(m.get(), mjOBJ_SENSOR, i);
    std::printf("  sensor %-12s", name ? name : "?");
    for (int j = 0; j < m->sensor_dim[i]; ++j) {
      std::printf(" % .6f", d->sensordata[m->sensor_adr[i] + j]);
    }
    std::printf("\n");
  }
  return kExitOk;
}

}  // namespace

Command AddRollout(CLI::App* app) {
  return AddSubcommand(app, "rollout", DeclareRollout, RunRollout);
}

}  // namespace mjsysid::cli
