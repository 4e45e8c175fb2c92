// Rollouts of a MuJoCo model and their Jacobians with respect to selected model parameters and the
// initial state, chained through the multi-step simulation.
//
// Time convention (docs/numerics.md, "Time convention"): sample k of a sequence is (t_k, u_k, y_k)
// with
//   y_k     = h(x_k, u_k; p)   the sensors MuJoCo computes at state x_k with control u_k,
//   x_{k+1} = f(x_k, u_k; p)   one mj_step.
// A rollout of T samples records x_0 .. x_T (T+1 states) and y_0 .. y_{T-1} (T sensor rows).
//
// Jacobians (forward mode; docs/numerics.md, "Tangent-space sensitivities"): S_k = dx_k/dcol in
// tangent space (nx = 2nv+na rows, layout of
// mjd_transitionFD), S_{k+1} = A_k S_k + F_k and dy_k/dcol = C_k S_k + G_k. Columns are the
// selected parameters (in ParameterSet order) followed, if requested, by the nx tangent directions
// of x_0. Three ways to compute them, equal up to finite-difference error (tested):
// - kDirectional: one perturbed step per column per time step, from the stored nominal state moved
//   along h*S_k with the parameter at p+h. Cost ~ T*ncol steps; parallel over columns, which
//   RolloutAndJacobians starts behind their rollouts (each step once x_{k+1} is recorded).
// - kMatrix: A_k, C_k from mjd_transitionFD and F_k, G_k by one perturbed step per parameter that
//   skips the pipeline stages the parameter cannot affect; then the chain. Parallel over time
//   steps.
// - kWholeRollout: whole perturbed rollouts (what mujoco.sysid does); kept as oracle and baseline.
// kAuto picks the cheaper of the first two from the counts (ChooseJacobianMode); for a model with
// native delays (nhistory > 0) it picks kWholeRollout, and kDirectional/kMatrix are refused
// (std::invalid_argument): the history buffer is state the one-step modes do not carry.
//
// Non-smooth steps (docs/numerics.md, "Contact-set changes"): a difference that straddles a
// contact-set change spikes. Central differences are computed as the mean of a forward and a
// backward difference; where the two disagree by more than 10% the step is non-smooth, and the
// smaller one-sided value is used and counted in Sensitivity::kinks. Forward differences whose
// perturbed step finds another number of contacts than the nominal step are checked the same way
// against the backward side.
//
// Ownership and threads: a Simulator owns a private copy of the model (the caller's model is never
// modified), a persistent thread pool, and one mjData and model copy per worker. Every output is
// computed by exactly one task whose inputs do not depend on the worker, so results are
// bit-identical for any thread count.
//
// Constraint solver: the private model's tolerance is min(model, 1e-10) (SimulatorOptions). Steps
// whose solver stopped at opt.iterations, and a solver other than Newton, are reported in
// Sensitivity::warnings with counts (docs/numerics.md, "Solver tolerance and iteration cap").
//
// Failure: a MuJoCo warning (bad qpos/qvel/qacc, buffer overflow) or a non-finite value in any
// nominal or perturbed step throws SimulationError naming the sequence, step and time; MuJoCo
// errors (e.g. mjData stack or arena overflow) throw MujocoError with MuJoCo's message, caught
// without unwinding MuJoCo's frames (core/mujoco_env.h). After either, the worker that failed has
// its mjData reset before it is used again, so the Simulator stays usable and gives the results of
// a fresh one (tested bit for bit); a failed SetParameters restores the previous values. Bad
// arguments (shapes) throw std::invalid_argument.
#pragma once

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <atomic>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/reduced_model.h"
#include "core/solver_stats.h"
#include "core/state.h"
#include "core/state_sensors.h"
#include "core/thread_pool.h"

namespace mjsysid {

// Rollout or Jacobians stopped because the cancel flag was set (SetCancelFlag)
class Cancelled : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class SimulationError : public std::runtime_error {
 public:
  SimulationError(const std::string& what, int sequence, int step)
      : std::runtime_error(what), sequence_(sequence), step_(step) {}
  int sequence() const { return sequence_; }
  int step() const { return step_; }

