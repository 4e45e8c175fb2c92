// The state behind Problem (sysid/problem.h): its inputs, the fit PrepareFit derives from
// them (simulators, channels, segments, variables, the evaluation cache) and what the cost
// functions met during a fit. Shared by the fit pass (sysid/fit/) and the Ceres cost
// functions (sysid/solve/cost_functions.h); not part of the public API.
//
// Variables, as Ceres sees them (parameter blocks, in this order): z (np: one per FitParameter,
// FitParameter::ToVariable of its physical value), m (the fitted measurement terms, in
// FitMeasurement order: delay, gain, bias of each; then the fitted control delays, seconds, in
// AddControlDelay order), then the state blocks (physics vectors
// [qpos, qvel, act] of the free initial states, one per sequence with estimate_initial_state and
// one per multiple-shooting segment after the first).
//
// Threads: single-threaded like its EvaluationCache (sysid/solve/evaluation_cache.h), which aborts
// on a call from another thread; the diagnostics below are written only by SegmentCost after it has
// called the cache. The one exception: the compressed blocks' folds ahead
// (sysid/solve/compressed_cost.h) run SegmentCost::Rows on the simulator's workers, reading the
// prepared fit and a cache entry while the fit thread waits for them in the same batch; nothing is
// written there.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "core/simulator.h"
#include "sysid/data/sample_grid.h"
#include "sysid/problem.h"
#include "sysid/solve/evaluation_cache.h"
#include "sysid/solve/fit_ledger.h"
#include "sysid/solve/progress.h"
#include "sysid/solve/residual_model.h"
#include "sysid/solve/state_manifold.h"
#include "sysid/solve/state_residuals.h"
#include "sysid/types.h"

namespace mjsysid {

class GaussNewtonStop;    // sysid/solve/gn_convergence.h
struct CompressedBlocks;  // sysid/solve/compressed_cost.h

// The state blocks of a fit (the segments' initial states, Ceres parameter blocks), stored
// contiguously in block order. Ceres keeps the blocks of an elimination group in a
// std::set<double*>, i.e. ordered by address, and orders the Schur elimination and the residual
// blocks by it: with one allocation per block that order followed the heap (other threads'
// allocations, the thread count), and so did the rounding of every sum over segments (measured:
// the pendulum in 100-step segments, iteration 0's cost 1 ulp apart between 1 and 2 threads,
// the finger 29 vs 49 iterations). Contiguous storage makes it the block order, always.
// Pointers (data()) stay valid until the next push_back or clear.
class StateBlocks {
 public:
  template <class T>
  struct View {
    T* p;
    int n;
    T* data() const { return p; }
    size_t size() const { return static_cast<size_t>(n); }
    T* begin() const { return p; }
    T* end() const { return p + n; }
  };
  void clear() {
    values_.clear();
    first_.clear();
  }
  size_t size() const { return first_.size(); }
  bool empty() const { return first_.empty(); }
  // appends a block with the values x
  void push_back(const std::vector<double>& x) {
    first_.push_back(values_.size());
    values_.insert(values_.end(), x.begin(), x.end());
  }
  View<double> operator[](size_t i) { return {values_.data() + first_[i], Size(i)}; }
  View<const double> operator[](size_t i) const { return {values_.data() + first_[i], Size(i)}; }

 private:
  int Size(size_t i) const {
    const size_t end = i + 1 < first_.size() ? first_[i + 1] : values_.size();
    return static_cast<int>(end - first_[i]);
  }
  std::vector<double> values_;  // every block, in order
  std::vector<size_t> first_;   // per block: its first value
};

struct Problem::Impl {
  struct Model {
    std::string name;
    ModelPtr model;                           // the copy given to AddModel
    std::unique_ptr<Simulator> sim;           // Prepare: with the parameters that apply to it
    std::vector<int> global;                  // index in z of each simulator parameter
    std::unique_ptr<StateManifold> manifold;  // its physics state as a Ceres manifold
  };

  // inputs (Add*)
  std::vector<Model> models;
  std::vector<FitParameter> params;
  std::vector<FitMeasurement> measurements;
  std::vector<FitSequence> sequences;
  std::vector<FitControlDelay> control_delays;
  ResidualShards* shards = nullptr;  // segment residuals evaluated elsewhere (sysid/mpi/)

