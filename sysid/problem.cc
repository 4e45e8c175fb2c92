#include "sysid/problem.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <set>
#include <stdexcept>

#include "sysid/state_manifold.h"

namespace mjsysid {
namespace {

constexpr double kZ95 = 1.959963984540054;
constexpr double kInf = std::numeric_limits<double>::infinity();
// multiple shooting: a continuity gap (tangent space: m, rad, m/s, rad/s) above this at the
// estimate is reported as segments that do not join
constexpr double kContinuityGapWarning = 1e-3;

// robust loss on one weighted residual e: returns rhat with rhat^2 = rho(e^2), and d rhat / d e
double RobustResidual(LossType loss, double c, double e, double* derivative) {
  const double s = e * e;
  double rho = s, rho1 = 1;
  switch (loss) {
    case LossType::kNone:
      *derivative = 1;
      return e;
    case LossType::kHuber:
      if (s > c * c) {
        const double r = std::sqrt(s);
        rho = 2 * c * r - c * c;
        rho1 = c / r;
      }
      break;
    case LossType::kCauchy:
      rho = c * c * std::log1p(s / (c * c));
      rho1 = 1 / (1 + s / (c * c));
      break;
  }
  if (s == 0) {
    *derivative = 1;
    return 0;
  }
  const double rhat = std::copysign(std::sqrt(rho), e);
  *derivative = rho1 * e / rhat;
  return rhat;
}

// Reduces the sequence's matrices (T x nsensordata, the model's layout) to the columns of the
// fitted sensors, in the order given, and fills their names, dimensions and the sample times.
void KeepFittedColumns(const mjModel& m, const std::vector<std::string>& fitted,
                       const FitSequence& sq, SequenceResult* sr) {
  std::vector<int> cols;
  for (const std::string& name : fitted) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
    sr->sensor_names.push_back(name);
    sr->sensor_dims.push_back(m.sensor_dim[id]);
    for (int c = 0; c < m.sensor_dim[id]; ++c) cols.push_back(m.sensor_adr[id] + c);
  }
  const Eigen::Index T = sr->measured.rows();
  for (RowMatrix* mat : {&sr->measured, &sr->simulated_initial, &sr->simulated_final}) {
    RowMatrix kept(T, static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) kept.col(c) = mat->col(cols[c]);
    *mat = std::move(kept);
  }
  if (sq.time.size() == T) {
    sr->time = sq.time;
  } else {
    sr->time = Eigen::VectorXd::LinSpaced(T, 0, static_cast<double>(T - 1)) * m.opt.timestep;
    sr->time.array() += sq.x0.time;
  }
}

}  // namespace

// -----------------------------------------------------------------------------------------------
// problem state

struct Problem::Impl {
  struct Model {
    std::string name;
    ModelPtr model;
    std::unique_ptr<Simulator> sim;
    std::vector<int> global;  // global parameter index of each simulator parameter
    std::unique_ptr<StateManifold> manifold;
  };
  // one fitted sensor column of a sequence
  struct Channel {
    int column;       // in the model's sensordata
    double weight;    // 1/sigma or weight
    int measurement;  // index into measurements, or -1
  };
  struct Segment {
    int seq = 0;        // sequence index
    int k0 = 0, T = 0;  // first sample and samples
    int block = -1;     // state block of x_0 (or -1: fixed, given by the sequence)
    int next = -1;      // state block of the next segment's x_0 (continuity), or -1
  };

  std::vector<Model> models;
  std::vector<FitParameter> params;
  std::vector<FitMeasurement> measurements;
  std::vector<FitSequence> sequences;

  // fit-time state
  FitOptions options;
  std::vector<std::vector<Channel>> channels;    // per sequence
  std::vector<std::vector<std::string>> fitted;  // per sequence: the fitted sensors, in order
  std::vector<Segment> segments;
  std::vector<double> z;                      // transformed physical parameters
  std::vector<double> m;                      // fitted measurement terms
  std::vector<std::vector<double>> states;    // state blocks (physics vectors)
  std::vector<std::vector<double>> fixed_x0;  // per sequence: the given x0 as physics vector
  struct MeasIndex {
    int delay = -1, gain = -1, bias = -1;  // index into m, -1 = fixed at initial
  };
  std::vector<MeasIndex> meas_index;

  // evaluation cache, one entry per segment: the rollout and, once asked for, the Jacobians at
  // the point last evaluated. Ceres evaluates the residuals at a trial point and, when it accepts
  // the step, the Jacobians at the same point: the rollout is reused. Before each evaluation
  // Prefetch() simulates every segment of a model in one batch, so the simulator runs the
  // sequences (and their Jacobian columns) in parallel instead of one segment after another.
  struct Cached {
    std::vector<double> key;  // z, then x_0 of the segment
    bool failed = false;      // the rollout at key failed (MuJoCo warning, non-finite)
    bool has_jacobians = false;
    bool jacobians_failed = false;
    std::string error;  // why the rollout or the Jacobians failed
    Trajectory tr;
    Sensitivity s;
  };
  std::vector<Cached> cache;

  // What the cost functions met during a fit, so that FitResult::warnings can say it (a rejected
  // trial point or a Jacobian past its validity is otherwise invisible to the user): the number
  // of evaluations that failed (simulation warning, NaN, exception) with the first message, and
  // the first core Jacobian warning per segment (e.g. a chaotic sensitivity that outgrew finite
  // differences). Guarded by a mutex: Ceres may evaluate residual blocks in parallel.
  std::mutex diagnostics_mutex;
  int rejected_evaluations = 0;
  std::string first_rejection;
  std::map<int, std::string> jacobian_warnings;  // segment -> first warning
  void NoteRejection(const std::string& what) {
    std::lock_guard<std::mutex> lock(diagnostics_mutex);
    if (rejected_evaluations++ == 0) first_rejection = what;
  }
  void NoteJacobianWarning(int segment, const std::string& what) {
    std::lock_guard<std::mutex> lock(diagnostics_mutex);
    jacobian_warnings.emplace(segment, what);
  }

  const Model& ModelOf(const std::string& name) const {
    for (const Model& mo : models) {
      if (mo.name == name) return mo;
    }
    throw std::invalid_argument("no model named '" + name + "' (add it with AddModel)");
  }
  Model& ModelOf(const std::string& name) {
    return const_cast<Model&>(static_cast<const Impl&>(*this).ModelOf(name));
  }

  double Physical(int g, double zg) const { return params[g].FromVariable(zg); }
  double ToZ(int g, double p) const { return params[g].ToVariable(p); }
  // dp/dz at z
  double DpDz(int g, double zg) const {
    switch (params[g].transform) {
      case Transform::kLog:
        return std::exp(zg);
      case Transform::kScale:
        return params[g].scale;
      default:
        return 1.0;
    }
  }