 private:
  int sequence_;
  int step_;
};

struct SimulatorOptions {
  int threads = 1;  // workers; <= 0: all cores
  // Constraint-solver tolerance on the private model copy, the same for nominal and perturbed
  // steps: min(model tolerance, solver_tolerance). Newton converges quadratically, so at 1e-10 the
  // solution error left is far below what a 1e-6 finite difference resolves (tested), and the
  // solver stops after the 1-5 iterations it needs. fixed_solver_iterations = true sets tolerance
  // 0 instead (opt.iterations every step, bit-for-bit the same count): exact but far slower on
  // contact-rich models (docs/numerics.md, "Solver tolerance and iteration cap").
  double solver_tolerance = 1e-10;
  bool fixed_solver_iterations = false;
  bool sensors = true;  // false: no sensor work anywhere (mjDSBL_SENSOR)
  // When every sensor of the model is a joint encoder (jointpos/jointvel of hinge and slide joints,
  // core/state_sensors.h), steps write them from the state and skip MuJoCo's sensor stage: the
  // same bits (tested); false runs the sensor stage (the oracle of that test).
  bool copy_state_sensors = true;
};

// Initial state of a sequence. Empty qvel/act mean zeros; empty qpos means the model's qpos0.
struct InitialState {
  Eigen::VectorXd qpos, qvel, act;
  double time = 0;
};

// One sequence to simulate: initial state and controls (T x nu, row k = u_k).
struct SequenceInput {
  InitialState x0;
  RowMatrix ctrl;
};

struct Trajectory {
  int T = 0;               // samples
  RowMatrix states;        // (T+1) x (nq+nv+na): x_0 .. x_T
  RowMatrix sensors;       // T x nsensordata: y_0 .. y_{T-1} (0 columns when sensors are off)
  RowMatrix step;          // (T+1) x nstep: step state (core/state.h) before step k: time, ...
  Eigen::VectorXd inputs;  // ninput: the inputs held during the rollout (kInputSig)
  std::vector<int> ncon;   // T: contacts found in step k (at x_k), to detect contact-set changes
  SolverStats solver;      // constraint solves of the T steps
};

// Writes into d what step k of tr reads (0 <= k < tr.T): the physics vector x_k, the step state
// and the controls ctrl (nu, u_k), so that a step of m from d repeats step k (with m's
// parameters). The inputs are not written: d must hold tr.inputs already (RestoreInputs; mj_step
// never changes them). Copies only: no allocation, no MuJoCo error for a model of tr's sizes.
// Inline: every perturbed step starts here.
inline void RestoreStep(const mjModel& m, const StateDims& dims, const Trajectory& tr, int k,
                        const double* ctrl, mjData* d) {
  SetPhysics(m, d, tr.states.row(k).data());
  SetStepState(m, dims, d, tr.step.row(k).data());
  for (int i = 0; i < dims.nu; ++i) d->ctrl[i] = ctrl[i];
}

// writes tr.inputs into d (once before restoring steps of tr)
void RestoreInputs(const mjModel& m, const StateDims& dims, const Trajectory& tr, mjData* d);

// the share of time steps of these trajectories with contacts, or a change of the contact count
// at the next step (where forward matrix mode differences both sides)
double ContactFraction(const std::vector<Trajectory>& trajectories);

enum class JacobianMode { kAuto, kDirectional, kMatrix, kWholeRollout };
const char* JacobianModeName(JacobianMode mode);

// A finite-difference perturbation h*|S| (parameter step times the state sensitivity, state
// units) past this is no longer local: the Jacobians warn (Sensitivity::warnings), and the fit's
// automatic multiple shooting (sysid/problem.h) splits horizons where it is reached.
constexpr double kSensitivityGrowthLimit = 1e-2;

struct JacobianOptions {
  JacobianMode mode = JacobianMode::kAuto;
  bool central = false;         // central instead of forward differences (twice the steps)
  double relative_step = 1e-6;  // parameter step h_j = relative_step * max(|p_j|, step_floor)
  double step_floor = 1e-3;
  std::vector<double> parameter_steps;  // absolute steps per parameter (overrides), or empty
  double state_step = 1e-6;     // absolute step for state directions (initial state, mjd_*FD)
  bool initial_state = false;   // add the nx columns of dx_0
  bool state_jacobians = true;  // fill DxDp (dy/dcol is always filled when sensors are on)
  // matrix mode and StepJacobians: near contacts (and where a perturbed parameter step finds
  // another number of contacts) also difference the backward side and apply the kink rule; false:
  // forward differences only there too (half the steps at contacts; a difference straddling a
  // contact onset is kept as it is)
  bool kink_check = true;
  bool zero_column_is_error = true;  // a parameter whose column is exactly zero in every
                                     // sequence (its write changes nothing here) throws
                                     // ParameterError instead of returning a zero column
};

struct Sensitivity {
  JacobianMode mode = JacobianMode::kAuto;  // the mode that was used
  int ncol = 0;                             // np (+ nx with initial_state)
  RowMatrix DyDp;                           // (T*ns) x ncol: row k*ns + i is d y_k[i] / d column
  RowMatrix DxDp;  // ((T+1)*nx) x ncol: row k*nx + i is d x_k[i] / d column (tangent space)
  int kinks = 0;   // one-sided differences used where the two sides disagreed (contact onset)
  // e.g. a sensitivity that grew past what FD can follow, a constraint solver that is not Newton
  // or stopped at its iteration cap in nominal or perturbed steps (with counts). Perturbed steps
  // counted: all of directional and whole-rollout mode; in matrix mode the parameter columns
  // (the state columns run inside mjd_transitionFD, which does not expose its solves).
  std::vector<std::string> warnings;
};

// The one-step derivative blocks of rollouts (Simulator::StepJacobians), what the chain rule of
// core/step_chain.h composes into rollout derivatives. For step k of a sequence, in tangent space
// (nx = 2nv+na, the layout of mjd_transitionFD; ns = nsensordata, nu controls, np parameters):
//   A_k = dx_{k+1}/dx_k, B_k = dx_{k+1}/du_k, F_k = dx_{k+1}/dp,
//   C_k = dy_k/dx_k,     D_k = dy_k/du_k,     G_k = dy_k/dp.
// Row-major stacks over k: block k of A is rows [k nx, (k+1) nx). B, D have 0 columns without
// controls, F, G without parameters; C, D, G have 0 rows without sensors.
struct StepBlocks {
  int T = 0;
  RowMatrix A;    // (T nx) x nx
  RowMatrix B;    // (T nx) x nu
  RowMatrix F;    // (T nx) x np
  RowMatrix C;    // (T ns) x nx
  RowMatrix D;    // (T ns) x nu
  RowMatrix G;    // (T ns) x np
  int kinks = 0;  // one-sided differences used where the two sides disagreed (as Sensitivity)
  std::vector<std::string> warnings;  // constraint-solver warnings (as Sensitivity)
};

// Progress inside one long step loop (Simulator::SetStepProgress): a rollout or a Jacobian
// column over a sequence of `total` steps calls Step(what, done, total) from the thread that runs
// it when it starts (done = 0) and each time another tenth of its steps is done; the loop pays one
// integer compare per step (no allocation, no lock, no clock). Several workers call it at once:
// the hook must be thread-safe and cheap, and outlive its use. what: "rollout", "Jacobian column"
// or "Jacobians" (static strings).
class StepProgress {
 public:
  virtual ~StepProgress() = default;
  virtual void Step(const char* what, int done, int total) = 0;
};

// Jacobian columns of one sequence computed ahead of being asked for
// (Simulator::RolloutWithColumnsAhead): the first `columns` columns of its Sensitivity at the
// parameter values `at` with the options `options`, with what their tasks reported (warnings and
// kinks in s, the constraint solves of their perturbed steps in perturbed) and the step calls
// they took. Simulator::Jacobians with them computes only the remaining columns.
struct ColumnsAhead {
  int columns = 0;  // 0: none
  Eigen::VectorXd at;
  JacobianOptions options;
  Sensitivity s;  // sized as Jacobians sizes it; columns [0, columns) filled
  SolverStats perturbed;
  long long steps = 0;
};

class Simulator {
 public:
  // copies m; resolves the parameters (throws ParameterError)
  Simulator(const mjModel& m, const std::vector<ParameterSpec>& params,
            const SimulatorOptions& options = SimulatorOptions());
  ~Simulator();

