// The equation-error start (see equation_error.h).
#include "sysid/equation_error.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/text.h"
#include "sysid/variable_manifold.h"

namespace mjsysid {

namespace {

// one logged sample: the state, the finite-difference acceleration and the held control
struct Sample {
  const FitSequence* seq;
  int k;
  Eigen::VectorXd qacc;
};

// how one column of the regressor is formed (ColumnFormOf)
enum class ColumnForm {
  kDamping,        // joint damping: +qvel at the joint's dofs (qfrc_damper = -damping qvel)
  kArmature,       // joint armature: +qacc at the joint's dofs (M's diagonal holds the armature)
  kFrictionLoss,   // joint friction loss: -1 / +1 / 0 where its row is linear neg / pos / quadratic
  kPointMass,      // body mass: J(xipos)^T (acceleration of xipos - gravity), a point mass
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
// (mjENBL_INVDISCRETE off; MuJoCo's engine_inverse.c, engine_passive.c, engine_core_smooth.c,
// engine_core_constraint.c); the stage skips follow the kind table's stage (core/parameters.h).
ColumnForm ColumnFormOf(const mjModel& m, const Parameter& p, RegressorColumns how) {
  if (how == RegressorColumns::kForwardDifference) return ColumnForm::kFull;
  const bool continuous = !(m.opt.enableflags & mjENBL_INVDISCRETE);
  const int id = p.id();
  switch (p.kind()) {
    case ParameterKind::kJointDamping:
      if (continuous && !(m.opt.disableflags & mjDSBL_DAMPER)) return ColumnForm::kDamping;
      break;
    case ParameterKind::kJointArmature:
      if (continuous) return ColumnForm::kArmature;
      break;
    case ParameterKind::kJointFrictionLoss: {
      // its rows exist only where the friction loss is > 0 at p0
      bool rows = continuous && !(m.opt.disableflags & mjDSBL_FRICTIONLOSS) &&
                  !(m.opt.disableflags & mjDSBL_CONSTRAINT);
      for (int i = 0; i < JointDofs(m, id); ++i) {
        rows = rows && m.dof_frictionloss[m.jnt_dofadr[id] + i] > 0;
      }
      if (rows) return ColumnForm::kFrictionLoss;
      break;
    }
    case ParameterKind::kBodyMass:
      // gravity compensation and fluid forces depend on the mass too
      if (continuous && m.body_gravcomp[id] == 0 && m.opt.density == 0 && m.opt.viscosity == 0) {
        return ColumnForm::kPointMass;
      }
      break;
    default:
      break;
  }
  if (!p.needs_set_const() && p.stage() == mjSTAGE_VEL) return ColumnForm::kActuation;
  if (!p.needs_set_const() && p.stage() == mjSTAGE_POS) return ColumnForm::kVelocityStage;
  return ColumnForm::kFull;
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
                                           RegressorColumns how, int window, int max_samples) {
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

  // the samples with qpos, qvel (and act) logged at k and qvel at k +- window
  int usable = 0;
  for (const FitSequence* s : sequences) {
    if (s->qpos.rows() && s->qvel.rows() && (m->na == 0 || s->act.rows())) {
      usable += std::max(0, static_cast<int>(s->qvel.rows()) - 2 * window);
    }
  }
  if (usable == 0) {
    sys.note = "the log has no qpos and qvel" + std::string(m->na ? " and act" : "");
    return sys;
  }
  const int stride = std::max(1, usable / max_samples);
  std::vector<Sample> samples;
  for (const FitSequence* s : sequences) {
    if (!(s->qpos.rows() && s->qvel.rows() && (m->na == 0 || s->act.rows()))) continue;
    const int T = static_cast<int>(s->qvel.rows());
    for (int k = window; k + window < T; k += stride) {
      const double dt = SampleTime(*m, *s, k + window) - SampleTime(*m, *s, k - window);
      Sample sm{s, k, (s->qvel.row(k + window) - s->qvel.row(k - window)).transpose() / dt};
      bool finite = sm.qacc.allFinite() && s->qpos.row(k).allFinite() && s->qvel.row(k).allFinite();
      if (m->na) finite = finite && s->act.row(k).allFinite();
      if (finite) samples.push_back(std::move(sm));
    }
  }
  sys.samples = static_cast<int>(samples.size());
  const int rows = sys.samples * nv;
  const int nc = static_cast<int>(cols.size());
  sys.e0.resize(rows);
  sys.A.setZero(rows, nc);

  // the form of each column; the closed forms first, then actuation, velocity stage, full
  std::vector<ColumnForm> form(nc);
  bool point_mass = false;
  for (int c = 0; c < nc; ++c) {
    form[c] = ColumnFormOf(*m, set[cols[c]], how);
    point_mass = point_mass || form[c] == ColumnForm::kPointMass;
  }
  sys.closed_form.assign(nc, false);
  for (int c = 0; c < nc; ++c) sys.closed_form[c] = form[c] < ColumnForm::kActuation;

  // pass 1, sample by sample at p0: e(p0) from one mj_inverse (sensors skipped) and
  // mj_fwdActuation, then every column but the full ones from that sample's pipeline results
  set.Write(m, d, p0.data());
  std::vector<double> f0(nv), a0(nv), jacp(3 * nv);
  for (int i = 0; i < sys.samples; ++i) {
    LoadSample(*m, samples[i], d);
    mj_inverseSkip(m, d, mjSTAGE_NONE, 1);
    mj_fwdActuation(m, d);
    sys.contacts += d->ncon > 0;
    mju_copy(f0.data(), d->qfrc_inverse, nv);
    mju_copy(a0.data(), d->qfrc_actuator, nv);
    for (int j = 0; j < nv; ++j) sys.e0[i * nv + j] = f0[j] - a0[j];
    if (sys.contacts) continue;  // refused below; no columns
    // the com-based accelerations (cacc, world at -gravity) for the point-mass columns
    if (point_mass) mj_rnePostConstraint(m, d);
    for (int c = 0; c < nc; ++c) {
      const Parameter& p = set[cols[c]];
      double* col = sys.A.col(c).data() + i * nv;
      switch (form[c]) {
        case ColumnForm::kDamping:
          for (int k = 0; k < JointDofs(*m, p.id()); ++k) {
            const int dof = m->jnt_dofadr[p.id()] + k;
            col[dof] = d->qvel[dof];
          }
          break;
        case ColumnForm::kArmature:
          for (int k = 0; k < JointDofs(*m, p.id()); ++k) {
            const int dof = m->jnt_dofadr[p.id()] + k;
            col[dof] = d->qacc[dof];
          }
          break;
        case ColumnForm::kFrictionLoss:
          // the dof's friction row applies +floss (linear negative) or -floss (linear positive),
          // a force independent of floss in its quadratic zone; qfrc_inverse subtracts it
          for (int r = d->ne; r < d->ne + d->nf; ++r) {
            if (d->efc_type[r] != mjCNSTR_FRICTION_DOF) continue;
            const int dof = d->efc_id[r];
            if (m->dof_jntid[dof] != p.id()) continue;
            col[dof] = d->efc_state[r] == mjCNSTRSTATE_LINEARNEG   ? -1.0
                       : d->efc_state[r] == mjCNSTRSTATE_LINEARPOS ? 1.0
                                                                   : 0.0;
          }
          break;
        case ColumnForm::kPointMass: {
          // a unit point mass at the body's centre of mass: J^T (its acceleration - gravity)
          double acc[6];
          mj_objectAcceleration(m, d, mjOBJ_BODY, p.id(), acc, 0);
          mj_jac(m, d, jacp.data(), nullptr, d->xipos + 3 * p.id(), p.id());
          for (int j = 0; j < nv; ++j) {
            col[j] = jacp[j] * acc[3] + jacp[nv + j] * acc[4] + jacp[2 * nv + j] * acc[5];
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
      set.WriteOne(m, d, cols[c], p0[cols[c]] + h);
      mj_fwdActuation(m, d);
      for (int j = 0; j < nv; ++j) sys.A(i * nv + j, c) = -(d->qfrc_actuator[j] - a0[j]) / h;
      set.WriteOne(m, d, cols[c], p0[cols[c]]);
    }
    for (int c = 0; c < nc; ++c) {
      if (form[c] != ColumnForm::kVelocityStage) continue;
      const double h = Step(p0[cols[c]]);
      set.WriteOne(m, d, cols[c], p0[cols[c]] + h);
      mj_inverseSkip(m, d, mjSTAGE_POS, 1);
      for (int j = 0; j < nv; ++j) sys.A(i * nv + j, c) = (d->qfrc_inverse[j] - f0[j]) / h;
      set.WriteOne(m, d, cols[c], p0[cols[c]]);
    }
  }
  if (sys.contacts) return sys;

  // pass 2, column by column: the full columns by a forward difference at p0 + h (one
  // mj_setConst per column, as the parameter may need it); e is linear in these p
  std::vector<double> p = p0;
  for (int c = 0; c < nc; ++c) {
    if (form[c] != ColumnForm::kFull) continue;
    const double h = Step(p0[cols[c]]);
    p[cols[c]] = p0[cols[c]] + h;
    set.Write(m, d, p.data());
    for (int i = 0; i < sys.samples; ++i) {
      LoadSample(*m, samples[i], d);
      mj_inverseSkip(m, d, mjSTAGE_NONE, 1);
      mj_fwdActuation(m, d);
      for (int j = 0; j < nv; ++j) {
        sys.A(i * nv + j, c) = (d->qfrc_inverse[j] - d->qfrc_actuator[j] - sys.e0[i * nv + j]) / h;
      }
    }
    p[cols[c]] = p0[cols[c]];
  }
  return sys;
}

EquationErrorStart SolveEquationError(const mjModel& model, const std::vector<FitParameter>& params,
                                      const std::vector<int>& which,
                                      const std::vector<const FitSequence*>& sequences, int window,
                                      int max_samples) {
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
      model, params, cols, sequences, RegressorColumns::kFastest, window, max_samples);
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
             " logged samples (mj_inverse): " + values;
  return out;
}

}  // namespace mjsysid