  // current measurement term values of measurement i, from the fitted vector mv (or initial)
  void Terms(int i, const double* mv, double* delay, double* gain, double* bias) const {
    const FitMeasurement& me = measurements[i];
    const MeasIndex& ix = meas_index[i];
    *delay = ix.delay >= 0 && mv ? mv[ix.delay] : me.delay.initial;
    *gain = ix.gain >= 0 && mv ? mv[ix.gain] : me.gain.initial;
    *bias = ix.bias >= 0 && mv ? mv[ix.bias] : me.bias.initial;
  }

  // writes the model's parameters from z into its simulator (only when they changed)
  void Apply(Model& mo, const double* zv) {
    const int n = mo.sim->parameters().size();
    if (n == 0) return;
    Eigen::VectorXd p(n);
    for (int j = 0; j < n; ++j) p[j] = Physical(mo.global[j], zv[mo.global[j]]);
    if (p != mo.sim->GetParameters()) mo.sim->SetParameters(p);
  }

  // x_0 of a segment in the current variables (its state block, or the sequence's given x0)
  const double* X0(int segment) const {
    const Segment& seg = segments[segment];
    return seg.block >= 0 ? states[seg.block].data() : fixed_x0[seg.seq].data();
  }
  std::vector<double> KeyOf(int segment, const double* zv, const double* x0) const {
    const Model& mo = ModelOf(sequences[segments[segment].seq].model);
    std::vector<double> key(zv, zv + (zv ? z.size() : 0));
    key.insert(key.end(), x0, x0 + mo.sim->dims().nphys);
    return key;
  }

  // fills the cache of segments segs (all of model mo) at parameters zv and initial states x0s:
  // rollouts of the segments whose key changed in one batch, then, if asked for, the Jacobians
  // of those that lack them, batched by the columns and rows they need
  void Simulate(Model& mo, const std::vector<int>& segs, const double* zv,
                const std::vector<const double*>& x0s, bool jacobians) {
    const double dt = mo.sim->model().opt.timestep;
    auto input = [&](int s, const double* x0) {
      const Segment& seg = segments[s];
      SequenceInput in;
      in.x0 = ToInitialState(mo, x0, seg.k0 * dt);
      in.ctrl = sequences[seg.seq].ctrl.middleRows(seg.k0, seg.T);
      return in;
    };
    if (zv) Apply(mo, zv);
    std::vector<int> roll;
    std::vector<SequenceInput> ins;
    for (size_t i = 0; i < segs.size(); ++i) {
      Cached& c = cache[segs[i]];
      std::vector<double> key = KeyOf(segs[i], zv, x0s[i]);
      if (key == c.key) continue;
      c = Cached();
      c.key = std::move(key);
      roll.push_back(segs[i]);
      ins.push_back(input(segs[i], x0s[i]));
    }
    if (!roll.empty()) {
      std::vector<Trajectory> trs;
      try {
        mo.sim->Rollout(ins, &trs);
        for (size_t i = 0; i < roll.size(); ++i) cache[roll[i]].tr = std::move(trs[i]);
      } catch (const std::exception& e) {
        for (int s : roll) {  // a divergent trial point: rejected
          cache[s].failed = true;
          cache[s].error = e.what();
        }
      }
    }
    if (!jacobians) return;
    // groups: initial-state columns (x_0 is a variable) x state rows (continuity needs them)
    for (int group = 0; group < 4; ++group) {
      const bool with_x0 = group & 1, with_states = group & 2;
      std::vector<int> jac;
      std::vector<SequenceInput> jins;
      std::vector<Trajectory> nominal;
      for (size_t i = 0; i < segs.size(); ++i) {
        const Cached& c = cache[segs[i]];
        const Segment& seg = segments[segs[i]];
        if (c.failed || c.has_jacobians || c.jacobians_failed) continue;
        if ((seg.block >= 0) != with_x0 || (seg.next >= 0) != with_states) continue;
        jac.push_back(segs[i]);
        jins.push_back(input(segs[i], x0s[i]));
        nominal.push_back(std::move(cache[segs[i]].tr));  // moved back below
      }
      if (jac.empty()) continue;
      JacobianOptions jo = options.jacobian;
      jo.initial_state = with_x0;
      jo.state_jacobians = with_states;
      jo.zero_column_is_error = false;
      std::vector<Sensitivity> sens;
      bool ok = true;
      std::string error;
      try {
        mo.sim->Jacobians(jins, nominal, jo, &sens);
      } catch (const std::exception& e) {
        ok = false;
        error = e.what();
      }
      for (size_t i = 0; i < jac.size(); ++i) {
        Cached& c = cache[jac[i]];
        c.tr = std::move(nominal[i]);
        c.has_jacobians = ok;
        c.jacobians_failed = !ok;
        c.error = error;
        if (ok) c.s = std::move(sens[i]);
      }
    }
  }

  // the cache entry of one segment at (zv, x0), simulated alone if it is not there
  const Cached& Evaluated(int segment, const double* zv, const double* x0, bool jacobians) {
    const Cached& c = cache[segment];
    if (c.key != KeyOf(segment, zv, x0) || (jacobians && !c.has_jacobians && !c.failed)) {
      Simulate(ModelOf(sequences[segments[segment].seq].model), {segment}, zv, {x0}, jacobians);
    }
    return c;
  }

  // every segment at the current variables, batched per model (before each Ceres evaluation)
  void Prefetch(bool jacobians) {
    for (Model& mo : models) {
      std::vector<int> segs;
      std::vector<const double*> x0s;
      for (size_t s = 0; s < segments.size(); ++s) {
        if (sequences[segments[s].seq].model != mo.name) continue;
        segs.push_back(static_cast<int>(s));
        x0s.push_back(X0(static_cast<int>(s)));
      }
      if (!segs.empty()) Simulate(mo, segs, z.empty() ? nullptr : z.data(), x0s, jacobians);
    }
  }

  InitialState ToInitialState(const Model& mo, const double* x, double time) const {
    const StateDims& d = mo.sim->dims();
    InitialState s;
    s.qpos = Eigen::Map<const Eigen::VectorXd>(x, d.nq);
    s.qvel = Eigen::Map<const Eigen::VectorXd>(x + d.nq, d.nv);
    s.act = Eigen::Map<const Eigen::VectorXd>(x + d.nq + d.nv, d.na);
    s.time = time;
    return s;
  }

  // simulated value of a channel at local sample k with delay (linear interpolation), and its
  // derivative with respect to the delay; rows: a function returning the value at sample i
  template <typename F>
  static double Delayed(const F& at, int k, int T, double delay, double dt, double* ddelay) {
    if (delay == 0) {
      *ddelay = 0;  // one-sided at zero: the derivative below would see the future
      const int i0 = k, i1 = std::max(k - 1, 0);
      *ddelay = i1 == i0 ? 0.0 : -(at(i0) - at(i1)) / dt;
      return at(k);
    }
    const double q = k - delay / dt;
    int i0 = static_cast<int>(std::floor(q));
    const double a = q - i0;
    if (i0 < 0) {
      *ddelay = 0;
      return at(0);
    }
    if (i0 >= T - 1) {
      *ddelay = 0;
      return at(T - 1);
    }
    *ddelay = -(at(i0 + 1) - at(i0)) / dt;
    return (1 - a) * at(i0) + a * at(i0 + 1);
  }
};