  const mjModel& model() const { return *model_; }
  const ParameterSet& parameters() const { return params_; }
  const StateDims& dims() const { return dims_; }
  const SimulatorOptions& options() const { return options_; }
  int threads() const { return pool_.size(); }

  // --- Parameters ---------------------------------------------------------------------------
  // current parameter values: length np, in ParameterSet order and the kinds' units
  // (core/parameters.h)
  Eigen::VectorXd GetParameters() const;
  // Writes parameter values (length np, as GetParameters) into the private model (mj_setConst
  // where needed). Wrong length: std::invalid_argument; a value MuJoCo rejects: MujocoError, with
  // the previous values restored.
  void SetParameters(const Eigen::VectorXd& values);

  // the model's reference state: qpos0, zero velocity and activation
  InitialState ReferenceState() const;

  // --- Rollouts -----------------------------------------------------------------------------
  // Nominal rollouts at the current parameters: out is resized to sequences.size() and (*out)[i]
  // shaped as Trajectory states (sequence i: T = its ctrl rows). In parallel across sequences. When
  // there are more sequences than workers and they do not share the workers evenly (3 on 2), each
  // rollout runs as q consecutive pieces (q = W / gcd(n, W) for n sequences on W workers, when
  // every piece has at least 50 steps: core/simulator_internal.h, RolloutPieces) of about equal
  // length, claimed piece by piece (every sequence's first piece, then every second one, ...); a
  // piece continues from the state its predecessor recorded (RestoreStep: bit for bit the
  // trajectory of one piece) on whichever worker is free, so that the workers share the last round:
  // 3 rollouts on 2 workers take 1.5 rollout times, not 2.
  void Rollout(const std::vector<SequenceInput>& sequences, std::vector<Trajectory>* out);
  Trajectory Rollout(const SequenceInput& sequence);
  // Rollouts of the sequences at several parameter vectors in one parallel pass (task k n + i:
  // sequence i at values[k], on a worker's copy of the private model with values[k] written as
  // SetParameters writes them): (*out)[k] is what SetParameters(values[k]) and Rollout give, bit
  // for bit; the simulator's own parameter values are unchanged. For points that are known
  // together (the interval check's +- one standard error), so that their rollouts share rounds
  // of the workers. Failure as Rollout (and as SetParameters for values MuJoCo rejects).
  void RolloutAt(const std::vector<SequenceInput>& sequences,
                 const std::vector<Eigen::VectorXd>& values,
                 std::vector<std::vector<Trajectory>>* out);

