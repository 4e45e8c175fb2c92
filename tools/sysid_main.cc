// sysid: the mjsysid command line.
//
// exit codes: 0 success, 1 run failed (e.g. fit did not converge), 2 bad input.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include "core/mujoco_env.h"
#include "mjsysid/version.h"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailed = 1;
constexpr int kExitBadInput = 2;

// rolls a model out from its reference state under a sinusoidal control and prints a summary
int RunRollout(const std::string& model_path, int steps, double amplitude) {
  mjsysid::ModelPtr m = mjsysid::LoadModel(model_path);
  mjsysid::DataPtr d = mjsysid::MakeData(*m);
  std::printf("model %s: nq=%d nv=%d nu=%d nsensordata=%d timestep=%g\n", model_path.c_str(),
              static_cast<int>(m->nq), static_cast<int>(m->nv), static_cast<int>(m->nu),
              static_cast<int>(m->nsensordata), m->opt.timestep);
  for (int k = 0; k < steps; ++k) {
    for (int i = 0; i < m->nu; ++i) {
      d->ctrl[i] = amplitude * std::sin(2.0 * M_PI * (0.5 + 0.3 * i) * d->time);
    }
    mj_step(m.get(), d.get());
    const std::string warnings = mjsysid::SimulationWarnings(*d);
    if (!warnings.empty()) {
      std::fprintf(stderr, "sysid rollout: simulation warning at step %d: %s\n", k,
                   warnings.c_str());
      return kExitFailed;
    }
  }
  std::printf("rolled out %d steps to t=%.4f s\n", steps, d->time);
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

int main(int argc, char** argv) {
  mjsysid::InstallMujocoHandlers();
  CLI::App app{"mjsysid: system identification for MuJoCo models"};
  app.set_version_flag("--version", std::string("mjsysid ") + MJSYSID_VERSION + " (MuJoCo " +
                                        mjsysid::MujocoVersion() + ")");
  app.require_subcommand(1);

  std::string model_path;
  int steps = 1000;
  double amplitude = 1.0;
  CLI::App* rollout = app.add_subcommand("rollout", "Roll a model out under a sine control");
  rollout->add_option("model", model_path, "MJCF model file")->required();
  rollout->add_option("--steps", steps, "number of steps")->check(CLI::PositiveNumber);
  rollout->add_option("--amplitude", amplitude, "control amplitude");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitBadInput;
  }
  try {
    if (*rollout) return RunRollout(model_path, steps, amplitude);
  } catch (const mjsysid::ModelLoadError& e) {
    std::fprintf(stderr, "sysid: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sysid: %s\n", e.what());
    return kExitFailed;
  }
  return kExitOk;
}
