// The state of a fit in four parts, each passed explicitly to the code that needs it:
// - PreparedFit: the inputs as added (Problem::Add*) and what PrepareFit (sysid/fit/prepare.h)
//   derives from them: simulators, channels, sample grids, segments, weights. Built once per
//   fit pass, then read during the solve; a solve changes only the simulators' parameters (each
//   rollout sets them) and the controls held at the fitted delays (SolveContext::
//   SyncControlDelays).
// - FitVariables: what Ceres moves, its parameter blocks (in this order): z (np: one per
//   FitParameter, FitParameter::ToVariable of its physical value), m (the fitted measurement
//   terms, in FitMeasurement order: delay, gain, bias of each; then the fitted control delays,
//   seconds, in AddControlDelay order), then the state blocks (physics vectors [qpos, qvel, act]
//   of the free initial states, one per sequence with estimate_initial_state and one per
//   multiple-shooting segment after the first).
// - FitDiagnostics: what the cost functions met (rejected trial points, Jacobian warnings), for
//   FitResult::warnings.
// - SolveContext: the evaluation cache and what the running solve lends the cost functions and
//   callbacks (its ledger, statistical stop, compressed blocks, progress events).
// Problem (sysid/problem.cc) owns one of each; FitParts lends all four to the fit pass, the
// preparation and the MPI shards. Not part of the public API.
//
// Threads: single-threaded like the EvaluationCache (sysid/solve/evaluation_cache.h), which
// aborts on a call from another thread; FitDiagnostics is written only by the cost functions
// after they have called the cache. The one exception: the compressed blocks' folds ahead
// (sysid/solve/compressed_cost.h) run SegmentCost::Rows on the simulator's workers, reading the
// prepared fit and a cache entry while the fit thread waits for them in the same batch; nothing
// is written there.
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
#include "sysid/solve/evaluation_cache.h"
#include "sysid/solve/fit_ledger.h"
#include "sysid/solve/progress.h"
#include "sysid/solve/residual_model.h"
#include "sysid/solve/state_blocks.h"
#include "sysid/solve/state_manifold.h"
#include "sysid/solve/state_residuals.h"
#include "sysid/types.h"

namespace mjsysid {

class GaussNewtonStop;    // sysid/solve/gn_convergence.h
struct CompressedBlocks;  // sysid/solve/compressed_cost.h
class ResidualShards;     // sysid/problem.h

// One model of a fit: as added, and its simulator as prepared
struct FitModel {
  std::string name;
  ModelPtr model;                           // the copy given to AddModel
  std::unique_ptr<Simulator> sim;           // PrepareFit: with the parameters that apply to it
  std::vector<int> global;                  // index in z of each simulator parameter
  std::unique_ptr<StateManifold> manifold;  // its physics state as a Ceres manifold
  // what the simulators PrepareFit replaced had counted: step calls, steps on the 2-worker critical
  // path, the pool's time. A pass's ledger reads the counts across its PrepareFit, which builds new
  // simulators: these totals keep growing where a simulator's own count restarts from 0.
  long long retired_steps = 0, retired_critical = 0;
  PoolTime retired_time;
  long long Steps() const { return retired_steps + (sim ? sim->StepCount() : 0); }
  long long CriticalSteps() const {
    return retired_critical + (sim ? sim->ParallelLoad().span[2] : 0);
  }
  PoolTime Time() const {
    PoolTime t = retired_time;
    if (sim) t += sim->ParallelTime();
    return t;
  }
};

struct PreparedFit {
  // inputs (Problem::Add*)
  std::vector<FitModel> models;
  std::vector<FitParameter> params;
  std::vector<FitMeasurement> measurements;
  std::vector<FitSequence> sequences;
  std::vector<FitControlDelay> control_delays;
  ResidualShards* shards = nullptr;  // segment residuals evaluated elsewhere (sysid/mpi/)
  // a sharded start (ShardStart, sysid/fit/prepare.h): the sequences PrepareFit simulates at the
  // initial values, given each sequence's work (SequenceWork; empty function or result: all)
  std::function<std::vector<bool>(const std::vector<double>& work)> owned_sequences;

  // derived (PrepareFit)
  FitOptions options;
  std::vector<std::vector<Channel>> channels;    // per sequence: its fitted sensor columns
  std::vector<std::vector<std::string>> fitted;  // per sequence: the fitted sensors, in order
  std::vector<TermIndex> term_index;             // per measurement: its terms in m
  std::vector<int> control_delay_index;          // per control delay: its index in m
  // per sequence, per actuator: the index in m of the fitted delay it follows, or -1 (its
  // FitSequence::ctrl_delay)
  std::vector<std::vector<int>> ctrl_delay_var;
  std::vector<Segment> segments;
  std::vector<std::vector<double>> fixed_x0;  // per sequence: the given x0 as physics vector
  std::vector<SampleGrid> grids;  // per sequence: its samples and controls on the simulation grid
  // per sequence and fitted channel (as `channels`): the samples not measured (NaN, masked)
  std::vector<std::vector<int>> missing;
  std::vector<std::string> prepare_warnings;  // what PrepareFit noticed (held NaN controls)
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
  // next PrepareFit starts from the data as given
  std::vector<std::tuple<int, int, int, double>> event_cells;
  // per parameter: its Jacobian moves the data of some simulated sequence (CheckParametersMove;
  // under a sharded start, of this process's sequences)
  std::vector<bool> moves;

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

