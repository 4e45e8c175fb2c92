// mjsysid.RolloutModel and mjsysid.Linearization: rollouts of a MuJoCo model on numpy arrays and
// their derivatives with respect to the initial state, the controls of every step and named
// model parameters (docs/python.md, "Gradients through physics").
//
// A RolloutModel owns a Simulator (core/simulator.h: a private model copy and its threads) that
// keeps the model's own options (timestep, integrator, solver tolerance, disable flags).
// linearize() runs the nominal rollouts and the one-step blocks of every step
// (Simulator::StepJacobians); the Linearization it returns keeps them and answers vector-Jacobian
// and Jacobian-vector products and full Jacobians through the chain of core/step_chain.h. Arrays
// cross in coordinates ([qpos, qvel, act] per state row); the full Jacobians' state rows are in
// tangent space (nx = 2nv+na). Batches run over the simulator's threads with the GIL released.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/step_chain.h"
#include "sysid/fit/memory_estimate.h"

namespace mjsysid::python {
namespace {

using nb::arg;
using namespace nb::literals;

using CArray = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using OutArray = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

const std::vector<std::string> kRolloutParameterKeys = {"name",   "target", "kind",
                                                        "object", "field",  "index"};

// "(2, 3)"
std::string ShapeText(const std::vector<size_t>& shape) {
  std::string s = "(";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

// a float64 C-contiguous copy (or view) of an array-like, with its shape; `what` names it
struct Array {
  nb::object owner;
  const double* data = nullptr;
  std::vector<size_t> shape;
  size_t size() const {
    size_t n = 1;
    for (size_t s : shape) n *= s;
    return n;
  }
};

Array ArrayOf(nb::handle value, const std::string& what) {
  nb::module_ np = nb::module_::import_("numpy");
  Array a;
  try {
    a.owner = np.attr("ascontiguousarray")(value, "dtype"_a = "float64");
  } catch (nb::python_error& e) {
    throw std::invalid_argument(
        what + ": not an array of numbers: " + nb::cast<std::string>(nb::str(e.value())));
  }
  const CArray view = nb::cast<CArray>(a.owner);
  a.data = view.data();
  for (size_t i = 0; i < view.ndim(); ++i) a.shape.push_back(view.shape(i));
  return a;
}

// a new numpy array of this shape and a pointer to its (C-contiguous) storage
nb::object NewArray(const std::vector<size_t>& shape, double** data) {
  nb::module_ np = nb::module_::import_("numpy");
  nb::list dims;
  for (size_t s : shape) dims.append(s);
  nb::object a = np.attr("zeros")(nb::tuple(dims), "dtype"_a = "float64");
  *data = nb::cast<OutArray>(a).data();
  return a;
}

// shape with the batch dimension in front when batched
std::vector<size_t> Batched(bool batched, size_t batch, std::vector<size_t> shape) {
  if (batched) shape.insert(shape.begin(), batch);
  return shape;
}

ParameterSpec RolloutParameterOf(nb::handle item, size_t i) {
  const std::string what = "parameters[" + std::to_string(i) + "]";
  if (!nb::isinstance<nb::dict>(item)) throw std::invalid_argument(what + ": expected a dict");
  const nb::dict d = nb::cast<nb::dict>(item);
  std::string valid;
  for (const std::string& k : kRolloutParameterKeys) valid += (valid.empty() ? "" : ", ") + k;
  for (auto [key, value] : d) {
    const std::string k = nb::cast<std::string>(nb::str(key));
    if (std::find(kRolloutParameterKeys.begin(), kRolloutParameterKeys.end(), k) ==
        kRolloutParameterKeys.end()) {
      throw std::invalid_argument(what + ": unknown key '" + k + "'; valid: " + valid);
    }
  }
  auto text = [&](const char* key) {
    if (!d.contains(key)) return std::string();
    try {
      return nb::cast<std::string>(d[key]);
    } catch (const nb::cast_error&) {
      throw std::invalid_argument(what + ": '" + key + "' must be a string");
    }
  };
  ParameterSpec p;
  p.kind = d.contains("target") ? text("target") : text("kind");
  if (p.kind.empty()) throw std::invalid_argument(what + ": 'target' is required");
  p.object = text("object");
  p.field = text("field");
  p.label = text("name");
  if (d.contains("index")) {
    try {
      p.index = nb::cast<int>(d["index"]);
    } catch (const nb::cast_error&) {
      throw std::invalid_argument(what + ": 'index' must be an integer");
    }
  }
  return p;
}

// what linearize() differentiates
struct Wrt {
  bool x0 = false, ctrl = false, params = false;
};

Wrt WrtOf(const std::vector<std::string>& names) {
  Wrt w;
  for (const std::string& n : names) {
    if (n == "x0") {
      w.x0 = true;
    } else if (n == "ctrl") {
      w.ctrl = true;
    } else if (n == "params") {
      w.params = true;
    } else {
      throw std::invalid_argument("wrt: unknown '" + n + "'; valid: x0, ctrl, params");
    }
  }
  return w;
}

class RolloutModel;

// the nominal rollouts of a batch and their one-step blocks
class Linearization {
 public:
  std::shared_ptr<const RolloutModel> owner;
  bool batched = false, x0_batched = false, ctrl_batched = false;
  Wrt wrt;
  int T = 0;
  std::vector<Eigen::VectorXd> x0;  // as given (raw coordinates), one per batch element
  std::vector<Trajectory> nominal;
  std::vector<StepBlocks> blocks;

  size_t batch() const { return nominal.size(); }
  nb::object States() const;
  nb::object Sensors() const;
  nb::tuple Vjp(nb::handle states_grad, nb::handle sensors_grad) const;
  nb::tuple Jvp(nb::handle x0_dot, nb::handle ctrl_dot, nb::handle params_dot) const;
  nb::dict Jacobians() const;
  nb::object Blocks(char which) const;
  std::vector<int> Kinks() const {
    std::vector<int> k;
    for (const StepBlocks& b : blocks) k.push_back(b.kinks);
    return k;
  }
  std::vector<std::string> Warnings() const {
    std::vector<std::string> w;
    for (size_t i = 0; i < blocks.size(); ++i) {
      for (const std::string& s : blocks[i].warnings) {
        w.push_back("sequence " + std::to_string(i) + ": " + s);
      }
    }
    return w;
  }
};

class RolloutModel : public std::enable_shared_from_this<RolloutModel> {
 public:
  RolloutModel(nb::handle model, nb::handle parameters, int threads, bool sensors, bool central,
               double relative_step, double state_step, bool kink_check) {
    ModelPtr m = ModelOf(model, "model");
    std::vector<ParameterSpec> specs;
    if (!parameters.is_none()) {
      if (!nb::isinstance<nb::list>(parameters) && !nb::isinstance<nb::tuple>(parameters)) {
        throw std::invalid_argument("parameters: expected a list of dicts");
      }
      size_t i = 0;
      for (nb::handle item : parameters) specs.push_back(RolloutParameterOf(item, i++));
    }
    if (!(relative_step > 0) || !(state_step > 0)) {
      throw std::invalid_argument("relative_step and state_step must be positive");
    }
    SimulatorOptions so;
    so.threads = CheckedThreads(threads, "threads");
    // the model's own tolerance: min(model, +inf)
    so.solver_tolerance = std::numeric_limits<double>::infinity();
    so.sensors = sensors;
    sim_ = std::make_unique<Simulator>(*m, specs, so);
    initial_ = sim_->GetParameters();
    jopt_.mode = JacobianMode::kMatrix;
    jopt_.central = central;
    jopt_.relative_step = relative_step;
    jopt_.state_step = state_step;
    jopt_.kink_check = kink_check;
  }

  const StateDims& dims() const { return sim_->dims(); }
  const mjModel& model() const { return sim_->model(); }
  int ns() const { return sim_->options().sensors ? dims().ns : 0; }
  int np() const { return sim_->parameters().size(); }
  int threads() const { return sim_->threads(); }
  std::vector<std::string> ParameterNames() const {
    std::vector<std::string> names;
    for (int j = 0; j < np(); ++j) names.push_back(sim_->parameters()[j].label());
    return names;
  }
  nb::object ParameterValues() const {
    double* p;
    nb::object a = NewArray({static_cast<size_t>(np())}, &p);
    for (int j = 0; j < np(); ++j) p[j] = initial_[j];
    return a;
  }

  nb::tuple Rollout(nb::handle x0, nb::handle ctrl, nb::handle params, double time) {
    auto lin = Prepare(x0, ctrl, params, time);
    {
      nb::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      SetParameters(lin.first);
      sim_->Rollout(lin.second.sequences, &lin.second.lin->nominal);
    }
    return nb::make_tuple(lin.second.lin->States(), lin.second.lin->Sensors());
  }

  std::shared_ptr<Linearization> Linearize(nb::handle x0, nb::handle ctrl, nb::handle params,
                                           const std::vector<std::string>& wrt, double time) {
    const mjModel& m = model();
    if (m.opt.integrator == mjINT_RK4 || m.nhistory > 0) {
      throw std::invalid_argument(
          std::string("linearize: the one-step derivatives come from mjd_transitionFD, which "
                      "supports ") +
          (m.nhistory > 0 ? "no native delays (this model has history buffers)"
                          : "no RK4 integrator (this model's integrator)") +
          "; rollout() works, linearize() needs Euler, implicit or implicitfast and no delays");
    }
    auto [values, job] = Prepare(x0, ctrl, params, time);
    Linearization& lin = *job.lin;
    lin.wrt = WrtOf(wrt);
    CheckMemory(lin.batch(), lin.T, lin.wrt);
    {
      nb::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      SetParameters(values);
      sim_->Rollout(job.sequences, &lin.nominal);
      sim_->StepJacobians(job.sequences, lin.nominal, jopt_, lin.wrt.ctrl, lin.wrt.params,
                          &lin.blocks);
    }
    return job.lin;
  }

  // bytes of a Linearization's blocks (and their ctrl Jacobian when `ctrl_jacobian`), refused
  // past the default share of the available memory (the fit's rule, sysid/fit/memory_estimate.h)
  void CheckMemory(size_t batch, int T, const Wrt& w, bool ctrl_jacobian = false) const {
    const double nx = dims().nx, nu = w.ctrl ? dims().nu : 0, npar = w.params ? np() : 0;
    double bytes = 8.0 * batch * T * (nx + ns()) * (nx + nu + npar);
    if (ctrl_jacobian) bytes = 8.0 * batch * (T + 1.0) * (nx + ns()) * T * dims().nu;
    const long long available = AvailableMemoryBytes();
    if (available > 0 && bytes > kDefaultMemoryShare * static_cast<double>(available)) {
      throw std::invalid_argument(
          std::string(ctrl_jacobian ? "jacobians" : "linearize") + ": " +
          std::to_string(static_cast<long long>(bytes / 1e6)) + " MB for " + std::to_string(batch) +
          " sequence(s) of " + std::to_string(T) + " steps exceed " +
          std::to_string(static_cast<int>(kDefaultMemoryShare * 100)) +
          " % of the available memory (" + std::to_string(available / 1000000) +
          " MB); use vjp/jvp (no full Jacobians), shorter sequences or smaller batches");
    }
  }

 private:
  struct Job {
    std::vector<SequenceInput> sequences;
    std::shared_ptr<Linearization> lin;
  };

  // the batch of sequences (x0 normalised) and parameter values of a call, checked
  std::pair<Eigen::VectorXd, Job> Prepare(nb::handle x0_in, nb::handle ctrl_in, nb::handle params,
                                          double time) {
    const StateDims& d = dims();
    const Array x0 = ArrayOf(x0_in, "x0"), ctrl = ArrayOf(ctrl_in, "ctrl");
    if (x0.shape.empty() || x0.shape.size() > 2 ||
        x0.shape.back() != static_cast<size_t>(d.nphys)) {
      throw std::invalid_argument(
          "x0: expected shape (" + std::to_string(d.nphys) + ",) or (B, " +
          std::to_string(d.nphys) + ") (nq + nv + na = " + std::to_string(d.nq) + " + " +
          std::to_string(d.nv) + " + " + std::to_string(d.na) + "), got " + ShapeText(x0.shape));
    }
    if (ctrl.shape.size() < 2 || ctrl.shape.size() > 3 ||
        ctrl.shape.back() != static_cast<size_t>(d.nu)) {
      throw std::invalid_argument("ctrl: expected shape (T, " + std::to_string(d.nu) +
                                  ") or (B, T, " + std::to_string(d.nu) + ") (nu = " +
                                  std::to_string(d.nu) + "), got " + ShapeText(ctrl.shape));
    }
    Job job;
    job.lin = std::make_shared<Linearization>();
    Linearization& lin = *job.lin;
    lin.owner = shared_from_this();
    lin.x0_batched = x0.shape.size() == 2;
    lin.ctrl_batched = ctrl.shape.size() == 3;
    lin.batched = lin.x0_batched || lin.ctrl_batched;
    const size_t bx = lin.x0_batched ? x0.shape[0] : 1, bu = lin.ctrl_batched ? ctrl.shape[0] : 1;
    if (lin.x0_batched && lin.ctrl_batched && bx != bu) {
      throw std::invalid_argument("x0 and ctrl: batch sizes differ (" + std::to_string(bx) +
                                  " and " + std::to_string(bu) + ")");
    }
    const size_t batch = std::max(bx, bu);
    if (batch == 0) throw std::invalid_argument("x0 and ctrl: an empty batch");
    lin.T = static_cast<int>(ctrl.shape[ctrl.shape.size() - 2]);
    if (lin.T == 0) throw std::invalid_argument("ctrl: no steps (T = 0)");
    for (size_t b = 0; b < batch; ++b) {
      const double* x = x0.data + (lin.x0_batched ? b : 0) * d.nphys;
      lin.x0.push_back(Eigen::Map<const Eigen::VectorXd>(x, d.nphys));
      if (!lin.x0.back().allFinite()) {
        throw std::invalid_argument(
            "x0" + std::string(lin.x0_batched ? "[" + std::to_string(b) + "]" : "") +
            ": not finite");
      }
      Eigen::VectorXd xn(d.nphys);
      NormalizedPhysics(model(), x, xn.data());
      SequenceInput s;
      s.x0.qpos = xn.head(d.nq);
      s.x0.qvel = xn.segment(d.nq, d.nv);
      s.x0.act = xn.tail(d.na);
      s.x0.time = time;
      const double* u = ctrl.data + (lin.ctrl_batched ? b : 0) * lin.T * d.nu;
      s.ctrl = Eigen::Map<const RowMatrix>(u, lin.T, d.nu);
      if (!s.ctrl.allFinite()) throw std::invalid_argument("ctrl: not finite");
      job.sequences.push_back(std::move(s));
    }
    Eigen::VectorXd values = initial_;
    if (!params.is_none()) {
      const Array p = ArrayOf(params, "params");
      if (p.shape.size() != 1 || p.shape[0] != static_cast<size_t>(np())) {
        throw std::invalid_argument("params: expected shape (" + std::to_string(np()) +
                                    ",) (the RolloutModel's parameters), got " +
                                    ShapeText(p.shape));
      }
      values = Eigen::Map<const Eigen::VectorXd>(p.data, np());
      if (!values.allFinite()) throw std::invalid_argument("params: not finite");
    }
    return {values, std::move(job)};
  }

  void SetParameters(const Eigen::VectorXd& values) {
    if (np() && values != sim_->GetParameters()) sim_->SetParameters(values);
  }

  std::unique_ptr<Simulator> sim_;
  Eigen::VectorXd initial_;
  JacobianOptions jopt_;
  std::mutex mutex_;  // one call at a time on the simulator
};

nb::object Linearization::States() const {
  const StateDims& d = owner->dims();
  double* out;
  nb::object a = NewArray(
      Batched(batched, batch(), {static_cast<size_t>(T) + 1, static_cast<size_t>(d.nphys)}), &out);
  for (size_t b = 0; b < batch(); ++b) {
    std::copy_n(nominal[b].states.data(), (T + 1) * d.nphys, out + b * (T + 1) * d.nphys);
  }
  return a;
}

nb::object Linearization::Sensors() const {
  const int ns = owner->ns();
  double* out;
  nb::object a =
      NewArray(Batched(batched, batch(), {static_cast<size_t>(T), static_cast<size_t>(ns)}), &out);
  for (size_t b = 0; b < batch(); ++b) {
    std::copy_n(nominal[b].sensors.data(), static_cast<size_t>(T) * ns, out + b * T * ns);
  }
  return a;
}

// an optional array argument of exactly this shape (None: absent); `what` names it
bool OptionalArray(nb::handle value, const std::vector<size_t>& shape, const std::string& what,
                   Array* out) {
  if (value.is_none()) return false;
  *out = ArrayOf(value, what);
  if (out->shape != shape) {
    throw std::invalid_argument(what + ": expected shape " + ShapeText(shape) + ", got " +
                                ShapeText(out->shape));
  }
  return true;
}

// a derivative asked for what linearize() did not differentiate
void RequireWrt(bool ok, const char* name) {
  if (!ok) {
    throw std::invalid_argument(std::string(name) + ": linearize() was called without '" + name +
                                "' in wrt");
  }
}

nb::tuple Linearization::Vjp(nb::handle states_grad, nb::handle sensors_grad) const {
  const StateDims& d = owner->dims();
  const mjModel& m = owner->model();
  const int ns = owner->ns(), nx = d.nx, nphys = d.nphys, nu = d.nu, np = owner->np();
  const size_t B = batch();
  Array gs, gy;
  const bool has_s = OptionalArray(
      states_grad, Batched(batched, B, {static_cast<size_t>(T) + 1, static_cast<size_t>(nphys)}),
      "states_grad", &gs);
  const bool has_y = OptionalArray(
      sensors_grad, Batched(batched, B, {static_cast<size_t>(T), static_cast<size_t>(ns)}),
      "sensors_grad", &gy);
  // per element: coordinate cotangents -> tangent ones, the backward chain, the initial state's
  // tangent gradient -> coordinates; elements broadcast from one x0 or ctrl are summed
  Eigen::MatrixXd gx0 = Eigen::MatrixXd::Zero(nphys, x0_batched ? B : 1);
  std::vector<RowMatrix> gu(ctrl_batched ? B : 1, RowMatrix::Zero(T, nu));
  Eigen::VectorXd gp = Eigen::VectorXd::Zero(np);
  {
    nb::gil_scoped_release release;
    RowMatrix gx, gyb, gub;
    Eigen::VectorXd gx0b, gpb, gcoords(nphys);
    for (size_t b = 0; b < B; ++b) {
      gx.resize(has_s ? T + 1 : 0, nx);
      for (int k = 0; has_s && k <= T; ++k) {
        CoordinatesToTangentCotangent(m, nominal[b].states.row(k).data(),
                                      gs.data + (b * (T + 1) + k) * nphys, gx.row(k).data());
      }
      gyb =
          has_y ? RowMatrix(Eigen::Map<const RowMatrix>(gy.data + b * T * ns, T, ns)) : RowMatrix();
      ChainBackward(blocks[b], gx, gyb, &gx0b, &gub, &gpb);
      TangentCotangentToCoordinates(m, x0[b].data(), gx0b.data(), gcoords.data());
      gx0.col(x0_batched ? b : 0) += gcoords;
      if (wrt.ctrl) gu[ctrl_batched ? b : 0] += gub;
      if (wrt.params) gp += gpb;
    }
  }
  nb::object x0_grad = nb::none(), ctrl_grad = nb::none(), params_grad = nb::none();
  double* out;
  if (wrt.x0) {
    x0_grad = NewArray(x0_batched ? std::vector<size_t>{B, static_cast<size_t>(nphys)}
                                  : std::vector<size_t>{static_cast<size_t>(nphys)},
                       &out);
    Eigen::Map<Eigen::MatrixXd>(out, nphys, gx0.cols()) = gx0;
  }
  if (wrt.ctrl) {
    ctrl_grad =
        NewArray(Batched(ctrl_batched, B, {static_cast<size_t>(T), static_cast<size_t>(nu)}), &out);
    for (size_t b = 0; b < gu.size(); ++b) std::copy_n(gu[b].data(), T * nu, out + b * T * nu);
  }
  if (wrt.params) {
    params_grad = NewArray({static_cast<size_t>(np)}, &out);
    std::copy_n(gp.data(), np, out);
  }
  return nb::make_tuple(x0_grad, ctrl_grad, params_grad);
}

nb::tuple Linearization::Jvp(nb::handle x0_dot, nb::handle ctrl_dot, nb::handle params_dot) const {
  const StateDims& d = owner->dims();
  const mjModel& m = owner->model();
  const int ns = owner->ns(), nx = d.nx, nphys = d.nphys, nu = d.nu, np = owner->np();
  const size_t B = batch();
  Array ax, au, ap;
  const bool has_x = OptionalArray(x0_dot,
                                   x0_batched ? std::vector<size_t>{B, static_cast<size_t>(nphys)}
                                              : std::vector<size_t>{static_cast<size_t>(nphys)},
                                   "x0_dot", &ax);
  const bool has_u = OptionalArray(
      ctrl_dot, Batched(ctrl_batched, B, {static_cast<size_t>(T), static_cast<size_t>(nu)}),
      "ctrl_dot", &au);
  const bool has_p = OptionalArray(params_dot, {static_cast<size_t>(np)}, "params_dot", &ap);
  if (has_x) RequireWrt(wrt.x0, "x0");
  if (has_u) RequireWrt(wrt.ctrl, "ctrl");
  if (has_p) RequireWrt(wrt.params, "params");
  double *xs, *ys;
  nb::object states_dot =
      NewArray(Batched(batched, B, {static_cast<size_t>(T) + 1, static_cast<size_t>(nphys)}), &xs);
  nb::object sensors_dot =
      NewArray(Batched(batched, B, {static_cast<size_t>(T), static_cast<size_t>(ns)}), &ys);
  {
    nb::gil_scoped_release release;
    Eigen::VectorXd dx0 = Eigen::VectorXd::Zero(nx), dp;
    RowMatrix du, dx, dy;
    if (has_p) dp = Eigen::Map<const Eigen::VectorXd>(ap.data, np);
    for (size_t b = 0; b < B; ++b) {
      if (has_x) {
        CoordinatesToTangent(m, x0[b].data(), ax.data + (x0_batched ? b : 0) * nphys, dx0.data());
      }
      if (has_u) du = Eigen::Map<const RowMatrix>(au.data + (ctrl_batched ? b : 0) * T * nu, T, nu);
      ChainForward(blocks[b], dx0, du, dp, &dx, &dy);
      for (int k = 0; k <= T; ++k) {
        TangentToCoordinates(m, nominal[b].states.row(k).data(), dx.row(k).data(),
                             xs + (b * (T + 1) + k) * nphys);
      }
      std::copy_n(dy.data(), static_cast<size_t>(T) * ns, ys + b * T * ns);
    }
  }
  return nb::make_tuple(states_dot, sensors_dot);
}

nb::dict Linearization::Jacobians() const {
  const StateDims& d = owner->dims();
  const size_t B = batch(), T1 = static_cast<size_t>(T) + 1, Ts = static_cast<size_t>(T);
  const size_t nx = d.nx, ns = owner->ns(), nu = d.nu, np = owner->np();
  if (wrt.ctrl) owner->CheckMemory(B, T, wrt, true);
  nb::dict out;
  // one array per entry, each element's block copied in (row-major stacks reshape as they are)
  struct Entry {
    const char* name;
    std::vector<size_t> shape;
    double* data = nullptr;
  };
  std::vector<Entry> entries;
  if (wrt.x0) {
    entries.push_back({"states_x0", {T1, nx, nx}});
    entries.push_back({"sensors_x0", {Ts, ns, nx}});
  }
  if (wrt.params) {
    entries.push_back({"states_params", {T1, nx, np}});
    entries.push_back({"sensors_params", {Ts, ns, np}});
  }
  if (wrt.ctrl) {
    entries.push_back({"states_ctrl", {T1, nx, Ts, nu}});
    entries.push_back({"sensors_ctrl", {Ts, ns, Ts, nu}});
  }
  for (Entry& e : entries) out[e.name] = NewArray(Batched(batched, B, e.shape), &e.data);
  {
    nb::gil_scoped_release release;
    RowMatrix M[6];
    for (size_t b = 0; b < B; ++b) {
      ChainJacobians(blocks[b], wrt.x0 ? &M[0] : nullptr, wrt.x0 ? &M[1] : nullptr,
                     wrt.params ? &M[2] : nullptr, wrt.params ? &M[3] : nullptr,
                     wrt.ctrl ? &M[4] : nullptr, wrt.ctrl ? &M[5] : nullptr);
      size_t e = 0;
      for (int i = 0; i < 6; ++i) {
        if ((i < 2 && !wrt.x0) || (i >= 2 && i < 4 && !wrt.params) || (i >= 4 && !wrt.ctrl)) {
          continue;
        }
        std::copy_n(M[i].data(), M[i].size(), entries[e++].data + b * M[i].size());
      }
    }
  }
  return out;
}

// the one-step blocks A..G of every element (StepBlocks), (B?, T, rows, cols)
nb::object Linearization::Blocks(char which) const {
  auto pick = [&](const StepBlocks& b) -> const RowMatrix& {
    switch (which) {
      case 'A':
        return b.A;
      case 'B':
        return b.B;
      case 'C':
        return b.C;
      case 'D':
        return b.D;
      case 'F':
        return b.F;
      default:
        return b.G;
    }
  };
  const RowMatrix& first = pick(blocks[0]);
  const size_t rows = T ? first.rows() / T : 0, cols = first.cols();
  double* out;
  nb::object a = NewArray(Batched(batched, batch(), {static_cast<size_t>(T), rows, cols}), &out);
  for (size_t b = 0; b < batch(); ++b) {
    const RowMatrix& M = pick(blocks[b]);
    std::copy_n(M.data(), M.size(), out + b * M.size());
  }
  return a;
}

constexpr const char* kRolloutModelDoc =
    "A MuJoCo model whose rollouts and their derivatives are numpy functions (docs/python.md, "
    "'Gradients through physics').\n\n"
    "model: an MJCF path, MJCF text, a mujoco.MjModel or a mujoco.MjSpec (copied; its options "
    "are kept: timestep, integrator, solver tolerance, disable flags). parameters: None or a "
    "list of dicts {name, target, object, field, index} (the experiment file's names; 'kind' for "
    "'target'), differentiated as `params`. threads: 0 (all cores) or 1..256, over the batch and "
    "the time steps. sensors: False skips MuJoCo's sensor stage (sensors have 0 columns). "
    "central: central instead of forward differences (twice the steps). relative_step: a "
    "parameter's step is relative_step * max(|p|, 1e-3). state_step: the step of mjd_transitionFD "
    "for state and control columns. kink_check: near contacts also difference the backward side "
    "and keep the smaller one where the two disagree (a contact onset inside the step), up to "
    "twice the steps there; False (default): forward differences as mjd_transitionFD gives them.";

}  // namespace

void BindRolloutApi(nb::module_& m) {
  nb::class_<Linearization> linearization(m, "Linearization",
                                          "Nominal rollouts and their one-step derivative blocks "
                                          "(RolloutModel.linearize)");
  linearization
      .def_prop_ro("states", &Linearization::States,
                   "(B?, T+1, nq+nv+na): the nominal states, row 0 the normalised x0")
      .def_prop_ro("sensors", &Linearization::Sensors, "(B?, T, nsensordata)")
      .def_prop_ro("kinks", &Linearization::Kinks,
                   "per sequence: one-sided differences used where the two sides disagreed")
      .def_prop_ro("warnings", &Linearization::Warnings, "constraint-solver warnings")
      .def("vjp", &Linearization::Vjp, arg("states_grad") = nb::none(),
           arg("sensors_grad") = nb::none(),
           "Vector-Jacobian product: cotangents of states (B?, T+1, nq+nv+na) and sensors (B?, "
           "T, nsensordata) (None: zeros) -> (x0_grad, ctrl_grad, params_grad) shaped as x0, ctrl "
           "and params (summed over a broadcast batch), None for what is not in wrt")
      .def("jvp", &Linearization::Jvp, arg("x0_dot") = nb::none(), arg("ctrl_dot") = nb::none(),
           arg("params_dot") = nb::none(),
           "Jacobian-vector product: directions of x0, ctrl and params (None: zero) -> "
           "(states_dot, sensors_dot) in coordinates")
      .def("jacobians", &Linearization::Jacobians,
           "Full Jacobians of what is in wrt, state rows (and x0 columns) in tangent space "
           "(2nv+na): states_x0 (B?, T+1, nx, nx), sensors_x0 (B?, T, ns, nx), states_params, "
           "sensors_params (.., np), states_ctrl (B?, T+1, nx, T, nu), sensors_ctrl (B?, T, ns, "
           "T, nu)");
  // the one-step blocks as properties (B?, T, rows, cols): A, B, F tangent rows, C, D, G sensors
  for (const char* name : {"A", "B", "C", "D", "F", "G"}) {
    const char which = name[0];
    linearization.def_prop_ro(
        name, [which](const Linearization& l) { return l.Blocks(which); },
        "one-step blocks (B?, T, rows, cols): A = dx'/dx, B = dx'/du, F = dx'/dp (tangent rows), "
        "C = dy/dx, D = dy/du, G = dy/dp");
  }

  nb::class_<RolloutModel>(m, "RolloutModel", kRolloutModelDoc)
      .def(nb::new_([](nb::handle model, nb::handle parameters, int threads, bool sensors,
                       bool central, double relative_step, double state_step, bool kink_check) {
             return std::make_shared<RolloutModel>(model, parameters, threads, sensors, central,
                                                   relative_step, state_step, kink_check);
           }),
           arg("model"), arg("parameters") = nb::none(), arg("threads") = 1, arg("sensors") = true,
           arg("central") = false, arg("relative_step") = 1e-6, arg("state_step") = 1e-6,
           arg("kink_check") = false)
      .def_prop_ro(
          "nq", [](const RolloutModel& r) { return r.dims().nq; }, "qpos size")
      .def_prop_ro(
          "nv", [](const RolloutModel& r) { return r.dims().nv; }, "qvel size")
      .def_prop_ro(
          "na", [](const RolloutModel& r) { return r.dims().na; }, "activation states")
      .def_prop_ro(
          "nu", [](const RolloutModel& r) { return r.dims().nu; }, "controls")
      .def_prop_ro("nsensordata", &RolloutModel::ns, "sensor values per row (0 with sensors=False)")
      .def_prop_ro(
          "nstate", [](const RolloutModel& r) { return r.dims().nphys; },
          "nq + nv + na: the coordinates of a state row [qpos, qvel, act]")
      .def_prop_ro(
          "ntangent", [](const RolloutModel& r) { return r.dims().nx; },
          "2 nv + na: a state's tangent space (the rows of full Jacobians and blocks)")
      .def_prop_ro("np", &RolloutModel::np, "the number of parameters")
      .def_prop_ro("threads", &RolloutModel::threads, "worker threads")
      .def_prop_ro("parameter_names", &RolloutModel::ParameterNames,
                   "the parameters' names (their 'name', else kind:object[index]), in params order")
      .def("parameter_values", &RolloutModel::ParameterValues,
           "the model's values of the parameters (np,), in the kinds' units")
      .def("rollout", &RolloutModel::Rollout, arg("x0"), arg("ctrl"), arg("params") = nb::none(),
           arg("time") = 0.0,
           "(states (B?, T+1, nq+nv+na), sensors (B?, T, nsensordata)) from x0 (nq+nv+na,) or (B, "
           "..) and ctrl (T, nu) or (B, T, nu); params (np,) or None (the model's values). "
           "Quaternions of x0 are normalised; batched when x0 or ctrl is")
      .def("linearize", &RolloutModel::Linearize, arg("x0"), arg("ctrl"),
           arg("params") = nb::none(),
           arg("wrt") = std::vector<std::string>{"x0", "ctrl", "params"}, arg("time") = 0.0,
           "The rollout and its one-step derivative blocks (1 + 2nv+na + nu steps per time step "
           "with 'ctrl' in wrt, 1 + 2nv+na without, plus 1 + np with 'params') -> Linearization");

  m.def(
      "rollout",
      [](nb::handle model, nb::handle x0, nb::handle ctrl, nb::handle params, nb::handle parameters,
         int threads) {
        auto r = std::make_shared<RolloutModel>(model, parameters, threads, true, false, 1e-6, 1e-6,
                                                false);
        return r->Rollout(x0, ctrl, params, 0.0);
      },
      arg("model"), arg("x0"), arg("ctrl"), arg("params") = nb::none(),
      arg("parameters") = nb::none(), arg("threads") = 1,
      "RolloutModel(model, parameters, threads).rollout(x0, ctrl, params): (states, sensors)");
}

}  // namespace mjsysid::python
