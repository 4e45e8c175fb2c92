// The experiment schema's sections about the data: models, data, sequences, sensors, controls,
// states.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/experiment.h"
#include "sysid/io/experiment_internal.h"
#include "sysid/io/plain_name.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io::experiment_internal {

namespace {

// in the order of ControlHold
const std::vector<std::string> kControlHolds = {"zoh", "linear"};
// ControlBefore's order
const std::vector<std::string> kControlBefore = {"hold", "zero"};

}  // namespace

void Parser::ParseModels(const MapReader& r, ExperimentConfig* c) const {
  const std::string hint =
      "give 'model: path/to/model.xml', or 'models:' as a list of {name, path}";
  if (r.Has("model") && r.Has("models")) {
    Fail(r.KeyMark("models"), "both 'model' and 'models' are given", "keep one: " + hint);
  }
  if (!r.Has("model") && !r.Has("models")) {
    Fail(c->marks.self, "missing required key 'model' (or 'models') in the experiment (top level)",
         hint);
  }
  if (r.Has("model")) {
    const Field f = r.Get("model");
    ModelSpec spec;
    spec.path = ResolvePath(f);
    spec.name = std::filesystem::path(spec.path).stem().string();
    spec.marks.self = f.mark;
    if (const std::string why = PlainNameProblem(spec.name); !why.empty()) {
      Fail(f.mark,
           "model: the file name gives the model name " + Quote(spec.name) +
               ", not a plain name: " + why,
           std::string("a model's name names its file NAME_identified.xml in the result "
                       "folder; rename the file, or give 'models:' with a name that is ") +
               kPlainNameRule);
    }
    c->models.push_back(std::move(spec));
    return;
  }
  c->model_list = true;
  const std::vector<Field> items = List(r.Get("models"));
  if (items.empty()) Fail(r.Get("models").mark, "models: the list is empty", hint);
  for (const Field& item : items) {
    const MapReader m(*this, item, {"name", "path"});
    m.Require("name");
    m.Require("path");
    ModelSpec spec;
    spec.name = Name(m.Get("name"));
    spec.path = ResolvePath(m.Get("path"));
    spec.marks = m.marks();
    if (const std::string why = PlainNameProblem(spec.name); !why.empty()) {
      Fail(m.KeyMark("name"),
           m.Path("name") + ": " + Quote(spec.name) + " is not a plain name: " + why,
           std::string("a model's name names its file NAME_identified.xml in the result folder "
                       "('/' also separates model and sequence in 'sequences'); give ") +
               kPlainNameRule);
    }
    if (const ModelSpec* first = c->FindModel(spec.name)) {
      Fail(m.Get("name").mark, "duplicate model name " + Quote(spec.name),
           "first defined at line " + std::to_string(first->marks.Of("name").line));
    }
    c->models.push_back(std::move(spec));
  }
}

void Parser::ParseData(const Field& f, ExperimentConfig* c) const {
  std::vector<Field> items;
  if (f.node.IsScalar()) {
    items.push_back(f);
  } else if (f.node.IsSequence()) {
    items = List(f);
  } else {
    Fail(f.mark,
         f.path + ": expected a file name or a list of file names, got " + Describe(f.node));
  }
  for (const Field& item : items) c->data.push_back(DataFile{ResolvePath(item), item.mark});
}