  // --- Jacobians ----------------------------------------------------------------------------
  // Jacobians around nominal trajectories computed by Rollout with the current parameters: out is
  // resized to sequences.size(), (*out)[i] shaped as Sensitivity states (ncol = np, + nx with
  // options.initial_state; DxDp empty without options.state_jacobians, DyDp with 0 rows without
  // sensors). A nominal that does not match its sequence, or a mode the model refuses:
  // std::invalid_argument; a parameter whose column is zero everywhere (zero_column_is_error):
  // ParameterError; simulation failures as Rollout.
  void Jacobians(const std::vector<SequenceInput>& sequences,
                 const std::vector<Trajectory>& nominal, const JacobianOptions& options,
                 std::vector<Sensitivity>* out);
  Sensitivity Jacobians(const SequenceInput& sequence, const Trajectory& nominal,
                        const JacobianOptions& options);

  // Rollout and then Jacobians, with the same results bit for bit, in one parallel pass where
  // that is faster: with more than one thread in directional mode (whatever the contacts), the
  // columns of a sequence start while its rollout runs and follow it step by step, so that a
  // single sequence's rollout no longer waits alone. Failure as Rollout and Jacobians.
  void RolloutAndJacobians(const std::vector<SequenceInput>& sequences,
                           const JacobianOptions& options, std::vector<Trajectory>* nominal,
                           std::vector<Sensitivity>* out);

  // --- One-step blocks ----------------------------------------------------------------------
  // The blocks of every time step of every sequence (StepBlocks) around nominal trajectories
  // computed by Rollout with the current parameters, as matrix mode computes them: A, C (and B, D
  // with controls) by mjd_transitionFD at x_k with options.state_step, F, G (with parameters) by
  // one perturbed step per parameter that skips the stages the parameter cannot affect; both sides
  // where options.central or where contacts are near, with the kink rule. In parallel over all
  // time steps of all sequences. options.initial_state and state_jacobians are ignored. A model
  // with RK4 or native delays: std::invalid_argument (mjd_transitionFD supports neither); a
  // nominal that does not match its sequence: std::invalid_argument; simulation failures as
  // Rollout.
  void StepJacobians(const std::vector<SequenceInput>& sequences,
                     const std::vector<Trajectory>& nominal, const JacobianOptions& options,
                     bool controls, bool parameters, std::vector<StepBlocks>* out);

