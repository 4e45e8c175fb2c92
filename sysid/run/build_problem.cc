// run::BuildProblem (sysid/run/fit_experiment.h): an experiment's models and logs checked against
// each other and the config, and mapped onto a Problem. The stages below run in the order
// BuildProblem calls them; the first bad input throws.
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>
#include <thread>
#include <tuple>

#include "core/text.h"
#include "sysid/fit/sigma_from_log.h"
#include "sysid/io/log.h"
#include "sysid/io/sequence_models.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/output_folder.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;

// the range of solver.relative_step that can give a derivative
constexpr double kMinRelativeStep = 1e-13;
constexpr double kMaxRelativeStep = 0.1;

// Models: takes the experiment; gives out's models (as loaded) and their names, each checked
// against the config (every parameter resolved) and added to the problem.
void LoadModels(const io::ExperimentConfig& cfg, BuiltProblem* out) {
  io::CheckModelFilesExist(cfg);
  for (const io::ModelSpec& ms : cfg.models) {
    ModelPtr m = LoadModel(ms.path);
    io::ValidateExperimentAgainstModel(cfg, *m, ms.name);  // resolves every parameter
    out->problem->AddModel(ms.name, *m);
    out->model_names.push_back(ms.name);
    out->models.push_back(std::move(m));
  }
}

// Settings: takes the experiment; throws for the settings a fit cannot work with: a
// finite-difference step that overflows or vanishes in rounding, two parameters of one model
// writing the same quantity.
void CheckFitSettings(const io::ExperimentConfig& cfg) {
  const double h = cfg.options.jacobian.relative_step;
  if (!(h >= kMinRelativeStep && h <= kMaxRelativeStep)) {
    throw io::ConfigError(
        cfg.solver_marks.Of("relative_step"),
        "solver.relative_step: " + FormatDigits(h, 6) + " cannot work as a finite-difference step",
        "between " + FormatDigits(kMinRelativeStep, 6) + " (below, p + h rounds to p) and " +
            FormatDigits(kMaxRelativeStep, 6) +
            " (above, the difference is no derivative); default 1e-6");
  }
  for (const io::ModelSpec& ms : cfg.models) {
    const std::vector<const io::ParameterSpec*> ps = cfg.ParametersOf(ms.name);
    for (size_t j = 0; j < ps.size(); ++j) {
      for (size_t i = 0; i < j; ++i) {
        const ParameterSpec& a = ps[i]->target;
        const ParameterSpec& b = ps[j]->target;
        if (a.kind == b.kind && a.object == b.object && a.field == b.field && a.index == b.index) {
          throw io::ConfigError(ps[j]->marks.self,
                                "parameters '" + ps[i]->name + "' and '" + ps[j]->name +
                                    "' both write " + a.kind + " " +
                                    (a.object.empty() ? a.field : a.object) + "[" +
                                    std::to_string(a.index) + "] of model '" + ms.name + "'",
                                "fit each model quantity with one parameter");
        }
      }
    }
  }
}

// Fitted values: takes the experiment; gives the parameters, the measurement terms and the fitted
// control delays (experiment `controls.delay` with fit: true), each added to the problem and
// recorded in out in the order added.
void AddFittedValues(const io::ExperimentConfig& cfg, BuiltProblem* out) {
  for (const FitParameter& p : cfg.parameters) {
    out->problem->AddParameter(p);
    out->parameters.push_back(p);
  }
  for (const FitMeasurement& me : cfg.measurement) {
    out->problem->AddMeasurement(me);
    out->measurements.push_back(me);
  }
  for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
    if (!cd.term.fit) continue;
    FitControlDelay d;
    d.actuator = cd.actuator;
    d.initial = cd.term.initial;
    d.lower = cd.term.lower;
    d.upper = cd.term.upper;
    out->problem->AddControlDelay(d);
    out->control_delays.push_back(d);
  }
}

// what the logs' sequences are checked against after the last log: the `sequences:` and
// `validation:` entries that named a group, and every group name seen
struct SequenceSelection {
  // `validation:` entries are assigned to models by the same rule as `sequences:` entries
  io::ExperimentConfig held_out_cfg;
  std::vector<bool> entry_used;
  std::vector<bool> held_out_used;
  std::vector<std::string> all_groups;
};

// the sequences of one log that belong to one model, in the order assigned, each marked held out
// (a `validation:` sequence) or fitted
struct ModelSequences {
  io::Log log;
  std::vector<bool> held_out;
};

