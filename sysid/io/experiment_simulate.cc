// The experiment schema's `simulate` section and its excitation signals.
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
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io::experiment_internal {

namespace {

const std::vector<std::string> kExcitationTypes = {"sines", "chirp", "prbs", "zero", "file"};

}  // namespace

Excitation Parser::ParseExcitation(const Field& f, bool needs_actuator) const {
  const MapReader r(
      *this, f,
      {"actuator", "type", "amplitude", "frequencies", "f0", "f1", "switch_period", "path"});
  Excitation e;
  e.marks = r.marks();
  if (needs_actuator) {
    r.Require("actuator", "in a list, each excitation names its actuator");
  }
  if (r.Has("actuator")) e.actuator = Name(r.Get("actuator"));
  if (r.Has("type")) e.type = static_cast<ExcitationType>(Enum(r.Get("type"), kExcitationTypes));
  if (r.Has("amplitude")) e.amplitude = NonNegative(r.Get("amplitude"));
  if (r.Has("frequencies")) {
    const Field ff = r.Get("frequencies");
    e.frequencies.clear();
    for (const Field& item : List(ff)) e.frequencies.push_back(Positive(item));
    if (e.frequencies.empty() && e.type == ExcitationType::kSines) {
      Fail(ff.mark, ff.path + ": sines need at least one frequency");
    }
  }
  if (r.Has("f0")) e.f0 = Positive(r.Get("f0"));
  if (r.Has("f1")) e.f1 = Positive(r.Get("f1"));
  if (r.Has("switch_period")) e.switch_period = Positive(r.Get("switch_period"));
  // file: every actuator's control from a CSV (e.g. sysid design's controls.csv)
  if (e.type == ExcitationType::kFile) {
    if (needs_actuator) {
      Fail(r.marks().Of("type"), f.path + ": a `file` excitation gives every actuator's control",
           "use it as the single map: excitation: {type: file, path: controls.csv}");
    }
    r.Require("path", "a `file` excitation names its CSV of controls");
    e.path = ResolvePath(r.Get("path"));
  } else if (r.Has("path")) {
    Fail(r.marks().Of("path"), f.path + ".path: only a `file` excitation reads a path",
         "add type: file");
  }
  return e;
}

void Parser::ParseSimulate(const Field& f, const ExperimentConfig& c, SimulateOptions* s) const {
  const MapReader r(*this, f,
                    {"truth", "sequences", "steps", "seed", "excitation", "noise", "initial_state",
                     "sample_rate", "jitter", "drop"});
  s->marks = r.marks();
  const long long kIntMax = std::numeric_limits<int>::max();

  // truth: values of declared parameters and fitted control delays (parsed before)
  if (r.Has("truth")) {
    s->truth = NamedValues(r.Get("truth"));
    std::vector<std::string> names;
    for (const ParameterSpec& p : c.parameters) names.push_back(p.name);
    const size_t parameters = names.size();
    for (const ExperimentConfig::ControlDelaySpec& cd : c.control_delays) {
      if (cd.term.fit) names.push_back(FitControlDelay{cd.actuator}.Name());
    }
    const bool delays = names.size() > parameters;
    for (const NamedValue& t : s->truth) {
      if (!c.FindParameter(t.name) && !c.FindFittedControlDelay(t.name)) {
        // a delay's name (or an experiment with fitted delays) says that delays have truths too
        const bool say = delays || t.name.rfind("controls.delay", 0) == 0;
        Fail(t.mark,
             r.Path("truth") + ": " + Quote(t.name) + " is not a parameter" +
                 (say ? " nor a fitted control delay" : ""),
             NamesHint(t.name, names,
                       delays ? "parameters and fitted control delays" : "parameters"));
      }
    }
  }
  if (r.Has("sequences")) s->sequences = static_cast<int>(Integer(r.Get("sequences"), 1, kIntMax));
  if (r.Has("steps")) s->steps = static_cast<int>(Integer(r.Get("steps"), 1, kIntMax));
  if (r.Has("seed")) {
    s->seed = static_cast<std::uint64_t>(
        Integer(r.Get("seed"), 0, std::numeric_limits<long long>::max()));
  }

  // excitation: one map for all actuators, or a list with one map per actuator
  if (r.Has("excitation")) {
    const Field fe = r.Get("excitation");
    s->excitation.clear();
    if (fe.node.IsSequence()) {
      for (const Field& item : List(fe)) {
        Excitation e = ParseExcitation(item, true);
        for (const Excitation& seen : s->excitation) {
          if (seen.actuator == e.actuator) {
            Fail(e.marks.Of("actuator"), "duplicate excitation for actuator " + Quote(e.actuator),
                 "first given at line " + std::to_string(seen.marks.Of("actuator").line));
          }
        }
        s->excitation.push_back(std::move(e));
      }
      if (s->excitation.empty()) Fail(fe.mark, fe.path + ": the list is empty");
    } else {
      s->excitation.push_back(ParseExcitation(fe, false));
    }
  }

  // noise: sensor -> sigma
  if (r.Has("noise")) {
    s->noise = NamedValues(r.Get("noise"));
    for (const NamedValue& n : s->noise) {
      if (n.value < 0) {
        Fail(n.mark, r.Path("noise") + "." + n.name + ": a noise sigma must be >= 0, got " +
                         FormatNumber(n.value));
      }
    }
  }

  if (r.Has("initial_state")) {
    const MapReader is(*this, r.Get("initial_state"), {"qpos", "qvel"});
    s->initial_state.marks = is.marks();
    if (is.Has("qpos")) s->initial_state.qpos = Numbers(is.Get("qpos"));
    if (is.Has("qvel")) s->initial_state.qvel = Numbers(is.Get("qvel"));
  }

  // logged as a robot logs: sample rate (Hz), stamp jitter (s), fraction of rows dropped
  if (r.Has("sample_rate")) {
    const Field fr = r.Get("sample_rate");
    s->sample_rate = Finite(fr);
    if (s->sample_rate <= 0) {
      Fail(fr.mark, fr.path + ": a sample rate must be > 0 Hz, got " + FormatNumber(s->sample_rate),
           "leave it out for one sample per simulation step");
    }
  }
  if (r.Has("jitter")) {
    const Field fj = r.Get("jitter");
    s->jitter = Finite(fj);
    if (s->jitter < 0 || !r.Has("sample_rate") || s->jitter >= 0.5 / s->sample_rate) {
      Fail(fj.mark, fj.path + ": jitter must be >= 0 s and below half a sample period (it needs " +
                        r.Path("sample_rate") + "), got " + FormatNumber(s->jitter));
    }
  }
  if (r.Has("drop")) {
    const Field fd = r.Get("drop");
    s->drop = Finite(fd);
    if (s->drop < 0 || s->drop >= 0.5 || !r.Has("sample_rate")) {
      Fail(fd.mark, fd.path + ": drop is the fraction of rows dropped, 0 <= drop < 0.5 (it needs " +
                        r.Path("sample_rate") + "), got " + FormatNumber(s->drop));
    }
  }
}

}  // namespace mjsysid::io::experiment_internal
