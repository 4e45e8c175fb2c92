// The experiment schema's sections about the fit: parameters, measurement terms, solver,
// multiple shooting.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "core/thread_pool.h"
#include "sysid/io/experiment.h"
#include "sysid/io/experiment_internal.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io::experiment_internal {

namespace {

const std::vector<std::string> kParameterKeys = {"name",  "target",  "object", "field",
                                                 "index", "initial", "bounds", "transform",
                                                 "scale", "prior",   "models"};
const std::vector<std::string> kTransforms = {"none", "log", "scale"};
// in the order of core's JacobianMode
const std::vector<std::string> kJacobianModes = {"auto", "directional", "matrix", "whole_rollout"};
const std::vector<std::string> kDifferences = {"forward", "central"};
const std::vector<std::string> kLossTypes = {"none", "huber", "cauchy"};
// the choice of the global stage, the subset start and the timestep check
const std::vector<std::string> kAutoOff = {"auto", "off"};

}  // namespace

ParameterSpec Parser::ParseParameter(const Field& f, const ExperimentConfig& c) const {
  const MapReader r(*this, f, kParameterKeys);
  ParameterSpec p;
  p.marks = r.marks();
  r.Require("name");
  p.name = Name(r.Get("name"));
  p.target.label = p.name;
  r.Require("target", "one of: " + JoinNames(ParameterKindNames()));
  const ParameterKindInfo& info = ParameterKindTable()[Enum(r.Get("target"), ParameterKindNames())];
  const std::string kind = info.name;
  p.target.kind = kind;

  // object for the named kinds, field for `field`
  if (info.kind == ParameterKind::kField) {
    if (r.Has("object")) {
      Fail(r.KeyMark("object"), r.Path("object") + ": not used by target 'field'",
           "name the mjModel array in 'field' and the element in 'index'");
    }
    r.Require("field", "the name of an mjModel array, e.g. 'field: dof_damping'");
    p.target.field = Name(r.Get("field"));
  } else {
    if (r.Has("field")) {
      Fail(r.KeyMark("field"), r.Path("field") + ": only used by target 'field', not " + kind,
           "name the MuJoCo object in 'object'");
    }
    r.Require("object", std::string("the MuJoCo name of the ") + info.object_name() + " that '" +
                            kind + "' applies to");
    p.target.object = Name(r.Get("object"));
  }

  // component: core's model-free check (the kind's index range)
  if (r.Has("index")) {
    p.target.index = static_cast<int>(Integer(r.Get("index"), 0, std::numeric_limits<int>::max()));
  }
  try {
    CheckParameterSpec(p.target);
  } catch (const ParameterError& e) {
    throw ParameterErrorAt(p, e);
  }

  // value, bounds, transform
  r.Require("initial", "the starting value of the fit, or auto");
  const Field fi = r.Get("initial");
  // `auto`: the equation-error start (sysid/data/equation_error.h), decided by the fit; NaN until
  // then
  p.initial_auto = fi.node.IsScalar() && fi.node.Scalar() == "auto";
  p.initial = p.initial_auto ? std::numeric_limits<double>::quiet_NaN() : Finite(fi);
  if (r.Has("bounds")) {
    Bounds(r.Get("bounds"), &p.lower, &p.upper);
    if (!p.initial_auto && (p.initial < p.lower || p.initial > p.upper)) {
      Fail(fi.mark,
           fi.path + ": " + FormatNumber(p.initial) + " is outside bounds [" +
               FormatNumber(p.lower) + ", " + FormatNumber(p.upper) + "]",
           "the bounds are given at line " + std::to_string(r.Get("bounds").mark.line));
    }
  }
  if (r.Has("transform"))
    p.transform = static_cast<Transform>(Enum(r.Get("transform"), kTransforms));
  if (r.Has("scale")) p.scale = Positive(r.Get("scale"));
  if (p.transform == Transform::kLog) {
    const Field ft = r.Get("transform");
    if (std::isfinite(p.lower) && !(p.lower > 0)) {
      Fail(ft.mark, ft.path + ": log needs a lower bound > 0, got " + FormatNumber(p.lower),
           "raise the lower bound above 0, or use transform: none or scale");
    }
    if (!p.initial_auto && !(p.initial > 0)) {
      Fail(ft.mark, ft.path + ": log needs initial > 0, got " + FormatNumber(p.initial),
           "use transform: none or scale for parameters that can be <= 0");
    }
  }

  // prior
  if (r.Has("prior")) {
    const MapReader pr(*this, r.Get("prior"), {"mean", "sigma"});
    pr.Require("mean");
    pr.Require("sigma", "the prior's standard deviation, > 0");
    p.Prior(Finite(pr.Get("mean")), Positive(pr.Get("sigma")));
    p.prior_marks = pr.marks();
  }

  // models it applies to
  if (r.Has("models")) {
    std::vector<std::string> model_names;
    for (const ModelSpec& m : c.models) model_names.push_back(m.name);
    const std::vector<Field> items = List(r.Get("models"));
    if (items.empty()) {
      Fail(r.Get("models").mark, r.Path("models") + ": the list is empty",
           "leave 'models' out to apply the parameter to every model");
    }
    for (const Field& item : items) {
      const std::string name = Name(item);
      if (!c.FindModel(name)) {
        Fail(item.mark, item.path + ": unknown model " + Quote(name),
             NamesHint(name, model_names, "models"));
      }
      if (std::find(p.models.begin(), p.models.end(), name) != p.models.end()) {
        Fail(item.mark, item.path + ": model " + Quote(name) + " is listed twice");
      }
      p.models.push_back(name);
    }
  }
  return p;
}

