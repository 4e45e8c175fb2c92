#include "sysid/design/design_write.h"

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/text.h"
#include "mjsysid/version.h"
#include "sysid/io/atomic_file.h"

namespace mjsysid::design {
namespace {

std::string N(double x) { return FormatYamlNumber(x); }

// name: value for every parameter
void PerParameter(YAML::Emitter& out, const char* key, const DesignResult& r,
                  const Eigen::VectorXd& v) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  for (size_t j = 0; j < r.parameters.size(); ++j) {
    out << YAML::Key << r.parameters[j] << YAML::Value << N(v[static_cast<Eigen::Index>(j)]);
  }
  out << YAML::EndMap;
}

// the criteria and margins of one excitation
void Excitation(YAML::Emitter& out, const char* key, const DesignResult& r, const Evaluated& e) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "criteria" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "d_optimal" << YAML::Value << N(-e.info.log_det);
  out << YAML::Key << "worst_relative_std" << YAML::Value << N(e.info.worst_relative_std);
  out << YAML::Key << "condition_number" << YAML::Value << N(e.info.condition);
  out << YAML::EndMap;
  out << YAML::Key << "amplitude_scale" << YAML::Value << N(e.scale);
  out << YAML::Key << "peak" << YAML::Value << YAML::BeginMap;
  for (size_t i = 0; i < r.actuators.size(); ++i) {
    out << YAML::Key << r.actuators[i] << YAML::Value << N(e.margins.peak[i]);
  }
  out << YAML::EndMap;
  out << YAML::Key << "joint_range" << YAML::Value << YAML::BeginMap;
  for (const Margins::Joint& j : e.margins.joints) {
    out << YAML::Key << j.name << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "allowed" << YAML::Value << YAML::Flow << YAML::BeginSeq << N(j.lower)
        << N(j.upper) << YAML::EndSeq;
    out << YAML::Key << "reached" << YAML::Value << YAML::Flow << YAML::BeginSeq << N(j.min)
        << N(j.max) << YAML::EndSeq;
    out << YAML::Key << "margin" << YAML::Value << N(j.margin) << YAML::EndMap;
  }
  out << YAML::EndMap;
  out << YAML::Key << "max_joint_speed" << YAML::Value << N(e.margins.max_joint_speed);
  out << YAML::Key << "fastest_joint" << YAML::Value << e.margins.fastest_joint;
  out << YAML::Key << "steps_with_contact" << YAML::Value << e.margins.steps_with_contact;
  out << YAML::Key << "meets_constraints" << YAML::Value << e.violation.empty();
  if (!e.violation.empty()) out << YAML::Key << "violation" << YAML::Value << e.violation;
  out << YAML::EndMap;
}

}  // namespace

std::string ControlsCsv(const DesignResult& r) {
  std::string csv = "time";
  for (const std::string& a : r.actuators) csv += "," + a;
  csv += "\n";
  const RowMatrix& u = r.design.ctrl;
  for (Eigen::Index k = 0; k < u.rows(); ++k) {
    csv += FormatShortest(static_cast<double>(k) * r.timestep);
    for (Eigen::Index i = 0; i < u.cols(); ++i) csv += "," + FormatShortest(u(k, i));
    csv += "\n";
  }
  return csv;
}

