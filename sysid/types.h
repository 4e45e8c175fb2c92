// The plain data of a fit, defined once and used by every layer above core/: the Ceres problem
// (sysid/problem.h), the experiment files (sysid/io/experiment.h), the result files
// (sysid/io/result.h), the runner (sysid/run/), the command line and the report. No Ceres here.
//
// What goes in: FitParameter (a model quantity to identify, in physical units), FitMeasurement
// (a sensor's delay/gain/bias terms), FitSequence (one logged sequence of one model), FitOptions.
// What comes out: FitResult with one ParameterEstimate per variable, the IterationInfo trace and
// one SequenceResult per sequence.
//
// Shapes: RowMatrix is row-major (core/state.h); T is the number of samples of a sequence, ns the
// model's nsensordata, np the number of estimated variables (physical parameters first, then the
// fitted measurement terms, as in FitResult::parameters).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/parameters.h"
#include "core/simulator.h"
#include "core/state.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/solve/residual_model.h"  // LossType, the robust loss of each residual

namespace mjsysid {

class FitObserver;  // sysid/fit_observer.h

// the optimiser's variable of a physical value p: z = p, log p, or p / scale
enum class Transform { kNone, kLog, kScale };

// "none", "huber", "cauchy" (the YAML spelling)
const char* LossTypeName(LossType loss);

// The verdict on a fit, decided once after the solve (sysid/fit/pass.cc, Decide) and written,
// printed and turned into the exit code everywhere else by these values and names (docs/cli.md):
// - kConverged: the optimiser converged, the Jacobian at the estimate is reliable and, with sigmas
//   given, the weighted residuals are as large as the noise explains; the intervals are valid.
// - kNotConverged: the optimiser stopped without converging (iteration limit, failure).
// - kModelMismatch: sigmas given and the weighted residual variance far above its chi-square
//   expectation (overall or for one sensor), or, without sigmas, residuals far above the noise the
//   log itself shows, at a point where no lower one is known: the model cannot explain the data
//   (or the sigmas are too small).
// - kJacobianUnreliable: the core flagged the Jacobian as not reliable (e.g. a horizon too long
//   for single shooting) and the cost fell by less than a few %; or the optimiser converged but
//   the cost at the estimate +- one standard error is far from the Jacobian's prediction (a cost
//   that jumps within the intervals, sysid/assess/interval_check.h).
// - kDidNotMove: no estimated value left its start (no step was accepted).
// - kSolverFailed: Ceres ended with a failure (e.g. its sparse linear solver could not factorise
//   the system); the estimate is the last accepted point and the warning names the cause.
// - kLocalMinimum: the residuals are above the noise (as kModelMismatch) at a point where a lower
//   one exists: the multiple-shooting segments do not join at the estimate (it describes no single
//   trajectory), or, for a start of a multi-start fit (StartResult), another start ended lower by
//   more than the noise explains. Other starts or the global stage are the way out, not the model.
// - kInterrupted: a stop signal ended the fit.
// Every value but kConverged marks the intervals not valid.
enum class FitStatus {
  kConverged,
  kNotConverged,
  kModelMismatch,
  kJacobianUnreliable,
  kDidNotMove,
  kInterrupted,
  kSolverFailed,
  kLocalMinimum
};

// "converged", "not_converged", "model_mismatch", "jacobian_unreliable", "did_not_move",
// "interrupted", "solver_failed", "local_minimum" (result files, CLI, report)
const char* FitStatusName(FitStatus status);
// the status of a name written by FitStatusName; nullopt for any other text (e.g. "running")
std::optional<FitStatus> FitStatusFromName(const std::string& name);

// one physical parameter to identify
struct FitParameter {
  FitParameter() = default;
  FitParameter(std::string name_, ParameterSpec target_, double initial_)
      : name(std::move(name_)), target(std::move(target_)), initial(initial_) {}
  FitParameter& Bounds(double lo, double hi) {
    lower = lo;
    upper = hi;
    return *this;
  }
  FitParameter& Log() {
    transform = Transform::kLog;
    return *this;
  }
  FitParameter& Prior(double mean, double sigma) {
    has_prior = true;
    prior_mean = mean;
    prior_sigma = sigma;
    return *this;
  }

  // the optimisation variable of a physical value: z = p, log p (-inf for p <= 0) or p / scale
  double ToVariable(double p) const;
  // the physical value of an optimisation variable (the inverse of ToVariable)
  double FromVariable(double z) const;
  // whether the parameter applies to the named model (models empty: every model)
  bool AppliesTo(const std::string& model_name) const;

