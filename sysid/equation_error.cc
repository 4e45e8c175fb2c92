// The equation-error start (see equation_error.h).
#include "sysid/equation_error.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <exception>
#include <thread>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/text.h"
#include "core/thread_pool.h"
#include "sysid/variable_manifold.h"

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

// the time of sample k of s
double SampleTime(const mjModel& m, const FitSequence& s, int k) {
  return s.time.size() ? s.time[k] : s.x0.time + k * m.opt.timestep;
}

// the control row held at time t (zero-order hold on ctrl_time, or the sample's own row)
int ControlRow(const FitSequence& s, int k, double t) {
  if (s.ctrl_time.size() == 0) return k;
  const double* b = s.ctrl_time.data();
  const double* it = std::upper_bound(b, b + s.ctrl_time.size(), t);
  return std::max(0, static_cast<int>(it - b) - 1);
}

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
  const double t = SampleTime(m, s, sm.k);
  mju_copy(d->qpos, s.qpos.row(sm.k).data(), m.nq);
  mju_copy(d->qvel, s.qvel.row(sm.k).data(), m.nv);
  mju_copy(d->qacc, sm.qacc.data(), m.nv);
  if (m.na) mju_copy(d->act, s.act.row(sm.k).data(), m.na);
  if (m.nu) mju_copy(d->ctrl, s.ctrl.row(ControlRow(s, sm.k, t)).data(), m.nu);
  d->time = t;
}

// the forward-difference step of parameter value v
double Step(double v) { return 1e-4 * std::max(std::abs(v), 1e-2); }

}  // namespace