// -----------------------------------------------------------------------------------------------
// cost functions

namespace {

// residuals of one segment: its sensor samples and (not last) its continuity with the next
class SegmentCost : public ceres::CostFunction {
 public:
  SegmentCost(Problem::Impl* impl, int segment) : impl_(impl), segment_(segment) {
    const auto& seg = impl->segments[segment];
    const auto& mo = impl->ModelOf(impl->sequences[seg.seq].model);
    const int nch = static_cast<int>(impl->channels[seg.seq].size());
    set_num_residuals(seg.T * nch + (seg.next >= 0 ? mo.sim->dims().nx : 0));
    if (!impl->z.empty()) mutable_parameter_block_sizes()->push_back(impl->z.size());
    if (!impl->m.empty()) mutable_parameter_block_sizes()->push_back(impl->m.size());
    if (seg.block >= 0) mutable_parameter_block_sizes()->push_back(mo.sim->dims().nphys);
    if (seg.next >= 0) mutable_parameter_block_sizes()->push_back(mo.sim->dims().nphys);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    try {
      if (EvaluateOrThrow(parameters, residuals, jacobians)) return true;
      impl_->NoteRejection("non-finite residual");
      return false;
    } catch (const std::exception& e) {
      // a divergent or warning trial point: reject it, the trust region shrinks
      impl_->NoteRejection(e.what());
      return false;
    }
  }

 private:
  bool EvaluateOrThrow(double const* const* parameters, double* residuals,
                       double** jacobians) const {
    Problem::Impl& I = *impl_;
    const auto& seg = I.segments[segment_];
    const FitSequence& sq = I.sequences[seg.seq];
    Problem::Impl::Model& mo = I.ModelOf(sq.model);
    Simulator& sim = *mo.sim;
    const StateDims& dims = sim.dims();
    const int nx = dims.nx, npm = sim.parameters().size();
    const auto& chans = I.channels[seg.seq];
    const int nch = static_cast<int>(chans.size());
    const double dt = sim.model().opt.timestep;

    // unpack blocks
    int b = 0;
    const double* zv = I.z.empty() ? nullptr : parameters[b++];
    const int zb = I.z.empty() ? -1 : b - 1;
    const double* mv = I.m.empty() ? nullptr : parameters[b++];
    const int mb = I.m.empty() ? -1 : b - 1;
    const double* x0 = seg.block >= 0 ? parameters[b++] : I.fixed_x0[seg.seq].data();
    const int xb = seg.block >= 0 ? b - 1 : -1;
    const double* xn = seg.next >= 0 ? parameters[b++] : nullptr;
    const int nb = seg.next >= 0 ? b - 1 : -1;

    // rollout (and Jacobians only when asked for), from the cache when Prefetch() or an earlier
    // evaluation at this point computed them
    const bool want = jacobians != nullptr;
    const Problem::Impl::Cached& cached = I.Evaluated(segment_, zv, x0, want);
    // a divergent or warning trial point: rejected in Evaluate, the trust region shrinks
    if (cached.failed || (want && !cached.has_jacobians)) throw std::runtime_error(cached.error);
    const Trajectory& tr = cached.tr;
    const Sensitivity& s = cached.s;
    if (want && !s.warnings.empty()) I.NoteJacobianWarning(segment_, s.warnings[0]);
    const int ns = dims.ns;
    const int ncol = want ? s.ncol : 0;
    std::vector<double> row_t(want ? ncol : 0);  // d(simulated)/d(column) of one residual

    // zero the Jacobian blocks
    if (want) {
      for (int i = 0; i < static_cast<int>(parameter_block_sizes().size()); ++i) {
        if (jacobians[i]) {
          std::fill(jacobians[i], jacobians[i] + num_residuals() * parameter_block_sizes()[i], 0.0);
        }
      }
    }
    std::vector<double> pinv;
    if (want && xb >= 0 && jacobians[xb]) {
      pinv.resize(static_cast<size_t>(nx) * dims.nphys);
      mo.manifold->PlusJacobianPseudoInverse(x0, pinv.data());
    }

    // sensor residuals
    for (int k = 0; k < seg.T; ++k) {
      for (int c = 0; c < nch; ++c) {
        const auto& ch = chans[c];
        double delay = 0, gain = 1, bias = 0;
        if (ch.measurement >= 0) I.Terms(ch.measurement, mv, &delay, &gain, &bias);
        double dydelay = 0;
        const double y = Problem::Impl::Delayed([&](int i) { return tr.sensors(i, ch.column); }, k,
                                                seg.T, delay, dt, &dydelay);
        const double e = ch.weight * (gain * y + bias - sq.measured(seg.k0 + k, ch.column));
        double de = 1;
        const int row = k * nch + c;
        residuals[row] = RobustResidual(I.options.loss, I.options.loss_scale, e, &de);
        if (!want) continue;
        const double f = de * ch.weight;
        // d(simulated y)/d(column), interpolated like the value
        for (int j = 0; j < ncol; ++j) {
          double unused = 0;
          row_t[j] = Problem::Impl::Delayed(
              [&](int i) { return s.DyDp(static_cast<Eigen::Index>(i) * ns + ch.column, j); }, k,
              seg.T, delay, dt, &unused);
        }
        if (zb >= 0 && jacobians[zb]) {
          const int nz = static_cast<int>(I.z.size());
          for (int j = 0; j < npm; ++j) {
            const int g = mo.global[j];
            jacobians[zb][row * nz + g] = f * gain * row_t[j] * I.DpDz(g, zv[g]);
          }
        }
        if (mb >= 0 && jacobians[mb] && ch.measurement >= 0) {
          const int nm = static_cast<int>(I.m.size());
          const auto& ix = I.meas_index[ch.measurement];
          if (ix.delay >= 0) jacobians[mb][row * nm + ix.delay] = f * gain * dydelay;
          if (ix.gain >= 0) jacobians[mb][row * nm + ix.gain] = f * y;
          if (ix.bias >= 0) jacobians[mb][row * nm + ix.bias] = f;
        }
        if (xb >= 0 && jacobians[xb]) {
          for (int a = 0; a < dims.nphys; ++a) {
            double v = 0;
            for (int i = 0; i < nx; ++i) v += row_t[npm + i] * pinv[i * dims.nphys + a];
            jacobians[xb][row * dims.nphys + a] = f * gain * v;
          }
        }
      }
    }

    // continuity: w * (x_end (-) x_next) in tangent space
    if (seg.next >= 0) {
      const double w = I.options.continuity_weight;
      const int r0 = seg.T * nch;
      std::vector<double> d(nx);
      TangentDifference(sim.model(), xn, tr.states.row(seg.T).data(), 1.0, d.data());
      for (int i = 0; i < nx; ++i) residuals[r0 + i] = w * d[i];
      if (want) {
        const auto S = s.DxDp.middleRows(static_cast<Eigen::Index>(seg.T) * nx, nx);
        if (zb >= 0 && jacobians[zb]) {
          const int nz = static_cast<int>(I.z.size());
          for (int i = 0; i < nx; ++i) {
            for (int j = 0; j < npm; ++j) {
              const int g = mo.global[j];
              jacobians[zb][(r0 + i) * nz + g] = w * S(i, j) * I.DpDz(g, zv[g]);
            }
          }
        }
        if (xb >= 0 && jacobians[xb]) {
          for (int i = 0; i < nx; ++i) {
            for (int a = 0; a < dims.nphys; ++a) {
              double v = 0;
              for (int t = 0; t < nx; ++t) v += S(i, npm + t) * pinv[t * dims.nphys + a];
              jacobians[xb][(r0 + i) * dims.nphys + a] = w * v;
            }
          }
        }
        if (nb >= 0 && jacobians[nb]) {
          // d(x_end (-) y)/dy = -I in tangent space (exact off quaternions, first order on them)
          std::vector<double> pn(static_cast<size_t>(nx) * dims.nphys);
          mo.manifold->PlusJacobianPseudoInverse(xn, pn.data());
          for (int i = 0; i < nx; ++i) {
            for (int a = 0; a < dims.nphys; ++a) {
              jacobians[nb][(r0 + i) * dims.nphys + a] = -w * pn[i * dims.nphys + a];
            }
          }
        }
      }
    }
    for (int i = 0; i < num_residuals(); ++i) {
      if (!std::isfinite(residuals[i])) return false;
    }
    return true;
  }

