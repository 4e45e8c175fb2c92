// Internal to sysid/io/experiment*.cc: the parser of the experiment schema
// (docs/experiment-schema.md). Its root and the public API are in experiment.cc; its sections in
// experiment_data.cc (models, data, sequences, sensors, controls, states), experiment_fit.cc
// (parameters, measurement, solver, multiple shooting) and experiment_simulate.cc (simulate,
// excitation).
#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io::experiment_internal {

// The experiment schema (docs/experiment-schema.md) on top of the YAML reader.
class Parser : public YamlReader {
 public:
  // file: as named in marks; base_dir: for relative paths; default_name: when `name` is absent
  Parser(std::string file, std::filesystem::path base_dir, std::string default_name)
      : YamlReader(std::move(file), std::move(base_dir)), default_name_(std::move(default_name)) {}

  ExperimentConfig Parse(const YAML::Node& root);

 private:
  // a map of arbitrary names to finite numbers, in file order
  std::vector<NamedValue> NamedValues(const Field& f) const;
  void ParseModels(const MapReader& root, ExperimentConfig* c) const;
  void ParseData(const Field& f, ExperimentConfig* c) const;
  // `sequences:` (into c->sequences) or `validation:` (into c->validation): "seq" or "model/seq"
  void ParseSequences(const Field& f, ExperimentConfig* c,
                      std::vector<SequenceRef> ExperimentConfig::*into) const;
  void ParseSensors(const Field& f, ExperimentConfig* c) const;
  ParameterSpec ParseParameter(const Field& f, const ExperimentConfig& c) const;
  MeasurementSpec ParseMeasurement(const Field& f, const ExperimentConfig& c) const;
  void ParseTerm(const Field& f, bool is_delay, FitMeasurement::Term* term, Marks* marks) const;
  void ParseControls(const Field& f, ExperimentConfig* c) const;
  void ParseSolver(const Field& f, ExperimentConfig* c) const;
  void ParseMultipleShooting(const Field& f, ExperimentConfig* c) const;
  void ParseStates(const Field& f, ExperimentConfig* c) const;
  void ParseSimulate(const Field& f, const ExperimentConfig& c, SimulateOptions* s) const;
  Excitation ParseExcitation(const Field& f, bool needs_actuator) const;

  std::string default_name_;
};

}  // namespace mjsysid::io::experiment_internal
