// Helpers of tests that run fits (sysid/problem.h): the estimate of a named variable, a chaotic
// case.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/problem.h"
#include "sysid/types.h"
#include "tests/test_util.h"

namespace mjsysid::test {

// the estimate named `name` of a fit result; throws when there is none
inline const ParameterEstimate& Estimate(const FitResult& r, const std::string& name) {
  for (const auto& p : r.parameters) {
    if (p.name == name) return p;
  }
  throw std::runtime_error("no estimate " + name);
}

// The double pendulum (models/double_pendulum.xml) at high energy, chaotic: released at
// (2.5, -2.0) rad with (0, 6) rad/s under a 3 Nm multi-sine (seed 5), T steps, truth link masses
// 1.0 and 0.8, every channel measured with Gaussian noise `noise` (seed 3; 0: noise-free). Adds the
// model "dp", its sequence "seq0" and the masses "m1" and "m2" fitted from the starts given
// (bounds 0.05 .. 20, log) to *problem.
inline void AddHighEnergyDoublePendulum(int T, double noise, double m1_start, double m2_start,
                                        Problem* problem) {
  ModelPtr m = LoadModel(std::string(MJSYSID_MODELS_DIR) + "/double_pendulum.xml");
  const std::vector<Truth> truth = {{"m1", Spec("body_mass", "link1"), 1.0},
                                    {"m2", Spec("body_mass", "link2"), 0.8}};
  InitialState x0;
  x0.qpos = Eigen::Vector2d(2.5, -2.0);
  x0.qvel = Eigen::Vector2d(0, 6.0);
  const RowMatrix u = Excitation(*m, T, 3.0, 5);
  const RowMatrix y = Measure(*m, truth, x0, u, noise, 3);
  problem->AddModel("dp", *m);
  problem->AddParameter(FitParameter("m1", truth[0].spec, m1_start).Bounds(0.05, 20).Log());
  problem->AddParameter(FitParameter("m2", truth[1].spec, m2_start).Bounds(0.05, 20).Log());
  problem->AddSequence(FitSequence("seq0", "dp", x0, u, y));
}

}  // namespace mjsysid::test