// Assignment: takes one log (read from path); gives its selected sequences per model, each once.
// The held-out sequences first, with their model: they are taken out of the fitted selection
// (without `sequences:` every sequence of the log is selected, the held-out ones too). Throws for a
// sequence that entries of both `sequences:` and `validation:` name.
std::vector<ModelSequences> AssignToModels(const io::ExperimentConfig& cfg, const io::Log& log,
                                           const std::string& path, SequenceSelection* sel) {
  std::vector<bool> held_out(log.sequences.size(), false);
  std::vector<io::SequenceOwner> owners;
  if (!cfg.validation.empty()) {
    owners = io::AssignSequences(sel->held_out_cfg, log, path, &sel->held_out_used);
    for (const io::SequenceOwner& o : owners) held_out[o.sequence] = true;
  }
  for (const io::SequenceOwner& o : io::AssignSequences(cfg, log, path, &sel->entry_used)) {
    // an entry of each list names it (e.g. `sequences: [runA:seq0]`, `validation: [seq0]`)
    if (held_out[o.sequence] && !cfg.sequences.empty()) {
      throw io::LogError(path + ": /" + log.sequences[o.sequence].name +
                         ": is named by `sequences:` and by `validation:`: a validation sequence "
                         "is held out of the fit (remove it from one of the lists)");
    }
    owners.push_back(o);
  }
  std::vector<ModelSequences> per_model(cfg.models.size());
  std::vector<bool> taken(log.sequences.size(), false);
  for (const io::SequenceOwner& o : owners) {
    if (taken[o.sequence]) continue;  // a held-out sequence also in the fit's selection
    taken[o.sequence] = true;
    per_model[o.model].log.sequences.push_back(log.sequences[o.sequence]);
    per_model[o.model].log.sensor_time = log.sensor_time;
    per_model[o.model].held_out.push_back(held_out[o.sequence]);
  }
  return per_model;
}

// Window: takes a logged sequence of model mi; gives the window the experiment fits
// (`sequences: [{name, start, end}]`), else all of it, and whether it is a window.
std::pair<io::Sequence, bool> SelectWindow(const io::ExperimentConfig& cfg, size_t mi,
                                           const io::Sequence& whole, const std::string& path) {
  const io::SequenceRef* ref = nullptr;
  for (const io::SequenceRef& r : cfg.sequences) {
    if (io::EntryNamesGroup(r, path, whole.name) &&
        (r.model.empty() || r.model == cfg.models[mi].name)) {
      ref = &r;
    }
  }
  const bool windowed = ref && (std::isfinite(ref->start) || std::isfinite(ref->end));
  return {windowed ? io::WindowOf(whole, ref->start, ref->end, path) : whole, windowed};
}

// Sensors: takes the sequence s of a log read from path (T fitted samples; sensor_time post: the
// sensors of row k+1 are y_k); gives fs->measured (the log's columns in the model's sensordata
// layout) and fs->sensors (the config's, or every logged one; none: a log of states only).
void MeasuredSensors(const io::ExperimentConfig& cfg, const mjModel& m, const io::Sequence& s,
                     int T, bool post, const std::string& path, FitSequence* fs) {
  fs->measured = RowMatrix::Zero(T, m.nsensordata);
  std::vector<std::string> logged;
  int col = 0;
  for (size_t i = 0; i < s.sensor_names.size(); ++i) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, s.sensor_names[i].c_str());
    for (int c = 0; c < s.sensor_dims[i]; ++c) {
      fs->measured.col(m.sensor_adr[id] + c) = s.sensordata.block(post ? 1 : 0, col + c, T, 1);
    }
    col += s.sensor_dims[i];
    logged.push_back(s.sensor_names[i]);
  }
  if (cfg.sensors.empty()) {
    fs->sensors = logged;
    fs->no_sensors = logged.empty() && cfg.options.states.any();
    return;
  }
  for (const io::SensorSpec& ss : cfg.sensors) {
    if (std::find(logged.begin(), logged.end(), ss.name) == logged.end()) {
      throw io::ConfigError(ss.marks.self, "sensor '" + ss.name + "' is not in the log " + path +
                                               " (sequence " + s.name + ")");
    }
    fs->sensors.push_back(ss.name);
  }
}

