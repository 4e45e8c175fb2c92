#include "sysid/run/fit_experiment.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <map>
#include <optional>
#include <system_error>
#include <thread>

#include "core/identified_model.h"
#include "core/text.h"
#include "mjsysid/version.h"
#include "sysid/derived_inertials.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/log.h"
#include "sysid/io/sequence_models.h"
#include "sysid/metrics.h"
#include "sysid/run/multi_start.h"
#include "sysid/run/output_folder.h"
#include "sysid/run/resume.h"
#include "sysid/run/validation.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;

// the range of solver.relative_step that can give a derivative
constexpr double kMinRelativeStep = 1e-13;
constexpr double kMaxRelativeStep = 0.1;

std::string NowIso() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

// the settings a fit cannot work with: a finite-difference step that overflows or vanishes in
// rounding, two parameters of one model writing the same quantity
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

}  // namespace

int ExitCodeOf(FitStatus status) {
  switch (status) {
    case FitStatus::kConverged:
      return 0;
    case FitStatus::kModelMismatch:
      return 3;
    case FitStatus::kJacobianUnreliable:
    case FitStatus::kDidNotMove:
      return 4;
    default:
      return 1;  // not converged, interrupted
  }
}

namespace {

// the true value of each derived quantity (sysid/derived_inertials.h) whose body has a truth for
// every body_inertial parameter (simulate.truth): the same derivation at the true values
void SetDerivedTruth(const BuiltProblem& bp, const std::map<std::string, double>& truth,
                     std::vector<DerivedQuantity>* derived) {
  if (derived->empty()) return;
  const auto n = static_cast<Eigen::Index>(bp.parameters.size());
  Eigen::VectorXd values = Eigen::VectorXd::Zero(n);
  std::map<std::string, bool> known;  // body -> every body_inertial parameter has a truth
  for (Eigen::Index v = 0; v < n; ++v) {
    const FitParameter& p = bp.parameters[static_cast<size_t>(v)];
    const auto it = truth.find(p.name);
    if (it != truth.end()) values[v] = it->second;
    if (p.target.kind != "body_inertial") continue;
    const bool has = it != truth.end();
    known[p.target.object] = known.count(p.target.object) ? known[p.target.object] && has : has;
  }
  for (size_t mi = 0; mi < bp.models.size(); ++mi) {
    const std::string prefix = bp.models.size() > 1 ? bp.model_names[mi] + "/" : "";
    for (const DerivedQuantity& t :
         DeriveInertials(*bp.models[mi], bp.model_names[mi], bp.parameters, values,
                         Eigen::VectorXd(), Eigen::MatrixXd(), prefix)) {
      const std::string body = t.name.substr(prefix.size(), t.name.rfind('.') - prefix.size());
      if (!known.count(body) || !known[body]) continue;
      for (DerivedQuantity& d : *derived) {
        if (d.name == t.name) d.truth = t.value;
      }
    }
  }
}

}  // namespace

