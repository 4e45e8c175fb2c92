// HDF5 logs against a model: ValidateLogAgainstModel, and windows of a sequence (WindowOf).
#include "sysid/io/log.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/log_internal.h"
#include "sysid/io/time_base.h"

namespace mjsysid::io {

using namespace log_internal;  // NOLINT(build/namespaces): the log format's own internals

Sequence WindowOf(const Sequence& seq, double start, double end, const std::string& file) {
  Eigen::Index first = 0, last = seq.time.size();  // rows [first, last)
  while (first < last && seq.time[first] < start) ++first;
  while (last > first && seq.time[last - 1] > end) --last;
  const Eigen::Index n = last - first;
  if (n < 2) {
    Fail(file, "/" + seq.name + "/time",
         "the window [" + FormatDigits(start, 9) + ", " + FormatDigits(end, 9) + "] s holds " +
             std::to_string(n) + " sample(s) of " + FormatDigits(seq.time[0], 9) + " .. " +
             FormatDigits(seq.time[seq.time.size() - 1], 9) + " s: at least 2 are needed");
  }
  Sequence w = seq;
  w.time = seq.time.segment(first, n);
  // controls at their own times stay whole: the hold and a delay reach back before the window
  if (seq.ctrl_time.size() == 0) w.ctrl = seq.ctrl.middleRows(first, n);
  w.sensordata = seq.sensordata.middleRows(first, n);
  for (auto [from, to] :
       {std::pair{&seq.qpos, &w.qpos}, {&seq.qvel, &w.qvel}, {&seq.act, &w.act}}) {
    if (from->rows() > 0) *to = from->middleRows(first, n);
  }
  return w;
}

void ValidateLogAgainstModel(const Log& log, const mjModel& m, const std::string& path_for_messages,
                             std::vector<std::string>* warnings) {
  const std::string& file = path_for_messages;
  CheckLog(log, file);
  const auto nu = static_cast<Eigen::Index>(m.nu);
  const auto nsensor = static_cast<int>(m.nsensor);

  // the model's names, for matching and hints
  std::vector<std::string> model_sensors;
  for (int i = 0; i < nsensor; ++i) {
    const char* n = mj_id2name(&m, mjOBJ_SENSOR, i);
    if (n) model_sensors.push_back(n);
  }
  std::vector<std::string> model_actuators;
  for (Eigen::Index i = 0; i < nu; ++i) {
    const char* n = mj_id2name(&m, mjOBJ_ACTUATOR, static_cast<int>(i));
    model_actuators.push_back(n ? n : "");
  }
  auto display = [](const std::string& n) { return n.empty() ? std::string("<unnamed>") : n; };

  for (const Sequence& seq : log.sequences) {
    const std::string gpath = "/" + seq.name;

    // sensors: known names, matching dimensions, no repeats
    std::set<std::string> seen;
    for (size_t i = 0; i < seq.sensor_names.size(); ++i) {
      const std::string& name = seq.sensor_names[i];
      const int id = name.empty() ? -1 : mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
      if (id < 0) {
        Fail(file, gpath + "/sensordata",
             "unknown sensor " + internal::NameHint(name, model_sensors, "the model's sensors"));
      }
      if (m.sensor_dim[id] != seq.sensor_dims[i]) {
        Fail(file, gpath + "/sensordata",
             "sensor " + Quote(name) + " has " + std::to_string(seq.sensor_dims[i]) +
                 " columns in the log but dimension " + std::to_string(m.sensor_dim[id]) +
                 " in the model");
      }
      if (!seen.insert(name).second) {
        Fail(file, gpath + "/sensordata", "sensor " + Quote(name) + " appears twice");
      }
    }

    // actuators: exactly the model's, in model order
    if (seq.actuator_names != model_actuators) {
      const std::string where = gpath + "/ctrl";
      const std::string counts = seq.ctrl.cols() == nu
                                     ? std::string()
                                     : "ctrl has " + std::to_string(seq.ctrl.cols()) +
                                           " columns, the model has nu = " + std::to_string(nu) +
                                           " actuators; ";
      for (const std::string& name : seq.actuator_names) {
        if (std::find(model_actuators.begin(), model_actuators.end(), name) ==
            model_actuators.end()) {
          Fail(file, where,
               counts + "unknown actuator " +
                   internal::NameHint(name, model_actuators, "the model's actuators"));
        }
      }
      std::vector<std::string> missing;
      for (const std::string& name : model_actuators) {
        if (std::find(seq.actuator_names.begin(), seq.actuator_names.end(), name) ==
            seq.actuator_names.end()) {
          missing.push_back(Quote(display(name)));
        }
      }
      if (!missing.empty()) {
        Fail(file, where,
             counts + "missing actuator(s) " + Join(missing) +
                 " (ctrl needs one column per actuator of the model, in model order)");
      }
      std::vector<std::string> got, want;
      for (const std::string& n : seq.actuator_names) got.push_back(display(n));
      for (const std::string& n : model_actuators) want.push_back(display(n));
      Fail(file, where,
           "actuator columns [" + Join(got) + "] must be the model's actuators in model order [" +
               Join(want) + "]");
    }

    // states: model widths
    const std::tuple<const char*, const RowMatrix*, const char*, Eigen::Index> states[] = {
        {"qpos", &seq.qpos, "nq", static_cast<Eigen::Index>(m.nq)},
        {"qvel", &seq.qvel, "nv", static_cast<Eigen::Index>(m.nv)},
        {"act", &seq.act, "na", static_cast<Eigen::Index>(m.na)}};
    for (const auto& [name, mat, size_name, width] : states) {
      if (mat->rows() == 0 || mat->cols() == width) continue;
      Fail(file, gpath + "/" + name,
           "has " + std::to_string(mat->cols()) + " columns, the model has " + size_name + " = " +
               std::to_string(width));
    }

    // values not measured (NaN): a control needs a valid first value to hold, a sensor column at
    // least one measured sample
    for (Eigen::Index i = 0; i < seq.ctrl.cols(); ++i) {
      if (std::isnan(seq.ctrl(0, i))) {
        Fail(file, gpath + "/ctrl",
             "row 0, column " + std::to_string(i) + " (actuator " +
                 Quote(display(seq.actuator_names[i])) +
                 "): NaN in the first row: a NaN control is held from the last valid value, and "
                 "there is none before it (start the log at the first command)");
      }
    }
    for (Eigen::Index c = 0, i = 0, first = 0; c < seq.sensordata.cols(); ++c) {
      if (c == first + seq.sensor_dims[i]) first += seq.sensor_dims[i++];
      if (seq.sensordata.col(c).array().isNaN().all()) {
        Fail(file, gpath + "/sensordata",
             "column " + std::to_string(c) + " (sensor " + Quote(seq.sensor_names[i]) +
                 "): every value is NaN (not measured): nothing to fit; leave the sensor out");
      }
    }

    // the time base (sysid/io/time_base.h) of every time dataset: increasing, in seconds; its
    // warnings. The sample times and the controls' own times must overlap. With sensors at their
    // own times the union is checked for errors only (its period varies by construction) and
    // each time dataset as read gives the warnings.
    const double dt = m.opt.timestep;
    const Eigen::VectorXd* ctrl_time = seq.ctrl_time.size() ? &seq.ctrl_time : nullptr;
    const bool merged = !seq.own_times.empty();
    std::vector<std::string> found = CheckTimeBase(
        seq.time, dt, file,
        gpath + (merged ? " (sample times: the union of its time datasets)" : "/time"), ctrl_time);
    if (merged) {
      found.clear();
      for (const auto& [object, times] : seq.own_times) {
        for (std::string& w :
             CheckTimeBase(times, dt, file, object, nullptr, TimeDataset::kOwnTimes)) {
          found.push_back(std::move(w));
        }
      }
    }
    if (ctrl_time && ctrl_time->size() >= 2) {
      for (std::string& w : CheckTimeBase(*ctrl_time, dt, file, gpath + "/ctrl_time", nullptr,
                                          TimeDataset::kOwnTimes)) {
        found.push_back(std::move(w));
      }
    }
    for (std::string& w : found) {
      if (warnings) warnings->push_back(std::move(w));
    }
  }
}

}  // namespace mjsysid::io