  // the prepared fit (Prepare)
  FitOptions options;
  std::vector<std::vector<Channel>> channels;    // per sequence: its fitted sensor columns
  std::vector<std::vector<std::string>> fitted;  // per sequence: the fitted sensors, in order
  std::vector<TermIndex> term_index;             // per measurement: its terms in m
  std::vector<int> control_delay_index;          // per control delay: its index in m
  // per sequence, per actuator: the index in m of the fitted delay it follows, or -1 (its
  // FitSequence::ctrl_delay)
  std::vector<std::vector<int>> ctrl_delay_var;
  std::vector<Segment> segments;
  std::vector<double> z;                      // transformed physical parameters
  std::vector<double> m;                      // fitted measurement terms
  StateBlocks states;                         // state blocks (physics vectors)
  std::vector<std::vector<double>> fixed_x0;  // per sequence: the given x0 as physics vector
  std::unique_ptr<EvaluationCache> cache;     // borrows params, sequences, segments, simulators
  std::vector<SampleGrid> grids;  // per sequence: its samples and controls on the simulation grid
  // per sequence and fitted channel (as `channels`): the samples not measured (NaN, masked)
  std::vector<std::vector<int>> missing;
  std::vector<std::string> prepare_warnings;  // what Prepare noticed (held NaN controls)
  // per sequence: its fitted states (FitOptions::states, sysid/solve/state_residuals.h) and, per
  // channel, the samples not measured (NaN, masked)
  std::vector<std::vector<StateChannel>> state_channels;
  std::vector<std::vector<int>> state_missing;
  // multiple shooting: per model, per tangent coordinate (nx): the continuity rows' weights
  // (sysid/solve/multiple_shooting.h, ContinuityWeights)
  std::vector<std::vector<double>> continuity_weights;
  // per sequence and fitted channel (as `channels`): the cells of `missing` that are event
  // windows (sysid/data/event_windows.h), not unmeasured samples
  std::vector<std::vector<int>> event_masked;
  // the measured cells the event windows set to NaN: (sequence, row, column, value), so that the
  // next Prepare starts from the data as given
  std::vector<std::tuple<int, int, int, double>> event_cells;

  // What the cost functions met during a fit, so that FitResult::warnings can say it (a rejected
  // trial point or a Jacobian past its validity is otherwise invisible to the user): the number
  // of evaluations that failed (simulation warning, NaN, exception) with the first message, and
  // the first core Jacobian warning per segment (e.g. a chaotic sensitivity that outgrew finite
  // differences).
  int rejected_evaluations = 0;
  std::string first_rejection;
  std::map<int, std::string> jacobian_warnings;  // segment -> first warning
  // auto multiple shooting chose single shooting: the first Jacobian warning ends the solve
  // (ProgressCallback), and Fit refits in multiple shooting
  bool stop_on_jacobian_warning = false;
  void NoteRejection(const std::string& what) {
    if (rejected_evaluations++ == 0) first_rejection = what;
  }
  // A cost function's evaluation: true when `evaluate` returns true; false (Ceres rejects the
  // trial point and shrinks the trust region) when it returns false (non-finite residuals,
  // counted under `non_finite`) or throws (counted under the exception's text)
  template <class F>
  bool EvaluateOrReject(const char* non_finite, F&& evaluate) {
    try {
      if (evaluate()) return true;
      NoteRejection(non_finite);
      return false;
    } catch (const std::exception& e) {
      NoteRejection(e.what());
      return false;
    }
  }
  void NoteJacobianWarning(int segment, const std::string& what) {
    jacobian_warnings.emplace(segment, what);
  }

  // index of the model added under name; throws std::invalid_argument when there is none
  int ModelIndex(const std::string& name) const {
    for (size_t i = 0; i < models.size(); ++i) {
      if (models[i].name == name) return static_cast<int>(i);
    }
    throw std::invalid_argument("no model named '" + name + "' (add it with AddModel)");
  }

  double Physical(int g, double zg) const { return params[g].FromVariable(zg); }
  double ToZ(int g, double p) const { return params[g].ToVariable(p); }
  // dp/dz at z
  double DpDz(int g, double zg) const {
    switch (params[g].transform) {
      case Transform::kLog:
        return std::exp(zg);
      case Transform::kScale:
        return params[g].scale;
      default:
        return 1.0;
    }
  }

