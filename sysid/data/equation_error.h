// The equation-error start (`initial: auto`): the parameters that enter MuJoCo's inverse dynamics
// linearly, estimated from logged positions and velocities by one linear least-squares solve,
// before the LM (output error) starts from there.
//
// The equations: at a logged sample k with qpos, qvel (and act, when the model has activations),
// mj_inverse at (qpos_k, qvel_k, qacc) and mj_fwdActuation at ctrl_k give the generalized force
// the model needs beyond its actuators, e_k(p) = qfrc_inverse - qfrc_actuator (nv), which the
// true parameters make zero up to noise. Which qacc, from the logged qvel:
// - the log's states are the integrator's own (one sample per step and qpos_{k+1} = qpos_k (+)
//   dt qvel_{k+1} to 1e-9: states logged by a MuJoCo simulation; not RK4): the one-step
//   acceleration (qvel_{k+1} - qvel_k) / dt with MuJoCo's discrete-time inverse
//   (mjENBL_INVDISCRETE: the implicit damping of Euler and implicitfast), which the true
//   parameters satisfy exactly; the rows of a window of 2 x window steps around every used sample
//   are the mean of its steps' equations (the same filter on the forces and on the regressor, so
//   the control held at each step enters as it was applied and the filter adds no bias);
// - else (noisy, quantized, jittered or resampled states, or joint encoders only): the states
//   and the applied controls filtered alike by local cubics whose width is chosen from the data,
//   the accelerations (and, without logged qvel, the velocities) central differences of the
//   filtered signals, a logged qvel's lag behind qpos removed, and the velocities in the
//   integrator's convention (sysid/data/state_smoothing.h), with the discrete-time inverse (RK4:
//   the continuous-time one), one equation per used sample. Measured on noisy and encoder-only
//   copies of the shipped logs in docs/numerics.md ("The equation-error start on noisy logs").
//   (Before: central differences of the raw qvel over +-5 samples against the raw control with
//   the continuous-time inverse, 6-81 % off at 1 % noise, and no start from encoders alone.)
// For the kinds of EntersInverseDynamicsLinearly (sysid/solve/variable_manifold.h) e is linear in p
// (friction loss: as long as the velocity keeps its sign), and the start is p = p0 - pinv(A)
// e(p0) with the regressor A = de/dp, clipped into the bounds. Parameters of other kinds keep
// their value.
//
// The regressor's columns (EquationErrorRegressor) cost one mj_inverse per step or sample for
// e(p0) and what each column needs beyond it, read from MuJoCo's inverse (qfrc_inverse = M qacc +
// bias - qfrc_passive - qfrc_constraint, plus h D qacc in the discrete-time form): joint damping
// +qvel (+ h qacc, discrete) and joint armature +qacc at the joint's dofs; joint friction loss
// -1 / +1 / 0 at a dof whose friction row is in its linear negative / linear positive /
// quadratic zone (rows exist where the friction loss is > 0); body mass J(xipos)^T (a(xipos) -
// gravity), the force a unit point mass there needs (mj_rnePostConstraint,
// mj_objectAcceleration, mj_jac), and for body_mass_inertia also Jr^T (I0w alpha + omega x I0w
// omega) / m0 (the inertia I0 at the mass m0 scaled along, in world axes); kinds that enter only
// the actuation: one mj_fwdActuation at p0 + h; kinds that enter the velocity stage: mj_inverseSkip
// past the position stage at p0 + h; the rest (and every column of the discrete form with free
// joints or another integrator than Euler and implicitfast, gravity compensation of the body, fluid
// forces): a full mj_inverse at p0 + h after mj_setConst. Sensors are never computed.
// tests/sysid/data/equation_error_test.cc checks the closed forms against forward differences of
// full mj_inverse calls (they leave out how the friction row's force in its quadratic zone moves
// with the other parameters).
//
// Contacts: refused. Treating the contact forces as per-sample unknowns (a normal force per
// contact, friction mu N against the slip) was measured on the robust suite's sliding crate and
// does not give a start within 5 % even with exact accelerations: a box's four corners carry a
// statically indeterminate load (the yaw inertia is not determined) and a pyramidal cone's
// friction is not opposite the slip (docs/stress.md, "The crate"; tools/bench/crate_probe.py).
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
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
// sequences of this model; window: the half-window of the integrator's own steps (above).
// Samples are thinned to at most max_samples. Solves nothing (note says
// why) when no sequence has qpos and qvel (or qpos alone for hinge and slide joints), no
// parameter's kind is linear, a logged sample has contacts (their inverse forces are not linear in
// p and amplify the noise of qacc), or the regressor is rank deficient. Throws MuJoCo errors
// (core/mujoco_env.h) only for a broken model. How the regressor's columns are formed: the closed
// forms and stage skips above where they hold (the fit's), or every column by a forward difference
// of full mj_inverse calls (the reference the closed forms are tested against). threads: the
// samples' inverse dynamics on up to this many threads (<= 0: every core; each with its own model
// copy, chunks of at least 256 samples); the result is the same bit for bit at any count.
enum class RegressorColumns { kFastest, kForwardDifference };

// The linear system of the start: e0 = e(p0) and A = de/dp, rows sample by sample (samples x nv,
// row i * nv + j: dof j of sample i), column c for params[cols[c]] (cols: indices into params of
// kinds that enter the inverse dynamics linearly).
struct EquationErrorSystem {
  std::vector<double> p0;         // per parameter: initial, else the model's value
  Eigen::MatrixXd A;              // rows x cols.size(); zero when contacts > 0
  Eigen::VectorXd e0;             // rows
  std::vector<bool> closed_form;  // per column: read from e(p0)'s pipeline, no second call
  int samples = 0;                // samples used (rows / nv)
  int contacts = 0;               // samples whose window has contacts at p0
  bool discrete = false;          // the integrator's steps (the log's states are its own)
  int half_width = 0;             // else: the smoothing's widest half-width (samples)
  bool from_positions = false;    // else: some sequence's velocities came from its positions
  std::string note;               // why there are no samples, else empty
};

// The system of SolveEquationError (same samples; arguments as there). Throws as there.
EquationErrorSystem EquationErrorRegressor(const mjModel& model,
                                           const std::vector<FitParameter>& params,
                                           const std::vector<int>& cols,
                                           const std::vector<const FitSequence*>& sequences,
                                           RegressorColumns how, int window = 5,
                                           int max_samples = 4000, int threads = 1);

EquationErrorStart SolveEquationError(const mjModel& model, const std::vector<FitParameter>& params,
                                      const std::vector<int>& which,
                                      const std::vector<const FitSequence*>& sequences,
                                      int window = 5, int max_samples = 4000, int threads = 1);

}  // namespace mjsysid