  std::string name;      // unique label (results use it)
  ParameterSpec target;  // what it writes: kind, object, field, index (core/parameters.h)
  double initial = 0;
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
  Transform transform = Transform::kNone;
  double scale = 1.0;  // Transform::kScale: z = p / scale, > 0
  bool has_prior = false;
  double prior_mean = 0, prior_sigma = 1;  // Gaussian prior residual (p - mean) / sigma
  std::vector<std::string> models;         // models it applies to; empty = all
  // `initial: auto`: Problem::Fit starts it at the equation-error estimate from the logged qpos
  // and qvel (sysid/data/equation_error.h; kinds that enter the inverse dynamics linearly), else at
  // the model's value; `initial` is ignored (NaN from the experiment file) and then set
  bool initial_auto = false;
};

// measurement terms of one sensor: measured = gain * simulated(t - delay) + bias
struct FitMeasurement {
  struct Term {
    double initial = 0;
    bool fit = false;
    double lower = -std::numeric_limits<double>::infinity();
    double upper = std::numeric_limits<double>::infinity();
  };
  std::string sensor;
  Term delay{0.0, false, 0.0, std::numeric_limits<double>::infinity()};  // seconds, >= 0
  Term gain{1.0, false};
  Term bias{0.0, false};
};

// how the logged controls of one actuator reach the simulation steps (sysid/data/sample_grid.h):
// zero-order hold (a digital controller's) or linear interpolation
enum class ControlHold { kZeroOrder, kLinear };

// "zoh", "linear" (the YAML spelling)
const char* ControlHoldName(ControlHold hold);

// what an actuator gets before its first logged control (sysid/data/sample_grid.h), e.g. when a
// control delay or a log whose commands start late reaches before it: the first command held, or 0
enum class ControlBefore { kHold, kZero };

// "hold", "zero" (the YAML spelling)
const char* ControlBeforeName(ControlBefore before);

// A transport delay of the logged controls fitted as a variable (sysid/data/sample_grid.h: the
// controls are shifted by it before the hold): one actuator's (actuator named) or shared by every
// actuator not given its own (actuator ""), in every sequence whose model has the actuator; it
// replaces FitSequence::ctrl_delay for those actuators. Seconds, lower >= 0. Estimated like a
// parameter, named "controls.delay" (shared) or "controls.delay.<actuator>"; its Jacobian column
// is a central difference of whole rollouts (sysid/solve/cost_functions.h).
struct FitControlDelay {
  std::string actuator;  // "" = every actuator without its own
  double initial = 0;
  double lower = 0;
  double upper = std::numeric_limits<double>::infinity();
  // "controls.delay" or "controls.delay.<actuator>" (FitResult::parameters)
  std::string Name() const {
    return actuator.empty() ? "controls.delay" : "controls.delay." + actuator;
  }
};

// One recorded sequence of one model. Its measured samples come at `time` (any rate, jitter,
// gaps: the simulation runs on the model's timestep from time[0] and each sample is compared with
// the simulation interpolated at its own time, sysid/data/sample_grid.h); NaN in measured means
// "not measured" (masked out of the residuals). The controls come at ctrl_time (their own rate) or,
// without it, at the sample times.
struct FitSequence {
  FitSequence() = default;
  FitSequence(std::string name_, std::string model_, InitialState x0_, RowMatrix ctrl_,
              RowMatrix measured_)
      : name(std::move(name_)),
        model(std::move(model_)),
        x0(std::move(x0_)),
        ctrl(std::move(ctrl_)),
        measured(std::move(measured_)) {}