  // the terms of measurement i at the fitted values mv (nullptr: initial values)
  MeasurementTerms Terms(int i, const double* mv) const {
    const FitMeasurement& me = measurements[i];
    return CurrentTerms({me.delay.initial, me.gain.initial, me.bias.initial}, term_index[i], mv);
  }

  // the measured samples of a segment: [*first, *first + *count) of its sequence, and the steps
  // its rollout holds (sysid/data/sample_grid.h)
  void SamplesOf(int segment, int* first, int* count) const {
    const Segment& seg = segments[segment];
    grids[seg.seq].SamplesOf(seg.k0, seg.T, first, count);
  }
  // residual rows of a segment's measured cells (NaN cells are masked out)
  int MeasuredRows(int segment) const {
    const Segment& seg = segments[segment];
    int first = 0, count = 0, rows = 0;
    SamplesOf(segment, &first, &count);
    const RowMatrix& y = sequences[seg.seq].measured;
    for (int k = first; k < first + count; ++k) {
      for (const Channel& ch : channels[seg.seq]) rows += std::isnan(y(k, ch.column)) ? 0 : 1;
    }
    return rows;
  }

  // whether sequence q has an actuator with a fitted control delay
  bool HasControlDelay(int q) const {
    for (int v : ctrl_delay_var[q]) {
      if (v >= 0) return true;
    }
    return false;
  }
  // the per-actuator delays (s) of sequence q at the m block mv (its fitted delays, the others
  // as given), each fitted one shifted by `shift` when it is m[shifted]
  std::vector<double> ControlDelays(int q, const double* mv, int shifted = -1,
                                    double shift = 0) const;
  // Holds sequence q's controls on its grid again (sysid/data/sample_grid.h HoldControls) when the
  // fitted delays in mv differ from those its controls were held with; the evaluation cache keys
  // its rollouts by them (SampleGrid::delay), so changed controls are simulated anew
  void SyncControlDelays(int q, const double* mv);
  void SyncControlDelays(const double* mv) {
    for (size_t q = 0; q < sequences.size(); ++q) SyncControlDelays(static_cast<int>(q), mv);
  }

  // a sharded start (Problem::ShardStart): the sequences Prepare simulates at the initial values
  // (empty function or result: all), and per parameter whether their Jacobian moves the data
  std::function<std::vector<bool>(const Impl&)> owned_sequences;
  std::vector<bool> moves;

  // when Fit began (the progress lines' clock, sysid/solve/progress.h)
  std::chrono::steady_clock::time_point fit_start = std::chrono::steady_clock::now();

