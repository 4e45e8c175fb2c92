// mjsysid.fit(model, parameters, sequences, options=None, callback=None): the library API
// (sysid/problem.h) on Python data. The dicts are read into FitParameter / FitSequence /
// FitOptions; unknown keys and wrong shapes raise ValueError naming the key; everything else
// (names, bounds, shapes against the model) is checked by Problem as for a C++ caller.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings.h"
#include "core/mujoco_env.h"
#include "sysid/problem.h"

namespace mjsysid::python {
namespace {

using nb::arg;
using namespace nb::literals;

// the keys of `d` must be in `valid`; `what` names the dict in messages
void CheckKeys(const nb::dict& d, const std::set<std::string>& valid, const std::string& what) {
  for (auto [key, value] : d) {
    const std::string k = nb::cast<std::string>(nb::str(key));
    if (!valid.count(k)) {
      std::string list;
      for (const std::string& v : valid) list += (list.empty() ? "" : ", ") + v;
      throw std::invalid_argument(what + ": unknown key '" + k + "'; valid: " + list);
    }
  }
}

// d[key] converted to T, or `fallback` when absent; a wrong type names the key
template <typename T>
T Get(const nb::dict& d, const char* key, const T& fallback, const std::string& what) {
  if (!d.contains(key)) return fallback;
  try {
    return nb::cast<T>(d[key]);
  } catch (const nb::cast_error&) {
    throw std::invalid_argument(what + ": '" + key + "' has the wrong type (" +
                                nb::cast<std::string>(nb::str(nb::handle(d[key]).type())) + ")");
  }
}

// d[key] as a float64 matrix (a 1-D array is one column), or 0 x 0 when absent
RowMatrix GetMatrix(const nb::dict& d, const char* key, const std::string& what) {
  if (!d.contains(key)) return RowMatrix();
  nb::module_ np = nb::module_::import_("numpy");
  nb::object a = np.attr("asarray")(d[key], "dtype"_a = "float64");
  const int ndim = nb::cast<int>(a.attr("ndim"));
  if (ndim == 1) a = a.attr("reshape")(-1, 1);
  if (ndim != 1 && ndim != 2) {
    throw std::invalid_argument(what + ": '" + key + "' must be a 1-D or 2-D array, not " +
                                std::to_string(ndim) + "-D");
  }
  return nb::cast<RowMatrix>(np.attr("ascontiguousarray")(a));
}

// a 1-D vector (empty when absent)
Eigen::VectorXd GetVector(const nb::dict& d, const char* key, const std::string& what) {
  if (!d.contains(key)) return Eigen::VectorXd();
  nb::module_ np = nb::module_::import_("numpy");
  nb::object a = np.attr("ravel")(np.attr("asarray")(d[key], "dtype"_a = "float64"));
  try {
    return nb::cast<Eigen::VectorXd>(a);
  } catch (const nb::cast_error&) {
    throw std::invalid_argument(what + ": '" + key + "' is not a vector of numbers");
  }
}

FitParameter ParameterOf(const nb::dict& d, size_t i) {
  const std::string what = "parameters[" + std::to_string(i) + "]";
  CheckKeys(d,
            {"name", "kind", "object", "field", "index", "initial", "lower", "upper", "log",
             "scale", "prior", "models"},
            what);
  for (const char* key : {"name", "kind", "initial"}) {
    if (!d.contains(key)) throw std::invalid_argument(what + ": '" + key + "' is required");
  }
  FitParameter p;
  p.name = Get<std::string>(d, "name", "", what);
  p.target.kind = Get<std::string>(d, "kind", "", what);
  p.target.object = Get<std::string>(d, "object", "", what);
  p.target.field = Get<std::string>(d, "field", "", what);
  p.target.index = Get<int>(d, "index", 0, what);
  p.initial = Get<double>(d, "initial", 0, what);
  p.lower = Get<double>(d, "lower", p.lower, what);
  p.upper = Get<double>(d, "upper", p.upper, what);
  if (Get<bool>(d, "log", false, what)) p.transform = Transform::kLog;
  if (d.contains("scale")) {
    p.transform = Transform::kScale;
    p.scale = Get<double>(d, "scale", 1, what);
  }
  if (d.contains("prior")) {
    const auto prior = Get<std::vector<double>>(d, "prior", {}, what);
    if (prior.size() != 2) throw std::invalid_argument(what + ": 'prior' is [mean, sigma]");
    p.Prior(prior[0], prior[1]);
  }
  p.models = Get<std::vector<std::string>>(d, "models", {}, what);
  return p;
}

FitSequence SequenceOf(const nb::dict& d, size_t i) {
  const std::string what = "sequences[" + std::to_string(i) + "]";
  CheckKeys(d, {"name", "ctrl", "measured", "qpos", "qvel", "act", "time", "sensors"}, what);
  for (const char* key : {"ctrl", "measured"}) {
    if (!d.contains(key)) throw std::invalid_argument(what + ": '" + key + "' is required");
  }
  FitSequence s;
  s.name = Get<std::string>(d, "name", "seq" + std::to_string(i), what);
  s.model = "model";
  s.ctrl = GetMatrix(d, "ctrl", what);
  s.measured = GetMatrix(d, "measured", what);
  s.x0.qpos = GetVector(d, "qpos", what);
  s.x0.qvel = GetVector(d, "qvel", what);
  s.x0.act = GetVector(d, "act", what);
  s.time = GetVector(d, "time", what);
  if (s.time.size() > 0) s.x0.time = s.time[0];
  s.sensors = Get<std::vector<std::string>>(d, "sensors", {}, what);
  return s;
}

FitOptions OptionsOf(const nb::dict& d) {
  const std::string what = "options";
  CheckKeys(d,
            {"max_iterations", "function_tolerance", "gradient_tolerance", "parameter_tolerance",
             "threads", "loss", "loss_scale", "estimate_initial_state", "segment_steps",
             "continuity_weight", "sensor_weights", "sensor_sigmas", "verbose"},
            what);
  FitOptions o;
  o.max_iterations = Get<int>(d, "max_iterations", o.max_iterations, what);
  o.function_tolerance = Get<double>(d, "function_tolerance", o.function_tolerance, what);
  o.gradient_tolerance = Get<double>(d, "gradient_tolerance", o.gradient_tolerance, what);
  o.parameter_tolerance = Get<double>(d, "parameter_tolerance", o.parameter_tolerance, what);
  o.threads = Get<int>(d, "threads", o.threads, what);
  const std::string loss = Get<std::string>(d, "loss", LossTypeName(o.loss), what);
  bool known = false;
  for (LossType t : {LossType::kNone, LossType::kHuber, LossType::kCauchy}) {
    if (loss == LossTypeName(t)) {
      o.loss = t;
      known = true;
    }
  }
  if (!known) {
    throw std::invalid_argument("options: loss '" + loss + "': expected none, huber or cauchy");
  }
  o.loss_scale = Get<double>(d, "loss_scale", o.loss_scale, what);
  o.estimate_initial_state = Get<bool>(d, "estimate_initial_state", false, what);
  o.segment_steps = Get<int>(d, "segment_steps", o.segment_steps, what);
  o.continuity_weight = Get<double>(d, "continuity_weight", o.continuity_weight, what);
  o.sensor_weights = Get<std::map<std::string, double>>(d, "sensor_weights", {}, what);
  // a sigma is a weight 1/sigma that also enters the model_mismatch verdict (as in YAML)
  for (const auto& [sensor, sigma] :
       Get<std::map<std::string, double>>(d, "sensor_sigmas", {}, what)) {
    if (!(sigma > 0)) {
      throw std::invalid_argument("options: sensor_sigmas['" + sensor + "'] must be > 0");
    }
    o.sensor_weights[sensor] = 1.0 / sigma;
    o.sensors_with_sigma.push_back(sensor);
  }
  o.verbose = Get<bool>(d, "verbose", false, what);
  return o;
}

// model: a path to an MJCF/MJB file, or MJCF text (anything starting with '<')
ModelPtr ModelOf(const std::string& model) {
  const size_t first = model.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && model[first] == '<') return LoadModelFromString(model);
  return LoadModel(model);
}

FitResult Fit(const std::string& model, const nb::list& parameters, const nb::list& sequences,
              nb::object options, nb::object callback) {
  ModelPtr m = ModelOf(model);
  Problem problem;
  problem.AddModel("model", *m);
  for (size_t i = 0; i < nb::len(parameters); ++i) {
    if (!nb::isinstance<nb::dict>(parameters[i])) {
      throw std::invalid_argument("parameters[" + std::to_string(i) + "]: expected a dict");
    }
    problem.AddParameter(ParameterOf(nb::cast<nb::dict>(parameters[i]), i));
  }
  for (size_t i = 0; i < nb::len(sequences); ++i) {
    if (!nb::isinstance<nb::dict>(sequences[i])) {
      throw std::invalid_argument("sequences[" + std::to_string(i) + "]: expected a dict");
    }
    problem.AddSequence(SequenceOf(nb::cast<nb::dict>(sequences[i]), i));
  }
  FitOptions fit_options;
  if (!options.is_none()) {
    if (!nb::isinstance<nb::dict>(options)) throw std::invalid_argument("options: expected a dict");
    fit_options = OptionsOf(nb::cast<nb::dict>(options));
  }
  FitGuard guard(std::move(callback));
  fit_options.interrupt = guard.interrupt();
  fit_options.on_iteration = guard.OnIteration(nullptr);
  FitResult result;
  {
    nb::gil_scoped_release release;
    result = problem.Fit(fit_options);
  }
  guard.RaiseCallbackError();
  return result;
}

}  // namespace

void BindFitApi(nb::module_& m) {
  m.def("fit", &Fit, arg("model"), arg("parameters"), arg("sequences"), arg("options") = nb::none(),
        arg("callback") = nb::none(),
        "Fits a model's parameters to logged sequences (sysid/problem.h).\n\n"
        "model: an MJCF path or MJCF text. parameters: list of dicts {name, kind, object | "
        "field, index?, initial, lower?, upper?, log?, scale?, prior? [mean, sigma], models?}. "
        "sequences: list of dicts {ctrl (T x nu), measured (T x nsensordata, model order), "
        "qpos?, qvel?, act? (the initial state), time? (T), name?, sensors? (the fitted ones)}. "
        "options: dict {max_iterations, function_tolerance, gradient_tolerance, "
        "parameter_tolerance, threads, loss, loss_scale, estimate_initial_state, "
        "segment_steps, continuity_weight, sensor_weights, sensor_sigmas, verbose}. "
        "callback(IterationInfo) after every successful iteration. The GIL is released during "
        "the fit; Ctrl-C stops it after the current iteration (status interrupted).");
}

}  // namespace mjsysid::python