  // --- Speculative columns (filled into workers that a batch of rollouts leaves idle) --------
  // Rollout, and in the same parallel pass the first columns[i] (at most ncol) directional
  // Jacobian columns of sequence i behind its rollout, step by step (as RolloutAndJacobians), into
  // ahead[i]: speculative columns that fill the workers a batch of rollouts leaves idle (3
  // rollouts on 2 workers leave one idle for a rollout's time). Where RolloutAndJacobians would not
  // pipeline (1 thread, a mode that is not directional at every contact share, native delays),
  // only the rollouts (ahead[i].columns = 0). The trajectories are Rollout's bit for bit, and so
  // is the failure: when a column fails, the rollouts are simulated again alone (no columns).
  void RolloutWithColumnsAhead(const std::vector<SequenceInput>& sequences,
                               const JacobianOptions& options, const std::vector<int>& columns,
                               std::vector<Trajectory>* nominal, std::vector<ColumnsAhead>* ahead);
  // Jacobians that take the columns of ahead[i] where they belong to the current parameter values
  // and these options (else they are computed anew) and compute the rest: the same result bit for
  // bit as Jacobians without them. The entries taken are left empty (columns 0), the others as
  // they were (ahead.size() other than sequences.size(): none taken).
  void Jacobians(const std::vector<SequenceInput>& sequences,
                 const std::vector<Trajectory>& nominal, const JacobianOptions& options,
                 std::vector<ColumnsAhead>* ahead, std::vector<Sensitivity>* out);

  // --- Jacobian mode and steps --------------------------------------------------------------
  // the mode kAuto resolves to for these options (deterministic: counts only). contact_fraction:
  // the share of time steps with contacts near (there forward matrix mode differences both
  // sides); < 0: 1 if the model can have contacts, else 0. Jacobians() passes the share measured
  // on the nominal trajectories.
  JacobianMode ChooseJacobianMode(const JacobianOptions& options,
                                  double contact_fraction = -1) const;

  // estimated cost of the Jacobian of one time step, in units of one full mj_step
  double JacobianCostPerStep(JacobianMode mode, const JacobianOptions& options,
                             double contact_fraction = -1) const;

  // whether the model can have contacts (two colliding geoms or an explicit pair, contacts on)
  bool ContactsPossible() const;

  // parameter steps h_j used for the current values: length np, absolute, in the parameters'
  // units. parameter_steps of another length than np, or a step that is not positive:
  // std::invalid_argument.
  Eigen::VectorXd ParameterSteps(const JacobianOptions& options) const;

  // --- Cancel and progress ------------------------------------------------------------------
  // While *flag is true, Rollout and Jacobians stop within one time step of every worker and
  // throw Cancelled (e.g. a user's interrupt during a long Jacobian); nullptr: never (default).
  // The flag must outlive its use here.
  void SetCancelFlag(const std::atomic<bool>* flag) { cancel_ = flag; }
  // the progress hook of long step loops (StepProgress); nullptr: none (default)
  void SetStepProgress(StepProgress* hook) { step_progress_ = hook; }

  // --- Load accounting (the fit's ledger, benchmarks) ----------------------------------------
  // Step calls made since construction or ResetStepCount(), over all workers: every mj_step of
  // a rollout or a perturbed step (also those skipping stages) counts 1, a call of
  // mjd_transitionFD counts 1 + nx (its nominal and perturbed state steps). Not thread-safe
  // against a running Rollout/Jacobians call.
  long long StepCount() const;
  void ResetStepCount();
  // The parallel structure of those steps (core/thread_pool.h, "Task model"): per parallel batch
  // the step calls of each task, summed as work (= StepCount) and as the makespan on 1-4 workers
  // under the pool's scheduling (span[2]: steps on the critical path at 2 workers). Reset with
  // ResetStepCount.
  const PoolLoad& ParallelLoad() const { return pool_.load(); }
  // the wall time of those batches and of their hand-off to the workers (core/thread_pool.h,
  // PoolTime); reset with ResetStepCount
  const PoolTime& ParallelTime() const { return pool_.time(); }