  // x_0 of a segment in the current variables (its state block, or the sequence's given x0)
  const double* X0(int segment) const {
    const Segment& seg = segments[segment];
    return seg.block >= 0 ? states[seg.block].data() : fixed_x0[seg.seq].data();
  }
  // the running fit's ledger (Fit's own, borrowed; nullptr outside Fit): the evaluation callback
  // charges the solve's simulation to it
  FitLedger* ledger = nullptr;
  // the statistical stop before the last Jacobian (sysid/solve/gn_convergence.h, GaussNewtonStop::
  // TestBeforeJacobian): the fit's stop where it may run it (borrowed, nullptr: not), and while
  // previous_jacobian is set the cost functions answer a Jacobian request at the current point
  // with the simulator's sensitivities at the previous iterate (EvaluationCache::Previous; the
  // chain to the variables at the current point) and the evaluation callback simulates nothing.
  // Set by the evaluation callback for the test and, when it fires, until Fit has evaluated the
  // estimate; cleared by Fit.
  GaussNewtonStop* gn_stop = nullptr;
  bool previous_jacobian = false;
  // sets previous_jacobian; a change advances cost_inputs_epoch
  void SetPreviousJacobian(bool on) {
    if (on != previous_jacobian) ++cost_inputs_epoch;
    previous_jacobian = on;
  }
  // the epoch of what the cost functions read besides their parameter values, for the compressed
  // blocks' last folds (sysid/solve/compressed_cost.h CompressedBlocks::epoch): advanced when
  // previous_jacobian changes, when a sequence's controls are held at other delays
  // (SyncControlDelays) and when jacobian_warnings loses entries a fold's evaluation noted (a
  // written-out fold notes none)
  std::uint64_t cost_inputs_epoch = 0;
  // a cost function's entry of segment at zv and x0, with Jacobians when want; *s: the
  // sensitivities to read (the entry's, or the previous iterate's under previous_jacobian).
  // Throws the entry's error when it failed (the cost function rejects the point).
  const EvaluationCache::Entry& CostEntry(int segment, const double* zv, const double* x0,
                                          bool want, const Sensitivity** s) {
    const bool previous = want && previous_jacobian;
    const EvaluationCache::Entry& e = cache->Evaluate(segment, zv, x0, want && !previous);
    const EvaluationCache::Entry* with =
        previous && !e.has_jacobians ? cache->Previous(segment) : &e;
    if (e.failed) throw std::runtime_error(e.error);
    if (want && (with == nullptr || !with->has_jacobians)) {
      throw std::runtime_error(with == &e ? e.error : "no Jacobian at the previous iterate");
    }
    *s = &with->s;
    return e;
  }
  // the running solve's compressed blocks (Fit's own, borrowed; nullptr outside the solve and the
  // evaluation at the estimate, and when FitOptions::advanced.fold_ahead is off): the evaluation
  // callback folds them ahead after each Jacobian batch (sysid/solve/compressed_cost.h FoldAhead)
  CompressedBlocks* compressed = nullptr;
  // fits with an observer: the progress events inside long rollouts (sysid/solve/progress.h), on
  // every simulator (created once, reset by each pass; PrepareFit installs it)
  std::unique_ptr<StepProgressEvents> step_progress;
};

// What PrepareFit decided besides the prepared state: the rollouts at the initial values, the
// variables' names, bounds and starts, the Jacobian mode and the segments chosen
struct FitPlan {
  std::vector<Trajectory> initial;  // rollouts at the initial values
  std::vector<std::string> names;   // parameters, measurement terms, then control delays
  std::vector<std::pair<double, double>> mbounds;  // bounds of the m block (terms, delays)
  std::vector<double> minitial;                    // their initial values
  std::string jacobian_mode;
  int segment_steps = 0;    // multiple shooting as chosen (0: single shooting)
  SegmentRecord segments;   // why (FitResult::segment_reason)
  double probe_rate = 0;    // growth rate per step of the auto probe
  double probe_growth = 0;  // its largest growth beyond linear (HorizonChoice::growth)
  FitResult::EventWindows event_windows;  // auto's contact segments (sysid/data/event_windows.h)
  bool contact_segments = false;          // auto chose contact segments (HorizonChoice)
};

// Validates the inputs (names, shapes, bounds, the data every parameter must move) and builds what
// a fit runs on (sysid/problem_prepare.cc): the simulators with their parameters, the variables,
// the sample grids, the segments, the initial rollouts and Jacobians and the evaluation cache.
// Throws std::invalid_argument / ParameterError on bad input.
FitPlan PrepareFit(Problem::Impl* impl, const FitOptions& options);

// throws ParameterError naming the first parameter g with !moves[g] (its Jacobian column is zero
// in every sequence at the initial values): what Prepare checks, or the caller of a sharded start
// with moves combined over every shard
void CheckParametersMove(const Problem::Impl& I, const std::vector<bool>& moves);

// A sharded start (Problem::ShardStart) simulated only the owned sequences at the initial values:
// rolls out the others (those with an empty trajectory in initial; no Jacobians), and leaves the
// simulators at the initial parameters
void RolloutUnowned(Problem::Impl* impl, std::vector<Trajectory>* initial);

// initial: auto (FitParameter::initial_auto): the equation-error start of each model's `auto`
// parameters from its sequences' logged qpos and qvel (sysid/data/equation_error.h); a parameter
// that cannot be solved starts at its model's value. The marks are cleared, so that a refit (auto
// multiple shooting) starts from the same values. Returns one line per model, for the warnings.
// threads: the fit's (FitOptions::threads), for the samples' inverse dynamics.
std::vector<std::string> SolveAutoStarts(Problem::Impl* impl, int threads);

}  // namespace mjsysid
