// mjsysid.design: `sysid design` from Python (sysid/design/design.h, docs/design.md). The search
// runs with the GIL released; the result is a dict of plain Python values and numpy arrays.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

#include "bindings.h"
#include "sysid/design/design.h"
#include "sysid/design/design_write.h"
#include "tools/report/design_page.h"

namespace mjsysid::python {
namespace {

using nb::arg;

// name -> value for every parameter
nb::dict PerParameter(const design::DesignResult& r, const Eigen::VectorXd& v) {
  nb::dict d;
  for (size_t j = 0; j < r.parameters.size(); ++j) {
    d[nb::str(r.parameters[j].c_str())] = v[static_cast<Eigen::Index>(j)];
  }
  return d;
}

// what one excitation tells and how it meets the constraints
nb::dict ExcitationDict(const design::DesignResult& r, const design::Evaluated& e) {
  nb::dict d;
  d["controls"] = e.ctrl;
  d["predicted_std"] = PerParameter(r, e.info.std);
  d["relative_std"] = PerParameter(r, e.info.relative_std);
  nb::dict criteria;
  criteria["d_optimal"] = -e.info.log_det;
  criteria["worst_relative_std"] = e.info.worst_relative_std;
  criteria["condition_number"] = e.info.condition;
  d["criteria"] = criteria;
  d["amplitude_scale"] = e.scale;
  nb::dict joints;
  for (const design::Margins::Joint& j : e.margins.joints) {
    nb::dict jd;
    jd["allowed"] = nb::make_tuple(j.lower, j.upper);
    jd["reached"] = nb::make_tuple(j.min, j.max);
    jd["margin"] = j.margin;
    joints[nb::str(j.name.c_str())] = jd;
  }
  d["joint_range"] = joints;
  d["max_joint_speed"] = e.margins.max_joint_speed;
  d["steps_with_contact"] = e.margins.steps_with_contact;
  d["meets_constraints"] = e.violation.empty();
  return d;
}

nb::dict Design(nb::handle experiment, std::optional<std::filesystem::path> out_path,
                double duration, const std::string& criterion, double base_frequency, int harmonics,
                double ramp, double range_margin, std::optional<double> max_joint_speed,
                bool contacts, int evaluations, double time_limit, unsigned long long seed,
                bool at_truth, int threads) {
  const io::ExperimentConfig config = ConfigOf(experiment);
  io::CheckModelFilesExist(config);
  const std::optional<std::string> out =
      out_path ? std::optional<std::string>(out_path->string()) : std::nullopt;
  design::DesignOptions o;
  if (!design::ParseCriterion(criterion, &o.criterion)) {
    throw std::invalid_argument("criterion: '" + criterion +
                                "' is not d_optimal, worst_relative_std or condition_number");
  }
  o.duration = duration;
  o.basis.base_frequency = base_frequency;
  o.basis.harmonics = harmonics;
  o.basis.ramp = ramp;
  o.range_margin = range_margin;
  o.max_joint_speed = max_joint_speed.value_or(0.0);
  if (max_joint_speed && !(*max_joint_speed > 0)) {
    throw std::invalid_argument("max_joint_speed: must be > 0 (None: no limit)");
  }
  o.contacts = contacts;
  o.evaluations = evaluations;
  o.time_limit = time_limit;
  o.seed = seed;
  o.at_truth = at_truth;
  o.threads = CheckedThreads(threads, "threads");
  if (out) design::CheckDesignOutputs(*out, config);

  design::DesignResult r;
  std::pair<std::string, std::string> files;
  std::string page;
  {
    nb::gil_scoped_release release;
    try {
      r = design::DesignExcitation(config, o);
    } catch (const design::DesignError& e) {
      throw std::invalid_argument(e.what());
    }
    if (out) {
      files = design::WriteDesign(r, *out, config);
      page = report::WriteDesignPage(r, config.source_file, *out);
    }
  }
  nb::dict d;
  d["parameters"] = r.parameters;
  d["actuators"] = r.actuators;
  d["values"] = PerParameter(r, r.values);
  d["timestep"] = r.timestep;
  Eigen::VectorXd time(r.steps);
  for (int k = 0; k < r.steps; ++k) time[k] = k * r.timestep;
  d["time"] = time;
  d["criterion"] = design::CriterionName(o.criterion);
  d["current"] = ExcitationDict(r, r.current);
  d["design"] = ExcitationDict(r, r.design);
  d["evaluations"] = r.evaluations;
  d["feasible"] = r.feasible;
  d["time_limited"] = r.time_limited;
  d["seconds"] = r.seconds;
  if (out) {
    nb::dict f;
    f["controls"] = files.first;
    f["design"] = files.second;
    f["page"] = page;
    d["files"] = f;
  } else {
    d["files"] = nb::none();
  }
  return d;
}

}  // namespace

void BindDesignApi(nb::module_& m) {
  const design::DesignOptions def;
  m.def("design", &Design, arg("experiment"), arg("out") = nb::none(), arg("duration") = 0.0,
        arg("criterion") = "d_optimal", arg("base_frequency") = def.basis.base_frequency,
        arg("harmonics") = def.basis.harmonics, arg("ramp") = def.basis.ramp,
        arg("range_margin") = def.range_margin, arg("max_joint_speed") = nb::none(),
        arg("contacts") = true, arg("evaluations") = def.evaluations,
        arg("time_limit") = def.time_limit, arg("seed") = def.seed, arg("at_truth") = false,
        arg("threads") = 0,
        "`sysid design`: an excitation for the experiment's parameters (docs/design.md).\n\n"
        "Searches per-actuator Fourier series under a smooth start and end for the most "
        "information (criterion: d_optimal, worst_relative_std or condition_number) within the "
        "amplitudes of simulate.excitation, the joint ranges shrunk by range_margin, "
        "max_joint_speed (None: no limit) and, with contacts=False, no contact. duration in s "
        "(0: simulate.steps x timestep). With out (a folder), writes out/controls.csv, "
        "out/design.yaml and out/design.html atomically. Returns a dict: parameters, actuators, "
        "values (where the "
        "information was computed), time, criterion, current and design (each: controls as a "
        "steps x nu array, predicted_std and relative_std per parameter, criteria, "
        "amplitude_scale, joint_range, max_joint_speed, steps_with_contact, "
        "meets_constraints), evaluations, feasible, time_limited (the time limit ended the "
        "search), seconds, files. Raises ValueError for bad "
        "arguments, a sensor without a sigma, or constraints no candidate meets.");
}

}  // namespace mjsysid::python
