#include "tools/report/logged.h"

#include <algorithm>
#include <exception>
#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/run/input_hashes.h"

namespace mjsysid::report {

const FitSequence* LoggedExperiment::Sequence(const std::string& name) const {
  for (const std::vector<FitSequence>* list : {&built.sequences, &built.validation}) {
    for (const FitSequence& s : *list) {
      if (s.name == name) return &s;
    }
  }
  return nullptr;
}

const mjModel* LoggedExperiment::ModelOf(const FitSequence& sequence) const {
  const auto at = std::find(built.model_names.begin(), built.model_names.end(), sequence.model);
  const auto i = static_cast<size_t>(at - built.model_names.begin());
  return i < built.models.size() ? built.models[i].get() : nullptr;
}

LoggedExperiment LoadLoggedExperiment(const io::FitResultFile& result) {
  LoggedExperiment out;
  if (result.experiment.empty()) {
    out.note = "the results name no experiment file";
    return out;
  }
  // the files as the fit read them (a gone file is left to the loading, which says so)
  if (!result.input_hashes.empty()) {
    std::vector<io::InputHash> now = run::HashAgain(result.input_hashes);
    for (size_t i = 0; i < now.size(); ++i) {
      if (now[i].sha256.empty()) now[i].sha256 = result.input_hashes[i].sha256;
    }
    std::string changes;
    for (const std::string& c : run::InputChanges(result.input_hashes, now)) {
      changes += (changes.empty() ? "" : "; ") + c;
    }
    if (!changes.empty()) {
      out.note = changes + " since the fit: the logs read now are not the fit's";
      return out;
    }
  }
  try {
    out.built = run::BuildProblem(io::LoadExperiment(result.experiment), 1);
  } catch (const std::exception& e) {
    out.note = std::string("the experiment could not be read again: ") + e.what();
  }
  return out;
}

LoggedInputs InputsOf(const LoggedExperiment& logged, const std::string& sequence) {
  LoggedInputs in;
  const FitSequence* s = logged.Sequence(sequence);
  const mjModel* m = s != nullptr ? logged.ModelOf(*s) : nullptr;
  if (m == nullptr || s->ctrl.rows() == 0 || s->ctrl.cols() != m->nu) return in;
  const Eigen::Index rows = s->ctrl.rows();
  // the controls' own times, else the samples', else the model's steps from the first state
  if (s->ctrl_time.size() == rows) {
    in.time = s->ctrl_time;
  } else if (s->time.size() == rows) {
    in.time = s->time;
  } else {
    in.time =
        s->x0.time + Eigen::VectorXd::LinSpaced(rows, 0, static_cast<double>(rows - 1)).array() *
                         m->opt.timestep;
  }
  in.ctrl = s->ctrl;
  for (int a = 0; a < m->nu; ++a) {
    const char* name = mj_id2name(m, mjOBJ_ACTUATOR, a);
    in.names.push_back(name != nullptr && *name != '\0' ? name : "actuator " + std::to_string(a));
    in.held.push_back(s->ctrl_hold.empty() ||
                      s->ctrl_hold[static_cast<size_t>(a)] == ControlHold::kZeroOrder);
  }
  return in;
}

}  // namespace mjsysid::report