void Parser::ParseSequences(const Field& f, ExperimentConfig* c,
                            std::vector<SequenceRef> ExperimentConfig::*into) const {
  std::vector<std::string> model_names;
  for (const ModelSpec& m : c->models) model_names.push_back(m.name);
  for (const Field& item : List(f)) {
    SequenceRef ref;
    // a name, or {name, start, end}: a window of the sequence (seconds)
    Field name_field = item;
    if (!item.node.IsScalar()) {
      const MapReader window(*this, item, {"name", "start", "end"});
      window.Require("name");
      name_field = window.Get("name");
      if (window.Has("start")) ref.start = Finite(window.Get("start"));
      if (window.Has("end")) ref.end = Finite(window.Get("end"));
      if (!(ref.start < ref.end)) {
        Fail(item.mark, item.path + ": the window's start must be before its end",
             "start and end are times in seconds on the log's clock");
      }
    }
    ref.name = Name(name_field);
    ref.mark = name_field.mark;
    const size_t slash = ref.name.find('/');
    if (c->models.size() > 1 && slash != std::string::npos) {
      ref.model = ref.name.substr(0, slash);
      ref.name = ref.name.substr(slash + 1);
      if (!c->FindModel(ref.model)) {
        Fail(item.mark,
             item.path + ": unknown model " + Quote(ref.model) + " in " +
                 Quote(name_field.node.Scalar()),
             NamesHint(ref.model, model_names, "models"));
      }
      if (ref.name.empty()) Fail(item.mark, item.path + ": the sequence name is empty");
    }
    for (const SequenceRef& seen : c->*into) {
      if (seen.model == ref.model && seen.name == ref.name) {
        Fail(item.mark, "duplicate sequence " + Quote(name_field.node.Scalar()),
             "first given at line " + std::to_string(seen.mark.line));
      }
    }
    (c->*into).push_back(std::move(ref));
  }
}

void Parser::ParseSensors(const Field& f, ExperimentConfig* c) const {
  for (const Field& item : List(f)) {
    SensorSpec s;
    if (item.node.IsScalar()) {
      // a bare name: weight 1
      s.name = Name(item);
      s.marks.self = item.mark;
      s.marks.keys["name"] = item.mark;
    } else {
      const MapReader m(*this, item, {"name", "sigma", "weight"});
      m.Require("name");
      s.name = Name(m.Get("name"));
      s.marks = m.marks();
      if (m.Has("sigma") && m.Has("weight")) {
        Fail(m.KeyMark("weight"), item.path + ": give either 'sigma' or 'weight', not both",
             "weight = 1 / sigma");
      }
      if (m.Has("sigma")) {
        // a number, or auto: the noise estimated from the log at the fit's start
        const Field sigma = m.Get("sigma");
        if (sigma.node.IsScalar() && sigma.node.Scalar() == "auto") {
          s.sigma_from_log = true;
        } else if (Describe(sigma.node).rfind("the number", 0) != 0) {
          Fail(sigma.mark,
               sigma.path + ": expected a number > 0 or auto, got " + Describe(sigma.node),
               "the sensor's noise standard deviation, or auto (estimated from the log)");
        } else {
          s.sigma = Positive(sigma);
        }
      }
      if (m.Has("weight")) s.weight = Positive(m.Get("weight"));
    }
    for (const SensorSpec& seen : c->sensors) {
      if (seen.name == s.name) {
        Fail(s.marks.Of("name"), "duplicate sensor " + Quote(s.name),
             "first given at line " + std::to_string(seen.marks.Of("name").line));
      }
    }
    c->sensors.push_back(std::move(s));
  }
}