// Unmeasured initial state: takes fs->x0 as logged; a logged initial state with NaN (not
// measured) cells is needed as logged unless the initial state is estimated (set, or a
// window's), which then starts them from the model's reference state. Sets
// out->estimate_initial_state for a window that starts at such a row; adds the warnings.
void FillUnmeasuredInitialState(const io::ExperimentConfig& cfg, const mjModel& m,
                                const io::Sequence& s, const std::string& where, bool windowed,
                                FitSequence* fs, BuiltProblem* out) {
  for (auto [name, x, reference] :
       {std::tuple<const char*, Eigen::VectorXd*, const mjtNum*>{"qpos", &fs->x0.qpos, m.qpos0},
        {"qvel", &fs->x0.qvel, nullptr},
        {"act", &fs->x0.act, nullptr}}) {
    if (x->size() == 0 || !x->array().isNaN().any()) continue;
    Eigen::Index c = 0;
    while (!std::isnan((*x)[c])) ++c;
    if (!cfg.options.estimate_initial_state && !windowed) {
      throw io::LogError(
          where + "/" + name + ": row 0 (t = " + FormatDigits(s.time[0], 9) +
          " s, the fit's initial state) is not measured (NaN in column " + std::to_string(c) +
          "): log it, set initial_state: {estimate: true}, or fit a window (sequences: "
          "[{name, start}]) that starts where the state is logged");
    }
    for (Eigen::Index i = 0; i < x->size(); ++i) {
      if (std::isnan((*x)[i])) (*x)[i] = reference ? reference[i] : 0.0;
    }
    // a window starting at a NaN row: its state is estimated, as a window without states
    if (windowed) out->estimate_initial_state = true;
    out->warnings.push_back(where + "/" + name + ": row 0" + (windowed ? " of the window" : "") +
                            " has NaN (not measured): the estimated initial state "
                            "starts there from the model's reference state");
  }
}

// Initial state: takes the sequence s (where: "FILE: /NAME", for messages); gives fs->x0, the
// logged state at its first sample (its unmeasured cells as above), else the model's reference
// state. Sets out->estimate_initial_state for a window without a logged state; adds the
// warnings.
void InitialState(const io::ExperimentConfig& cfg, const mjModel& m, const io::Sequence& s,
                  const std::string& where, bool windowed, FitSequence* fs, BuiltProblem* out) {
  if (s.qpos.rows() > 0) fs->x0.qpos = s.qpos.row(0).transpose();
  if (s.qvel.rows() > 0) fs->x0.qvel = s.qvel.row(0).transpose();
  if (s.act.rows() > 0) fs->x0.act = s.act.row(0).transpose();
  fs->x0.time = s.time[0];
  FillUnmeasuredInitialState(cfg, m, s, where, windowed, fs, out);
  if (windowed && s.qpos.rows() == 0) {
    // a window starts mid-motion: without a logged state there, the state is estimated
    out->estimate_initial_state = true;
    out->warnings.push_back(where + ": the window from " + FormatDigits(s.time[0], 9) +
                            " s has no logged qpos/qvel: its initial state is estimated");
  } else if (s.qpos.rows() == 0 && !cfg.options.estimate_initial_state) {
    out->warnings.push_back(where +
                            ": the log has no qpos: the fit starts from the model's "
                            "reference state (set initial_state: {estimate: true} to fit it)");
  }
}

// Logged states: takes the sequence s (T fitted samples); gives fs->qpos/qvel/act (row k is x_k),
// fitted as data (experiment `states`) and where multiple shooting starts its segments. Throws
// for a fitted part the log does not have.
void LoggedStates(const io::ExperimentConfig& cfg, const io::Sequence& s, int T,
                  const std::string& where, FitSequence* fs) {
  const FitStates& st = cfg.options.states;
  const std::pair<const char*, const RowMatrix*> parts[3] = {
      {"qpos", &s.qpos}, {"qvel", &s.qvel}, {"act", &s.act}};
  const bool fit_part[3] = {st.qpos.fit, st.qvel.fit, st.act.fit};
  for (int i = 0; i < 3; ++i) {
    if (fit_part[i] && parts[i].second->rows() == 0) {
      throw io::ConfigError(
          cfg.states_marks.Of(parts[i].first),
          "states." + std::string(parts[i].first) + " is fitted but " + where + " has no " +
              parts[i].first + " dataset",
          "log the states, or leave states." + std::string(parts[i].first) + " out");
    }
    RowMatrix& dst = i == 0 ? fs->qpos : i == 1 ? fs->qvel : fs->act;
    if (parts[i].second->rows() >= T) dst = parts[i].second->topRows(T);
  }
}