BuiltProblem BuildProblem(const io::ExperimentConfig& cfg, int threads) {
  BuiltProblem out;
  out.problem = std::make_unique<Problem>();
  io::CheckModelFilesExist(cfg);

  // models, checked against the config
  for (const io::ModelSpec& ms : cfg.models) {
    ModelPtr m = LoadModel(ms.path);
    io::ValidateExperimentAgainstModel(cfg, *m, ms.name);  // resolves every parameter
    out.problem->AddModel(ms.name, *m);
    out.model_names.push_back(ms.name);
    out.models.push_back(std::move(m));
  }

  // the fit's settings that cannot work, and two parameters writing one model quantity
  CheckFitSettings(cfg);

  // parameters and measurement terms
  for (const FitParameter& p : cfg.parameters) {
    out.problem->AddParameter(p);
    out.parameters.push_back(p);
  }
  for (const FitMeasurement& me : cfg.measurement) {
    out.problem->AddMeasurement(me);
    out.measurements.push_back(me);
  }
  // fitted control delays (experiment `controls.delay` with fit: true)
  for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
    if (!cd.term.fit) continue;
    FitControlDelay d;
    d.actuator = cd.actuator;
    d.initial = cd.term.initial;
    d.lower = cd.term.lower;
    d.upper = cd.term.upper;
    out.problem->AddControlDelay(d);
    out.control_delays.push_back(d);
  }

  // sequences from the logs
  if (cfg.data.empty()) {
    throw io::ConfigError(cfg.marks.self, "no `data:` log files to fit",
                          "run `sysid simulate` first, or list HDF5 logs under data:");
  }
  std::vector<bool> entry_used(cfg.sequences.size(), false);
  std::vector<std::string> all_groups;
  // `validation:` entries are assigned to models by the same rule as `sequences:` entries
  io::ExperimentConfig held_out_cfg;
  held_out_cfg.models = cfg.models;
  held_out_cfg.sequences = cfg.validation;
  std::vector<bool> held_out_used(cfg.validation.size(), false);
  for (const io::DataFile& df : cfg.data) {
    if (!fs::exists(df.path)) {
      throw io::ConfigError(df.mark, "data file not found: " + df.path,
                            "run `sysid simulate EXP.yaml` to generate it");
    }
    const io::Log log = io::ReadLog(df.path);
    for (const io::Sequence& s : log.sequences) all_groups.push_back(s.name);
    // held-out sequences first, with their model: they are taken out of the fitted selection
    // (without `sequences:` every sequence of the log is selected, the held-out ones too)
    std::vector<bool> held_out(log.sequences.size(), false);
    std::vector<io::SequenceOwner> owners;
    if (!cfg.validation.empty()) {
      owners = io::AssignSequences(held_out_cfg, log, df.path, &held_out_used);
      for (const io::SequenceOwner& o : owners) held_out[o.sequence] = true;
    }
    for (const io::SequenceOwner& o : io::AssignSequences(cfg, log, df.path, &entry_used)) {
      owners.push_back(o);
    }
    // one validation per model over the sequences that belong to it (fitted and held out)
    std::vector<io::Log> per_model(cfg.models.size());
    std::vector<std::vector<bool>> per_model_held_out(cfg.models.size());
    std::vector<bool> taken(log.sequences.size(), false);
    for (const io::SequenceOwner& o : owners) {
      if (taken[o.sequence]) continue;  // a held-out sequence also in the fit's selection
      taken[o.sequence] = true;
      per_model[o.model].sequences.push_back(log.sequences[o.sequence]);
      per_model[o.model].sensor_time = log.sensor_time;
      per_model_held_out[o.model].push_back(held_out[o.sequence]);
    }
    for (size_t mi = 0; mi < cfg.models.size(); ++mi) {
      const mjModel& m = *out.models[mi];
      if (per_model[mi].sequences.empty()) continue;
      io::ValidateLogAgainstModel(per_model[mi], m, df.path, &out.warnings);
      const bool post = log.sensor_time == "post" || cfg.sensor_time == io::SensorTime::kPost;
      for (size_t si = 0; si < per_model[mi].sequences.size(); ++si) {
        const io::Sequence& whole = per_model[mi].sequences[si];
        // the window the experiment fits (`sequences: [{name, start, end}]`), else all of it
        const io::SequenceRef* ref = nullptr;
        for (const io::SequenceRef& r : cfg.sequences) {
          if (r.name == whole.name && (r.model.empty() || r.model == cfg.models[mi].name)) ref = &r;
        }
        const bool windowed = ref && (std::isfinite(ref->start) || std::isfinite(ref->end));
        const io::Sequence s =
            windowed ? io::WindowOf(whole, ref->start, ref->end, df.path) : whole;
        const std::string where = df.path + ": /" + s.name;
        // any sample period: each sample is fitted at its own time (sysid/sample_grid.h)
        const int rows = static_cast<int>(s.time.size());
        // sensor_time post: the sensors of row k+1 are y_k
        const int T = post ? rows - 1 : rows;
        if (T < 2) throw io::LogError(where + ": too few samples");
        FitSequence fs_;
        fs_.name = s.name;
        fs_.model = cfg.models[mi].name;
        if (s.ctrl_time.size() > 0) {
          fs_.ctrl = s.ctrl;  // the controls at their own times (dataset ctrl_time)
          fs_.ctrl_time = s.ctrl_time;
        } else {
          fs_.ctrl = s.ctrl.topRows(T);
        }
        fs_.measured = RowMatrix::Zero(T, m.nsensordata);
        // log columns into the model's sensordata layout
        std::vector<std::string> logged;
        int col = 0;
        for (size_t i = 0; i < s.sensor_names.size(); ++i) {
          const int id = mj_name2id(&m, mjOBJ_SENSOR, s.sensor_names[i].c_str());
          for (int c = 0; c < s.sensor_dims[i]; ++c) {
            fs_.measured.col(m.sensor_adr[id] + c) =
                s.sensordata.block(post ? 1 : 0, col + c, T, 1);
          }
          col += s.sensor_dims[i];
          logged.push_back(s.sensor_names[i]);
        }
        // fitted sensors: the config's, or every logged one (none: a log of states only)
        if (cfg.sensors.empty()) {
          fs_.sensors = logged;
          fs_.no_sensors = logged.empty() && cfg.options.states.any();
        } else {
          for (const io::SensorSpec& ss : cfg.sensors) {
            if (std::find(logged.begin(), logged.end(), ss.name) == logged.end()) {
              throw io::ConfigError(ss.marks.self, "sensor '" + ss.name + "' is not in the log " +
                                                       df.path + " (sequence " + s.name + ")");
            }
            fs_.sensors.push_back(ss.name);
          }
        }
        // initial state: the logged one, else the model's reference state
        if (s.qpos.rows() > 0) fs_.x0.qpos = s.qpos.row(0).transpose();
        if (s.qvel.rows() > 0) fs_.x0.qvel = s.qvel.row(0).transpose();
        if (s.act.rows() > 0) fs_.x0.act = s.act.row(0).transpose();
        fs_.x0.time = s.time[0];
        // a logged initial state with NaN (not measured) cells: needed as logged unless the initial
        // state is estimated (set, or a window's), which then starts them from the model's
        // reference state
        for (auto [name, x, reference] : {std::tuple<const char*, Eigen::VectorXd*, const mjtNum*>{
                                              "qpos", &fs_.x0.qpos, m.qpos0},
                                          {"qvel", &fs_.x0.qvel, nullptr},
                                          {"act", &fs_.x0.act, nullptr}}) {
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
          if (windowed) out.estimate_initial_state = true;
          out.warnings.push_back(where + "/" + name + ": row 0" +
                                 (windowed ? " of the window" : "") +
                                 " has NaN (not measured): the estimated initial state "
                                 "starts there from the model's reference state");
        }
        if (windowed && s.qpos.rows() == 0) {
          // a window starts mid-motion: without a logged state there, the state is estimated
          out.estimate_initial_state = true;
          out.warnings.push_back(where + ": the window from " + FormatDigits(s.time[0], 9) +
                                 " s has no logged qpos/qvel: its initial state is estimated");
        } else if (s.qpos.rows() == 0 && !cfg.options.estimate_initial_state) {
          out.warnings.push_back(where +
                                 ": the log has no qpos: the fit starts from the model's "
                                 "reference state (set initial_state: {estimate: true} to fit it)");
        }
        fs_.time = s.time.head(T);
        // logged states: fitted as data (experiment `states`; row k is x_k) and where multiple
        // shooting starts its segments
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
          RowMatrix& dst = i == 0 ? fs_.qpos : i == 1 ? fs_.qvel : fs_.act;
          if (parts[i].second->rows() >= T) dst = parts[i].second->topRows(T);
        }
        // controls: the experiment's hold rule and transport delay for every actuator
        fs_.ctrl_hold.assign(m.nu, cfg.control_hold);
        fs_.ctrl_delay.assign(m.nu, cfg.control_delay);
        // per actuator: its own hold, its own given delay (a fitted one is the Problem's)
        for (const auto& [actuator, hold] : cfg.control_holds) {
          const int id = mj_name2id(&m, mjOBJ_ACTUATOR, actuator.c_str());
          if (id >= 0) fs_.ctrl_hold[id] = hold;
        }
        for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
          const int id = mj_name2id(&m, mjOBJ_ACTUATOR, cd.actuator.c_str());
          if (!cd.term.fit && id >= 0) fs_.ctrl_delay[id] = cd.term.initial;
        }
        if (per_model_held_out[mi][si]) {
          out.validation.push_back(fs_);  // simulated after the fit, never fitted
          continue;
        }
        out.problem->AddSequence(fs_);
        out.sequences.push_back(fs_);
      }
    }
  }
  io::CheckSequenceEntriesUsed(cfg, entry_used, all_groups);
  io::CheckSequenceEntriesUsed(held_out_cfg, held_out_used, all_groups);
  // residual rows: fitted sensor columns x samples, and priors; none leaves nothing to fit
  long long rows = 0;
  for (size_t i = 0; i < out.sequences.size(); ++i) {
    const FitSequence& fs_ = out.sequences[i];
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

  // options: the experiment's, the threads resolved, the sensors' weights
  FitOptions& o = out.options;
  o = cfg.options;
  o.threads = threads >= 0 ? threads : cfg.options.threads;
  if (out.estimate_initial_state) o.estimate_initial_state = true;
  if (o.threads <= 0)
    o.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (const io::SensorSpec& ss : cfg.sensors) {
    o.sensor_weights[ss.name] = ss.ResidualWeight();
    if (ss.sigma) o.sensors_with_sigma.push_back(ss.name);
  }
  return out;
}