  // --- The workers, lent to the caller between batches -------------------------------------
  // Runs fn(worker, i) for every i in [0, n) on the simulator's workers (ThreadPool::ParallelFor:
  // the calling thread is worker 0; with one thread, in order on it): the caller's own work
  // between the simulator's batches (the fit's residual blocks' folds,
  // sysid/solve/compressed_cost.h), a batch of ParallelTime and, without steps, of ParallelLoad. fn
  // must not call this simulator (its workers' mjData are not fn's); the first exception thrown by
  // fn is rethrown.
  void ParallelFor(int n, const std::function<void(int worker, int i)>& fn) {
    pool_.ParallelFor(n, fn);
  }

  // --- Reduced model -------------------------------------------------------------------------
  // The reduced model (core/reduced_model.h): switches r off in the private model (r from
  // AnalyzeReduction on this simulator's model and its nominal rollouts). Rollout, Jacobians and
  // RolloutAndJacobians then check the guard after every nominal step; when it trips (a pair
  // switched off came near), the reduction is dropped for good (the private model is the full one
  // again) and the call is simulated again, so every result equals the full model's bit for bit.
  // ContactsPossible answers for the full model throughout.
  void SetReduction(const ModelReduction& r);
  // the reduction SetReduction got (empty before), and whether it is switched off now (false
  // after a trip)
  const ModelReduction& reduction() const { return reduction_; }
  bool reduced() const { return reduced_; }
  // calls that the guard made simulate again with the full model (0 or 1)
  int ReductionTrips() const { return reduction_trips_; }