  // a segment with its sequence and model, as its cost functions read them
  struct Refs {
    const Segment& seg;
    const FitSequence& sq;
    const FitModel& mo;
  };
  Refs SegmentRefs(int segment) const {
    const Segment& seg = segments[segment];
    return {seg, sequences[seg.seq], models[seg.model]};
  }

  // the work of sequence q's rollout with Jacobians: its simulation steps x (its model's
  // parameters + 1), for sharing the sequences out (sysid/mpi/); needs the simulators and grids
  double SequenceWork(int q) const {
    const FitModel& mo = models[ModelIndex(sequences[q].model)];
    const int columns = mo.sim->parameters().size() + 1;  // + the rollout
    return static_cast<double>(grids[q].steps) * columns;
  }

  // x_0 of a segment at the state blocks `states` (its block, or the sequence's given x0)
  const double* X0(const StateBlocks& states, int segment) const {
    const Segment& seg = segments[segment];
    return seg.block >= 0 ? states[seg.block].data() : fixed_x0[seg.seq].data();
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
  // its rollouts by them (SampleGrid::delay), so changed controls are simulated anew. Returns
  // whether it held them again.
  bool HoldControlsAt(int q, const double* mv);
};

// the variables Ceres moves (see the top of this file)
struct FitVariables {
  std::vector<double> z;  // transformed physical parameters
  std::vector<double> m;  // fitted measurement terms, then fitted control delays
  StateBlocks states;     // state blocks (physics vectors)
};

// What the cost functions met during a fit, so that FitResult::warnings can say it (a rejected
// trial point or a Jacobian past its validity is otherwise invisible to the user): the number of
// evaluations that failed (simulation warning, NaN, exception) with the first message, and the
// first core Jacobian warning per segment (e.g. a chaotic sensitivity that outgrew finite
// differences).
struct FitDiagnostics {
  int rejected_evaluations = 0;
  std::string first_rejection;
  std::map<int, std::string> jacobian_warnings;  // segment -> first warning

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
};

// The evaluation cache and what a running fit pass lends the cost functions and callbacks
struct SolveContext {
  std::unique_ptr<EvaluationCache> cache;  // borrows the prepared fit's params, sequences,
                                           // segments, grids and simulators
  // when the pass began (the progress lines' clock, sysid/solve/progress.h)
  std::chrono::steady_clock::time_point fit_start = std::chrono::steady_clock::now();
  // auto multiple shooting chose single shooting: the first Jacobian warning ends the solve
  // (ProgressCallback), and the fit policy refits in multiple shooting
  bool stop_on_jacobian_warning = false;
  // the running pass's ledger (borrowed; nullptr outside a pass): the evaluation callback charges
  // the solve's simulation to it
  FitLedger* ledger = nullptr;
  // the statistical stop before the last Jacobian (sysid/solve/gn_convergence.h, GaussNewtonStop::
  // TestBeforeJacobian): the pass's stop where it may run it (borrowed, nullptr: not), and while
  // previous_jacobian is set the cost functions answer a Jacobian request at the current point
  // with the simulator's sensitivities at the previous iterate (EvaluationCache::Previous; the
  // chain to the variables at the current point) and the evaluation callback simulates nothing.
  // Set by the evaluation callback for the test and, when it fires, until the pass has evaluated
  // the estimate; cleared by the pass.
  GaussNewtonStop* gn_stop = nullptr;
  bool previous_jacobian = false;
  // the epoch of what the cost functions read besides their parameter values, for the compressed
  // blocks' last folds (sysid/solve/compressed_cost.h CompressedBlocks::epoch): advanced when
  // previous_jacobian changes, when a sequence's controls are held at other delays
  // (SyncControlDelays) and when the jacobian warnings lose entries a fold's evaluation noted (a
  // written-out fold notes none)
  std::uint64_t cost_inputs_epoch = 0;
  // the running solve's compressed blocks (borrowed; nullptr outside the solve and the evaluation
  // at the estimate, and when FitOptions::advanced.fold_ahead is off): the evaluation callback
  // folds them ahead after each Jacobian batch (sysid/solve/compressed_cost.h FoldAhead)
  CompressedBlocks* compressed = nullptr;
  // fits with an observer: the progress events inside long rollouts (sysid/solve/progress.h), on
  // every simulator (created once, reset by each pass; PrepareFit installs it)
  std::unique_ptr<StepProgressEvents> step_progress;

  // sets previous_jacobian; a change advances cost_inputs_epoch
  void SetPreviousJacobian(bool on) {
    if (on != previous_jacobian) ++cost_inputs_epoch;
    previous_jacobian = on;
  }
  // the controls of sequence q (every sequence) held at the fitted delays in mv
  // (PreparedFit::HoldControlsAt); a change advances cost_inputs_epoch (the cost functions read
  // the controls)
  void SyncControlDelays(PreparedFit* fit, int q, const double* mv) {
    if (fit->HoldControlsAt(q, mv)) ++cost_inputs_epoch;
  }
  void SyncControlDelays(PreparedFit* fit, const double* mv) {
    for (size_t q = 0; q < fit->sequences.size(); ++q) {
      SyncControlDelays(fit, static_cast<int>(q), mv);
    }
  }
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
};

// The four parts of one Problem's fit, borrowed (Problem owns them)
struct FitParts {
  PreparedFit* fit;
  FitVariables* vars;
  FitDiagnostics* diag;
  SolveContext* solve;
};

}  // namespace mjsysid