  Problem::Impl* impl_;
  int segment_;
};

// Gaussian prior on one physical parameter: (p - mean) / sigma
class PriorCost : public ceres::CostFunction {
 public:
  PriorCost(const Problem::Impl* impl, int g) : impl_(impl), g_(g) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(impl->z.size());
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const FitParameter& p = impl_->params[g_];
    const double zg = parameters[0][g_];
    residuals[0] = (impl_->Physical(g_, zg) - p.prior_mean) / p.prior_sigma;
    if (jacobians && jacobians[0]) {
      std::fill(jacobians[0], jacobians[0] + impl_->z.size(), 0.0);
      jacobians[0][g_] = impl_->DpDz(g_, zg) / p.prior_sigma;
    }
    return std::isfinite(residuals[0]);
  }

 private:
  const Problem::Impl* impl_;
  int g_;
};

// progress lines, trace, checkpoint callback and interruption
// before each Ceres evaluation: simulate every segment at the new point in parallel batches
class Prefetch : public ceres::EvaluationCallback {
 public:
  explicit Prefetch(Problem::Impl* impl) : impl_(impl) {}
  void PrepareForEvaluation(bool evaluate_jacobians, bool /*new_evaluation_point*/) override {
    impl_->Prefetch(evaluate_jacobians);  // compares keys itself: unchanged segments are kept
  }

 private:
  Problem::Impl* impl_;
};

