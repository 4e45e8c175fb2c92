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

// e(p) of every sample into e (samples x nv, stacked); returns the samples with contacts
int InverseResiduals(const mjModel& m, mjData* d, const std::vector<Sample>& samples,
                     Eigen::VectorXd* e) {
  const int nv = m.nv;
  int contacts = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    const Sample& sm = samples[i];
    const FitSequence& s = *sm.seq;
    const double t = SampleTime(m, s, sm.k);
    mju_copy(d->qpos, s.qpos.row(sm.k).data(), m.nq);
    mju_copy(d->qvel, s.qvel.row(sm.k).data(), nv);
    mju_copy(d->qacc, sm.qacc.data(), nv);
    if (m.na) mju_copy(d->act, s.act.row(sm.k).data(), m.na);
    if (m.nu) mju_copy(d->ctrl, s.ctrl.row(ControlRow(s, sm.k, t)).data(), m.nu);
    d->time = t;
    mj_inverse(&m, d);
    mj_fwdActuation(&m, d);
    for (int j = 0; j < nv; ++j) (*e)[i * nv + j] = d->qfrc_inverse[j] - d->qfrc_actuator[j];
    contacts += d->ncon > 0;
  }
  return contacts;
}

}  // namespace

EquationErrorStart SolveEquationError(const mjModel& model, const std::vector<FitParameter>& params,
                                      const std::vector<int>& which,
                                      const std::vector<const FitSequence*>& sequences, int window,
                                      int max_samples) {
  EquationErrorStart out;
  const int np = static_cast<int>(params.size());
  out.solved.assign(np, false);
  ModelPtr m = CopyModel(model);
  DataPtr d = MakeData(*m);

  // the parameters of this model and their values p0 (initial, else the model's value)
  std::vector<ParameterSpec> specs;
  for (const FitParameter& p : params) specs.push_back(p.target);
  const ParameterSet set(*m, specs);
  set.Prepare(m.get());
  std::vector<double> p0(np);
  set.Read(*m, p0.data());
  for (int g = 0; g < np; ++g) {
    if (std::isfinite(params[g].initial)) p0[g] = params[g].initial;
  }
  out.values = p0;
  std::vector<int> cols;
  for (int g : which) {
    const ParameterKindInfo* info = FindParameterKind(params[g].target.kind);
    if (info && EntersInverseDynamicsLinearly(info->kind)) cols.push_back(g);
  }
  if (cols.empty()) {
    out.note = "no parameter of a kind that enters the inverse dynamics linearly";
    return out;
  }

  // the samples with qpos, qvel (and act) logged at k and qvel at k +- window
  int usable = 0;
  for (const FitSequence* s : sequences) {
    if (s->qpos.rows() && s->qvel.rows() && (m->na == 0 || s->act.rows())) {
      usable += std::max(0, static_cast<int>(s->qvel.rows()) - 2 * window);
    }
  }
  if (usable == 0) {
    out.note = "the log has no qpos and qvel" + std::string(m->na ? " and act" : "");
    return out;
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
  out.samples = static_cast<int>(samples.size());
  const int rows = out.samples * m->nv;
  if (rows < static_cast<int>(cols.size())) {
    out.note = "too few logged samples (" + std::to_string(out.samples) + ")";
    return out;
  }

  // e(p0) and the regressor A = de/dp by forward differences (e is linear in these p)
  Eigen::VectorXd e0(rows), e1(rows);
  set.Write(m.get(), d.get(), p0.data());
  // contacts: their inverse forces follow the noisy qacc through the soft-contact model and swamp
  // the parameters' share (measured on box_floor: mass 0.12 for a truth of 2.5); no start there
  const int contacts = InverseResiduals(*m, d.get(), samples, &e0);
  if (contacts > 0) {
    out.note = "the logged motion has contacts (" + std::to_string(contacts) + " of " +
               std::to_string(out.samples) + " samples): no equation-error start";
    return out;
  }
  Eigen::MatrixXd A(rows, cols.size());
  for (size_t c = 0; c < cols.size(); ++c) {
    std::vector<double> p = p0;
    const double h = 1e-4 * std::max(std::abs(p0[cols[c]]), 1e-2);
    p[cols[c]] += h;
    set.Write(m.get(), d.get(), p.data());
    InverseResiduals(*m, d.get(), samples, &e1);
    A.col(c) = (e1 - e0) / h;
  }

  // the least-squares step, columns scaled to unit norm; rank deficient: no start
  const Eigen::VectorXd norms = A.colwise().norm().transpose().cwiseMax(1e-300);
  const Eigen::MatrixXd As = A * norms.cwiseInverse().asDiagonal();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(As, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd& sv = svd.singularValues();
  if (!(sv.minCoeff() > 1e-8 * sv.maxCoeff())) {
    out.note = "the logged motion does not determine the parameters (rank deficient regressor)";
    return out;
  }
  const Eigen::VectorXd step = norms.cwiseInverse().asDiagonal() * svd.solve(-e0);
  std::string values;
  for (size_t c = 0; c < cols.size(); ++c) {
    const FitParameter& p = params[cols[c]];
    double v = p0[cols[c]] + step[c];
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