// controls: {hold: zoh|linear | {<actuator>: zoh|linear}, delay: s | {initial, fit, bounds} |
// {<actuator>: s | {initial, fit, bounds}}}; a map with any of initial/fit/bounds is one delay
// for every actuator, any other map names actuators (checked against the model later)
void Parser::ParseControls(const Field& f, ExperimentConfig* c) const {
  const MapReader s(*this, f, {"hold", "delay", "before"});
  if (s.Has("before"))
    c->control_before = static_cast<ControlBefore>(Enum(s.Get("before"), kControlBefore));
  // the entries of an actuator-keyed map, in file order, each name once
  auto by_actuator = [&](const Field& m, auto&& each) {
    std::vector<std::string> seen;
    for (auto it = m.node.begin(); it != m.node.end(); ++it) {
      const Mark key_mark = At(it->first, m.mark);
      const std::string name = it->first.IsScalar() ? it->first.Scalar() : "";
      if (name.empty()) Fail(key_mark, m.path + ": expected actuator names as keys");
      if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
        Fail(key_mark, m.path + ": actuator " + Quote(name) + " given twice");
      }
      seen.push_back(name);
      each(name, key_mark, Field{it->second, At(it->second, key_mark), m.path + "." + name});
    }
  };
  if (s.Has("hold")) {
    const Field fh = s.Get("hold");
    if (fh.node.IsMap()) {
      by_actuator(fh, [&](const std::string& name, const Mark& key, const Field& value) {
        c->control_holds.emplace_back(name, static_cast<ControlHold>(Enum(value, kControlHolds)));
        c->control_hold_marks.push_back(key);
      });
    } else {
      c->control_hold = static_cast<ControlHold>(Enum(fh, kControlHolds));
    }
  }
  if (!s.Has("delay")) return;
  const Field fd = s.Get("delay");
  if (!fd.node.IsMap()) {
    c->control_delay = NonNegative(fd);
    return;
  }
  // one term: a number (given) or {initial, fit, bounds}
  auto term = [&](const Field& value, ExperimentConfig::ControlDelaySpec* spec) {
    if (value.node.IsMap()) {
      ParseTerm(value, true, &spec->term, &spec->marks);
    } else {
      spec->term.initial = NonNegative(value);
    }
  };
  const bool shared =
      fd.node["initial"].IsDefined() || fd.node["fit"].IsDefined() || fd.node["bounds"].IsDefined();
  if (shared) {
    ExperimentConfig::ControlDelaySpec spec;
    spec.mark = fd.mark;
    term(fd, &spec);
    if (!spec.term.fit) {
      c->control_delay = spec.term.initial;  // given: the plain shared delay
      return;
    }
    c->control_delays.push_back(std::move(spec));
    return;
  }
  by_actuator(fd, [&](const std::string& name, const Mark& key, const Field& value) {
    ExperimentConfig::ControlDelaySpec spec;
    spec.actuator = name;
    spec.mark = key;
    term(value, &spec);
    c->control_delays.push_back(std::move(spec));
  });
}

// states: {qpos: {sigma, joints}, qvel: {sigma, joints}, act: {sigma, actuators}}; sigma a
// positive number (shared) or a list with one per name (then the names must be given); marks
// under "<part>", "<part>.sigma" and "<part>.<joints|actuators>[i]"
void Parser::ParseStates(const Field& f, ExperimentConfig* c) const {
  const MapReader r(*this, f, {"qpos", "qvel", "act"});
  c->states_marks = r.marks();
  FitStates& st = c->options.states;
  FitStates::Part* parts[3] = {&st.qpos, &st.qvel, &st.act};
  const char* names[3] = {"qpos", "qvel", "act"};
  for (int i = 0; i < 3; ++i) {
    if (!r.Has(names[i])) continue;
    const std::string objects = i == 2 ? "actuators" : "joints";
    const MapReader pr(*this, r.Get(names[i]), {"sigma", objects});
    pr.Require("sigma", "the noise level of the logged " + std::string(names[i]) +
                            ": one positive number, or a list with one per name in '" + objects +
                            "'");
    FitStates::Part& part = *parts[i];
    part.fit = true;
    const std::string at = std::string(names[i]) + ".";
    c->states_marks.keys[at + "sigma"] = pr.Get("sigma").mark;
    if (pr.Has(objects)) {
      const std::vector<Field> items = List(pr.Get(objects));
      for (size_t k = 0; k < items.size(); ++k) {
        part.names.push_back(Name(items[k]));
        for (size_t j = 0; j < k; ++j) {
          if (part.names[j] == part.names[k]) {
            Fail(items[k].mark, items[k].path + ": " + Quote(part.names[k]) + " given twice");
          }
        }
        c->states_marks.keys[at + objects + "[" + std::to_string(k) + "]"] = items[k].mark;
      }
      if (items.empty()) {
        Fail(pr.Get(objects).mark, pr.Path(objects) + " is empty",
             "leave it out to fit every one of the model's " + objects);
      }
    }
    const Field sigma = pr.Get("sigma");
    if (sigma.node.IsSequence()) {
      for (const Field& item : List(sigma)) part.sigma.push_back(Positive(item));
      if (part.sigma.size() != part.names.size()) {
        Fail(sigma.mark,
             sigma.path + " has " + std::to_string(part.sigma.size()) + " values for " +
                 std::to_string(part.names.size()) + " " + objects,
             "give one sigma per entry of '" + objects + "', or one number for all");
      }
    } else {
      part.sigma.push_back(Positive(sigma));
    }
  }
}

}  // namespace mjsysid::io::experiment_internal