class Progress : public ceres::IterationCallback {
 public:
  Progress(Problem::Impl* impl, FitResult* result, std::chrono::steady_clock::time_point start)
      : impl_(impl), result_(result), start_(start) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    IterationInfo info;
    info.iteration = s.iteration;
    info.cost = s.cost;
    info.step_norm = s.step_norm;
    info.gradient_norm = s.gradient_max_norm;
    info.successful = s.step_is_successful || s.iteration == 0;
    info.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const int np = static_cast<int>(impl_->params.size());
    info.parameters.resize(np + static_cast<int>(impl_->m.size()));
    for (int g = 0; g < np; ++g) info.parameters[g] = impl_->Physical(g, impl_->z[g]);
    for (size_t i = 0; i < impl_->m.size(); ++i) info.parameters[np + i] = impl_->m[i];
    if (impl_->options.verbose) {
      std::fprintf(stderr, "iter %3d  cost %.6e  |step| %.2e  |grad| %.2e  %s  %7.2f s\n",
                   info.iteration, info.cost, info.step_norm, info.gradient_norm,
                   info.successful ? "ok      " : "rejected", info.seconds);
    }
    result_->trace.push_back(info);
    if (impl_->options.on_iteration && info.successful) impl_->options.on_iteration(info);
    if (impl_->options.interrupt && impl_->options.interrupt->load()) {
      result_->interrupted = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  Problem::Impl* impl_;
  FitResult* result_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace

// -----------------------------------------------------------------------------------------------
// building

Problem::Problem() : impl_(std::make_unique<Impl>()) { InstallMujocoHandlers(); }
Problem::~Problem() = default;

void Problem::AddModel(const std::string& name, const mjModel& m) {
  for (const auto& mo : impl_->models) {
    if (mo.name == name) throw std::invalid_argument("model '" + name + "' added twice");
  }
  Impl::Model mo;
  mo.name = name;
  mo.model = CopyModel(m);
  impl_->models.push_back(std::move(mo));
}

void Problem::AddParameter(const FitParameter& p) {
  for (const auto& q : impl_->params) {
    if (q.name == p.name) throw std::invalid_argument("parameter '" + p.name + "' added twice");
  }
  impl_->params.push_back(p);
}

void Problem::AddMeasurement(const FitMeasurement& me) { impl_->measurements.push_back(me); }

void Problem::AddSequence(const FitSequence& s) { impl_->sequences.push_back(s); }

void Problem::Prepare(const FitOptions& options, Prepared* out) {
  Impl& I = *impl_;
  I.options = options;
  if (I.models.empty()) throw std::invalid_argument("no model: call AddModel first");
  if (I.sequences.empty()) throw std::invalid_argument("no sequence: call AddSequence first");
  std::vector<Trajectory>& initial = out->initial;
  std::vector<std::string>& names = out->names;
  std::vector<std::pair<double, double>>& mbounds = out->mbounds;
  const int np = static_cast<int>(I.params.size());

  // parameters: bounds, transforms, initial values
  for (int g = 0; g < np; ++g) {
    const FitParameter& p = I.params[g];
    const std::string where = "parameter '" + p.name + "': ";
    if (!std::isfinite(p.initial)) throw std::invalid_argument(where + "initial value not finite");
    if (!(p.lower < p.upper)) throw std::invalid_argument(where + "lower bound >= upper bound");
    if (p.initial < p.lower || p.initial > p.upper) {
      throw std::invalid_argument(where + "initial value " + std::to_string(p.initial) +
                                  " outside its bounds");
    }
    if (p.transform == Transform::kLog && !(p.initial > 0)) {
      throw std::invalid_argument(where + "log transform needs a positive initial value");
    }
    if (p.transform == Transform::kLog && p.lower < 0) {
      throw std::invalid_argument(where + "log transform needs a lower bound >= 0");
    }
    if (p.transform == Transform::kScale && !(p.scale > 0)) {
      throw std::invalid_argument(where + "scale must be positive");
    }
    if (p.has_prior && !(p.prior_sigma > 0)) {
      throw std::invalid_argument(where + "prior sigma must be positive");
    }
    for (const std::string& mname : p.models) I.ModelOf(mname);
  }

  // simulators: each model with the parameters that apply to it
  SimulatorOptions so;
  so.threads = options.threads;
  for (auto& mo : I.models) {
    std::vector<ParameterSpec> specs;
    mo.global.clear();
    for (int g = 0; g < np; ++g) {
      const FitParameter& p = I.params[g];
      if (!p.models.empty() &&
          std::find(p.models.begin(), p.models.end(), mo.name) == p.models.end()) {
        continue;
      }
      ParameterSpec spec = p.target;
      spec.label = p.name;
      specs.push_back(spec);
      mo.global.push_back(g);
    }
    try {
      mo.sim = std::make_unique<Simulator>(*mo.model, specs, so);
    } catch (const ParameterError& e) {
      throw ParameterError("model '" + mo.name + "': " + e.what());
    }
    mo.manifold = std::make_unique<StateManifold>(&mo.sim->model());
  }
  I.z.resize(np);
  for (int g = 0; g < np; ++g) I.z[g] = I.ToZ(g, I.params[g].initial);

  // measurement terms
  I.m.clear();
  I.meas_index.assign(I.measurements.size(), Impl::MeasIndex());
  names.clear();
  for (int g = 0; g < np; ++g) names.push_back(I.params[g].name);
  mbounds.clear();
  out->minitial.clear();
  for (size_t i = 0; i < I.measurements.size(); ++i) {
    const FitMeasurement& me = I.measurements[i];
    auto add = [&](const FitMeasurement::Term& t, int* index, const char* what) {
      if (!t.fit) return;
      if (t.initial < t.lower || t.initial > t.upper) {
        throw std::invalid_argument("measurement " + std::string(what) + " of sensor '" +
                                    me.sensor + "': initial value outside its bounds");
      }
      *index = static_cast<int>(I.m.size());
      I.m.push_back(t.initial);
      mbounds.emplace_back(t.lower, t.upper);
      out->minitial.push_back(t.initial);
      names.push_back(me.sensor + "." + what);
    };
    add(me.delay, &I.meas_index[i].delay, "delay");
    add(me.gain, &I.meas_index[i].gain, "gain");
    add(me.bias, &I.meas_index[i].bias, "bias");
  }

  // sequences: shapes, finite data, channels
  I.channels.assign(I.sequences.size(), {});
  I.fitted.assign(I.sequences.size(), {});
  I.fixed_x0.assign(I.sequences.size(), {});
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    FitSequence& sq = I.sequences[q];
    Impl::Model& mo = I.ModelOf(sq.model);
    const StateDims& d = mo.sim->dims();
    const std::string where = "sequence '" + sq.name + "': ";
    const int T = static_cast<int>(sq.ctrl.rows());
    if (T < 1 || sq.ctrl.cols() != d.nu) {
      throw std::invalid_argument(
          where + "ctrl must be T x nu with T >= 1 and nu = " + std::to_string(d.nu));
    }
    if (sq.measured.rows() != T || sq.measured.cols() != d.ns) {
      throw std::invalid_argument(where + "measured must be " + std::to_string(T) + " x " +
                                  std::to_string(d.ns) + " (T x nsensordata), got " +
                                  std::to_string(sq.measured.rows()) + " x " +
                                  std::to_string(sq.measured.cols()));
    }
    if (sq.time.size() != 0 && sq.time.size() != T) {
      throw std::invalid_argument(where + "time must be empty or have " + std::to_string(T) +
                                  " entries, got " + std::to_string(sq.time.size()));
    }
    const mjModel& m = mo.sim->model();
    std::vector<std::string> used = sq.sensors;
    if (used.empty()) {
      for (int i = 0; i < m.nsensor; ++i) {
        const char* nm = mj_id2name(&m, mjOBJ_SENSOR, i);
        used.push_back(nm ? nm : "");
      }
    }
    for (const std::string& sname : used) {
      const int id = mj_name2id(&m, mjOBJ_SENSOR, sname.c_str());
      if (id < 0) {
        throw std::invalid_argument(where + "no sensor named '" + sname + "' in model '" + mo.name +
                                    "'");
      }
      double weight = 1.0;
      const auto it = options.sensor_weights.find(sname);
      if (it != options.sensor_weights.end()) weight = it->second;
      if (!(weight > 0) || !std::isfinite(weight)) {
        throw std::invalid_argument("sensor '" + sname + "': weight must be positive");
      }
      int meas = -1;
      for (size_t i = 0; i < I.measurements.size(); ++i) {
        if (I.measurements[i].sensor == sname) meas = static_cast<int>(i);
      }
      for (int c = 0; c < m.sensor_dim[id]; ++c) {
        const int col = m.sensor_adr[id] + c;
        for (int k = 0; k < T; ++k) {
          if (!std::isfinite(sq.measured(k, col))) {
            throw std::invalid_argument(where + "measured sensor '" + sname +
                                        "' is not finite at row " + std::to_string(k));
          }
        }
        I.channels[q].push_back({col, weight, meas});
      }
      if (std::find(I.fitted[q].begin(), I.fitted[q].end(), sname) == I.fitted[q].end()) {
        I.fitted[q].push_back(sname);
      }
    }
    if (!sq.ctrl.allFinite()) throw std::invalid_argument(where + "ctrl contains NaN/Inf");
    // the given initial state as a physics vector
    InitialState x0 = sq.x0;
    if (x0.qpos.size() == 0) x0.qpos = Eigen::Map<const Eigen::VectorXd>(m.qpos0, d.nq);
    if (x0.qvel.size() == 0) x0.qvel = Eigen::VectorXd::Zero(d.nv);
    if (x0.act.size() == 0) x0.act = Eigen::VectorXd::Zero(d.na);
    if (x0.qpos.size() != d.nq || x0.qvel.size() != d.nv || x0.act.size() != d.na) {
      throw std::invalid_argument(where + "initial state sizes differ from nq/nv/na");
    }
    I.fixed_x0[q].resize(d.nphys);
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data(), d.nq) = x0.qpos;
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data() + d.nq, d.nv) = x0.qvel;
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data() + d.nq + d.nv, d.na) = x0.act;
    sq.x0 = x0;
  }
  for (const FitMeasurement& me : I.measurements) {
    bool found = false;
    for (const auto& ch : I.channels) {
      for (const auto& c : ch)
        found = found || (c.measurement >= 0 && I.measurements[c.measurement].sensor == me.sensor);
    }
    if (!found) {
      throw std::invalid_argument("measurement terms for sensor '" + me.sensor +
                                  "', which no sequence fits");
    }
  }

  // initial rollouts at the initial parameters; the Jacobian there must see every parameter
  initial.assign(I.sequences.size(), Trajectory());
  std::vector<Sensitivity> initial_sensitivity(I.sequences.size());  // parameter columns
  std::vector<bool> moves(np, false);
  for (auto& mo : I.models) {
    I.Apply(mo, I.z.data());
    std::vector<SequenceInput> ins;
    std::vector<int> which;
    for (size_t q = 0; q < I.sequences.size(); ++q) {
      if (I.sequences[q].model != mo.name) continue;
      ins.push_back({I.sequences[q].x0, I.sequences[q].ctrl});
      which.push_back(static_cast<int>(q));
    }
    if (ins.empty()) continue;
    std::vector<Trajectory> trs;
    mo.sim->Rollout(ins, &trs);
    for (size_t i = 0; i < which.size(); ++i) initial[which[i]] = trs[i];
    if (mo.sim->parameters().size() == 0) continue;
    JacobianOptions jo = options.jacobian;
    jo.zero_column_is_error = false;
    jo.state_jacobians = true;
    std::vector<Sensitivity> sens;
    mo.sim->Jacobians(ins, trs, jo, &sens);
    for (const Sensitivity& s : sens) {
      for (int j = 0; j < mo.sim->parameters().size(); ++j) {
        if (!s.DxDp.col(j).isZero(0) || (s.DyDp.rows() && !s.DyDp.col(j).isZero(0))) {
          moves[mo.global[j]] = true;
        }
      }
    }
    out->jacobian_mode = JacobianModeName(sens.empty() ? jo.mode : sens[0].mode);
    for (size_t i = 0; i < which.size(); ++i) initial_sensitivity[which[i]] = std::move(sens[i]);
  }
  for (int g = 0; g < np; ++g) {
    if (!moves[g]) {
      throw ParameterError("parameter '" + I.params[g].name +
                           "' has no effect on the simulated states or sensors of any sequence "
                           "(its Jacobian column is exactly zero): remove it or add data that "
                           "excites it");
    }
  }

  // segments (multiple shooting) and state blocks
  I.segments.clear();
  I.states.clear();
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    const int T = static_cast<int>(I.sequences[q].ctrl.rows());
    const int len = options.segment_steps > 0 ? options.segment_steps : T;
    const size_t first = I.segments.size();
    for (int k0 = 0; k0 < T; k0 += len) {
      Impl::Segment seg;
      seg.seq = static_cast<int>(q);
      seg.k0 = k0;
      seg.T = std::min(len, T - k0);
      const bool free = k0 > 0 || options.estimate_initial_state;
      if (free) {
        seg.block = static_cast<int>(I.states.size());
        // start from the initial-parameter rollout (continuity holds at the start)
        const auto row = initial[q].states.row(k0);
        I.states.emplace_back(row.data(), row.data() + row.size());
      }
      I.segments.push_back(seg);
    }
    for (size_t s = first; s + 1 < I.segments.size(); ++s) {
      I.segments[s].next = I.segments[s + 1].block;
    }
  }

  // evaluation cache, seeded with the initial rollouts (and Jacobians) of whole sequences
  I.cache.assign(I.segments.size(), Impl::Cached());
  for (size_t s = 0; s < I.segments.size(); ++s) {
    const Impl::Segment& seg = I.segments[s];
    if (seg.block >= 0 || seg.next >= 0 || seg.T != initial[seg.seq].T) continue;
    Impl::Cached& c = I.cache[s];
    c.key = I.KeyOf(static_cast<int>(s), I.z.empty() ? nullptr : I.z.data(), I.X0(s));
    c.tr = initial[seg.seq];
    c.s = std::move(initial_sensitivity[seg.seq]);
    c.has_jacobians =
        c.s.ncol ==
            static_cast<int>(I.ModelOf(I.sequences[seg.seq].model).sim->parameters().size()) &&
        c.s.ncol > 0;
  }
}

