// The equation-error start (see equation_error.h).
#include "sysid/data/equation_error.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <thread>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/text.h"
#include "core/thread_pool.h"
#include "sysid/data/state_smoothing.h"
#include "sysid/solve/variable_manifold.h"

namespace mjsysid {

namespace {

// one logged step: the state at k and the acceleration (qvel_{k+1} - qvel_k) / (t_{k+1} - t_k),
// the one the integrator applied from k to k + 1 when the log has one sample per step
struct Sample {
  const FitSequence* seq;
  int k;
  Eigen::VectorXd qacc;
};

// one row block of the system: the mean of the equations of `count` consecutive steps from
// `first` (indices into the steps)
struct Window {
  int first;
  int count;
};

// how one column of the regressor is formed (ColumnFormOf)
enum class ColumnForm {
  kDamping,        // joint damping: +qvel at the joint's dofs (qfrc_damper = -damping qvel)
  kArmature,       // joint armature: +qacc at the joint's dofs (M's diagonal holds the armature)
  kFrictionLoss,   // joint friction loss: -1 / +1 / 0 where its row is linear neg / pos / quadratic
  kPointMass,      // body mass: J(xipos)^T (acceleration of xipos - gravity), a point mass
  kRigidBody,      // body mass with its inertia scaled along: the point mass and the rotation
  kActuation,      // enters the actuation only: mj_fwdActuation again
  kVelocityStage,  // enters the velocity stage: mj_inverseSkip past the position stage
  kFull,           // anything else: a full mj_inverse at p0 + h (after mj_setConst)
};

// the number of dofs of joint j
int JointDofs(const mjModel& m, int j) {
  return m.jnt_type[j] == mjJNT_FREE ? 6 : m.jnt_type[j] == mjJNT_BALL ? 3 : 1;
}

// the form of parameter p's column. The closed forms hold for the continuous-time inverse
// (qfrc_inverse = M qacc + bias - qfrc_passive - qfrc_constraint; MuJoCo's engine_inverse.c,
// engine_passive.c, engine_core_smooth.c, engine_core_constraint.c) and for the discrete-time one
// (mjENBL_INVDISCRETE) of the Euler and implicitfast integrators without free joints, which adds
// h D qacc (D: the dof damping) and leaves the rest linear in qacc as above; the stage skips
// follow the kind table's stage (core/parameters.h).
ColumnForm ColumnFormOf(const mjModel& m, const Parameter& p, RegressorColumns how) {
  if (how == RegressorColumns::kForwardDifference) return ColumnForm::kFull;
  bool closed = true;
  if (m.opt.enableflags & mjENBL_INVDISCRETE) {
    closed = m.opt.integrator == mjINT_EULER || m.opt.integrator == mjINT_IMPLICITFAST;
    for (int j = 0; j < m.njnt; ++j) closed = closed && m.jnt_type[j] != mjJNT_FREE;
  }
  const int id = p.id();
  switch (p.kind()) {
    case ParameterKind::kJointDamping:
      if (closed && !(m.opt.disableflags & mjDSBL_DAMPER)) return ColumnForm::kDamping;
      break;
    case ParameterKind::kJointArmature:
      if (closed) return ColumnForm::kArmature;
      break;
    case ParameterKind::kJointFrictionLoss: {
      // its rows exist only where the friction loss is > 0 at p0
      bool rows = closed && !(m.opt.disableflags & mjDSBL_FRICTIONLOSS) &&
                  !(m.opt.disableflags & mjDSBL_CONSTRAINT);
      for (int i = 0; i < JointDofs(m, id); ++i) {
        rows = rows && m.dof_frictionloss[m.jnt_dofadr[id] + i] > 0;
      }
      if (rows) return ColumnForm::kFrictionLoss;
      break;
    }
    case ParameterKind::kBodyMass:
    case ParameterKind::kBodyMassInertia:
      // gravity compensation and fluid forces depend on the mass too
      if (closed && m.body_gravcomp[id] == 0 && m.opt.density == 0 && m.opt.viscosity == 0) {
        return p.kind() == ParameterKind::kBodyMass ? ColumnForm::kPointMass
                                                    : ColumnForm::kRigidBody;
      }
      break;
    default:
      break;
  }
  if (!p.needs_set_const() && p.stage() == mjSTAGE_VEL) return ColumnForm::kActuation;
  if (!p.needs_set_const() && p.stage() == mjSTAGE_POS) return ColumnForm::kVelocityStage;
  return ColumnForm::kFull;
}

// whether the discrete-time inverse treats the dof damping implicitly (qfrc + h D qacc)
bool ImplicitDamping(const mjModel& m) {
  if (!(m.opt.enableflags & mjENBL_INVDISCRETE)) return false;
  if (m.opt.integrator == mjINT_EULER) return !(m.opt.disableflags & mjDSBL_EULERDAMP);
  return m.opt.integrator == mjINT_IMPLICITFAST || m.opt.integrator == mjINT_IMPLICIT;
}

// the state, acceleration and control of sample sm into d (no allocation)
void LoadSample(const mjModel& m, const Sample& sm, mjData* d) {
  const FitSequence& s = *sm.seq;
  const double t = LogSampleTime(m, s, sm.k);
  mju_copy(d->qpos, s.qpos.row(sm.k).data(), m.nq);
  mju_copy(d->qvel, s.qvel.row(sm.k).data(), m.nv);
  mju_copy(d->qacc, sm.qacc.data(), m.nv);
  if (m.na) mju_copy(d->act, s.act.row(sm.k).data(), m.na);
  if (m.nu) mju_copy(d->ctrl, s.ctrl.row(HeldControlRow(s, sm.k, t)).data(), m.nu);
  d->time = t;
}

// the forward-difference step of parameter value v
double Step(double v) { return 1e-4 * std::max(std::abs(v), 1e-2); }

// the values p0 of params in m (set: their ParameterSet, prepared): the initial value where it is
// finite, else the model's
std::vector<double> StartValues(const mjModel& m, const ParameterSet& set,
                                const std::vector<FitParameter>& params) {
  const int np = static_cast<int>(params.size());
  std::vector<double> p0(np);
  set.Read(m, p0.data());
  for (int g = 0; g < np; ++g) {
    if (std::isfinite(params[g].initial)) p0[g] = params[g].initial;
  }
  return p0;
}

// whether s has the states the equations need: qpos, qvel (and act, when the model has them)
bool UsableSequence(const mjModel& m, const FitSequence& s) {
  return s.qpos.rows() && s.qvel.rows() && (m.na == 0 || s.act.rows());
}

// whether the log's states are the integrator's own: every sample one step after the previous
// one and qpos_{k+1} = qpos_k (+) dt qvel_{k+1} (semi-implicit Euler, implicit and implicitfast)
// to 1e-9 (states logged by a simulator; noisy or filtered states fail it); RK4: never
bool StatesAreIntegratorsOwn(const mjModel& m, const std::vector<const FitSequence*>& sequences) {
  if (m.opt.integrator == mjINT_RK4) return false;
  const int nv = m.nv;
  std::vector<double> dq(nv);
  for (const FitSequence* s : sequences) {
    if (s->qpos.rows() && !s->qvel.rows()) return false;  // encoders only
    if (!UsableSequence(m, *s)) continue;
    for (int k = 0; k + 1 < s->qvel.rows(); ++k) {
      const double dt = LogSampleTime(m, *s, k + 1) - LogSampleTime(m, *s, k);
      if (!(std::abs(dt - m.opt.timestep) <= 1e-9 * m.opt.timestep)) return false;
      mj_differentiatePos(&m, dq.data(), dt, s->qpos.row(k).data(), s->qpos.row(k + 1).data());
      for (int j = 0; j < nv; ++j) {
        const double v = s->qvel(k + 1, j);
        if (!(std::abs(dq[j] - v) <= 1e-9 * (1 + std::abs(v)))) return false;
      }
    }
  }
  return true;
}

// The steps of one usable sequence s whose states are the integrator's own: around every
// stride-th logged sample k, the steps k - window .. k + window - 1, each step's equation at its
// one-step acceleration (each step added once however many windows hold it, a window's steps
// consecutive in samples). Steps with a non-finite state or acceleration are left out, and so is
// every window that holds one.
void AddOwnSteps(const mjModel& m, const FitSequence* s, int window, int stride,
                 std::vector<Sample>* samples, std::vector<Window>* windows) {
  const int T = static_cast<int>(s->qvel.rows());
  std::vector<int> index(T, -1);  // step k's index in samples, -2: not finite
  auto add = [&](int k) {
    const double dt = LogSampleTime(m, *s, k + 1) - LogSampleTime(m, *s, k);
    Sample sm{s, k, (s->qvel.row(k + 1) - s->qvel.row(k)).transpose() / dt};
    bool finite = sm.qacc.allFinite() && s->qpos.row(k).allFinite() && s->qvel.row(k).allFinite();
    if (m.na) finite = finite && s->act.row(k).allFinite();
    if (!finite) return -2;
    samples->push_back(std::move(sm));
    return static_cast<int>(samples->size()) - 1;
  };
  for (int k = window; k + window < T; k += stride) {
    bool finite = true;
    int first = -1;
    for (int j = k - window; j < k + window; ++j) {
      if (index[j] == -1) index[j] = add(j);
      finite = finite && index[j] >= 0;
      if (j == k - window) first = index[j];
    }
    if (finite) windows->push_back(Window{first, 2 * window});
  }
}

// The samples of one smoothed sequence (sysid/data/state_smoothing.h): every stride-th sample k
// whose filtered states, control and acceleration are finite, one equation each
void AddSmoothedSamples(const mjModel& m, const SmoothedStates& sm, int stride,
                        std::vector<Sample>* samples, std::vector<Window>* windows) {
  const FitSequence& f = sm.states;
  const int T = static_cast<int>(f.qpos.rows());
  for (int k = 0; k < T; k += stride) {
    bool finite = sm.qacc.row(k).allFinite() && f.qpos.row(k).allFinite() &&
                  f.qvel.row(k).allFinite() && (m.nu == 0 || f.ctrl.row(k).allFinite());
    if (m.na) finite = finite && f.act.row(k).allFinite();
    if (!finite) continue;
    samples->push_back(Sample{&f, k, sm.qacc.row(k).transpose()});
    windows->push_back(Window{static_cast<int>(samples->size()) - 1, 1});
  }
}

// how pass 1 forms the columns: per column its form, parameter index and p0; whether any column
// needs the com-based accelerations; the implicit damping's timestep (0: none)
struct ColumnPlan {
  const ParameterSet* set;
  std::vector<int> cols;
  std::vector<ColumnForm> form;
  std::vector<double> p0;  // per parameter
  bool point_mass = false;
  double implicit_h = 0;
};

// a pass-1 chunk's buffers (nv each; 3 x nv for the Jacobians)
struct Scratch {
  explicit Scratch(int nv) : f0(nv), a0(nv), jacp(3 * nv), jacr(3 * nv) {}
  std::vector<double> f0, a0, jacp, jacr;
};

// joint damping: +qvel at the joint's dofs, + h qacc with the implicit damping
void DampingColumn(const mjModel& m, const mjData& d, int joint, double implicit_h, double* col) {
  for (int k = 0; k < JointDofs(m, joint); ++k) {
    const int dof = m.jnt_dofadr[joint] + k;
    col[dof] = d.qvel[dof] + implicit_h * d.qacc[dof];
  }
}

// joint armature: +qacc at the joint's dofs
void ArmatureColumn(const mjModel& m, const mjData& d, int joint, double* col) {
  for (int k = 0; k < JointDofs(m, joint); ++k) {
    const int dof = m.jnt_dofadr[joint] + k;
    col[dof] = d.qacc[dof];
  }
}

// joint friction loss: the dof's friction row applies +floss (linear negative) or -floss (linear
// positive), a force independent of floss in its quadratic zone; qfrc_inverse subtracts it
void FrictionLossColumn(const mjModel& m, const mjData& d, int joint, double* col) {
  for (int r = d.ne; r < d.ne + d.nf; ++r) {
    if (d.efc_type[r] != mjCNSTR_FRICTION_DOF) continue;
    const int dof = d.efc_id[r];
    if (m.dof_jntid[dof] != joint) continue;
    col[dof] = d.efc_state[r] == mjCNSTRSTATE_LINEARNEG   ? -1.0
               : d.efc_state[r] == mjCNSTRSTATE_LINEARPOS ? 1.0
                                                          : 0.0;
  }
}

// body mass: a unit point mass at body b's centre of mass, Jp^T (its acceleration - gravity)
// (acc: mj_objectAcceleration's); rigid: the inertia scaled along (I = I0 m / m0 about the centre
// of mass, world frame I0w = R I0 R^T, m0: the mass at p0), also Jr^T (I0w alpha + omega x I0w
// omega) / m0
void MassColumn(const mjModel& m, const mjData& d, int b, bool rigid, double m0, Scratch* scratch,
                double* col) {
  const int nv = m.nv;
  const double* jacp = scratch->jacp.data();
  const double* jacr = scratch->jacr.data();
  double acc[6], vel[6];
  mj_objectAcceleration(&m, &d, mjOBJ_BODY, b, acc, 0);
  mj_jac(&m, &d, scratch->jacp.data(), rigid ? scratch->jacr.data() : nullptr, d.xipos + 3 * b, b);
  for (int j = 0; j < nv; ++j) {
    col[j] = jacp[j] * acc[3] + jacp[nv + j] * acc[4] + jacp[2 * nv + j] * acc[5];
  }
  if (!rigid) return;
  mj_objectVelocity(&m, &d, mjOBJ_BODY, b, vel, 0);
  // torque = R (I0 / m0) R^T alpha + omega x R (I0 / m0) R^T omega, R = ximat
  const double* R = d.ximat + 9 * b;
  double la[3], lw[3], ta[3], tw[3], torque[3];
  mju_mulMatTVec3(la, R, acc);  // alpha in the inertial frame
  mju_mulMatTVec3(lw, R, vel);  // omega in the inertial frame
  for (int k = 0; k < 3; ++k) {
    const double i0 = m.body_inertia[3 * b + k] / m0;
    la[k] *= i0;
    lw[k] *= i0;
  }
  mju_mulMatVec3(ta, R, la);
  mju_mulMatVec3(tw, R, lw);
  mju_cross(torque, vel, tw);
  for (int k = 0; k < 3; ++k) torque[k] += ta[k];
  for (int j = 0; j < nv; ++j) {
    col[j] += jacr[j] * torque[0] + jacr[nv + j] * torque[1] + jacr[2 * nv + j] * torque[2];
  }
}

// column c's rows of one sample (col: nv values) in closed form from the sample's pipeline
// results; nothing for the other forms
void ClosedFormColumn(const mjModel& m, const mjData& d, const ColumnPlan& plan, int c,
                      Scratch* scratch, double* col) {
  const int g = plan.cols[c];
  const int id = (*plan.set)[g].id();
  switch (plan.form[c]) {
    case ColumnForm::kDamping:
      DampingColumn(m, d, id, plan.implicit_h, col);
      break;
    case ColumnForm::kArmature:
      ArmatureColumn(m, d, id, col);
      break;
    case ColumnForm::kFrictionLoss:
      FrictionLossColumn(m, d, id, col);
      break;
    case ColumnForm::kPointMass:
    case ColumnForm::kRigidBody:
      MassColumn(m, d, id, plan.form[c] == ColumnForm::kRigidBody, plan.p0[g], scratch, col);
      break;
    default:
      break;
  }
}

// the stage skips of sample i: actuation first (it reads the nominal velocity stage), then the
// velocity stage; each writes its parameter at p0 + h, recomputes, and writes p0 back
void StageSkipColumns(mjModel* m, mjData* d, const ColumnPlan& plan, int i, const Scratch& scratch,
                      Eigen::MatrixXd* A) {
  const int nv = m->nv;
  const int nc = static_cast<int>(plan.cols.size());
  for (int c = 0; c < nc; ++c) {
    if (plan.form[c] != ColumnForm::kActuation) continue;
    const int g = plan.cols[c];
    const double h = Step(plan.p0[g]);
    plan.set->WriteOne(m, d, g, plan.p0[g] + h);
    mj_fwdActuation(m, d);
    for (int j = 0; j < nv; ++j) (*A)(i * nv + j, c) = -(d->qfrc_actuator[j] - scratch.a0[j]) / h;
    plan.set->WriteOne(m, d, g, plan.p0[g]);
  }
  for (int c = 0; c < nc; ++c) {
    if (plan.form[c] != ColumnForm::kVelocityStage) continue;
    const int g = plan.cols[c];
    const double h = Step(plan.p0[g]);
    plan.set->WriteOne(m, d, g, plan.p0[g] + h);
    mj_inverseSkip(m, d, mjSTAGE_POS, 1);
    for (int j = 0; j < nv; ++j) (*A)(i * nv + j, c) = (d->qfrc_inverse[j] - scratch.f0[j]) / h;
    plan.set->WriteOne(m, d, g, plan.p0[g]);
  }
}

// Pass 1, samples [first, last) on (m, d) with p0 written: e(p0) from one mj_inverse (sensors
// skipped) and mj_fwdActuation, whether the sample has contacts, then (without contacts) every
// column but the full ones from that sample's pipeline results and the stage skips
void SampleRows(mjModel* m, mjData* d, const std::vector<Sample>& samples, const ColumnPlan& plan,
                int first, int last, EquationErrorSystem* sys, std::vector<char>* contact) {
  const int nv = m->nv;
  const int nc = static_cast<int>(plan.cols.size());
  Scratch scratch(nv);
  for (int i = first; i < last; ++i) {
    LoadSample(*m, samples[i], d);
    mj_inverseSkip(m, d, mjSTAGE_NONE, 1);
    mj_fwdActuation(m, d);
    (*contact)[i] = d->ncon > 0;
    mju_copy(scratch.f0.data(), d->qfrc_inverse, nv);
    mju_copy(scratch.a0.data(), d->qfrc_actuator, nv);
    for (int j = 0; j < nv; ++j) sys->e0[i * nv + j] = scratch.f0[j] - scratch.a0[j];
    if ((*contact)[i]) continue;  // refused; no columns
    // the com-based accelerations (cacc, world at -gravity) for the point-mass columns
    if (plan.point_mass) mj_rnePostConstraint(m, d);
    for (int c = 0; c < nc; ++c) {
      ClosedFormColumn(*m, *d, plan, c, &scratch, sys->A.col(c).data() + i * nv);
    }
    StageSkipColumns(m, d, plan, i, scratch, &sys->A);
  }
}

// pass(m, d, first, last) over [0, steps) in up to `threads` contiguous chunks of at least
// kMinChunk samples (a model copy costs about as much as a few samples): chunk 0 on m and d, the
// others on copies of m made before any chunk writes a parameter step into its model; the first
// chunk's exception rethrown
void ForChunks(mjModel* m, mjData* d, int steps, int threads,
               const std::function<void(mjModel*, mjData*, int, int)>& pass) {
  constexpr int kMinChunk = 256;
  const int chunks = std::max(1, std::min(ThreadCount(threads), steps / kMinChunk));
  if (chunks == 1) {
    pass(m, d, 0, steps);
    return;
  }
  std::vector<std::thread> pool;
  std::vector<std::exception_ptr> failed(chunks);
  std::vector<ModelPtr> models;
  std::vector<DataPtr> datas;
  for (int t = 1; t < chunks; ++t) {
    models.push_back(CopyModel(*m));
    datas.push_back(MakeData(*models.back()));
  }
  auto chunk = [&](int t) {
    try {
      pass(t ? models[t - 1].get() : m, t ? datas[t - 1].get() : d,
           static_cast<int>(static_cast<long long>(steps) * t / chunks),
           static_cast<int>(static_cast<long long>(steps) * (t + 1) / chunks));
    } catch (...) {
      failed[t] = std::current_exception();
    }
  };
  for (int t = 1; t < chunks; ++t) pool.emplace_back(chunk, t);
  chunk(0);
  for (std::thread& th : pool) th.join();
  for (const std::exception_ptr& e : failed) {
    if (e) std::rethrow_exception(e);
  }
}

// the windows that hold a step with contacts
int ContactWindows(const std::vector<Window>& windows, const std::vector<char>& contact) {
  int n = 0;
  for (const Window& w : windows) {
    for (int i = w.first; i < w.first + w.count; ++i) {
      if (contact[i]) {
        ++n;
        break;
      }
    }
  }
  return n;
}

// Pass 2, column by column: the full columns by a forward difference at p0 + h (one mj_setConst
// per column, as the parameter may need it); e is linear in these p
void FullColumns(mjModel* m, mjData* d, const std::vector<Sample>& samples, const ColumnPlan& plan,
                 EquationErrorSystem* sys) {
  const int nv = m->nv;
  const int steps = static_cast<int>(samples.size());
  std::vector<double> p = plan.p0;
  for (size_t c = 0; c < plan.cols.size(); ++c) {
    if (plan.form[c] != ColumnForm::kFull) continue;
    const int g = plan.cols[c];
    const double h = Step(plan.p0[g]);
    p[g] = plan.p0[g] + h;
    plan.set->Write(m, d, p.data());
    for (int i = 0; i < steps; ++i) {
      LoadSample(*m, samples[i], d);
      mj_inverseSkip(m, d, mjSTAGE_NONE, 1);
      mj_fwdActuation(m, d);
      for (int j = 0; j < nv; ++j) {
        sys->A(i * nv + j, c) =
            (d->qfrc_inverse[j] - d->qfrc_actuator[j] - sys->e0[i * nv + j]) / h;
      }
    }
    p[g] = plan.p0[g];
  }
}

// each window's rows: the mean of its steps' equations (the same filter on the forces and on
// every column of the regressor), sample by sample; sys's step rows become window rows
void WindowMeans(const std::vector<Window>& windows, int nv, EquationErrorSystem* sys) {
  const auto nc = sys->A.cols();
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(sys->samples * nv, nc);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(sys->samples * nv);
  for (int w = 0; w < sys->samples; ++w) {
    const Window& win = windows[w];
    for (int i = win.first; i < win.first + win.count; ++i) {
      A.middleRows(w * nv, nv) += sys->A.middleRows(i * nv, nv);
      e.segment(w * nv, nv) += sys->e0.segment(i * nv, nv);
    }
    A.middleRows(w * nv, nv) /= win.count;
    e.segment(w * nv, nv) /= win.count;
  }
  sys->A = std::move(A);
  sys->e0 = std::move(e);
}

}  // namespace

EquationErrorSystem EquationErrorRegressor(const mjModel& model,
                                           const std::vector<FitParameter>& params,
                                           const std::vector<int>& cols,
                                           const std::vector<const FitSequence*>& sequences,
                                           RegressorColumns how, int window, int max_samples,
                                           int threads) {
  EquationErrorSystem sys;
  ModelPtr mp = CopyModel(model);
  mjModel* m = mp.get();
  DataPtr dp = MakeData(*m);
  mjData* d = dp.get();
  const int nv = m->nv;

  // the parameters of this model and their values p0 (initial, else the model's value)
  std::vector<ParameterSpec> specs;
  for (const FitParameter& p : params) specs.push_back(p.target);
  const ParameterSet set(*m, specs);
  set.Prepare(m);
  sys.p0 = StartValues(*m, set, params);

  // own states (a simulator's log): each step's equation at its one-step acceleration
  // (qvel_{k+1} - qvel_k) / dt, the integrator's (mjENBL_INVDISCRETE), and a window's rows the
  // mean of its 2 x window steps' equations, around every stride-th sample; else the states and
  // controls filtered alike (sysid/data/state_smoothing.h), one equation per stride-th sample
  const bool own = StatesAreIntegratorsOwn(*m, sequences);
  std::vector<SmoothedStates> smoothed;
  std::vector<std::string> why;
  int usable = 0;
  if (own) {
    for (const FitSequence* s : sequences) {
      if (UsableSequence(*m, *s))
        usable += std::max(0, static_cast<int>(s->qvel.rows()) - 2 * window);
    }
  } else {
    smoothed.reserve(sequences.size());
    for (const FitSequence* s : sequences) {
      SmoothedStates sm;
      std::string reason;
      if (SmoothLoggedStates(*m, *s, &sm, &reason)) {
        usable += static_cast<int>(sm.states.qpos.rows());
        sys.half_width = std::max(sys.half_width, sm.half_width);
        sys.from_positions = sys.from_positions || sm.velocities_from_positions;
        smoothed.push_back(std::move(sm));
      } else if (std::find(why.begin(), why.end(), reason) == why.end()) {
        why.push_back(reason);
      }
    }
  }
  if (usable == 0) {
    sys.note = why.empty() ? "the log has no qpos and qvel" + std::string(m->na ? " and act" : "")
                           : JoinNames(why);
    return sys;
  }
  const int stride = std::max(1, usable / max_samples);
  std::vector<Sample> samples;  // the steps (own states) or the smoothed samples
  std::vector<Window> windows;
  if (own) {
    for (const FitSequence* s : sequences) {
      if (UsableSequence(*m, *s)) AddOwnSteps(*m, s, window, stride, &samples, &windows);
    }
  } else {
    for (const SmoothedStates& sm : smoothed)
      AddSmoothedSamples(*m, sm, stride, &samples, &windows);
  }
  // the discrete-time inverse wherever MuJoCo has one (not RK4): the smoothed velocities follow
  // the integrator's convention (sysid/data/state_smoothing.h)
  if (own || m->opt.integrator != mjINT_RK4) m->opt.enableflags |= mjENBL_INVDISCRETE;
  sys.discrete = own;
  sys.samples = static_cast<int>(windows.size());
  const int steps = static_cast<int>(samples.size());
  const int nc = static_cast<int>(cols.size());
  sys.e0.resize(steps * nv);
  sys.A.setZero(steps * nv, nc);

  // the form of each column (under the inverse the samples use); the closed forms first, then
  // actuation, velocity stage, full
  ColumnPlan plan{&set, cols, std::vector<ColumnForm>(nc), sys.p0};
  for (int c = 0; c < nc; ++c) {
    plan.form[c] = ColumnFormOf(*m, set[cols[c]], how);
    plan.point_mass = plan.point_mass || plan.form[c] == ColumnForm::kPointMass ||
                      plan.form[c] == ColumnForm::kRigidBody;
  }
  plan.implicit_h = ImplicitDamping(*m) ? m->opt.timestep : 0.0;
  sys.closed_form.assign(nc, false);
  for (int c = 0; c < nc; ++c) sys.closed_form[c] = plan.form[c] < ColumnForm::kActuation;

  // pass 1, sample by sample at p0, on up to `threads` threads: every row depends only on its
  // sample, so the system is the same bit for bit at any thread count. A sample with contacts
  // refuses the start: no columns, the windows that hold one counted
  set.Write(m, d, sys.p0.data());
  std::vector<char> contact(steps, 0);
  ForChunks(m, d, steps, threads, [&](mjModel* mm, mjData* dd, int first, int last) {
    SampleRows(mm, dd, samples, plan, first, last, &sys, &contact);
  });
  if (std::find(contact.begin(), contact.end(), 1) != contact.end()) {
    sys.A.setZero();
    sys.contacts = ContactWindows(windows, contact);
    return sys;
  }

  FullColumns(m, d, samples, plan, &sys);
  WindowMeans(windows, nv, &sys);
  return sys;
}

EquationErrorStart SolveEquationError(const mjModel& model, const std::vector<FitParameter>& params,
                                      const std::vector<int>& which,
                                      const std::vector<const FitSequence*>& sequences, int window,
                                      int max_samples, int threads) {
  EquationErrorStart out;
  const int np = static_cast<int>(params.size());
  out.solved.assign(np, false);
  std::vector<int> cols;
  for (int g : which) {
    const ParameterKindInfo* info = FindParameterKind(params[g].target.kind);
    if (info && EntersInverseDynamicsLinearly(info->kind)) cols.push_back(g);
  }
  if (cols.empty()) {
    // the values p0 without building the system
    ModelPtr m = CopyModel(model);
    std::vector<ParameterSpec> specs;
    for (const FitParameter& p : params) specs.push_back(p.target);
    const ParameterSet set(*m, specs);
    set.Prepare(m.get());
    out.values = StartValues(*m, set, params);
    out.note = "no parameter of a kind that enters the inverse dynamics linearly";
    return out;
  }

  // e(p0) and the regressor A = de/dp (e is linear in these p)
  const EquationErrorSystem sys = EquationErrorRegressor(
      model, params, cols, sequences, RegressorColumns::kFastest, window, max_samples, threads);
  out.values = sys.p0;
  out.samples = sys.samples;
  if (!sys.note.empty()) {
    out.note = sys.note;
    return out;
  }
  if (sys.A.rows() < static_cast<int>(cols.size())) {
    out.note = "too few logged samples (" + std::to_string(out.samples) + ")";
    return out;
  }
  // contacts: their inverse forces follow the noisy qacc through the soft-contact model and swamp
  // the parameters' share (measured on box_floor: mass 0.12 for a truth of 2.5); no start there
  if (sys.contacts > 0) {
    out.note = "the logged motion has contacts (" + std::to_string(sys.contacts) + " of " +
               std::to_string(out.samples) + " samples): no equation-error start";
    return out;
  }

  // the least-squares step, columns scaled to unit norm: a Householder QR of A (blocked; no Q
  // formed), the singular values of its n x n R (those of A) for the rank, then R \ Q^T (-e0);
  // rank deficient: no start
  const int nc = static_cast<int>(cols.size());
  const Eigen::VectorXd norms = sys.A.colwise().norm().transpose().cwiseMax(1e-300);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(sys.A * norms.cwiseInverse().asDiagonal());
  const Eigen::MatrixXd R = qr.matrixQR().topRows(nc).triangularView<Eigen::Upper>();
  const Eigen::VectorXd sv = Eigen::JacobiSVD<Eigen::MatrixXd>(R).singularValues();
  if (!(sv.minCoeff() > 1e-8 * sv.maxCoeff())) {
    out.note = "the logged motion does not determine the parameters (rank deficient regressor)";
    return out;
  }
  const Eigen::VectorXd qtb = qr.householderQ().adjoint() * (-sys.e0);
  const Eigen::VectorXd step = norms.cwiseInverse().asDiagonal() *
                               R.triangularView<Eigen::Upper>().solve(qtb.head(nc)).eval();
  std::string values;
  for (size_t c = 0; c < cols.size(); ++c) {
    const FitParameter& p = params[cols[c]];
    double v = sys.p0[cols[c]] + step[c];
    // strictly inside the bounds (and positive for log): 1e-3 of the range from a bound
    const double lo = p.transform == Transform::kLog ? std::max(p.lower, 0.0) : p.lower;
    const double span = std::isfinite(p.upper - lo) ? p.upper - lo : std::abs(v) + 1.0;
    v = std::clamp(v, lo + 1e-3 * span, p.upper - 1e-3 * span);
    out.values[cols[c]] = v;
    out.solved[cols[c]] = true;
    values += (values.empty() ? "" : ", ") + p.name + " " + FormatDigits(v, 4);
  }
  out.note =
      "equation-error start from " + std::to_string(out.samples) + " logged samples (mj_inverse, " +
      (sys.discrete
           ? std::string("the integrator's steps")
           : std::string(sys.from_positions ? "positions" : "states") +
                 " smoothed by cubics over +-" + std::to_string(sys.half_width) + " samples") +
      "): " + values;
  return out;
}

}  // namespace mjsysid