// Controls: takes the sequence s (T fitted samples); gives fs->ctrl (at their own times when the
// log has ctrl_time), every actuator's hold rule and transport delay (ExperimentConfig::
// ActuatorControlsOf; a fitted delay at its initial value here, the Problem's variable in the
// fit) and the rule before the first logged command.
void Controls(const io::ExperimentConfig& cfg, const mjModel& m, const io::Sequence& s, int T,
              FitSequence* fs) {
  if (s.ctrl_time.size() > 0) {
    fs->ctrl = s.ctrl;  // the controls at their own times (dataset ctrl_time)
    fs->ctrl_time = s.ctrl_time;
  } else {
    fs->ctrl = s.ctrl.topRows(T);
  }
  io::ExperimentConfig::ActuatorControls ac = cfg.ActuatorControlsOf(m);
  fs->ctrl_hold = std::move(ac.hold);
  fs->ctrl_delay = std::move(ac.delay);
  fs->ctrl_before = cfg.control_before;
}

// Sequence: takes a logged sequence of model mi (log read from path; post: sensor_time post);
// gives its FitSequence through the stages above. Any sample period: each sample is fitted at its
// own time (sysid/data/sample_grid.h).
FitSequence SequenceOf(const io::ExperimentConfig& cfg, size_t mi, const io::Sequence& whole,
                       const std::string& path, bool post, BuiltProblem* out) {
  const mjModel& m = *out->models[mi];
  const auto [s, windowed] = SelectWindow(cfg, mi, whole, path);
  const std::string where = path + ": /" + s.name;
  const int rows = static_cast<int>(s.time.size());
  const int T = post ? rows - 1 : rows;  // sensor_time post: the sensors of row k+1 are y_k
  if (T < 2) throw io::LogError(where + ": too few samples");
  FitSequence fs_;
  fs_.name = s.name;
  fs_.model = cfg.models[mi].name;
  MeasuredSensors(cfg, m, s, T, post, path, &fs_);
  InitialState(cfg, m, s, where, windowed, &fs_, out);
  fs_.time = s.time.head(T);
  LoggedStates(cfg, s, T, where, &fs_);
  Controls(cfg, m, s, T, &fs_);
  return fs_;
}

// Data files: takes the experiment's `data:` files; throws for a file listed twice (by any path:
// its data would count twice).
void CheckDataFilesDistinct(const io::ExperimentConfig& cfg) {
  for (size_t j = 0; j < cfg.data.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      if (!SamePath(cfg.data[i].path, cfg.data[j].path)) continue;
      throw io::ConfigError(cfg.data[j].mark,
                            "data file listed twice: " + cfg.data[j].path +
                                (cfg.data[i].path == cfg.data[j].path
                                     ? std::string()
                                     : " (the same file as " + cfg.data[i].path + ")"),
                            "first given at line " + std::to_string(cfg.data[i].mark.line) +
                                ", column " + std::to_string(cfg.data[i].mark.column) +
                                "; its data would count twice: list each log once");
    }
  }
}

// Logs: takes the experiment's `data:` files; gives out's fitted sequences (each added to the
// problem) and its held-out validation sequences, every log checked against the model of its
// sequences (the log's warnings in out), each named by file and group (io::SequenceNamesInFit;
// a renaming in out's warnings). Throws for a missing file, a file listed twice, a `sequences:` or
// `validation:` entry that names no group of any log, and two sequences of one name.
void ReadSequences(const io::ExperimentConfig& cfg, BuiltProblem* out) {
  if (cfg.data.empty()) {
    throw io::ConfigError(cfg.marks.self, "no `data:` log files to fit",
                          "run `sysid simulate` first, or list HDF5 logs under data:");
  }
  CheckDataFilesDistinct(cfg);
  // the selected sequences in order, named by the rule once all logs are read
  std::vector<FitSequence> built;
  std::vector<bool> held_out;
  std::vector<io::LoggedSequence> where, in_logs;
  SequenceSelection sel;
  sel.entry_used.assign(cfg.sequences.size(), false);
  sel.held_out_cfg.models = cfg.models;
  sel.held_out_cfg.sequences = cfg.validation;
  sel.held_out_used.assign(cfg.validation.size(), false);
  for (const io::DataFile& df : cfg.data) {
    if (!fs::exists(df.path)) {
      throw io::ConfigError(df.mark, "data file not found: " + df.path,
                            "run `sysid simulate EXP.yaml` to generate it");
    }
    const io::Log log = io::ReadLog(df.path);
    for (const io::Sequence& s : log.sequences) {
      sel.all_groups.push_back(s.name);
      in_logs.push_back({df.path, s.name});
    }
    const std::vector<ModelSequences> per_model = AssignToModels(cfg, log, df.path, &sel);
    const bool post = log.sensor_time == "post" || cfg.sensor_time == io::SensorTime::kPost;
    // one validation per model over the sequences that belong to it (fitted and held out)
    for (size_t mi = 0; mi < cfg.models.size(); ++mi) {
      const ModelSequences& mine = per_model[mi];
      if (mine.log.sequences.empty()) continue;
      io::ValidateLogAgainstModel(mine.log, *out->models[mi], df.path, &out->warnings);
      for (size_t si = 0; si < mine.log.sequences.size(); ++si) {
        built.push_back(SequenceOf(cfg, mi, mine.log.sequences[si], df.path, post, out));
        held_out.push_back(mine.held_out[si]);
        where.push_back({df.path, mine.log.sequences[si].name});
      }
    }
  }
  io::CheckSequenceEntriesUsed(cfg, sel.entry_used, sel.all_groups);
  io::CheckSequenceEntriesUsed(sel.held_out_cfg, sel.held_out_used, sel.all_groups);
  const std::vector<std::string> names = io::SequenceNamesInFit(where, in_logs, &out->warnings);
  for (size_t i = 0; i < built.size(); ++i) {
    built[i].name = names[i];
    if (held_out[i]) {
      out->validation.push_back(std::move(built[i]));  // simulated after the fit, never fitted
      continue;
    }
    out->problem->AddSequence(built[i]);
    out->sequences.push_back(std::move(built[i]));
  }
}