FitResult Problem::Fit(const FitOptions& options) {
  Impl& I = *impl_;
  const auto start = std::chrono::steady_clock::now();
  FitResult result;
  Prepared prepared;
  Prepare(options, &prepared);
  const int np = static_cast<int>(I.params.size());
  const std::vector<Trajectory>& initial = prepared.initial;
  const std::vector<std::string>& names = prepared.names;
  const std::vector<std::pair<double, double>>& mbounds = prepared.mbounds;
  result.jacobian_mode = prepared.jacobian_mode;

  // ceres problem
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  Prefetch prefetch(&I);
  po.evaluation_callback = &prefetch;
  ceres::Problem problem(po);
  if (np) {
    problem.AddParameterBlock(I.z.data(), np);
    for (int g = 0; g < np; ++g) {
      const FitParameter& p = I.params[g];
      const double zl = I.ToZ(g, p.lower), zu = I.ToZ(g, p.upper);
      const double lo = p.transform == Transform::kScale ? std::min(zl, zu) : zl;
      const double hi = p.transform == Transform::kScale ? std::max(zl, zu) : zu;
      if (std::isfinite(lo) && p.lower > -kInf) problem.SetParameterLowerBound(I.z.data(), g, lo);
      if (std::isfinite(hi) && p.upper < kInf) problem.SetParameterUpperBound(I.z.data(), g, hi);
    }
  }
  if (!I.m.empty()) {
    problem.AddParameterBlock(I.m.data(), static_cast<int>(I.m.size()));
    for (size_t i = 0; i < I.m.size(); ++i) {
      if (std::isfinite(mbounds[i].first)) {
        problem.SetParameterLowerBound(I.m.data(), static_cast<int>(i), mbounds[i].first);
      }
      if (std::isfinite(mbounds[i].second)) {
        problem.SetParameterUpperBound(I.m.data(), static_cast<int>(i), mbounds[i].second);
      }
    }
  }
  for (size_t s = 0; s < I.segments.size(); ++s) {
    const Impl::Segment& seg = I.segments[s];
    Impl::Model& mo = I.ModelOf(I.sequences[seg.seq].model);
    std::vector<double*> blocks;
    if (np) blocks.push_back(I.z.data());
    if (!I.m.empty()) blocks.push_back(I.m.data());
    if (seg.block >= 0) blocks.push_back(I.states[seg.block].data());
    if (seg.next >= 0) blocks.push_back(I.states[seg.next].data());
    problem.AddResidualBlock(new SegmentCost(&I, static_cast<int>(s)), nullptr, blocks);
    if (seg.block >= 0) problem.SetManifold(I.states[seg.block].data(), mo.manifold.get());
  }
  for (int g = 0; g < np; ++g) {
    if (I.params[g].has_prior) problem.AddResidualBlock(new PriorCost(&I, g), nullptr, I.z.data());
  }

  // solve
  ceres::Solver::Options so_ceres;
  so_ceres.minimizer_type = ceres::TRUST_REGION;
  so_ceres.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  int tangent = np + static_cast<int>(I.m.size());
  for (const auto& st : I.states) tangent += static_cast<int>(st.size());
  so_ceres.linear_solver_type = tangent <= 200 ? ceres::DENSE_QR : ceres::SPARSE_NORMAL_CHOLESKY;
  so_ceres.max_num_iterations = options.max_iterations;
  so_ceres.function_tolerance = options.function_tolerance;
  so_ceres.gradient_tolerance = options.gradient_tolerance;
  so_ceres.parameter_tolerance = options.parameter_tolerance;
  so_ceres.num_threads = 1;  // the simulator is parallel inside
  // with bounds, Ceres' trust region minimizer runs a projected Armijo line search along every
  // step. With its default cubic interpolation each trial length evaluates the gradient, i.e.
  // the full Jacobian (4-6 per iteration on the pendulum); quadratic interpolation needs cost
  // values only, one rollout each. Measured (bench_fit, simulation steps of whole fits; cubic /
  // quadratic / no line search): pendulum 918k / 558k / 528k, arm7 1722k / 1338k / 1212k, same
  // estimates; without the search two stress fits (tests/stress: chaotic multiple shooting,
  // dt 0.05 contact) no longer converge, so the search stays.
  so_ceres.line_search_interpolation_type = ceres::QUADRATIC;
  so_ceres.update_state_every_iteration = true;
  so_ceres.logging_type = ceres::SILENT;
  Progress progress(&I, &result, start);
  so_ceres.callbacks.push_back(&progress);
  ceres::Solver::Summary summary;
  I.rejected_evaluations = 0;
  I.jacobian_warnings.clear();
  ceres::Solve(so_ceres, &problem, &summary);

  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.converged = summary.termination_type == ceres::CONVERGENCE && !result.interrupted;
  result.termination = summary.message;
  result.num_residuals = summary.num_residuals;
  if (summary.termination_type == ceres::FAILURE) {
    result.warnings.push_back("Ceres failed: " + summary.message);
  }
  if (I.rejected_evaluations > 0) {
    result.warnings.push_back(std::to_string(I.rejected_evaluations) +
                              " evaluation(s) rejected (trial points where the simulation "
                              "diverged or was not finite; the trust region shrank); first: " +
                              I.first_rejection);
  }
  if (!I.jacobian_warnings.empty()) {
    const auto& [segment, what] = *I.jacobian_warnings.begin();
    const Impl::Segment& seg = I.segments[segment];
    result.warnings.push_back(
        "Jacobian not reliable in " + std::to_string(I.jacobian_warnings.size()) + " of " +
        std::to_string(I.segments.size()) + " segment(s); first: sequence '" +
        I.sequences[seg.seq].name + "' from step " + std::to_string(seg.k0) + ": " + what);
  }

  // Jacobian at the estimate, in physical units (tangent space for states)
  ceres::Problem::EvaluateOptions eo;
  double cost = 0;
  ceres::CRSMatrix crs;
  std::vector<double> residuals;
  const bool evaluated = problem.Evaluate(eo, &cost, &residuals, nullptr, &crs);
  const int nm = static_cast<int>(I.m.size());
  const int nvar = np + nm;
  if (evaluated) {
    RowMatrix J = RowMatrix::Zero(crs.num_rows, crs.num_cols);
    for (int r = 0; r < crs.num_rows; ++r) {
      for (int i = crs.rows[r]; i < crs.rows[r + 1]; ++i) J(r, crs.cols[i]) = crs.values[i];
    }
    for (int g = 0; g < np; ++g) J.col(g) /= I.DpDz(g, I.z[g]);
    // parameters first (as Ceres ordered the blocks: z, m, states)
    Eigen::VectorXd values(J.cols());
    values.setZero();
    std::vector<bool> fixed(J.cols(), false);
    std::vector<std::string> all_names = names;
    for (int g = 0; g < np; ++g) values[g] = I.Physical(g, I.z[g]);
    for (int i = 0; i < nm; ++i) values[np + i] = I.m[i];
    for (Eigen::Index c = nvar; c < J.cols(); ++c) {
      all_names.push_back("x0[" + std::to_string(c - nvar) + "]");
    }
    // parameters stopped on a bound are not estimated
    auto on_bound = [&](int v, bool lower) {
      double lo, hi, val;
      if (v < np) {
        lo = I.params[v].lower;
        hi = I.params[v].upper;
        val = values[v];
      } else {
        lo = mbounds[v - np].first;
        hi = mbounds[v - np].second;
        val = values[v];
      }
      const double tol = 1e-6 * std::max(1.0, std::abs(val));
      return lower ? (std::isfinite(lo) && val - lo <= tol)
                   : (std::isfinite(hi) && hi - val <= tol);
    };
    result.parameters.resize(nvar);
    for (int v = 0; v < nvar; ++v) {
      ParameterEstimate& e = result.parameters[v];
      e.name = names[v];
      e.value = values[v];
      e.initial = v < np ? I.params[v].initial : prepared.minitial[v - np];
      e.at_lower = on_bound(v, true);
      e.at_upper = on_bound(v, false);
      fixed[v] = e.at_lower || e.at_upper;
    }
    result.uncertainty = AnalyzeUncertainty(J, cost, all_names, values, fixed, options.uncertainty);
    // keep the parameter block of the covariance
    Eigen::MatrixXd cov = result.uncertainty.covariance.topLeftCorner(nvar, nvar);
    result.uncertainty.covariance = cov;
    Eigen::VectorXd se = result.uncertainty.std_error.head(nvar);
    result.uncertainty.std_error = se;
    result.uncertainty.identifiable.resize(nvar);
    for (int v = 0; v < nvar; ++v) {
      ParameterEstimate& e = result.parameters[v];
      e.std_error = se[v];
      e.identifiable = result.uncertainty.identifiable[v];
      e.ci95_low = e.value - kZ95 * e.std_error;
      e.ci95_high = e.value + kZ95 * e.std_error;
    }
    result.jacobian = J.leftCols(nvar);
  } else {
    result.warnings.push_back("the residuals could not be evaluated at the estimate");
  }
  for (const auto& p : result.parameters) {
    if (p.at_lower || p.at_upper) {
      result.warnings.push_back("parameter '" + p.name + "' stopped on its " +
                                (p.at_lower ? "lower" : "upper") +
                                " bound: not estimated (no interval); the data may prefer a value "
                                "outside the bounds");
    }
  }
  for (const std::string& line : result.uncertainty.unidentifiable) {
    result.warnings.push_back("unidentifiable: " + line);
  }

  // simulated signals before and after, per sequence (segment-wise in multiple shooting); in
  // multiple shooting also the largest continuity gap at the estimate: segments that do not join
  // describe no single trajectory (a chaotic fit stuck far from the data), which the user must
  // be told (docs/stress.md)
  double worst_gap = 0;
  std::string worst_gap_where;
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    const FitSequence& sq = I.sequences[q];
    Impl::Model& mo = I.ModelOf(sq.model);
    SequenceResult sr;
    sr.name = sq.name;
    sr.model = sq.model;
    sr.measured = sq.measured;
    sr.simulated_initial = initial[q].sensors;
    sr.simulated_final.resize(sq.measured.rows(), sq.measured.cols());
    if (np) I.Apply(mo, I.z.data());
    const double dt = mo.sim->model().opt.timestep;
    for (size_t s = 0; s < I.segments.size(); ++s) {
      const Impl::Segment& seg = I.segments[s];
      if (seg.seq != static_cast<int>(q)) continue;
      const double* x0 = I.X0(static_cast<int>(s));
      if (seg.k0 == 0) sr.x0_final = Eigen::Map<const Eigen::VectorXd>(x0, mo.sim->dims().nphys);
      try {
        // the rollout at the estimate, from the evaluation cache (the final evaluation above ran
        // it; simulated here only if that evaluation failed)
        const Impl::Cached& cached =
            I.Evaluated(static_cast<int>(s), np ? I.z.data() : nullptr, x0, false);
        if (cached.failed) throw std::runtime_error(cached.error);
        const Trajectory& tr = cached.tr;
        sr.simulated_final.middleRows(seg.k0, seg.T) = tr.sensors;
        if (seg.next >= 0) {
          const int nx = mo.sim->dims().nx;
          Eigen::VectorXd gap(nx);
          TangentDifference(mo.sim->model(), I.states[seg.next].data(), tr.states.row(seg.T).data(),
                            1.0, gap.data());
          if (gap.lpNorm<Eigen::Infinity>() > worst_gap) {
            worst_gap = gap.lpNorm<Eigen::Infinity>();
            worst_gap_where =
                "sequence '" + sq.name + "' at step " + std::to_string(seg.k0 + seg.T);
          }
        }
        // apply the measurement terms to the fitted columns
        for (const auto& ch : I.channels[q]) {
          if (ch.measurement < 0) continue;
          double delay, gain, bias;
          I.Terms(ch.measurement, I.m.empty() ? nullptr : I.m.data(), &delay, &gain, &bias);
          for (int k = 0; k < seg.T; ++k) {
            double unused;
            sr.simulated_final(seg.k0 + k, ch.column) =
                gain * Impl::Delayed([&](int i) { return tr.sensors(i, ch.column); }, k, seg.T,
                                     delay, dt, &unused) +
                bias;
          }
        }
      } catch (const std::exception& e) {
        result.warnings.push_back("sequence '" + sq.name +
                                  "': final simulation failed: " + e.what());
      }
    }
    KeepFittedColumns(mo.sim->model(), I.fitted[q], sq, &sr);
    result.sequences.push_back(std::move(sr));
  }
  if (worst_gap > kContinuityGapWarning) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.3g", worst_gap);
    result.warnings.push_back(
        std::string("multiple shooting: segments do not join at the estimate (largest continuity "
                    "gap ") +
        buf + " in state units, " + worst_gap_where +
        "): it describes no single trajectory; try shorter segments, a larger continuity_weight "
        "or a start closer to the data");
  }
  for (const auto& mo : I.models) result.simulation_steps += mo.sim->StepCount();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