void Parser::ParseTerm(const Field& f, bool is_delay, FitMeasurement::Term* term,
                       Marks* marks) const {
  const MapReader r(*this, f, {"initial", "fit", "bounds"});
  *marks = r.marks();
  if (r.Has("initial")) term->initial = Finite(r.Get("initial"));
  if (r.Has("fit")) term->fit = Bool(r.Get("fit"));
  if (r.Has("bounds")) {
    const Field fb = r.Get("bounds");
    Bounds(fb, &term->lower, &term->upper);
    if (is_delay && term->lower < 0) {
      Fail(fb.mark,
           fb.path + ": a delay cannot be negative, lower bound " + FormatNumber(term->lower),
           "delays are in seconds, >= 0");
    }
  }
  if (term->initial < term->lower || term->initial > term->upper) {
    const Mark& at = marks->Of("initial");
    Fail(at,
         r.Path("initial") + ": " + FormatNumber(term->initial) + " is outside bounds [" +
             FormatNumber(term->lower) + ", " + FormatNumber(term->upper) + "]",
         is_delay ? "delays are in seconds, >= 0" : "widen the bounds or change initial");
  }
}

MeasurementSpec Parser::ParseMeasurement(const Field& f, const ExperimentConfig& c) const {
  const MapReader r(*this, f, {"sensor", "delay", "gain", "bias"});
  MeasurementSpec ms;
  ms.marks = r.marks();
  r.Require("sensor");
  const Field fs = r.Get("sensor");
  ms.sensor = Name(fs);
  if (!c.sensors.empty()) {
    std::vector<std::string> names;
    for (const SensorSpec& s : c.sensors) names.push_back(s.name);
    if (std::find(names.begin(), names.end(), ms.sensor) == names.end()) {
      Fail(fs.mark, fs.path + ": sensor " + Quote(ms.sensor) + " is not in 'sensors'",
           NamesHint(ms.sensor, names, "sensors"));
    }
  }
  if (r.Has("delay")) ParseTerm(r.Get("delay"), true, &ms.delay, &ms.delay_marks);
  if (r.Has("gain")) ParseTerm(r.Get("gain"), false, &ms.gain, &ms.gain_marks);
  if (r.Has("bias")) ParseTerm(r.Get("bias"), false, &ms.bias, &ms.bias_marks);
  return ms;
}

void Parser::ParseSolver(const Field& f, ExperimentConfig* c) const {
  const MapReader r(
      *this, f,
      {"max_iterations", "function_tolerance", "gradient_tolerance", "parameter_tolerance",
       "jacobian", "differences", "relative_step", "threads", "loss", "verbose", "starts", "seed",
       "reduce_model", "gauss_newton_stop", "memory_limit_gb", "global", "global_budget",
       "timestep_check", "subset_start"});
  c->solver_marks = r.marks();
  FitOptions* o = &c->options;
  const long long kIntMax = std::numeric_limits<int>::max();
  if (r.Has("max_iterations")) {
    o->max_iterations = static_cast<int>(Integer(r.Get("max_iterations"), 1, kIntMax));
  }
  if (r.Has("function_tolerance")) o->function_tolerance = NonNegative(r.Get("function_tolerance"));
  if (r.Has("gradient_tolerance")) o->gradient_tolerance = NonNegative(r.Get("gradient_tolerance"));
  if (r.Has("parameter_tolerance")) {
    o->parameter_tolerance = NonNegative(r.Get("parameter_tolerance"));
  }
  if (r.Has("jacobian")) {
    o->jacobian.mode = static_cast<JacobianMode>(Enum(r.Get("jacobian"), kJacobianModes));
  }
  if (r.Has("differences")) o->jacobian.central = Enum(r.Get("differences"), kDifferences) == 1;
  if (r.Has("relative_step")) o->jacobian.relative_step = Positive(r.Get("relative_step"));
  if (r.Has("threads")) {
    // one bound for threads everywhere (core/thread_pool.h kMaxThreads)
    const Field t = r.Get("threads");
    const long long n = Integer(t, 0, std::numeric_limits<long long>::max());
    if (!ThreadRequestError(n).empty()) {
      Fail(t.mark, t.path + ": " + ThreadRequestError(n),
           "0 uses every core; more threads than cores only share them");
    }
    o->threads = static_cast<int>(n);
  }
  // the fit's memory limit (sysid/fit/memory_estimate.h), GB; absent: a share of the machine's
  if (r.Has("memory_limit_gb")) c->memory_limit_gb = Positive(r.Get("memory_limit_gb"));
  if (r.Has("loss")) {
    const MapReader l(*this, r.Get("loss"), {"type", "scale"});
    if (l.Has("type")) o->loss = static_cast<LossType>(Enum(l.Get("type"), kLossTypes));
    if (l.Has("scale")) o->loss_scale = Positive(l.Get("scale"));
  }
  if (r.Has("verbose")) o->verbose = Bool(r.Get("verbose"));
  // the reduced model (core/reduced_model.h)
  if (r.Has("reduce_model")) o->reduce_model = Bool(r.Get("reduce_model"));
  // the statistical stop (sysid/solve/gn_convergence.h): a fraction of a standard error, 0 = off
  if (r.Has("gauss_newton_stop")) {
    o->gauss_newton_stop = NonNegative(r.Get("gauss_newton_stop"));
  }
  // the global stage (sysid/fit/global_stage.h): auto | off, and its budget in local fits
  if (r.Has("global")) o->global_stage = Enum(r.Get("global"), kAutoOff) == 0;
  if (r.Has("global_budget")) o->global_budget = Positive(r.Get("global_budget"));
  // the subset start (sysid/fit/subset_start.h): auto | off
  if (r.Has("subset_start")) o->subset_start = Enum(r.Get("subset_start"), kAutoOff) == 0;
  // the timestep check (sysid/fit/timestep_check.h): auto | off
  if (r.Has("timestep_check")) {
    o->timestep_check = Enum(r.Get("timestep_check"), kAutoOff) == 0;
  }
  // multi-start (sysid/run/multi_start.h)
  if (r.Has("starts")) c->starts = static_cast<int>(Integer(r.Get("starts"), 1, 10000));
  if (r.Has("seed")) {
    c->start_seed = static_cast<std::uint64_t>(
        Integer(r.Get("seed"), 0, std::numeric_limits<long long>::max()));
  }
}