  std::string name;
  std::string model;   // a name given to Problem::AddModel
  InitialState x0;     // initial state (the estimate's start when initial states are fitted)
  RowMatrix ctrl;      // T x nu
  RowMatrix measured;  // T x nsensordata of the model: y_k in the model's sensordata layout
  std::vector<std::string> sensors;  // sensors whose columns are fitted; empty = all sensors
  Eigen::VectorXd time;              // T sample times (s); empty: x0.time + k * timestep
  // the controls' own times: Tc (s), ctrl then Tc x nu; empty: ctrl rows at `time`
  Eigen::VectorXd ctrl_time;
  std::vector<ControlHold> ctrl_hold;  // per actuator (nu) or empty: zero-order hold
  std::vector<double> ctrl_delay;      // per actuator (nu, s, >= 0) or empty: no transport delay
  // every actuator's control before its first logged one: the first held (default) or 0
  ControlBefore ctrl_before = ControlBefore::kHold;
  // logged states at the sample times (rows as `measured`): T x nq, T x nv, T x na; NaN = not
  // measured (masked); 0 rows = not logged. Fitted as data where FitOptions::states says so;
  // multiple shooting starts its segments at logged qpos and qvel.
  RowMatrix qpos, qvel, act;
  // no sensor column is fitted (a log of states only, FitOptions::states); `sensors` must be empty
  bool no_sensors = false;
};

// Logged states fitted as data next to the sensors (sysid/solve/state_residuals.h): the positions
// and velocities of joints and the activations of actuators, in tangent space (a ball or free
// joint's orientation as the 3-vector of mju_subQuat, rad). Each part fits the named joints
// (actuators for act; empty = every joint or actuator with one, in model order) with a noise level
// sigma
// (> 0, the part's units: m or rad, m/s or rad/s, activation units): one sigma shared, or one per
// name. Every fitted state counts in the chi-square test of FitStatus::kModelMismatch.
struct FitStates {
  struct Part {
    bool fit = false;
    std::vector<std::string> names;  // joints (qpos, qvel) or actuators (act); empty = all
    std::vector<double> sigma;       // 1 shared value, or one per name
  };
  Part qpos, qvel, act;
  bool any() const { return qpos.fit || qvel.fit || act.fit; }
};

// one Gauss-Newton/LM iteration, as reported to callbacks and kept in FitResult::trace
struct IterationInfo {
  int iteration = 0;
  double cost = 0;
  double step_norm = 0;
  double gradient_norm = 0;
  double seconds = 0;  // since the fit started
  bool successful = false;
  Eigen::VectorXd parameters;  // physical values after the iteration (FitResult order)
};

struct FitOptions {
  int max_iterations = 100;  // > 0
  double function_tolerance = 1e-10;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-10;
  JacobianOptions jacobian;  // mode, differences, steps (core/simulator.h)
  int threads = 0;           // simulator threads; <= 0: all cores
  LossType loss = LossType::kNone;
  double loss_scale = 1.0;  // in weighted residual units, > 0
  bool estimate_initial_state = false;
  // multiple shooting: simulation steps per segment; 0 = single shooting; -1 = auto (the
  // sensitivity growth measured at the initial values decides, see FitResult::segment_reason)
  int segment_steps = -1;
  double continuity_weight = 1.0;
  std::map<std::string, double> sensor_weights;  // sensor name -> weight (1/sigma); default 1
  // sensors whose weight is 1/sigma (a noise level, not a mere weight): their weighted residuals
  // are compared with their chi-square expectation to decide FitStatus::kModelMismatch
  std::vector<std::string> sensors_with_sigma;
  // sensors whose sigma is estimated from the fitted sequences' logs at the fit's start
  // (sigma: auto; sysid/fit/sigma_from_log.h): their weights and sensors_with_sigma are set from
  // it, and FitResult::sigma_from_log says what was used
  std::vector<std::string> sensors_sigma_from_log;
  UncertaintyOptions uncertainty;
  // the front end's choice to show progress (the experiment's solver.verbose): the runner
  // (sysid/run/) passes its observer only when set; Problem::Fit itself reads `observer` alone
  bool verbose = false;
  // receives the fit's events (sysid/fit_observer.h; borrowed, nullptr: none); the library never
  // prints
  FitObserver* observer = nullptr;
  std::function<void(const IterationInfo&)> on_iteration;  // e.g. checkpoint the iterate
  const std::atomic<bool>* interrupt = nullptr;  // set to stop after the current iteration
  FitStates states;                              // logged states fitted as data (none by default)
  // fit on a reduced copy of each model (core/reduced_model.h): island discovery and collision
  // pairs that never come near switched off, guarded; the estimate is the same bit for bit
  bool reduce_model = true;
  // multiple shooting: continuity_weight relative to the sensors (the default: a gap of a fraction
  // f of a state coordinate's spread costs as much as a sensor residual of f of its sensor's
  // spread; sysid/solve/multiple_shooting.h, ContinuityWeights), or absolute (false: the weight
  // itself)
  bool continuity_relative = true;
  // auto's contact segments (sysid/solve/multiple_shooting.h, OmitJumpingSensors): fit the touch,
  // accelerometer, force and torque sensors too (true), or leave them out with a warning (false)
  bool fit_jumping_sensors = false;
  // auto's contact segments (sysid/data/event_windows.h): the cells of velocity- and
  // acceleration-level sensors within this many samples of a contact event are left out of the
  // fit (0, the default: none)
  int event_window = 0;
  // auto's contact segments (sysid/solve/multiple_shooting.h, SolveWithStatesHeld): a first solve
  // with the segment states held on the data, then the solve with them free (false: the free solve
  // only)
  bool hold_states_first = true;
  // the solve's statistical stop (sysid/solve/gn_convergence.h): converged once the predicted
  // Gauss-Newton step is at most this fraction of every standard error, where the test is valid
  // (single shooting, no robust loss, no fitted control delay, segment_steps auto with its probe's
  // growth at most kRefitGrowth: sysid/fit/pass_build.cc); 0: off, Ceres' tolerances alone
  double gauss_newton_stop = 0.03;
  // the global stage (sysid/fit/global_stage.h): when the local fit ends other than converged,
  // horizon continuation from its estimate, the better of the two kept; false: the local fit only
  bool global_stage = true;
  // its budget, in multiples of the local fit's simulation steps (> 0): no pass of the stage
  // starts once the stage has simulated this many steps (steps, not seconds: the same rounds on
  // any machine at any load)
  double global_budget = 3.0;
  // the subset start (sysid/fit/subset_start.h): the first iterations on the first 1/8 of every
  // sequence, their estimate the start of the fit on all the data; false (the default for now,
  // docs/numerics.md "Subset start"): every iteration on all the data
  bool subset_start = false;
  // the timestep check (sysid/fit/timestep_check.h): when a fit with sigmas ends model_mismatch on
  // the chi-square test with residuals that are not white, the same fit at half the timestep tells
  // whether the misfit is the model's discretisation; false: never
  bool timestep_check = true;