JacobianCheck Problem::CheckJacobians(const FitOptions& options) {
  Impl& I = *impl_;
  Prepared prepared;
  Prepare(options, &prepared);
  const int np = static_cast<int>(I.params.size());
  const int nm = static_cast<int>(I.m.size());
  JacobianCheck check;
  std::map<std::string, double> worst;
  std::vector<std::string> order = prepared.names;

  // each residual block against Ceres' central differences of the same block
  // GradientChecker extrapolates with Ridders' method, whose first step (1e-2 relative by default)
  // would straddle the kinks of the sensor-delay interpolation (one per timestep): start small
  ceres::NumericDiffOptions nd;
  nd.relative_step_size = 1e-6;
  nd.ridders_relative_initial_step_size = 1e-5;
  for (size_t s = 0; s < I.segments.size(); ++s) {
    const Impl::Segment& seg = I.segments[s];
    Impl::Model& mo = I.ModelOf(I.sequences[seg.seq].model);
    SegmentCost cost(&I, static_cast<int>(s));
    std::vector<const double*> blocks;
    std::vector<const ceres::Manifold*> manifolds;
    std::vector<std::vector<std::string>> labels;
    if (np) {
      blocks.push_back(I.z.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin(), prepared.names.begin() + np);
    }
    if (nm) {
      blocks.push_back(I.m.data());
      manifolds.push_back(nullptr);
      labels.emplace_back(prepared.names.begin() + np, prepared.names.end());
    }
    const std::string seq_name = I.sequences[seg.seq].name;
    for (int b : {seg.block, seg.next}) {
      if (b < 0) continue;
      blocks.push_back(I.states[b].data());
      manifolds.push_back(mo.manifold.get());
      const std::string label = "x0 of " + seq_name + (b == seg.block ? "" : " (next segment)");
      labels.emplace_back(mo.sim->dims().nx, label);
      if (std::find(order.begin(), order.end(), label) == order.end()) order.push_back(label);
    }
    ceres::GradientChecker checker(&cost, &manifolds, nd);
    ceres::GradientChecker::ProbeResults results;
    checker.Probe(blocks.data(), 1.0, &results);
    if (!results.return_value) {
      throw SimulationError("CheckJacobians: the residuals of sequence '" + seq_name +
                                "' cannot be evaluated at the initial values",
                            seg.seq, seg.k0);
    }
    // worst column-scaled error of each variable
    for (size_t b = 0; b < blocks.size(); ++b) {
      const auto& A = results.local_jacobians[b];
      const auto& N = results.local_numeric_jacobians[b];
      for (Eigen::Index c = 0; c < A.cols(); ++c) {
        const double scale = std::max(N.col(c).lpNorm<Eigen::Infinity>(), 1e-12);
        const double err = (A.col(c) - N.col(c)).lpNorm<Eigen::Infinity>() / scale;
        const std::string& label = labels[b][std::min<size_t>(c, labels[b].size() - 1)];
        worst[label] = std::max(worst[label], err);
        if (err > check.worst_relative_error) {
          check.worst_relative_error = err;
          check.worst_where = label + ", residual block of sequence '" + seq_name + "' from step " +
                              std::to_string(seg.k0);
        }
      }
    }
  }
  for (const std::string& label : order) {
    if (worst.count(label)) check.per_variable.emplace_back(label, worst[label]);
  }
  return check;
}

}  // namespace mjsysid