// multiple_shooting: auto (also when absent), or {segment_steps: auto|0|N, continuity_weight,
// continuity_scale, jumping_sensors, event_window, hold_states_first}
void Parser::ParseMultipleShooting(const Field& f, ExperimentConfig* c) const {
  auto segment_steps = [&](const Field& steps) {
    if (steps.node.IsScalar() && steps.node.Scalar() == "auto") return -1;
    return static_cast<int>(Integer(steps, 0, std::numeric_limits<int>::max()));
  };
  if (f.node.IsScalar()) {
    if (f.node.Scalar() != "auto") {
      Fail(f.mark, f.path + ": expected 'auto' or a map, got " + Quote(f.node.Scalar()),
           "multiple_shooting: auto, or {segment_steps: auto|0|N, continuity_weight: w}");
    }
    c->options.segment_steps = -1;
  } else {
    const MapReader s(*this, f,
                      {"segment_steps", "continuity_weight", "continuity_scale", "jumping_sensors",
                       "event_window", "hold_states_first"});
    if (s.Has("segment_steps")) c->options.segment_steps = segment_steps(s.Get("segment_steps"));
    if (s.Has("continuity_weight")) {
      c->options.continuity_weight = Positive(s.Get("continuity_weight"));
    }
    // continuity_scale: relative (the default: to the sensors) or absolute
    if (s.Has("continuity_scale")) {
      const Field g = s.Get("continuity_scale");
      const std::string v = g.node.IsScalar() ? g.node.Scalar() : "";
      if (v != "relative" && v != "absolute") {
        Fail(g.mark, g.path + ": expected 'relative' or 'absolute', got " + Quote(v),
             "multiple_shooting: {continuity_scale: relative|absolute}");
      }
      c->options.continuity_relative = v == "relative";
    }
    // jumping_sensors: omit (the default: left out under auto's contact segments) or fit
    if (s.Has("jumping_sensors")) {
      const Field g = s.Get("jumping_sensors");
      const std::string v = g.node.IsScalar() ? g.node.Scalar() : "";
      if (v != "omit" && v != "fit") {
        Fail(g.mark, g.path + ": expected 'omit' or 'fit', got " + Quote(v),
             "multiple_shooting: {jumping_sensors: omit|fit}");
      }
      c->options.fit_jumping_sensors = v == "fit";
    }
    // event_window: samples either side of a contact event left out (sysid/data/event_windows.h)
    if (s.Has("event_window")) {
      c->options.event_window = static_cast<int>(Integer(s.Get("event_window"), 0, 1000));
    }
    // hold_states_first: auto's contact segments start with their states held on the data
    if (s.Has("hold_states_first")) {
      const Field g = s.Get("hold_states_first");
      const std::string v = g.node.IsScalar() ? g.node.Scalar() : "";
      if (v != "true" && v != "false") {
        Fail(g.mark, g.path + ": expected true or false, got " + Quote(v),
             "multiple_shooting: {hold_states_first: true|false}");
      }
      c->options.hold_states_first = v == "true";
    }
  }
}

}  // namespace mjsysid::io::experiment_internal