EquationErrorSystem EquationErrorRegressor(const mjModel& model,
                                           const std::vector<FitParameter>& params,
                                           const std::vector<int>& cols,
                                           const std::vector<const FitSequence*>& sequences,
                                           RegressorColumns how, int window, int max_samples,
                                           int threads) {
  EquationErrorSystem sys;
  const int np = static_cast<int>(params.size());
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
  sys.p0.resize(np);
  set.Read(*m, sys.p0.data());
  for (int g = 0; g < np; ++g) {
    if (std::isfinite(params[g].initial)) sys.p0[g] = params[g].initial;
  }
  const std::vector<double>& p0 = sys.p0;

  // the windows: around every stride-th logged sample k with qpos, qvel (and act), the steps
  // k - window .. k + window - 1 (their accelerations span qvel_{k-window} .. qvel_{k+window});
  // each step evaluated once, however many windows hold it
  auto usable_sequence = [&](const FitSequence& s) {
    return s.qpos.rows() && s.qvel.rows() && (m->na == 0 || s.act.rows());
  };
  int usable = 0;
  for (const FitSequence* s : sequences) {
    if (usable_sequence(*s)) usable += std::max(0, static_cast<int>(s->qvel.rows()) - 2 * window);
  }
  if (usable == 0) {
    sys.note = "the log has no qpos and qvel" + std::string(m->na ? " and act" : "");
    return sys;
  }
  const int stride = std::max(1, usable / max_samples);
  // the log's states are the integrator's own when every sample is one step after the previous
  // one and qpos_{k+1} = qpos_k (+) dt qvel_{k+1} (semi-implicit Euler, implicit and implicitfast)
  // holds to 1e-9 (states logged by a simulator; noisy or filtered states fail it); RK4: never
  bool own = m->opt.integrator != mjINT_RK4;
  std::vector<double> dq(nv);
  for (const FitSequence* s : sequences) {
    if (!own || !usable_sequence(*s)) continue;
    for (int k = 0; own && k + 1 < s->qvel.rows(); ++k) {
      const double dt = SampleTime(*m, *s, k + 1) - SampleTime(*m, *s, k);
      own = std::abs(dt - m->opt.timestep) <= 1e-9 * m->opt.timestep;
      if (!own) break;
      mj_differentiatePos(m, dq.data(), dt, s->qpos.row(k).data(), s->qpos.row(k + 1).data());
      for (int j = 0; j < nv; ++j) {
        const double v = s->qvel(k + 1, j);
        own = own && std::abs(dq[j] - v) <= 1e-9 * (1 + std::abs(v));
      }
    }
  }
  // own states: each step's equation at its one-step acceleration (qvel_{k+1} - qvel_k) / dt, the
  // integrator's (mjENBL_INVDISCRETE), and a window's rows the mean of its 2 x window steps'
  // equations; else one equation per window at the central difference of qvel over it
  std::vector<Sample> samples;  // the steps (own states) or the windows' centres
  std::vector<Window> windows;
  for (const FitSequence* s : sequences) {
    if (!usable_sequence(*s)) continue;
    const int T = static_cast<int>(s->qvel.rows());
    std::vector<int> index(T, -1);  // step k's index in samples, -2: not finite
    auto add = [&](int k, int k0, int k1) {
      const double dt = SampleTime(*m, *s, k1) - SampleTime(*m, *s, k0);
      Sample sm{s, k, (s->qvel.row(k1) - s->qvel.row(k0)).transpose() / dt};
      bool finite = sm.qacc.allFinite() && s->qpos.row(k).allFinite() && s->qvel.row(k).allFinite();
      if (m->na) finite = finite && s->act.row(k).allFinite();
      if (!finite) return -2;
      samples.push_back(std::move(sm));
      return static_cast<int>(samples.size()) - 1;
    };
    for (int k = window; k + window < T; k += stride) {
      if (!own) {
        const int i = add(k, k - window, k + window);
        if (i >= 0) windows.push_back(Window{i, 1});
        continue;
      }
      // a window's steps are consecutive in samples (each is new, or the previous window's)
      bool finite = true;
      int first = -1;
      for (int j = k - window; j < k + window; ++j) {
        if (index[j] == -1) index[j] = add(j, j, j + 1);
        finite = finite && index[j] >= 0;
        if (j == k - window) first = index[j];
      }
      if (finite) windows.push_back(Window{first, 2 * window});
    }
  }
  if (own) m->opt.enableflags |= mjENBL_INVDISCRETE;
  sys.discrete = own;
  sys.samples = static_cast<int>(windows.size());
  const int steps = static_cast<int>(samples.size());
  const int rows = steps * nv;
  const int nc = static_cast<int>(cols.size());
  sys.e0.resize(rows);
  sys.A.setZero(rows, nc);

  // the form of each column; the closed forms first, then actuation, velocity stage, full
  std::vector<ColumnForm> form(nc);
  bool point_mass = false;
  for (int c = 0; c < nc; ++c) {
    form[c] = ColumnFormOf(*m, set[cols[c]], how);
    point_mass =
        point_mass || form[c] == ColumnForm::kPointMass || form[c] == ColumnForm::kRigidBody;
  }
  sys.closed_form.assign(nc, false);
  for (int c = 0; c < nc; ++c) sys.closed_form[c] = form[c] < ColumnForm::kActuation;

  // pass 1, sample by sample at p0: e(p0) from one mj_inverse (sensors skipped) and
  // mj_fwdActuation, then every column but the full ones from that sample's pipeline results.
  // The samples are split into up to `threads` contiguous chunks, each on its own copy of the
  // model (p0 written) and its own mjData; every row depends only on its sample, so the system is
  // the same bit for bit at any thread count
  set.Write(m, d, p0.data());
  std::vector<char> contact(steps, 0);
  const double implicit_h = ImplicitDamping(*m) ? m->opt.timestep : 0.0;
  auto pass1 = [&](mjModel* mm, mjData* dd, int first, int last) {
    std::vector<double> f0(nv), a0(nv), jacp(3 * nv), jacr(3 * nv);
    for (int i = first; i < last; ++i) {
      LoadSample(*mm, samples[i], dd);
      mj_inverseSkip(mm, dd, mjSTAGE_NONE, 1);
      mj_fwdActuation(mm, dd);
      contact[i] = dd->ncon > 0;
      mju_copy(f0.data(), dd->qfrc_inverse, nv);
      mju_copy(a0.data(), dd->qfrc_actuator, nv);
      for (int j = 0; j < nv; ++j) sys.e0[i * nv + j] = f0[j] - a0[j];
      if (contact[i]) continue;  // refused below; no columns
      // the com-based accelerations (cacc, world at -gravity) for the point-mass columns
      if (point_mass) mj_rnePostConstraint(mm, dd);
      for (int c = 0; c < nc; ++c) {
        const Parameter& p = set[cols[c]];
        double* col = sys.A.col(c).data() + i * nv;
        switch (form[c]) {
          case ColumnForm::kDamping:
            for (int k = 0; k < JointDofs(*mm, p.id()); ++k) {
              const int dof = mm->jnt_dofadr[p.id()] + k;
              col[dof] = dd->qvel[dof] + implicit_h * dd->qacc[dof];
            }
            break;
          case ColumnForm::kArmature:
            for (int k = 0; k < JointDofs(*mm, p.id()); ++k) {
              const int dof = mm->jnt_dofadr[p.id()] + k;
              col[dof] = dd->qacc[dof];
            }
            break;
          case ColumnForm::kFrictionLoss:
            // the dof's friction row applies +floss (linear negative) or -floss (linear
            // positive), a force independent of floss in its quadratic zone; qfrc_inverse
            // subtracts it
            for (int r = dd->ne; r < dd->ne + dd->nf; ++r) {
              if (dd->efc_type[r] != mjCNSTR_FRICTION_DOF) continue;
              const int dof = dd->efc_id[r];
              if (mm->dof_jntid[dof] != p.id()) continue;
              col[dof] = dd->efc_state[r] == mjCNSTRSTATE_LINEARNEG   ? -1.0
                         : dd->efc_state[r] == mjCNSTRSTATE_LINEARPOS ? 1.0
                                                                      : 0.0;
            }
            break;
          case ColumnForm::kPointMass:
          case ColumnForm::kRigidBody: {
            // a unit point mass at the body's centre of mass: Jp^T (its acceleration - gravity);
            // with the inertia scaled along (I = I0 m / m0 about the centre of mass, world frame
            // I0w = R I0 R^T), also Jr^T (I0w alpha + omega x I0w omega) / m0
            const int b = p.id();
            double acc[6], vel[6];
            mj_objectAcceleration(mm, dd, mjOBJ_BODY, b, acc, 0);
            const bool rigid = form[c] == ColumnForm::kRigidBody;
            mj_jac(mm, dd, jacp.data(), rigid ? jacr.data() : nullptr, dd->xipos + 3 * b, b);
            for (int j = 0; j < nv; ++j) {
              col[j] = jacp[j] * acc[3] + jacp[nv + j] * acc[4] + jacp[2 * nv + j] * acc[5];
            }
            if (!rigid) break;
            mj_objectVelocity(mm, dd, mjOBJ_BODY, b, vel, 0);
            // torque = R (I0 / m0) R^T alpha + omega x R (I0 / m0) R^T omega, R = ximat
            const double* R = dd->ximat + 9 * b;
            double la[3], lw[3], ta[3], tw[3], torque[3];
            mju_mulMatTVec3(la, R, acc);  // alpha in the inertial frame
            mju_mulMatTVec3(lw, R, vel);  // omega in the inertial frame
            for (int k = 0; k < 3; ++k) {
              const double i0 = mm->body_inertia[3 * b + k] / p0[cols[c]];
              la[k] *= i0;
              lw[k] *= i0;
            }
            mju_mulMatVec3(ta, R, la);
            mju_mulMatVec3(tw, R, lw);
            mju_cross(torque, vel, tw);
            for (int k = 0; k < 3; ++k) torque[k] += ta[k];
            for (int j = 0; j < nv; ++j) {
              col[j] +=
                  jacr[j] * torque[0] + jacr[nv + j] * torque[1] + jacr[2 * nv + j] * torque[2];
            }
            break;
          }
          default:
            break;
        }
      }
      // the stage skips: actuation first (it reads the nominal velocity stage), then the velocity
      // stage; each writes its parameter, recomputes, and writes p0 back
      for (int c = 0; c < nc; ++c) {
        if (form[c] != ColumnForm::kActuation) continue;
        const double h = Step(p0[cols[c]]);
        set.WriteOne(mm, dd, cols[c], p0[cols[c]] + h);
        mj_fwdActuation(mm, dd);
        for (int j = 0; j < nv; ++j) sys.A(i * nv + j, c) = -(dd->qfrc_actuator[j] - a0[j]) / h;
        set.WriteOne(mm, dd, cols[c], p0[cols[c]]);
      }
      for (int c = 0; c < nc; ++c) {
        if (form[c] != ColumnForm::kVelocityStage) continue;
        const double h = Step(p0[cols[c]]);
        set.WriteOne(mm, dd, cols[c], p0[cols[c]] + h);
        mj_inverseSkip(mm, dd, mjSTAGE_POS, 1);
        for (int j = 0; j < nv; ++j) sys.A(i * nv + j, c) = (dd->qfrc_inverse[j] - f0[j]) / h;
        set.WriteOne(mm, dd, cols[c], p0[cols[c]]);
      }
    }
  };
  // chunks of at least kMinChunk samples: a model copy costs about as much as a few samples
  constexpr int kMinChunk = 256;
  const int chunks = std::max(1, std::min(ThreadCount(threads), steps / kMinChunk));
  if (chunks == 1) {
    pass1(m, d, 0, steps);
  } else {
    std::vector<std::thread> pool;
    std::vector<std::exception_ptr> failed(chunks);
    // chunk 0 on the caller's model and data, the others on copies made before any chunk writes
    // a parameter step into its model
    std::vector<ModelPtr> models;
    std::vector<DataPtr> datas;
    for (int t = 1; t < chunks; ++t) {
      models.push_back(CopyModel(*m));
      datas.push_back(MakeData(*models.back()));
    }
    auto chunk = [&](int t) {
      try {
        pass1(t ? models[t - 1].get() : m, t ? datas[t - 1].get() : d,
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
  const bool any_contact = std::find(contact.begin(), contact.end(), 1) != contact.end();
  if (any_contact) sys.A.setZero();  // no columns where the start is refused
  if (any_contact) {
    for (const Window& w : windows) {
      for (int i = w.first; i < w.first + w.count; ++i) {
        if (contact[i]) {
          ++sys.contacts;
          break;
        }
      }
    }
    return sys;
  }

  // pass 2, column by column: the full columns by a forward difference at p0 + h (one
  // mj_setConst per column, as the parameter may need it); e is linear in these p
  std::vector<double> p = p0;
  for (int c = 0; c < nc; ++c) {
    if (form[c] != ColumnForm::kFull) continue;
    const double h = Step(p0[cols[c]]);
    p[cols[c]] = p0[cols[c]] + h;
    set.Write(m, d, p.data());
    for (int i = 0; i < steps; ++i) {
      LoadSample(*m, samples[i], d);
      mj_inverseSkip(m, d, mjSTAGE_NONE, 1);
      mj_fwdActuation(m, d);
      for (int j = 0; j < nv; ++j) {
        sys.A(i * nv + j, c) = (d->qfrc_inverse[j] - d->qfrc_actuator[j] - sys.e0[i * nv + j]) / h;
      }
    }
    p[cols[c]] = p0[cols[c]];
  }

  // each window's rows: the mean of its steps' equations (the same filter on the forces and on
  // every column of the regressor), sample by sample
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(sys.samples * nv, nc);
  Eigen::VectorXd e = Eigen::VectorXd::Zero(sys.samples * nv);
  for (int w = 0; w < sys.samples; ++w) {
    const Window& win = windows[w];
    for (int i = win.first; i < win.first + win.count; ++i) {
      A.middleRows(w * nv, nv) += sys.A.middleRows(i * nv, nv);
      e.segment(w * nv, nv) += sys.e0.segment(i * nv, nv);
    }
    A.middleRows(w * nv, nv) /= win.count;
    e.segment(w * nv, nv) /= win.count;
  }
  sys.A = std::move(A);
  sys.e0 = std::move(e);
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
    out.values.resize(np);
    set.Read(*m, out.values.data());
    for (int g = 0; g < np; ++g) {
      if (std::isfinite(params[g].initial)) out.values[g] = params[g].initial;
    }
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
  out.note = "equation-error start from " + std::to_string(out.samples) +
             " logged samples (mj_inverse, " +
             (sys.discrete ? std::string("the integrator's steps")
                           : "central differences over +-" + std::to_string(window) + " samples") +
             "): " + values;
  return out;
}

}  // namespace mjsysid
