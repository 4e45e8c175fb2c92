// The equation-error start (`initial: auto`): the parameters that enter MuJoCo's inverse dynamics
// linearly, estimated from logged positions and velocities by one linear least-squares solve,
// before the LM (output error) starts from there.
//
// For every logged sample k with qpos, qvel (and act, when the model has activations) measured,
// qacc_k is the central difference of the logged qvel over +-window samples; mj_inverse at
// (qpos_k, qvel_k, qacc_k) and mj_fwdActuation at ctrl_k give the generalized force the model
// needs beyond its actuators, e_k(p) = qfrc_inverse - qfrc_actuator (nv), which the true
// parameters make zero up to noise. For the kinds of EntersInverseDynamicsLinearly
// (sysid/variable_manifold.h) e is linear in p (friction loss: as long as the velocity keeps its
// sign), so one forward difference per parameter gives the regressor A = de/dp and the start is
// p = p0 - pinv(A) e(p0), clipped into the bounds. Parameters of other kinds keep their value.
//
// Noise: qacc from differenced velocity noise is the weak part; the window (default 5 samples
// each side) averages it, and the LM then removes what bias remains (this is only a start).
//
// Contacts: refused. Treating the contact forces as per-sample unknowns (a normal force per
// contact, friction mu N against the slip) was measured on the robust suite's sliding crate and
// does not give a start within 5 % even with exact accelerations: a box's four corners carry a
// statically indeterminate load (the yaw inertia is not determined) and a pyramidal cone's
// friction is not opposite the slip (docs/stress.md, "The crate"; tools/bench/crate_probe.py).
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid {

struct EquationErrorStart {
  // per parameter (the `params` order): whether it was solved here, and its start value
  std::vector<bool> solved;
  std::vector<double> values;
  int samples = 0;   // samples used (rows / nv)
  std::string note;  // what was done or why not, one line (e.g. for the result's warnings)
};

// params: the fit's parameters (values p0 = initial, or the model's value where the initial is
// not finite); which: the indices to solve (others stay fixed at p0); sequences: the logged
// sequences of this model. Samples are thinned to at most max_samples. Solves nothing (note says
// why) when no sequence has qpos and qvel, no parameter's kind is linear, a logged sample has
// contacts (their inverse forces are not linear in p and amplify the noise of qacc), or the
// regressor is rank deficient. Throws MuJoCo errors (core/mujoco_env.h) only for a broken model.
EquationErrorStart SolveEquationError(const mjModel& model, const std::vector<FitParameter>& params,
                                      const std::vector<int>& which,
                                      const std::vector<const FitSequence*>& sequences,
                                      int window = 5, int max_samples = 4000);

}  // namespace mjsysid