 private:
  // Implementation: simulator.cc (construction, parameters, per-step helpers),
  // simulator_rollout.cc, simulator_mode.cc, simulator_jacobians.cc, simulator_columns.cc,
  // simulator_matrix.cc, simulator_ahead.cc (speculative columns); shared private pieces in
  // core/simulator_internal.h.
  struct Worker;      // per-worker mjData, model copies and scratch
  struct TaskReport;  // what one Jacobian column task reports besides its column
  void CheckInputs(const std::vector<SequenceInput>& sequences) const;
  // mj_resetData and cleared warning counters: after a MuJoCo error d is usable again
  void ResetData(mjData* d) const;
  void ResetWorker(Worker& w) const;
  // runs task() for worker w; if it throws, resets w before rethrowing
  template <class Task>
  void OnWorker(Worker& w, Task&& task) const;
  void SetInitialState(mjData* d, const InitialState& x0) const;
  // steps [k0, k1) of a rollout from the state in w's mjData (k1 = -1: to the end); a piece that
  // ends before T also records the state row k1 the next piece starts from
  void RolloutOne(Worker& w, const mjModel* m, const SequenceInput& seq, int seq_index,
                  RowMatrix* states, RowMatrix* sensors, RowMatrix* step, std::vector<int>* ncon,
                  SolverStats* solver, std::atomic<int>* progress = nullptr, int k0 = 0,
                  int k1 = -1) const;
  // checks the inputs and sizes the trajectories of Rollout
  void SizeTrajectories(const std::vector<SequenceInput>& sequences,
                        std::vector<Trajectory>* out) const;
  // one rollout task (RolloutPiece's only piece); progress (optional): state rows recorded,
  // kRolloutFailed when it throws (m: the model to step, default the private one)
  void RolloutTask(Worker& w, const SequenceInput& seq, int seq_index, Trajectory* tr,
                   std::atomic<int>* progress, const mjModel* m = nullptr) const;
  // piece `piece` of `pieces` of a rollout task (Rollout): the first starts from x0, the others
  // wait until progress shows the state they continue from (and stop, without error, when the
  // piece before failed; progress required with more than one piece); progress and m as
  // RolloutTask's
  void RolloutPiece(Worker& w, const SequenceInput& seq, int seq_index, Trajectory* tr,
                    std::atomic<int>* progress, int piece, int pieces,
                    const mjModel* m = nullptr) const;
  // Jacobians; rollouts (sized, not simulated yet) are simulated in the same pass when given.
  // ahead (optional): with ahead_end, only the columns [0, ahead_end[i]) are computed, into
  // ahead[i] (directional mode); without, the columns of ahead[i] that match are taken and the
  // rest computed (see ColumnsAhead)
  void JacobiansImpl(const std::vector<SequenceInput>& sequences,
                     const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                     std::vector<Sensitivity>* out, std::vector<Trajectory>* rollouts,
                     std::vector<ColumnsAhead>* ahead = nullptr,
                     const std::vector<int>* ahead_end = nullptr);
  // whether RolloutAndJacobians can pipeline these options (ncol columns)
  bool CanPipeline(const JacobianOptions& opt, int ncol) const;
  void DirectionalColumn(Worker& w, const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                         const JacobianOptions& opt, int col, const Eigen::VectorXd& steps,
                         Sensitivity* out, TaskReport* report,
                         const std::atomic<int>* ready = nullptr) const;
  void WholeRolloutColumn(Worker& w, const SequenceInput& seq, int seq_index, const Trajectory& nom,
                          const JacobianOptions& opt, int col, const Eigen::VectorXd& steps,
                          Sensitivity* out, TaskReport* report) const;
  void MatrixJacobian(const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                      const JacobianOptions& opt, const Eigen::VectorXd& steps, Sensitivity* out,
                      SolverStats* solver);
  void ColumnJacobians(const std::vector<SequenceInput>& sequences,
                       const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                       JacobianMode mode, const Eigen::VectorXd& steps,
                       std::vector<Sensitivity>* out, std::vector<SolverStats>* solver,
                       std::vector<Trajectory>* rollouts = nullptr,
                       const std::vector<int>* col_begin = nullptr,
                       const std::vector<int>* col_end = nullptr,
                       std::vector<long long>* task_steps = nullptr);
  void CheckZeroColumns(const std::vector<Sensitivity>& out) const;
  // ChooseJacobianMode, and std::invalid_argument for a mode this model cannot use (matrix with
  // RK4 or delays, directional with delays)
  JacobianMode CheckedJacobianMode(const JacobianOptions& opt, double contact_fraction) const;
  // out sized and zeroed for Jacobians of these sequences (nominal checked against them)
  void SizeSensitivities(const std::vector<SequenceInput>& sequences,
                         const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                         JacobianMode mode, int ncol, std::vector<Sensitivity>* out) const;
  // each worker's vectors of one perturbed step
  void SizeColumnScratch();
  // matrix mode: each worker's scratch for steps with nu control columns
  void SizeMatrixScratch(int nu);
  // matrix mode: each worker's model copies with one parameter at p + steps and p - steps
  void PrepareMatrixModels(const Eigen::VectorXd& steps);
  // matrix mode: the blocks of time step k, step kk of the chunk c (simulator_matrix.cc)
  struct MatrixChunk;
  void MatrixStep(Worker& w, const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                  const JacobianOptions& opt, const Eigen::VectorXd& steps,
                  const std::vector<int>& order, int k, int kk, MatrixChunk* c) const;
  // runs call(); when the reduction's guard tripped during it, drops the reduction and runs it
  // again
  template <class Call>
  void Guarded(Call&& call);
  // throws Cancelled when the cancel flag is set
  void CheckCancel() const;
  // one step of m from d skipping the stages before skipstage (StepSkip), the sensors computed by
  // MuJoCo or, with a complete state_sensors_ plan, copied from d's state first
  void Step(const mjModel* m, mjData* d, int skipstage) const;
  // throws SimulationError when the step just taken warned; t: the time at the start of the step
  void CheckStep(const mjData& d, double t, int seq_index, int step, const char* what) const;

  ModelPtr model_;
  ParameterSet params_;
  StateDims dims_;
  SimulatorOptions options_;
  ThreadPool pool_;
  const std::atomic<bool>* cancel_ = nullptr;
  StateSensorPlan state_sensors_;  // complete only when copy_state_sensors applies
  DataPtr scratch_;                // for mj_setConst on model_
  std::vector<std::unique_ptr<Worker>> workers_;
  ModelReduction reduction_;                        // given to SetReduction
  bool reduced_ = false;                            // reduction_ is switched off in model_
  bool contacts_possible_full_ = false;             // ContactsPossible of the full model
  int reduction_trips_ = 0;                         // see ReductionTrips
  mutable std::atomic<bool> guard_tripped_{false};  // set by RolloutOne when the guard trips
  StepProgress* step_progress_ = nullptr;           // SetStepProgress
};

}  // namespace mjsysid