std::vector<std::string> WriteIdentifiedModel(const io::ExperimentConfig& cfg,
                                              const std::string& model_name,
                                              const std::string& model_path,
                                              const std::vector<ParameterEstimate>& estimates,
                                              const std::string& out_path,
                                              const std::string& run_id) {
  // the estimates of the parameters that apply to this model
  std::vector<ParameterSpec> specs;
  std::vector<double> values;
  for (const io::ParameterSpec* p : cfg.ParametersOf(model_name)) {
    for (const ParameterEstimate& e : estimates) {
      if (e.name != p->name) continue;
      specs.push_back(p->target);
      values.push_back(e.value);
    }
  }

  // core writes them into the model's MJCF (and checks it); the run id as a comment before the
  // root element; saved atomically (a temporary file next to out_path, flushed, renamed over it)
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(model_path, specs, values, &warnings);
  io::WriteFileAtomically(out_path, run_id.empty() ? xml : io::RunIdComment(run_id) + "\n" + xml);
  for (std::string& w : warnings) w = out_path + ": " + w;
  return warnings;
}

std::vector<std::string> InputsOf(const io::ExperimentConfig& cfg) {
  std::vector<std::string> inputs = {cfg.source_file};
  for (const io::ModelSpec& ms : cfg.models) inputs.push_back(ms.path);
  for (const io::DataFile& df : cfg.data) inputs.push_back(df.path);
  return inputs;
}

