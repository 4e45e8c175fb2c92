// States, tangent-space arithmetic and the stepping primitive of the core.
//
// Vocabulary (docs/numerics.md, "Time convention" and "Tangent-space sensitivities"):
// - physics vector x = [qpos (nq), qvel (nv), act (na)]: what a log records per sample.
// - tangent vector dx = [dq (nv), dv (nv), da (na)], nx = 2nv + na: the layout of mjd_transitionFD.
//   Positions are perturbed with mj_integratePos and compared with mj_differentiatePos, so ball
//   and free joints (quaternions) are handled in their body frame. Never subtract qpos directly.
// - full state: everything a step reads (mjSTATE_INTEGRATION: time, qpos, qvel, act, history,
//   warmstart, ctrl, applied forces, mocap, ...). Saved and restored by mjtState names.
// Every MuJoCo call here that can raise a MuJoCo error runs inside CallMujoco (mujoco_env.h): it
// throws MujocoError.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>

namespace mjsysid {

// row-major dense matrix: row k of a trajectory is sample k (and Ceres wants row-major Jacobians)
using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// everything a step reads (mjSTATE_INTEGRATION): saved and restored whole by GetFullState
constexpr unsigned int kFullStateSig = mjSTATE_INTEGRATION;

// What a step reads splits in four (together exactly kFullStateSig; tested):
// - the physics vector [qpos, qvel, act] (GetPhysics);
// - the controls u_k (mjSTATE_CTRL), the caller's input;
// - the step state: time, qacc_warmstart and, where the model has them, history buffers, plugin
//   and plastic state: what a step changes besides the physics vector (GetStepState);
// - the inputs held during a rollout: applied forces, equality activation, mocap poses and user
//   data (kInputSig), which mj_step never writes. A model with plugins (which may write them)
//   records them in the step state instead, and StateDims::input_sig is 0.
constexpr unsigned int kStepExtraSig = mjSTATE_HISTORY | mjSTATE_PLUGIN | mjSTATE_PLASTIC;
constexpr unsigned int kInputSig = mjSTATE_USER & ~static_cast<unsigned int>(mjSTATE_CTRL);

// sizes of one model's state spaces
struct StateDims {
  explicit StateDims(const mjModel& m);
  int nq, nv, na, nu;
  int ns;                       // nsensordata
  int nphys;                    // nq + nv + na: physics vector
  int nx;                       // 2 nv + na: tangent vector
  int nfull;                    // mj_stateSize(m, kFullStateSig)
  unsigned int step_extra_sig;  // kStepExtraSig, with kInputSig added for a model with plugins
  unsigned int input_sig;       // kInputSig, or 0 for a model with plugins
  int nstep;                    // 1 + nv + mj_stateSize(m, step_extra_sig): the step state
  int ninput;                   // mj_stateSize(m, input_sig)
};

// reads the physics vector [qpos, qvel, act] of d into x (length nphys); inline, as the step state
// below: every step of a rollout and of a Jacobian column copies these few numbers
inline void GetPhysics(const mjModel& m, const mjData& d, double* x) {
  const int nq = static_cast<int>(m.nq), nv = static_cast<int>(m.nv), na = static_cast<int>(m.na);
  for (int i = 0; i < nq; ++i) x[i] = d.qpos[i];
  for (int i = 0; i < nv; ++i) x[nq + i] = d.qvel[i];
  for (int i = 0; i < na; ++i) x[nq + nv + i] = d.act[i];
}

// writes the physics vector x into d (qpos, qvel, act)
inline void SetPhysics(const mjModel& m, mjData* d, const double* x) {
  const int nq = static_cast<int>(m.nq), nv = static_cast<int>(m.nv), na = static_cast<int>(m.na);
  for (int i = 0; i < nq; ++i) d->qpos[i] = x[i];
  for (int i = 0; i < nv; ++i) d->qvel[i] = x[nq + i];
  for (int i = 0; i < na; ++i) d->act[i] = x[nq + nv + i];
}

// reads the full state (kFullStateSig, length StateDims::nfull) of d into state
void GetFullState(const mjModel* m, const mjData* d, double* state);

// writes the full state (kFullStateSig, length StateDims::nfull) into d
void SetFullState(const mjModel* m, mjData* d, const double* state);

// the extras of the step state (step_extra_sig, after time and qacc_warmstart) through
// mj_getState / mj_setState, for a model that has any (dims.nstep > 1 + nv)
void GetStepExtras(const mjModel& m, const StateDims& dims, const mjData& d, double* extras);
void SetStepExtras(const mjModel& m, const StateDims& dims, mjData* d, const double* extras);

// reads the step state [time, qacc_warmstart (nv), extras (step_extra_sig)] of d into step
// (length StateDims::nstep)
inline void GetStepState(const mjModel& m, const StateDims& dims, const mjData& d, double* step) {
  step[0] = d.time;
  for (int i = 0; i < dims.nv; ++i) step[1 + i] = d.qacc_warmstart[i];
  // the extras only where the model has them (mj_getState walks every state element)
  if (dims.nstep > 1 + dims.nv) GetStepExtras(m, dims, d, step + 1 + dims.nv);
}

// writes the step state (length StateDims::nstep) into d
inline void SetStepState(const mjModel& m, const StateDims& dims, mjData* d, const double* step) {
  d->time = step[0];
  for (int i = 0; i < dims.nv; ++i) d->qacc_warmstart[i] = step[1 + i];
  if (dims.nstep > 1 + dims.nv) SetStepExtras(m, dims, d, step + 1 + dims.nv);
}

// dx = (x2 (-) x1) * inv_scale in tangent space; x1, x2 physics vectors, dx of length nx. Positions
// as mj_differentiatePos with dt = 1 / inv_scale, bit for bit (a model without ball and free
// joints skips the call: the same subtraction and division inline; tested)
inline void TangentDifference(const mjModel& m, const double* x1, const double* x2,
                              double inv_scale, double* dx) {
  const int nq = static_cast<int>(m.nq), nv = static_cast<int>(m.nv), na = static_cast<int>(m.na);
  // positions: manifold difference, (q2 - q1) / dt with dt = 1/inv_scale; without ball and free
  // joints (nq = nv: hinges and slides, qpos and dof addresses equal) the same arithmetic here
  const double dt = 1.0 / inv_scale;
  if (nq == nv) {
    for (int i = 0; i < nv; ++i) dx[i] = (x2[i] - x1[i]) / dt;
  } else {
    mj_differentiatePos(&m, dx, dt, x1, x2);
  }
  // velocities and activations: vector difference
  for (int i = 0; i < nv; ++i) dx[nv + i] = (x2[nq + i] - x1[nq + i]) * inv_scale;
  for (int i = 0; i < na; ++i) dx[2 * nv + i] = (x2[nq + nv + i] - x1[nq + nv + i]) * inv_scale;
}

// out = w Jr^-1(phi) (3 x 3, row-major): the inverse right Jacobian of SO(3), so that
// log(exp(phi) exp(d)) = phi + Jr^-1(phi) d + O(|d|^2) for rotation vectors phi, d (rad), and
// log(exp(-d) exp(phi)) = phi - Jr^-1(phi)^T d + O(|d|^2). An orientation's TangentDifference
// (mju_subQuat: log(q1^-1 q2)) moves by Jr^-1 times a tangent perturbation of q2 on the right.
void InverseRightJacobianSO3(const double* phi, double w, double* out);

// perturbs d's qpos, qvel, act in place along the tangent vector dx scaled by scale; positions as
// mj_integratePos, bit for bit (inline without ball and free joints; tested)
inline void TangentPerturb(const mjModel& m, mjData* d, const double* dx, double scale) {
  const int nv = static_cast<int>(m.nv), na = static_cast<int>(m.na);
  // positions: integrate along the velocity-space direction for "time" scale; without ball and
  // free joints (nq = nv) mj_integratePos's own arithmetic, q + scale * dq, here
  if (m.nq == m.nv) {
    for (int i = 0; i < nv; ++i) d->qpos[i] += scale * dx[i];
  } else {
    mj_integratePos(&m, d->qpos, dx, scale);
  }
  for (int i = 0; i < nv; ++i) d->qvel[i] += scale * dx[nv + i];
  for (int i = 0; i < na; ++i) d->act[i] += scale * dx[2 * nv + i];
}

// one step of the simulation that skips the pipeline stages before skipstage (mjtStage), and the
// sensors if skipsensor. With mjSTAGE_NONE and skipsensor = false it computes exactly what mj_step
// computes (same calls in the same order; tested bit for bit). Skipping is valid only when the
// quantities of the skipped stages in d were computed at the same qpos/qvel by a model that agrees
// with m in everything those stages read. The integrator's own factorisation (Euler with damping,
// implicit) is always redone: reusing it would be wrong for damping and actuator parameters
// (docs/numerics.md, "Stage-skipping steps").
// Failure: a MuJoCo error (e.g. mjData stack or arena overflow) throws MujocoError and leaves d
// to be reset with mj_resetData (mujoco_env.h).
void StepSkip(const mjModel* m, mjData* d, int skipstage, bool skipsensor);

}  // namespace mjsysid
