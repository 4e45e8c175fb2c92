#include "sysid/design/design.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/design/cma_es.h"
#include "sysid/sim/excitation.h"

namespace mjsysid::design {
namespace {

constexpr double kShrink = 0.7;  // amplitude factor after a broken constraint
constexpr int kShrinks = 6;      // tries at smaller amplitudes before a shape is rejected
// CMA-ES's first step, in the units of the coefficients (each about 1 on the sphere |c| =
// sqrt(nvar))
constexpr double kSearchSigma = 0.3;

// the noise sigma of every fitted sensor column: sensors[].sigma, else simulate.noise
SensorWeights WeightsOf(const io::ExperimentConfig& config, const mjModel& m) {
  std::vector<io::SensorSpec> specs = config.sensors;
  if (specs.empty()) {
    for (int i = 0; i < m.nsensor; ++i) {
      const char* name = mj_id2name(&m, mjOBJ_SENSOR, i);
      io::SensorSpec s;
      s.name = name ? name : "";
      s.marks.self = config.marks.self;
      specs.push_back(s);
    }
  }
  SensorWeights w;
  for (const io::SensorSpec& s : specs) {
    std::optional<double> sigma = s.sigma;
    for (const io::NamedValue& n : config.simulate.noise) {
      if (!sigma && n.name == s.name && n.value > 0) sigma = n.value;
    }
    if (!sigma) {
      throw io::ConfigError(s.marks.self,
                            "sensor '" + s.name +
                                "' has no noise sigma: the design weighs each "
                                "sensor by its noise",
                            "give sensors[].sigma or simulate.noise." + s.name);
    }
    const int id = mj_name2id(&m, mjOBJ_SENSOR, s.name.c_str());
    if (id < 0) throw io::ConfigError(s.marks.self, "the model has no sensor '" + s.name + "'");
    for (int c = 0; c < m.sensor_dim[id]; ++c) {
      w.columns.push_back(m.sensor_adr[id] + c);
      w.sigma.push_back(*sigma);
    }
  }
  return w;
}

// the initial state of the sequence: simulate.initial_state, else qpos0 at rest
InitialState InitialOf(const io::ExperimentConfig& config, const Simulator& sim) {
  InitialState x0 = sim.ReferenceState();
  const io::SimulateInitialState& is = config.simulate.initial_state;
  if (!is.qpos.empty()) x0.qpos = Eigen::Map<const Eigen::VectorXd>(is.qpos.data(), is.qpos.size());
  if (!is.qvel.empty()) x0.qvel = Eigen::Map<const Eigen::VectorXd>(is.qvel.data(), is.qvel.size());
  return x0;
}

// centre and amplitude limit of every actuator (see the contract)
// (shipped: the experiment's own controls)
void Limits(const io::ExperimentConfig& config, const mjModel& m, const RowMatrix& shipped,
            Eigen::VectorXd* centre, Eigen::VectorXd* amplitude) {
  centre->setZero(m.nu);
  amplitude->setZero(m.nu);
  for (int i = 0; i < m.nu; ++i) {
    const char* name = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    for (const io::Excitation& e : config.simulate.excitation) {
      if (e.actuator.empty() || (name && e.actuator == name)) {
        (*amplitude)[i] = e.type == io::ExcitationType::kZero ? 0.0 : e.amplitude;
        // a file: the largest |u - centre| it plays (set by the caller from its controls)
        if (e.type == io::ExcitationType::kFile) (*amplitude)[i] = -1;
      }
    }
    if (m.actuator_ctrllimited[i]) {
      const double lo = m.actuator_ctrlrange[2 * i], hi = m.actuator_ctrlrange[2 * i + 1];
      (*centre)[i] = lo <= 0 && 0 <= hi ? 0.0 : 0.5 * (lo + hi);
    }
  }
  for (int i = 0; i < m.nu; ++i) {
    if ((*amplitude)[i] < 0) {
      (*amplitude)[i] = (shipped.col(i).array() - (*centre)[i]).abs().maxCoeff();
    }
    if (m.actuator_ctrllimited[i]) {
      const double lo = m.actuator_ctrlrange[2 * i], hi = m.actuator_ctrlrange[2 * i + 1];
      (*amplitude)[i] = std::min({(*amplitude)[i], hi - (*centre)[i], (*centre)[i] - lo});
    }
  }
}

// the constraint checks of a design
struct Constraints {
  struct Joint {
    int qpos, dof;
    std::string name;
    double lower, upper;
  };
  std::vector<Joint> limited;  // limited hinge and slide joints, band shrunk by the margin
  std::vector<Joint> speed;    // every hinge and slide joint
  double max_speed = 0;
  bool contacts = true;
};

Constraints ConstraintsOf(const mjModel& m, const DesignOptions& o) {
  Constraints c;
  c.max_speed = o.max_joint_speed;
  c.contacts = o.contacts;
  for (int j = 0; j < m.njnt; ++j) {
    if (m.jnt_type[j] != mjJNT_HINGE && m.jnt_type[j] != mjJNT_SLIDE) continue;
    const char* name = mj_id2name(&m, mjOBJ_JOINT, j);
    Constraints::Joint joint{m.jnt_qposadr[j], m.jnt_dofadr[j],
                             name ? name : "joint " + std::to_string(j), 0, 0};
    c.speed.push_back(joint);
    if (!m.jnt_limited[j]) continue;
    const double lo = m.jnt_range[2 * j], hi = m.jnt_range[2 * j + 1];
    joint.lower = lo + o.range_margin * (hi - lo);
    joint.upper = hi - o.range_margin * (hi - lo);
    c.limited.push_back(joint);
  }
  return c;
}

// the margins of a motion, and the first constraint it breaks ("" when none)
std::string Check(const Constraints& c, const StateDims& dims, const Trajectory& tr, Margins* out) {
  std::string violation;
  out->joints.clear();
  for (const Constraints::Joint& j : c.limited) {
    Margins::Joint mj{j.name, j.lower, j.upper, 0, 0, 0};
    const auto q = tr.states.col(j.qpos);
    mj.min = q.minCoeff();
    mj.max = q.maxCoeff();
    mj.margin = std::min(mj.min - j.lower, j.upper - mj.max);
    if (mj.margin < 0 && violation.empty()) {
      violation = "joint " + j.name + " leaves its range (with the margin)";
    }
    out->joints.push_back(mj);
  }
  out->max_joint_speed = 0;
  for (const Constraints::Joint& j : c.speed) {
    const double v = tr.states.col(dims.nq + j.dof).cwiseAbs().maxCoeff();
    if (v > out->max_joint_speed) {
      out->max_joint_speed = v;
      out->fastest_joint = j.name;
    }
  }
  if (c.max_speed > 0 && out->max_joint_speed > c.max_speed && violation.empty()) {
    violation = "joint " + out->fastest_joint + " moves faster than the speed limit";
  }
  out->steps_with_contact = 0;
  for (int n : tr.ncon) out->steps_with_contact += n > 0;
  if (!c.contacts && out->steps_with_contact > 0 && violation.empty()) {
    violation = "contacts at " + std::to_string(out->steps_with_contact) + " steps";
  }
  return violation;
}

// everything one candidate needs
struct Context {
  Simulator* sim;
  InitialState x0;
  Constraints constraints;
  SensorWeights sensors;
  Eigen::VectorXd values, prior_precision, centre, amplitude;
  DesignCriterion criterion;
};

// rolls out e->ctrl, checks the constraints and records the peaks
void Simulate(const Context& cx, Evaluated* e) {
  e->motion = cx.sim->Rollout(SequenceInput{cx.x0, e->ctrl});
  e->violation = Check(cx.constraints, cx.sim->dims(), e->motion, &e->margins);
  e->feasible = e->violation.empty();
  e->margins.peak.resize(e->ctrl.cols());
  for (Eigen::Index i = 0; i < e->ctrl.cols(); ++i) {
    e->margins.peak[i] = (e->ctrl.col(i).array() - cx.centre[i]).abs().maxCoeff();
  }
}

// the information of a simulated excitation: one Jacobian of its rollout
void Inform(const Context& cx, Evaluated* e) {
  JacobianOptions jo;
  jo.state_jacobians = false;
  jo.zero_column_is_error = false;
  const Sensitivity s = cx.sim->Jacobians(SequenceInput{cx.x0, e->ctrl}, e->motion, jo);
  e->info =
      InformationOf({s}, cx.sim->model().nsensordata, cx.sensors, cx.values, cx.prior_precision);
  e->criterion = CriterionValue(e->info, cx.criterion);
  e->score = SearchScore(e->info, cx.criterion);
}

// A candidate shape: simulated at full amplitude, then at kShrink times less until the
// constraints hold (at most kShrinks times); the information of the first that holds, else
// infeasible (score +inf)
Evaluated Evaluate(const Context& cx, const RowMatrix& shapes) {
  Evaluated e;
  for (int t = 0; t <= kShrinks; ++t) {
    if (t > 0) e.scale *= kShrink;
    e.ctrl = DesignControls(shapes, cx.centre, cx.amplitude, e.scale);
    Simulate(cx, &e);
    if (e.feasible) break;
  }
  if (!e.feasible) {
    e.criterion = e.score = std::numeric_limits<double>::infinity();
    return e;
  }
  Inform(cx, &e);
  return e;
}

void CheckOptions(const DesignOptions& o) {
  if (!(o.range_margin >= 0 && o.range_margin < 0.5)) {
    throw std::invalid_argument("--range-margin must be in [0, 0.5)");
  }
  if (o.evaluations < 1 || o.evaluations > 100000) {
    throw std::invalid_argument("--evaluations must be in [1, 100000]");
  }
  if (!(o.time_limit > 0 && o.time_limit <= 7 * 86400)) {
    throw std::invalid_argument("--time-limit must be in (0, 604800] seconds");
  }
  if (o.basis.harmonics < 1 || o.basis.harmonics > 1000) {
    throw std::invalid_argument("--harmonics must be in [1, 1000]");
  }
  if (!(o.basis.base_frequency > 0 && std::isfinite(o.basis.base_frequency))) {
    throw std::invalid_argument("--base-frequency must be > 0");
  }
  if (!(o.basis.ramp >= 0 && std::isfinite(o.basis.ramp))) {
    throw std::invalid_argument("--ramp must be >= 0");
  }
  if (!std::isfinite(o.duration) || !std::isfinite(o.max_joint_speed)) {
    throw std::invalid_argument("--duration and --max-joint-speed must be finite");
  }
}

}  // namespace

DesignResult DesignExcitation(const io::ExperimentConfig& config, const DesignOptions& options,
                              const std::function<void(const DesignProgress&)>& progress) {
  const auto start = std::chrono::steady_clock::now();
  const auto seconds = [&start] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  InstallMujocoHandlers();
  CheckOptions(options);
  if (config.models.size() != 1) {
    throw io::ConfigError(config.marks.self,
                          "sysid design works on one model; the experiment has " +
                              std::to_string(config.models.size()),
                          "design for each model with its own experiment file");
  }
  const io::ModelSpec& spec = config.models.front();
  ModelPtr model = LoadModel(spec.path);
  io::ValidateExperimentAgainstModel(config, *model, spec.name);

  // the parameters, at their initial values (or the truth)
  DesignResult r;
  r.model_name = spec.name;
  r.model_path = spec.path;
  r.options = options;
  std::vector<ParameterSpec> targets;
  const std::vector<const io::ParameterSpec*> used = config.ParametersOf(spec.name);
  for (const io::ParameterSpec* p : used) targets.push_back(p->target);
  if (used.empty()) throw io::ConfigError(config.marks.self, "the experiment has no parameters");
  SimulatorOptions so;
  so.threads = options.threads;
  Simulator sim(*model, targets, so);
  const mjModel& m = sim.model();
  Context cx{&sim,
             InitialOf(config, sim),
             ConstraintsOf(m, options),
             WeightsOf(config, m),
             sim.GetParameters(),
             Eigen::VectorXd::Zero(static_cast<Eigen::Index>(used.size())),
             {},
             {},
             options.criterion};
  for (size_t i = 0; i < used.size(); ++i) {
    const auto j = static_cast<Eigen::Index>(i);
    r.parameters.push_back(used[i]->name);
    if (!used[i]->initial_auto && std::isfinite(used[i]->initial)) cx.values[j] = used[i]->initial;
    if (options.at_truth) {
      for (const io::NamedValue& t : config.simulate.truth) {
        if (t.name == used[i]->name) cx.values[j] = t.value;
      }
    }
    if (used[i]->has_prior)
      cx.prior_precision[j] = 1.0 / (used[i]->prior_sigma * used[i]->prior_sigma);
  }
  sim.SetParameters(cx.values);
  r.values = cx.values;
  // the horizon
  r.timestep = m.opt.timestep;
  const double duration =
      options.duration > 0 ? options.duration : config.simulate.steps * m.opt.timestep;
  r.steps = static_cast<int>(std::lround(duration / m.opt.timestep));
  if (r.steps < 2 || 2 * options.basis.ramp > (r.steps - 1) * m.opt.timestep) {
    throw std::invalid_argument("--duration must be longer than two ramps (2 x " +
                                std::to_string(options.basis.ramp) + " s)");
  }
  // the Jacobian of the sensors is held whole: bounded to 4 GB
  const double bytes = 8.0 * r.steps * std::max<double>(1, m.nsensordata) * used.size();
  if (bytes > 4e9) {
    throw std::invalid_argument("--duration: the sensor Jacobian of " + std::to_string(r.steps) +
                                " steps would take " + std::to_string(bytes / 1e9) +
                                " GB (at most 4 GB); design a shorter excitation");
  }

  // the experiment's own excitation over the same horizon
  const RowMatrix shipped =
      sim::GenerateControls(m, config.simulate.excitation, r.steps, config.simulate.seed);
  Limits(config, m, shipped, &cx.centre, &cx.amplitude);
  r.centre = cx.centre;
  r.amplitude = cx.amplitude;
  for (int i = 0; i < m.nu; ++i) {
    const char* name = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    r.actuators.push_back(name ? name : "actuator " + std::to_string(i));
  }
  for (const Constraints::Joint& j : cx.constraints.limited) r.joints_checked.push_back(j.name);
  for (const Constraints::Joint& j : cx.constraints.speed) {
    DesignResult::JointColumn col{j.name, j.qpos, false, 0, 0};
    for (const Constraints::Joint& l : cx.constraints.limited) {
      if (l.qpos == j.qpos) col = {j.name, j.qpos, true, l.lower, l.upper};
    }
    r.joints.push_back(col);
  }
  if (cx.amplitude.isZero()) {
    throw io::ConfigError(config.simulate.marks.self,
                          "simulate.excitation gives no actuator an amplitude: nothing to design",
                          "give simulate.excitation an amplitude > 0");
  }

  // the experiment's own excitation over the same horizon (checked, never shrunk)
  r.current.ctrl = shipped;
  Simulate(cx, &r.current);
  Inform(cx, &r.current);

  // the search: random shapes, then CMA-ES from the best of them
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Index nvar =
      static_cast<Eigen::Index>(m.nu) * CoefficientsPerActuator(options.basis);
  // the search's variables are the coefficients times the harmonic's number h (the constant
  // counts as h = 1): random shapes have a spectrum falling as 1/h, as most of a robot's
  // response lies at its low frequencies, and higher harmonics enter where they pay
  const int H = options.basis.harmonics;
  Eigen::VectorXd per_harmonic(CoefficientsPerActuator(options.basis));
  for (int h = 1; h <= H; ++h) per_harmonic[h - 1] = per_harmonic[H + h] = 1.0 / h;
  per_harmonic[H] = 1.0;
  const Eigen::VectorXd spectrum = per_harmonic.replicate(m.nu, 1);
  Eigen::VectorXd best_c;
  bool have = false;
  std::string last_violation;
  DesignProgress p;
  p.evaluations = options.evaluations;
  p.best = p.best_worst_relative_std = std::numeric_limits<double>::infinity();
  // one candidate: its shape evaluated, the best kept, progress reported; its score
  const auto candidate = [&](const Eigen::VectorXd& x) {
    // only the shape counts: every candidate on the sphere |c| = sqrt(nvar)
    const Eigen::VectorXd c = x / (std::max(x.norm(), 1e-300) / std::sqrt(double(nvar)));
    Evaluated cand = Evaluate(
        cx, FourierShapes(options.basis, spectrum.cwiseProduct(c), m.nu, r.steps, m.opt.timestep));
    ++r.evaluations;
    r.feasible += cand.feasible;
    if (!cand.feasible) last_violation = cand.violation;
    const double score = cand.score;
    if (cand.feasible && (!have || cand.score < r.design.score)) {
      r.design = std::move(cand);
      best_c = c;
      have = true;
    }
    if (progress) {
      p.evaluation = r.evaluations;
      p.seconds = seconds();
      p.best = have ? r.design.criterion : p.best;
      p.best_worst_relative_std =
          have ? r.design.info.worst_relative_std : p.best_worst_relative_std;
      progress(p);
    }
    return score;
  };
  const auto budget_left = [&] {
    return r.evaluations < options.evaluations &&
           (r.evaluations == 0 || seconds() < options.time_limit);
  };
  const int random = std::max(1, options.evaluations / 8);
  // (random shapes go on while none met the constraints)
  while (budget_left() && (r.evaluations < random || !have)) {
    Eigen::VectorXd x(nvar);
    for (Eigen::Index v = 0; v < nvar; ++v) x[v] = normal(rng);
    candidate(x);
  }
  if (have) {
    CmaEs es(best_c, kSearchSigma, sim::SeedFor(options.seed, 1));
    while (budget_left()) {
      std::vector<double> scores;
      for (const Eigen::VectorXd& x : es.Ask()) {
        scores.push_back(budget_left() ? candidate(x) : std::numeric_limits<double>::infinity());
      }
      es.Tell(scores);
    }
  }
  if (!have) {
    throw DesignError("no candidate met the constraints (" + std::to_string(r.evaluations) +
                      " tried), even at " + std::to_string(std::pow(kShrink, kShrinks)) +
                      " of the amplitude limits; the last one: " + last_violation +
                      " (see --range-margin, --max-joint-speed, --contacts, the amplitudes of "
                      "simulate.excitation and simulate.initial_state)");
  }
  r.coefficients = spectrum.cwiseProduct(best_c);
  r.time_limited = r.evaluations < options.evaluations;

  // the design simulated and checked once more, as written
  Margins check;
  const std::string violation =
      Check(cx.constraints, sim.dims(), sim.Rollout(SequenceInput{cx.x0, r.design.ctrl}), &check);
  if (!violation.empty()) throw DesignError("the design breaks a constraint: " + violation);
  r.seconds = seconds();
  return r;
}

}  // namespace mjsysid::design