  // What one pass of the global stage changes (sysid/fit/global_stage.h sets these on its copies
  // of the options; a user's fit leaves them at their defaults).
  struct Continuation {
    // segment_steps >= 0 counts as auto's contact segments (jumping sensors left out, event
    // windows, the states held first): a pass that repeats a local fit's auto choice
    bool contact_segments = false;
    // segments of any kind start with their states held on the data (hold_states_first)
    bool hold_states = false;
    // ... and keep them held: the solve with the states held is the whole solve
    bool held_only = false;
  };
  Continuation continuation;

  // How the fit is computed, not what it computes: switches that keep the estimate (the same bits,
  // or the same fit) and exist for benchmarks and tests; the defaults are what a user wants.
  struct Advanced {
    // each segment's residual blocks (single and multiple shooting; not under sysid/mpi/, which
    // compresses its own) handed to Ceres as their thin-QR triangles
    // (sysid/solve/compressed_cost.h: the same cost, gradient and Gauss-Newton matrix in n + 1
    // rows), not row by row; false: every row (the memory of Ceres' copies grows with the samples)
    bool compress_blocks = true;
    // the compressed blocks (compress_blocks above): a block asked for its Jacobian at the inputs
    // of its last fold writes that fold out instead of re-folding (sysid/solve/compressed_cost.h;
    // the same bits); false: every request re-folds (the same fit, slower)
    bool reuse_folds = true;
    // single shooting's compressed blocks: after each Jacobian batch, the blocks' rows and folds
    // made on the simulator's workers, one task per block, before Ceres asks for them one by one
    // (sysid/solve/compressed_cost.h, "Folds ahead"; the same bits at any thread count); false:
    // each block folded when Ceres asks (the same fit)
    bool fold_ahead = true;
    // the statistical stop also before a point's Jacobians (sysid/solve/gn_convergence.h, "Before
    // the last Jacobian"): with the previous iterate's Jacobian when the last step was within
    // kPreviousJacobianSteps standard errors, so that the last Jacobian is not simulated; false:
    // only after each Jacobian
    bool gauss_newton_stop_before_jacobian = true;
    // with an observer: progress events inside one long rollout or Jacobian column
    // (FitObserver::OnProgress) every tenth of its steps, at most one per this many seconds of it
    double progress_seconds = 2.0;
  };
  Advanced advanced;
};

// a value is on its bound (lower or upper; an infinite bound: never) within 1e-6 relative:
// ParameterEstimate::at_lower / at_upper, and the statistical stop's active set
// (sysid/solve/gn_convergence.h)
inline bool OnBound(double value, double bound, bool lower) {
  const double tol = 1e-6 * std::max(1.0, std::abs(value));
  return std::isfinite(bound) && (lower ? value - bound : bound - value) <= tol;
}

// one estimated variable: a physical parameter or a measurement term ("<sensor>.delay", ...)
struct ParameterEstimate {
  std::string name;
  double value = 0, initial = 0;
  double std_error = 0;  // +inf when unidentifiable, 0 when fixed on a bound
  double ci95_low = 0, ci95_high = 0;
  bool at_lower = false, at_upper = false;  // stopped on a bound (then not estimated: fixed)
  bool identifiable = true;
  std::optional<double> truth;  // the true value when known (synthetic data), for reports
  // the timestep check (sysid/fit/timestep_check.h): the model's timestep's bias of the value
  // (value at the timestep - value in continuous time, estimated); unset when it did not run
  std::optional<double> timestep_bias;
};

// how well a simulation reproduces one measured column (sysid/assess/metrics.h), at the start and
// at the estimate: NRMSE = RMS(simulated - measured) / std(measured) and % fit = 100 (1 - NRMSE)
struct ChannelFit {
  std::string channel;  // "sensor" (1-D) or "sensor[i]"
  double nrmse_initial = 0, nrmse_final = 0;
  // %; NaN for a constant measured column. fit_final is the estimate simulated in one piece
  // (SequenceResult::simulated_one_piece under multiple shooting)
  double fit_initial = 0, fit_final = 0;
  // multiple shooting: the estimate's fit segment by segment (each segment from its own fitted
  // state: SequenceResult::simulated_final), beside fit_final; NaN for a fit in one piece
  double nrmse_segments = std::numeric_limits<double>::quiet_NaN();
  double fit_segments = std::numeric_limits<double>::quiet_NaN();
};

// the fitted sensor columns of one sequence: measured and simulated, sensor by sensor
struct SequenceResult {
  std::string name, model;
  std::vector<std::string> sensor_names;  // fitted sensors, in model order
  std::vector<int> sensor_dims;           // their dimensions; the columns below, in order
  Eigen::VectorXd time;                   // T
  RowMatrix measured;                     // T x sum(sensor_dims)
  RowMatrix simulated_initial;            // T x sum(sensor_dims), at the initial parameters
  RowMatrix simulated_final;  // T x sum(sensor_dims), at the estimate (measurement terms on)
  // multiple shooting, where simulated_final is segment by segment (each segment from its own
  // fitted state: what the fit fitted): the estimate simulated in one piece from the sequence's
  // first state (what the identified model gives), T x sum(sensor_dims); empty for a fit in one
  // piece (simulated_final is that)
  RowMatrix simulated_one_piece;
  Eigen::VectorXd x0_final;  // estimated initial physics vector (or the given one); may be empty
  // one per column above (sysid/assess/metrics.h ChannelFits; filled by the runner and the result
  // reader)
  std::vector<ChannelFit> channel_fits;
  // per column of measured: the samples not measured (NaN in measured, masked out of the fit)
  std::vector<int> missing;
  // fitted states (FitOptions::states), as the sensors above: "qpos:<joint>", "qvel:<joint>",
  // "act:<actuator>", their physics-vector widths (a free joint's qpos 7, a ball joint's 4, else
  // 1) and T x sum(state_dims) columns in physics coordinates (NaN where not measured)
  std::vector<std::string> state_names;
  std::vector<int> state_dims;
  RowMatrix state_measured, state_simulated_initial, state_simulated_final;
  RowMatrix state_simulated_one_piece;  // as simulated_one_piece (empty: none)
  // T x sum(state_residual_dims) weighted residuals (simulated (-) measured) / sigma at the
  // estimate in tangent space (an orientation 3 rows), NaN where not measured: what the
  // chi-square test sums
  std::vector<int> state_residual_dims;
  RowMatrix state_residual_final;
};

// The sequence's plotted columns: the sensor columns followed by the fitted state columns, each
// state as one more "sensor" named as in state_names (what the report draws)
SequenceResult WithStateColumns(const SequenceResult& s);

// one fit of a multi-start run (sysid/run/multi_start.h): where it started, where it ended
struct StartResult {
  Eigen::VectorXd start;                    // physical start values (FitResult::parameters order)
  Eigen::VectorXd estimate;                 // the fit's values; empty when the fit failed
  double initial_cost = 0, final_cost = 0;  // +inf when the fit failed
  FitStatus status = FitStatus::kNotConverged;
  int iterations = 0;
  std::string error;  // why the fit failed (e.g. the simulation at the start); "" otherwise
};

// the spread of one estimated value over the starts that did not fail
struct ParameterSpread {
  std::string name;
  double min = 0, max = 0;
  double relative = 0;  // (max - min) / |best estimate| (inf when the best is 0 and max > min)
};

// A quantity computed from estimated variables, not itself estimated (e.g. a body's mass from its
// log-Cholesky variables): its value at the estimate and a first-order (delta-method) standard
// error and 95 % interval from the covariance of the variables it is derived from. std_error is
// NaN without intervals (FitResult::intervals_valid false or no uncertainty step) and +inf when a
// source variable is unidentifiable.
struct DerivedQuantity {
  std::string name;  // e.g. "payload.mass", "payload.com[0]", "payload.inertia[2]"
  std::string unit;  // "kg", "m", "kg m^2"
  double value = 0;
  double std_error = std::numeric_limits<double>::quiet_NaN();
  double ci95_low = std::numeric_limits<double>::quiet_NaN();
  double ci95_high = std::numeric_limits<double>::quiet_NaN();
  std::string derived_from;     // how: the estimated variables and the method, one line
  std::optional<double> truth;  // the true value when known (synthetic data), for reports
};

// one phase of a fit in its ledger (sysid/solve/fit_ledger.h): how often it was entered, the
// simulator step calls (Simulator::StepCount) and the wall seconds spent in it
struct LedgerRow {
  std::string phase;
  int entries = 0;
  long long steps = 0;
  double seconds = 0;
  // of steps, those on the critical path at 2 workers: the phase's parallel batches' makespans on
  // 2 workers under the thread pool's scheduling, in steps (Simulator::ParallelLoad), whatever
  // the fit's thread count; steps / critical_steps is the phase's modelled 2-thread speed-up
  long long critical_steps = 0;
  // of seconds, those inside the simulators' batches (ThreadPool::ParallelFor, core/thread_pool.h,
  // PoolTime): seconds - batch_seconds is the phase's serial time (residuals, Ceres, setup, the
  // equation-error start); batches: their number; of batch_seconds, wake_seconds from each
  // batch's publication to its last worker's start, wait_seconds the fit thread's wait for the
  // workers after its own last task (more than one thread only)
  double batch_seconds = 0;
  long long batches = 0;
  double wake_seconds = 0;
  double wait_seconds = 0;
  // the fit thread's CPU time inside the batches (at 1 thread their whole work; PoolTime)
  double batch_cpu_seconds = 0;
};

// Why the optimiser stopped, as a record (FitResult::termination): a kind and its numbers,
// rendered by TerminationText as result.yaml's `termination`, the CLI's "stopped:" line, the
// report's and Python's text. The solver's kinds come from Ceres' termination type
// (sysid/fit/pass_solve.cc), the statistical stop's from GaussNewtonStop::Termination
// (sysid/solve/gn_convergence.h), the run's (an interruption, a checkpoint) from
// sysid/run/fit_experiment.cc.
struct FitTermination {
  enum class Kind {
    kNone,               // nothing recorded (no solve): ""
    kSolverConvergence,  // Ceres CONVERGENCE (a tolerance met): solver_message
    kIterationLimit,     // Ceres NO_CONVERGENCE (the iteration limit; no time limit is set)
    kSolverFailure,      // Ceres FAILURE: solver_message
    kCallbackStop,       // Ceres USER_SUCCESS: a callback ended the solve (the interrupt flag)
    kCallbackAbort,      // Ceres USER_FAILURE: a callback aborted it (auto's Jacobian warning)
    kGaussNewtonStop,    // the statistical stop (FitOptions::gauss_newton_stop)
    kInterrupted,        // the run: a stop signal after `iteration`
    kCheckpoint,         // the run: a checkpoint after `iteration` (the fit still running)
    kUnknown,            // read from a result file written before the kinds: read_text only
  };
  Kind kind = Kind::kNone;
  std::string solver_message;  // Ceres' summary message (every solve's; the text of its kinds)
  // kGaussNewtonStop: the iteration tested; kInterrupted, kCheckpoint: the last iteration
  int iteration = 0;
  // kGaussNewtonStop: the fraction of every standard error the predicted Gauss-Newton step is
  // below (FitOptions::gauss_newton_stop) and the largest step's fraction; with the Jacobian of
  // an earlier iteration (jacobian_iteration, -1: the estimate's own) the last step's size in
  // standard errors
  double fraction = 0, largest = 0;
  int jacobian_iteration = -1;
  double step_std_errors = std::numeric_limits<double>::quiet_NaN();
  // a record read from a result file (sysid/io/result.h): the text as written there (the file
  // keeps the kind, not the numbers); TerminationText gives it as it is. Empty in a fit's result.
  std::string read_text;
};

// the record as one line, e.g. "converged: predicted Gauss-Newton step below 3 % of every
// standard error (largest 1.3 %, iteration 1)", Ceres' message, "interrupted (a stop signal) after
// iteration 4", "checkpoint after iteration 2"
std::string TerminationText(const FitTermination& t);
// "solver_convergence", "iteration_limit", "gauss_newton_stop", ... (result.yaml's
// termination_kind); "none" and "unknown" for kNone and kUnknown
const char* TerminationKindName(FitTermination::Kind kind);
// the kind of a name written by TerminationKindName; nullopt for any other text
std::optional<FitTermination::Kind> TerminationKindFromName(const std::string& name);

// Whether the interval check (sysid/assess/interval_check.h) ran, along which variables and why
// (FitResult::interval_check, set by sysid/fit/pass_intervals.cc), rendered by IntervalCheckText
// as result.yaml's `interval_check`.
struct IntervalCheckRecord {
  enum class Kind {
    kNotRun,         // no uncertainty step: "" (not written)
    kRanRugged,      // along every variable: the rollouts at the estimate can make the cost
                     // rugged (`rugged` says why)
    kRanSmooth,      // along every variable: smooth rollouts, every standard error wide
    kSkippedSmooth,  // smooth rollouts: skipped along the `skipped` of the `parameters` simulator
                     // parameters whose standard error is not wide
    kUnknown,        // read from a result file written before the kinds: read_text only
  };
  Kind kind = Kind::kNotRun;
  int evaluations = 0;  // cost evaluations made
  int skipped = 0;      // kSkippedSmooth: simulator parameters skipped
  int parameters = 0;   // the simulator parameters
  std::string rugged;   // kRanRugged: why (RuggedReason, e.g. "constraint rows come, go ...")
  // kRanRugged because the dynamics jump: contacts, or constraint rows that come, go or change
  // state (not kept in result files: the fit's own record)
  bool dynamics_jump = false;
  // the check found the cost not smooth at the intervals' scale (kCostNotSmoothWarning; not kept
  // in result files: the fit's own record)
  bool cost_not_smooth = false;
  // kRanRugged, the check failed and the envelope held (sysid/assess/interval_check.h,
  // CheckRuggedEnvelope): what the intervals are, e.g. "the Jacobian's, widened x1.4 on NAME"
  std::string envelope;
  // a standard error is wide above this fraction of its value (kSmoothRelativeStd)
  double wide_fraction = 0;
  // a record read from a result file: the text as written there; IntervalCheckText gives it as it
  // is. Empty in a fit's result.
  std::string read_text;
};

// the record as one line, e.g. "ran: 4 cost evaluations (smooth rollouts, standard errors above
// 10 % of the value)", "skipped along 2 of the 2 simulator parameters (...): ...; 0 cost
// evaluations along the other variables"; "" for kNotRun
std::string IntervalCheckText(const IntervalCheckRecord& r);
// "ran_rugged", "ran_smooth", "skipped_smooth" (result.yaml's interval_check_kind); "not_run" and
// "unknown" for kNotRun and kUnknown
const char* IntervalCheckKindName(IntervalCheckRecord::Kind kind);
// the kind of a name written by IntervalCheckKindName; nullopt for any other text
std::optional<IntervalCheckRecord::Kind> IntervalCheckKindFromName(const std::string& name);

// Why the fit runs in the segments it runs in, as parts (FitResult::segment_reason;
// SegmentReasonText is its text): the choice of the segment length, where later segments start,
// the continuity weights, and the first solve with the segment states held (auto's contact
// segments). A refit in segments (sysid/fit/policy.cc) replaces the choice with its own reason. A
// record read from a result file has the whole text as its choice.
struct SegmentRecord {
  std::string choice;        // why this length (HorizonChoice::reason, or the refit's reason)
  std::string start_source;  // where later segments start ("": no later segment)
  std::string weights;       // the continuity weights ("": no segment joins the next)
  int held_iterations = -1;  // iterations of the solve with the states held (-1: none ran)
  double held_initial_cost = 0, held_final_cost = 0;
};
// "CHOICE; segment states from SOURCE; WEIGHTS; first N iterations with the segment states held
// on the data (cost A -> B)", the parts present
std::string SegmentReasonText(const SegmentRecord& r);

// how one channel's residuals at the estimate look, pooled over the sequences
// (sysid/assess/residual_diagnostics.h computes and explains every field)
struct ResidualDiagnostics {
  std::string channel;          // "sensor" (1-D), "sensor[i]"
  int samples = 0;              // measured rows over every sequence
  double mean = 0;              // bias, the channel's units
  double rms = 0;               // the channel's units
  double sigma = 0;             // the stated sigma (NaN: none)
  bool sigma_from_log = false;  // sigma estimated from the log (sigma: auto), not stated
  double ratio = 0;             // rms / sigma (NaN without sigma)
  double bias_units = 0;        // |mean| in standard errors of a mean of correlated residuals
  double lag1 = 0;              // autocorrelation at one sample
  double tau = 0;               // integrated correlation time, samples (1: white)
  double portmanteau_p = 0;     // Ljung-Box p-value
  bool white = true;            // the portmanteau test passed (or too few samples to tell)
};

struct FitResult {
  std::vector<ParameterEstimate> parameters;  // physical parameters, then measurement terms
  double initial_cost = 0, final_cost = 0;    // 0.5 |r|^2
  int iterations = 0;      // -1 (and costs -1) when the solver stopped before its first iteration;
                           // run::RunFit's result file says 0 and NaN costs (result.yaml .nan)
  bool converged = false;  // the optimiser reported convergence (Ceres); the verdict is `outcome`
  bool interrupted = false;
  FitStatus outcome = FitStatus::kNotConverged;  // the verdict (see FitStatus)
  bool intervals_valid = false;  // std_error and ci95 mean something: outcome is kConverged
  // with sensors_with_sigma: the weighted residual variance of those sensors' columns at the
  // estimate, sum(r^2) / (m - p) (expected 1), and per sensor sum(r^2) / rows (NaN without sigmas);
  // fitted states count too, each under its name ("qpos:<joint>", ...)
  double chi2_ratio = std::numeric_limits<double>::quiet_NaN();
  std::map<std::string, double> sensor_chi2_ratio;
  // sensors without a sigma: the residual RMS at the estimate over the noise estimated from the
  // log itself (sysid/assess/noise_estimate.h), the worst of the sensor's columns pooled over
  // sequences (about 1 when the model explains the data; absent where the log gives no estimate)
  std::map<std::string, double> sensor_noise_ratio;
  // the sigmas estimated from the log (FitOptions::sensors_sigma_from_log), sensor -> sigma
  std::map<std::string, double> sigma_from_log;
  FitTermination termination;  // why the optimiser stopped (TerminationText)
  int num_residuals = 0;
  Uncertainty uncertainty;  // over FitResult::parameters (order as there)
  // the fitted sensor columns' residuals at the estimate, one entry per channel pooled over the
  // fitted sequences (sysid/assess/residual_diagnostics.h)
  std::vector<ResidualDiagnostics> residuals;
  // what the intervals come from: the covariance s^2 (J^T J)^-1 times interval_inflation, the
  // residuals' correlation time when they are not white (1: white residuals; the uncertainty's
  // covariance, std_error and ci95 of parameters and derived quantities include it), and why
  double interval_inflation = 1;
  std::string intervals_from;
  // the timestep check (sysid/fit/timestep_check.h): what it ran and found; "" when it did not run
  std::string timestep_check;
  // the subset start (sysid/fit/subset_start.h): what it ran and whether its estimate was the
  // start; "" when it did not run
  std::string subset_start;
  // dr/dp at the estimate (physical units) as its thin-QR triangle R: min(num_residuals, np) x
  // np, upper triangular, R^T R = J^T J (the per-sample rows are not kept:
  // sysid/assess/uncertainty.h RowTriangle)
  RowMatrix jacobian;
  std::vector<IterationInfo> trace;
  std::vector<SequenceResult> sequences;
  std::vector<std::string> warnings;
  double seconds = 0;  // wall time of the fit
  // held-out sequences (experiment `validation:`), simulated at the start and at the estimate,
  // never fitted (sysid/run/validation.h); x0 as logged
  std::vector<SequenceResult> validation;
  // multi-start (solver.starts > 1): every start in order, the index of the one this result is,
  // and the spread of each estimated value; empty for a single start
  std::vector<StartResult> starts;
  int best_start = 0;
  std::vector<ParameterSpread> start_spread;
  // multiple shooting as used: samples per segment (0: single shooting) and why (its text, e.g.
  // "single shooting: sensitivity bounded (max h*|S| 3.1e-05 <= 0.01)": SegmentReasonText)
  int segment_steps_used = 0;
  SegmentRecord segment_reason;
  // physical quantities derived from the estimate (sysid/assess/derived_inertials.h): per body
  // fitted through body_inertial its mass, centre of mass and principal moments, with delta-method
  // intervals; empty when nothing is derived
  std::vector<DerivedQuantity> derived;
  // whether the interval check (sysid/assess/interval_check.h) ran, along which variables and why
  // (IntervalCheckText); kNotRun when the uncertainty step did not run
  IntervalCheckRecord interval_check;
  // auto's contact segments: the event windows left out of the fit (sysid/data/event_windows.h; all
  // 0 when none); sensors: those with masked cells
  struct EventWindows {
    int window = 0;  // half-width in samples (FitOptions::event_window)
    int events = 0;  // contact-count changes found in the data
    int masked = 0;  // measured cells left out
    std::vector<std::string> sensors;
  };
  EventWindows event_windows;
  // the solve ended on the statistical stop (FitOptions::gauss_newton_stop,
  // sysid/solve/gn_convergence.h): converged with the point, possibly the start, already within the
  // fraction of every standard error of the Gauss-Newton optimum
  bool gauss_newton_converged = false;