std::string AtInitialValues(const io::ExperimentConfig& cfg, const Problem* problem) {
  std::string out;
  for (size_t i = 0; i < cfg.parameters.size(); ++i) {
    const FitParameter& p = problem && i < problem->parameters().size()
                                ? problem->parameters()[i]
                                : static_cast<const FitParameter&>(cfg.parameters[i]);
    out += (out.empty() ? "" : ", ") + p.name + " = " +
           (p.initial_auto ? std::string("auto") : FormatDigits(p.initial, 6));
  }
  return "at the initial values " + out + " (" + cfg.source_file + ")";
}

std::vector<std::string> FittedNames(const io::ExperimentConfig& cfg) {
  std::vector<std::string> names;
  for (const io::ParameterSpec& p : cfg.parameters) names.push_back(p.name);
  for (const io::MeasurementSpec& me : cfg.measurement) {
    if (me.delay.fit) names.push_back(me.sensor + ".delay");
    if (me.gain.fit) names.push_back(me.sensor + ".gain");
    if (me.bias.fit) names.push_back(me.sensor + ".bias");
  }
  for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
    if (cd.term.fit) names.push_back(FitControlDelay{cd.actuator}.Name());
  }
  return names;
}

FitRunOutcome RunFit(const io::ExperimentConfig& cfg, const FitRunOptions& ro) {
  FitRunOutcome out;
  out.out_dir = ro.out_dir.empty() ? cfg.output : ro.out_dir;

  // --resume: the fit starts from the checkpoint's values (sysid/run/resume.h)
  std::optional<io::FitResultFile> base;
  if (ro.resume) {
    base = FindCheckpoint(out.out_dir);
    if (!base) {
      throw OutputError("--resume " + out.out_dir + ": nothing to resume: no checkpoint " +
                        StagingFolder(out.out_dir) +
                        "/checkpoint.yaml and no interrupted result in the folder");
    }
  }
  const io::ExperimentConfig run_cfg = base ? ResumedConfig(cfg, *base) : cfg;
  BuiltProblem bp = BuildProblem(run_cfg, ro.threads);
  // multi-start: N whole fits, no checkpoints (a resumed fit continues one start)
  const int starts = ro.starts >= 1 ? ro.starts : cfg.starts;
  const std::uint64_t start_seed =
      ro.seed >= 0 ? static_cast<std::uint64_t>(ro.seed) : cfg.start_seed;
  if (starts > 1 && base) {
    throw OutputError("--resume " + out.out_dir + ": a resumed fit continues one start, not " +
                      std::to_string(starts) +
                      " (--starts or solver.starts); resume with --starts 1, or fit again");
  }

  // the output folder only once the input is known good (bad input leaves nothing behind), never
  // one that holds an input, never a foreign one without force
  CheckOutputFolder(out.out_dir, InputsOf(cfg), ro.force);
  const fs::path parent = fs::absolute(out.out_dir).lexically_normal().parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) {
    // the folder comes from --out, or from `output:` (or its default) in the experiment
    const io::Mark where = ro.out_dir.empty() ? cfg.marks.Of("output") : io::Mark{"--out", 0, 0};
    throw io::ConfigError(where,
                          "cannot create the output folder " + out.out_dir + ": " + ec.message(),
                          "a file of that name exists, or the parent folder is not writable");
  }

  // one fit at a time into a folder; everything written into the staging folder DIR.partial,
  // which replaces DIR only once complete
  const FolderLock lock(out.out_dir, "sysid fit of " + cfg.source_file);
  if (base) {
    const std::optional<io::FitResultFile> now = FindCheckpoint(out.out_dir);
    if (!now || now->run_id != base->run_id || now->iterations != base->iterations) {
      throw OutputError("--resume " + out.out_dir + ": the checkpoint changed while starting");
    }
  }
  const std::string staging =
      CreateStagingFolder(out.out_dir, /*keep_checkpoint=*/base.has_value());
  FitOptions options = bp.options;
  options.verbose = ro.verbose && options.verbose;
  options.observer = options.verbose ? ro.observer : nullptr;
  options.interrupt = ro.interrupt;

  // what every result file says about the run
  io::FitResultFile& file = out.file;
  file.name = cfg.name;
  file.experiment = cfg.source_file;
  file.mjsysid_version = MJSYSID_VERSION;
  file.mujoco_version = MujocoVersion();
  file.created = NowIso();
  file.run_id = NewRunId();
  const SimulatorOptions sim_defaults;
  file.solver = {
      {"max_iterations", std::to_string(options.max_iterations)},
      {"function_tolerance", FormatG17(options.function_tolerance)},
      {"gradient_tolerance", FormatG17(options.gradient_tolerance)},
      {"parameter_tolerance", FormatG17(options.parameter_tolerance)},
      {"gauss_newton_stop", FormatG17(options.gauss_newton_stop)},
      {"jacobian", JacobianModeName(options.jacobian.mode)},
      {"differences", options.jacobian.central ? "central" : "forward"},
      {"relative_step", FormatG17(options.jacobian.relative_step)},
      {"threads", std::to_string(options.threads)},
      {"loss", LossTypeName(options.loss)},
      {"loss_scale", FormatG17(options.loss_scale)},
      {"estimate_initial_state", options.estimate_initial_state ? "true" : "false"},
      {"segment_steps", std::to_string(options.segment_steps)},
      {"continuity_weight", FormatG17(options.continuity_weight)},
      {"continuity_scale", options.continuity_relative ? "relative" : "absolute"},
      {"jumping_sensors", options.fit_jumping_sensors ? "fit" : "omit"},
      {"event_window", std::to_string(options.event_window)},
      {"hold_states_first", options.hold_states_first ? "true" : "false"},
      {"mujoco_solver_tolerance", "min(model, " + FormatG17(sim_defaults.solver_tolerance) + ")"},
      {"minimizer", "ceres levenberg-marquardt"},
      {"starts", std::to_string(starts)},
      {"seed", std::to_string(start_seed)},
  };
  std::map<std::string, double> truth;
  for (const io::NamedValue& t : cfg.simulate.truth) truth[t.name] = t.value;

  // checkpoint after every good iteration (DIR.partial/checkpoint.{yaml,h5}): status running,
  // the current values, the successful iterations so far; a resumed run continues the
  // checkpoint's count, trace and clock
  const std::string checkpoint_path = (fs::path(staging) / "checkpoint.yaml").string();
  const std::string checkpoint_h5 = (fs::path(staging) / "checkpoint.h5").string();
  const std::string yaml_path = (fs::path(staging) / "result.yaml").string();
  const std::string h5_path = (fs::path(staging) / "result.h5").string();
  const std::vector<std::string> names = FittedNames(cfg);
  std::vector<double> first_initial;  // the first run's start values
  for (const FitParameter& p : bp.parameters) first_initial.push_back(p.initial);
  for (const FitMeasurement& me : run_cfg.measurement) {
    for (const FitMeasurement::Term* t : {&me.delay, &me.gain, &me.bias}) {
      if (t->fit) first_initial.push_back(t->initial);
    }
  }
  for (const io::ExperimentConfig::ControlDelaySpec& cd : run_cfg.control_delays) {
    if (cd.term.fit) first_initial.push_back(cd.term.initial);
  }
  if (base) {
    for (size_t i = 0; i < first_initial.size(); ++i)
      first_initial[i] = base->parameters[i].initial;
  }
  io::FitResultFile progress;     // the checkpoint so far
  std::string checkpoint_failed;  // the first checkpoint write failure
  if (base) progress = *base;
  options.on_iteration = [&](const IterationInfo& it) {
    if (base && it.iteration == 0) return;  // the checkpoint it starts from
    // `initial: auto`: the start values the fit solved (NaN in the config)
    for (size_t i = 0; i < bp.parameters.size(); ++i) {
      if (std::isnan(first_initial[i])) first_initial[i] = bp.problem->parameters()[i].initial;
    }
    IterationInfo entry = it;
    entry.iteration += base ? base->iterations : 0;
    entry.seconds += base ? base->seconds : 0;
    if (!base && it.iteration == 0) progress.initial_cost = it.cost;
    progress.trace.push_back(entry);
    io::FitResultFile cp = file;
    cp.status = "running";
    cp.termination = "checkpoint after iteration " + std::to_string(entry.iteration);
    cp.iterations = entry.iteration;
    cp.initial_cost = progress.initial_cost;
    cp.final_cost = it.cost;
    cp.seconds = entry.seconds;
    cp.trace = progress.trace;
    for (int i = 0; i < it.parameters.size() && i < static_cast<int>(names.size()); ++i) {
      ParameterEstimate e;
      e.name = names[i];
      e.value = it.parameters[i];
      e.initial = first_initial[i];
      e.std_error = std::numeric_limits<double>::quiet_NaN();
      e.ci95_low = e.ci95_high = std::numeric_limits<double>::quiet_NaN();
      if (truth.count(e.name)) e.truth = truth[e.name];
      cp.parameters.push_back(e);
    }
    // a checkpoint that cannot be written (full disk) does not stop the fit: its estimates are
    // still printed; the warning is given once
    try {
      io::WriteResultH5(checkpoint_h5, cp);
      io::WriteResultYaml(checkpoint_path, cp);
    } catch (const io::ResultError& e) {
      if (checkpoint_failed.empty()) {
        checkpoint_failed = e.what();
        if (ro.observer) ro.observer->OnWarning(std::string("checkpoint not written: ") + e.what());
      }
    }
    if (ro.on_iteration) ro.on_iteration(it);
  };

  // fit
  for (const std::string& w : bp.warnings) {
    if (ro.observer) ro.observer->OnWarning(w);
  }
  try {
    if (starts > 1) {
      static_cast<FitResult&>(file) =
          FitFromStarts(bp, options, starts, start_seed, /*progress=*/true, ro.on_problem);
    } else {
      if (ro.on_problem) ro.on_problem(*bp.problem, &options);
      static_cast<FitResult&>(file) = bp.problem->Fit(options);
    }
  } catch (const SimulationError& e) {
    // trial points that fail are rejected: this is the start
    throw SimulationError(std::string(e.what()) + "; " +
                              AtInitialValues(run_cfg, starts > 1 ? nullptr : bp.problem.get()),
                          e.sequence(), e.step());
  }
  if (base) {
    AppendToCheckpoint(*base, &file);
    file.warnings.push_back("resumed from the checkpoint of run " + base->run_id +
                            " after iteration " + std::to_string(base->iterations));
  }
  const FitResult& r = file;

  // fit metrics per channel of every fitted sequence; the held-out sequences simulated at the
  // start and at the estimate (never fitted), with theirs
  for (SequenceResult& sr : file.sequences) sr.channel_fits = ChannelFits(sr);
  for (FitSequence sq : bp.validation) {
    const size_t mi = static_cast<size_t>(
        std::find(bp.model_names.begin(), bp.model_names.end(), sq.model) - bp.model_names.begin());
    // fitted control delays: the held-out sequence's controls at the estimated delays (at the
    // start and at the estimate alike); the shared one first, an actuator's own over it
    const mjModel& vm = *bp.models[mi];
    for (const bool own : {false, true}) {
      for (const io::ExperimentConfig::ControlDelaySpec& cd : cfg.control_delays) {
        if (!cd.term.fit || cd.actuator.empty() == own) continue;
        const int id = mj_name2id(&vm, mjOBJ_ACTUATOR, cd.actuator.c_str());
        if (own && id < 0) continue;
        for (const ParameterEstimate& e : file.parameters) {
          if (e.name != FitControlDelay{cd.actuator}.Name()) continue;
          for (int i = 0; i < vm.nu; ++i) {
            if (!own || i == id) sq.ctrl_delay[i] = e.value;
          }
        }
      }
    }
    file.validation.push_back(SimulateHeldOut(vm, bp.parameters, bp.measurements, file.parameters,
                                              sq, options.threads, &file.warnings));
  }

  // results: the fit as it came, the truth where known, the run's warnings first
  file.status = FitStatusName(r.outcome);
  if (r.interrupted) {
    file.termination =
        "interrupted (a stop signal) after iteration " + std::to_string(r.iterations);
  }
  for (ParameterEstimate& e : file.parameters) {
    if (truth.count(e.name)) e.truth = truth[e.name];
  }
  SetDerivedTruth(bp, truth, &file.derived);
  file.warnings.insert(file.warnings.begin(), bp.warnings.begin(), bp.warnings.end());
  out.printed_warnings = static_cast<int>(bp.warnings.size());
  out.exit_code = ExitCodeOf(r.outcome);

  // the estimates are shown before any file is written (a full disk loses no result)
  if (ro.on_estimates) ro.on_estimates(file);

  // identified models, result.h5, then result.yaml (which says the run is complete), into the
  // staging folder; then the staging folder replaces DIR
  for (size_t i = 0; i < cfg.models.size(); ++i) {
    const std::string fname = cfg.models[i].name + "_identified.xml";
    try {
      const std::vector<std::string> w =
          WriteIdentifiedModel(cfg, cfg.models[i].name, cfg.models[i].path, r.parameters,
                               (fs::path(staging) / fname).string(), file.run_id);
      file.warnings.insert(file.warnings.end(), w.begin(), w.end());
      file.identified_models[cfg.models[i].name] = fname;
    } catch (const io::FileError&) {
      throw;  // the disk refused: not a property of the model
    } catch (const std::exception& e) {
      file.warnings.push_back(std::string("identified model not written: ") + e.what());
    }
  }
  io::WriteResultH5(h5_path, file);
  fs::remove(checkpoint_path, ec);
  fs::remove(checkpoint_h5, ec);
  io::WriteResultYaml(yaml_path, file);
  PublishFolder(staging, out.out_dir);
  return out;
}

}  // namespace mjsysid::run