// Something to fit: takes the built sequences; throws when there are no residual rows (fitted
// sensor columns x samples, priors, fitted states) or no fitted sequence.
void CheckSomethingToFit(const io::ExperimentConfig& cfg, const BuiltProblem& out) {
  long long rows = 0;
  for (const FitSequence& fs_ : out.sequences) {
    const mjModel& m =
        *out.models[std::find(out.model_names.begin(), out.model_names.end(), fs_.model) -
                    out.model_names.begin()];
    for (const std::string& name : fs_.sensors) {
      const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
      if (id >= 0) rows += static_cast<long long>(fs_.time.size()) * m.sensor_dim[id];
    }
  }
  for (const FitParameter& p : cfg.parameters) rows += p.has_prior ? 1 : 0;
  // fitted states (their columns are checked by the Problem)
  if (cfg.options.states.any()) {
    for (const FitSequence& fs_ : out.sequences) rows += fs_.time.size();
  }
  if (rows == 0) {
    throw io::ConfigError(cfg.marks.Of("sensors"),
                          "the fit has no residuals: no sensor column of the selected log "
                          "sequences is fitted and no `states`",
                          "the logs need sensordata columns of the sensors listed under sensors:");
  }
  if (out.sequences.empty()) {
    throw io::ConfigError(cfg.marks.Of("sequences"), "no log sequence selected",
                          "check `sequences:` against the group names in the logs");
  }
}

// Options: takes the experiment and the threads asked for (< 0: the config's); gives out's
// options: the experiment's, the threads resolved (<= 0: every core), the initial states
// estimated where a window needs it, the sensors' weights.
void ResolveOptions(const io::ExperimentConfig& cfg, int threads, BuiltProblem* out) {
  FitOptions& o = out->options;
  o = cfg.options;
  o.threads = threads >= 0 ? threads : cfg.options.threads;
  if (out->estimate_initial_state) o.estimate_initial_state = true;
  if (o.threads <= 0)
    o.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const io::SensorSpec& ss : cfg.sensors) {
    if (ss.sigma_from_log) {
      // Problem::Fit estimates it; an estimate that cannot be made is bad input, said here
      try {
        SigmaFromLog(ss.name, out->sequences, [&](const std::string& model) {
          for (size_t i = 0; i < out->model_names.size(); ++i) {
            if (out->model_names[i] == model)
              return static_cast<const mjModel*>(out->models[i].get());
          }
          return static_cast<const mjModel*>(nullptr);
        });
      } catch (const std::invalid_argument& e) {
        throw io::ConfigError(ss.marks.Of("sigma"), e.what(),
                              "sigma: auto estimates the noise from the fitted sequences' logs");
      }
      o.sensors_sigma_from_log.push_back(ss.name);
      continue;
    }
    o.sensor_weights[ss.name] = ss.ResidualWeight();
    if (ss.sigma) o.sensors_with_sigma.push_back(ss.name);
  }
}

}  // namespace

BuiltProblem BuildProblem(const io::ExperimentConfig& cfg, int threads) {
  BuiltProblem out;
  out.problem = std::make_unique<Problem>();
  LoadModels(cfg, &out);
  CheckFitSettings(cfg);
  AddFittedValues(cfg, &out);
  ReadSequences(cfg, &out);
  CheckSomethingToFit(cfg, out);
  ResolveOptions(cfg, threads, &out);
  return out;
}

}  // namespace mjsysid::run