  // How the fit got its answer, not the answer: the simulation it cost, the Jacobian mode, the
  // reduced model, the ledger, where the covariance's Jacobian came from and the compressed
  // blocks' folds. For benchmarks, tests and the curious (result.yaml keeps some of it).
  struct Diagnostics {
    long long simulation_steps = 0;  // step calls of all simulators (Simulator::StepCount)
    std::string jacobian_mode;       // the core mode used
    // the reduced model (FitOptions::reduce_model, core/reduced_model.h), summed over the models:
    // whether it was used, candidate collision pairs and those switched off, geoms switched off,
    // the MuJoCo features switched off (e.g. "island", "contact"), and the calls the guard made
    // simulate again with the full model (then the reduction was dropped for the rest of the fit)
    struct Reduction {
      bool recorded = false;  // false: a result written before the reduced model (nothing known)
      bool used = false;
      int collision_pairs = 0, collision_pairs_off = 0, geoms_off = 0;
      std::vector<std::string> disabled;
      int guard_trips = 0;
    };
    Reduction reduction;
    // the fit's steps and seconds by phase (sysid/solve/fit_ledger.h); rows add up to
    // simulation_steps
    std::vector<LedgerRow> ledger;
    // the statistical stop fired before the estimate's Jacobian (FitOptions::
    // advanced.gauss_newton_stop_before_jacobian): the covariance, standard errors and result's
    // jacobian come from the previous iterate's Jacobian (iteration covariance_jacobian_iteration)
    // with the residuals, cost and s^2 at the estimate; last_step_std_errors: the last step's
    // largest |x_{k+1,i} - x_{k,i}| / s_i. -1 and NaN: the Jacobian is the estimate's own.
    int covariance_jacobian_iteration = -1;
    double last_step_std_errors = std::numeric_limits<double>::quiet_NaN();
    // the compressed blocks (FitOptions::advanced.reuse_folds): Jacobian requests answered
    // with a block's last fold instead of a re-fold, and the folds made
    // (sysid/solve/compressed_cost.h)
    long long reused_folds = 0;
    long long folds = 0;
    // of the folds, those made ahead on the simulator's workers (FitOptions::advanced.fold_ahead)
    long long ahead_folds = 0;
  };
  Diagnostics diagnostics;
};

// one line for a user, e.g. "collision pairs off 3 of 4, geoms off 2, disabled [island], guard
// trips 0", or "off (solver.reduce_model: false)"
std::string ReductionText(const FitResult::Diagnostics::Reduction& r);

}  // namespace mjsysid