std::string DesignYaml(const DesignResult& r, const std::string& experiment) {
  const DesignOptions& o = r.options;
  YAML::Emitter out;
  out.SetIndent(2);
  out << YAML::Comment("mjsysid excitation design (layout: docs/design.md)");
  out << YAML::BeginMap;
  out << YAML::Key << "generator" << YAML::Value
      << std::string("mjsysid ") + MJSYSID_VERSION + " design";
  out << YAML::Key << "mujoco_version" << YAML::Value << MujocoVersion();
  out << YAML::Key << "experiment" << YAML::Value << experiment;
  out << YAML::Key << "model" << YAML::Value << r.model_path;
  out << YAML::Key << "controls" << YAML::Value << "controls.csv";
  out << YAML::Key << "timestep" << YAML::Value << N(r.timestep);
  out << YAML::Key << "steps" << YAML::Value << r.steps;
  out << YAML::Key << "duration" << YAML::Value << N((r.steps - 1) * r.timestep);
  out << YAML::Key << "criterion" << YAML::Value << CriterionName(o.criterion);
  out << YAML::Key << "evaluated_at" << YAML::Value << (o.at_truth ? "truth" : "initial");
  out << YAML::Key << "basis" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << "fourier";
  out << YAML::Key << "base_frequency" << YAML::Value << N(o.basis.base_frequency);
  out << YAML::Key << "harmonics" << YAML::Value << o.basis.harmonics;
  out << YAML::Key << "ramp" << YAML::Value << N(o.basis.ramp) << YAML::EndMap;
  out << YAML::Key << "constraints" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "range_margin" << YAML::Value << N(o.range_margin);
  out << YAML::Key << "max_joint_speed" << YAML::Value
      << (o.max_joint_speed > 0 ? N(o.max_joint_speed) : std::string("none"));
  out << YAML::Key << "contacts" << YAML::Value << (o.contacts ? "allowed" : "forbidden");
  out << YAML::Key << "amplitude" << YAML::Value << YAML::BeginMap;
  for (size_t i = 0; i < r.actuators.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    out << YAML::Key << r.actuators[i] << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key
        << "centre" << YAML::Value << N(r.centre[k]) << YAML::Key << "limit" << YAML::Value
        << N(r.amplitude[k]) << YAML::EndMap;
  }
  out << YAML::EndMap << YAML::EndMap;
  PerParameter(out, "values", r, r.values);
  out << YAML::Key << "predicted_std" << YAML::Value << YAML::BeginMap;
  PerParameter(out, "current", r, r.current.info.std);
  PerParameter(out, "design", r, r.design.info.std);
  out << YAML::EndMap;
  out << YAML::Key << "relative_std" << YAML::Value << YAML::BeginMap;
  PerParameter(out, "current", r, r.current.info.relative_std);
  PerParameter(out, "design", r, r.design.info.relative_std);
  out << YAML::EndMap;
  Excitation(out, "current", r, r.current);
  Excitation(out, "design", r, r.design);
  out << YAML::Key << "search" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "evaluations" << YAML::Value << r.evaluations;
  out << YAML::Key << "feasible" << YAML::Value << r.feasible;
  out << YAML::Key << "stopped_by" << YAML::Value
      << (r.time_limited ? "time_limit" : "evaluations");
  out << YAML::Key << "seed" << YAML::Value << o.seed;
  out << YAML::Key << "seconds" << YAML::Value << N(r.seconds);
  out << YAML::Key << "coefficients" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (Eigen::Index v = 0; v < r.coefficients.size(); ++v) out << N(r.coefficients[v]);
  out << YAML::EndSeq << YAML::EndMap;
  out << YAML::EndMap;
  if (!out.good()) throw io::FileError("cannot format design.yaml: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

void CheckDesignOutputs(const std::string& dir, const io::ExperimentConfig& config) {
  std::vector<std::string> inputs = {config.source_file};
  for (const io::ModelSpec& m : config.models) inputs.push_back(m.path);
  for (const io::DataFile& d : config.data) inputs.push_back(d.path);
  for (const char* name : {"controls.csv", "design.yaml"}) {
    const std::filesystem::path out = std::filesystem::path(dir) / name;
    std::error_code ec;
    if (std::filesystem::is_directory(out, ec)) {
      throw std::invalid_argument(out.string() + " is a folder; sysid design writes a file there");
    }
    for (const std::string& in : inputs) {
      if (std::filesystem::exists(out, ec) && std::filesystem::equivalent(out, in, ec)) {
        throw std::invalid_argument(out.string() + " is an input of this run (" + in +
                                    "); write the design elsewhere");
      }
    }
  }
}

std::pair<std::string, std::string> WriteDesign(const DesignResult& r, const std::string& dir,
                                                const io::ExperimentConfig& config) {
  CheckDesignOutputs(dir, config);
  const std::string& experiment = config.source_file;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw io::FileError(dir + ": cannot create the folder: " + ec.message());
  const std::string csv = (std::filesystem::path(dir) / "controls.csv").string();
  const std::string yaml = (std::filesystem::path(dir) / "design.yaml").string();
  io::WriteFileAtomically(csv, ControlsCsv(r));
  io::WriteFileAtomically(yaml, DesignYaml(r, experiment));
  return {csv, yaml};
}

}  // namespace mjsysid::design
