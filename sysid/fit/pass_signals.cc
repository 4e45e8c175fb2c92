// Stage 8 of a fit pass (sysid/fit/pass.h): what the estimate means beyond its values: bound and
// identifiability warnings, and the simulated signals at the start and at the estimate, sequence by
// sequence; and stage 9's derived inertials.
#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "core/text.h"
#include "sysid/assess/derived_inertials.h"
#include "sysid/fit/pass.h"
#include "sysid/solve/residual_model.h"
#include "sysid/solve/state_residuals.h"

namespace mjsysid {
namespace {

// multiple shooting: a continuity gap (tangent space: m, rad, m/s, rad/s) above this at the
// estimate is reported as segments that do not join
constexpr double kContinuityGapWarning = 1e-3;

// Reduces the sequence's matrices (T x nsensordata, the model's layout) to the columns of the
// fitted sensors, in the order given, and fills their names, dimensions and the sample times.
void KeepFittedColumns(const mjModel& m, const std::vector<std::string>& fitted,
                       const FitSequence& sq, SequenceResult* sr) {
  std::vector<int> cols;
  for (const std::string& name : fitted) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
    sr->sensor_names.push_back(name);
    sr->sensor_dims.push_back(m.sensor_dim[id]);
    for (int c = 0; c < m.sensor_dim[id]; ++c) cols.push_back(m.sensor_adr[id] + c);
  }
  const Eigen::Index T = sr->measured.rows();
  for (RowMatrix* mat :
       {&sr->measured, &sr->simulated_initial, &sr->simulated_final, &sr->simulated_one_piece}) {
    if (mat->rows() == 0) continue;  // (no one-piece simulation)
    RowMatrix kept(T, static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) kept.col(c) = mat->col(cols[c]);
    *mat = std::move(kept);
  }
  sr->missing.assign(cols.size(), 0);
  for (size_t c = 0; c < cols.size(); ++c) {
    sr->missing[c] = static_cast<int>(sr->measured.col(c).array().isNaN().count());
  }
  if (sq.time.size() == T) {
    sr->time = sq.time;
  } else {
    sr->time = Eigen::VectorXd::LinSpaced(T, 0, static_cast<double>(T - 1)) * m.opt.timestep;
    sr->time.array() += sq.x0.time;
  }
}

// Rows [first, first + count) of *out: the simulated sensors (a rollout's T x ns rows from step
// k0) at those measured samples' positions, interpolated between steps like the residuals
void SensorsAtSamples(const RowMatrix& sensors, const SampleGrid& grid, int k0, int first,
                      int count, double dt, RowMatrix* out) {
  const int T = static_cast<int>(sensors.rows());
  for (int k = first; k < first + count; ++k) {
    const DelayedSample at(grid.position[k] - k0, T, 0.0, dt);
    for (Eigen::Index c = 0; c < sensors.cols(); ++c) {
      (*out)(k, c) = at.Value({sensors.data() + c, sensors.cols()});
    }
  }
}

}  // namespace

// 8. Bound and identifiability warnings, then every sequence's signals at the start and at the
// estimate (segment-wise in multiple shooting) with the largest continuity gap: segments that do
// not join describe no single trajectory, which the user must be told (docs/stress.md).
void FitPass::FinalSignals() {
  ledger_.Enter(kPhaseSignals);
  for (const auto& p : result_.parameters) {
    if (p.at_lower || p.at_upper) {
      result_.warnings.push_back("parameter '" + p.name + "' stopped on its " +
                                 (p.at_lower ? "lower" : "upper") +
                                 " bound: not estimated (no interval); the data may prefer a "
                                 "value outside the bounds");
    }
  }
  for (const std::string& line : result_.uncertainty.unidentifiable) {
    result_.warnings.push_back("unidentifiable: " + line);
  }
  // the controls at the fitted delays (the interval check evaluated others)
  if (nm_) solve_.SyncControlDelays(&fit_, vars_.m.data());
  if (fit_.shards) {
    SegmentEvaluator segments(parts_);
    fit_.shards->CollectStates(segments);
  }
  RolloutUnowned(&fit_, &plan_.initial);
  double worst_gap = 0;
  std::string worst_gap_where;
  for (size_t q = 0; q < fit_.sequences.size(); ++q)
    SequenceSignals(q, &worst_gap, &worst_gap_where);
  if (worst_gap > kContinuityGapWarning) {
    result_.warnings.push_back(std::string(kSegmentsDoNotJoinWarning) +
                               " (largest continuity gap " + FormatDigits(worst_gap, 3) +
                               " in state units, " + worst_gap_where + ")" +
                               kSegmentsDoNotJoinTail);
  }
}

// the physical quantities of bodies fitted through body_inertial (mass, centre of mass,
// principal moments) with delta-method intervals from the parameters' covariance
void FitPass::DerivedQuantities() {
  Eigen::VectorXd values(np_), se(np_);
  for (int v = 0; v < np_; ++v) {
    values[v] = result_.parameters[v].value;
    se[v] = result_.parameters[v].std_error;
  }
  Eigen::MatrixXd cov;
  if (result_.uncertainty.covariance.rows() >= np_) {
    cov = result_.uncertainty.covariance.topLeftCorner(np_, np_);
  }
  for (const auto& mo : fit_.models) {
    const std::string prefix = fit_.models.size() > 1 ? mo.name + "/" : "";
    for (DerivedQuantity& d :
         DeriveInertials(*mo.model, mo.name, fit_.params, values, se, cov, prefix)) {
      result_.derived.push_back(std::move(d));
    }
  }
}

// Sequence q's SequenceResult: measured, simulated at the start and at the estimate (measurement
// terms applied), the fitted states likewise, and the samples not measured (warned); the largest
// continuity gap at the estimate so far in *worst_gap
void FitPass::SequenceSignals(size_t q, double* worst_gap, std::string* worst_gap_where) {
  const FitSequence& sq = fit_.sequences[q];
  const FitModel& mo = fit_.models[fit_.ModelIndex(sq.model)];
  const std::vector<Trajectory>& initial = plan_.initial;
  SequenceResult sr;
  sr.name = sq.name;
  sr.model = sq.model;
  sr.measured = sq.measured;
  const SampleGrid& grid = fit_.grids[q];
  const double dt = mo.sim->model().opt.timestep;
  sr.simulated_initial.resize(sq.measured.rows(), sq.measured.cols());
  SensorsAtSamples(initial[q].sensors, grid, 0, 0, static_cast<int>(sq.measured.rows()), dt,
                   &sr.simulated_initial);
  sr.simulated_final.resize(sq.measured.rows(), sq.measured.cols());
  if (np_) ApplyVariables(fit_.params, mo.global, vars_.z.data(), mo.sim.get());
  const double* zv = np_ ? vars_.z.data() : nullptr;
  for (size_t s = 0; s < fit_.segments.size(); ++s) {
    const Segment& seg = fit_.segments[s];
    if (seg.seq != static_cast<int>(q)) continue;
    const double* x0 = fit_.X0(vars_.states, static_cast<int>(s));
    if (seg.k0 == 0) sr.x0_final = Eigen::Map<const Eigen::VectorXd>(x0, mo.sim->dims().nphys);
    try {
      // the rollout at the estimate, from the evaluation cache (the evaluation at the estimate
      // ran it; simulated here only if that evaluation failed)
      const EvaluationCache::Entry& cached =
          solve_.cache->Evaluate(static_cast<int>(s), zv, x0, false);
      if (cached.failed) throw std::runtime_error(cached.error);
      const Trajectory& tr = cached.tr;
      int first = 0, count = 0;
      fit_.SamplesOf(static_cast<int>(s), &first, &count);
      SimulatedAtSamples(q, tr, seg.k0, first, count, &sr.simulated_final);
      if (seg.next >= 0) {
        const int nx = mo.sim->dims().nx;
        Eigen::VectorXd gap(nx);
        TangentDifference(mo.sim->model(), vars_.states[seg.next].data(),
                          tr.states.row(seg.T).data(), 1.0, gap.data());
        if (gap.lpNorm<Eigen::Infinity>() > *worst_gap) {
          *worst_gap = gap.lpNorm<Eigen::Infinity>();
          *worst_gap_where = "sequence '" + sq.name + "' at step " + std::to_string(seg.k0 + seg.T);
        }
      }
    } catch (const std::exception& e) {
      result_.warnings.push_back("sequence '" + sq.name +
                                 "': final simulation failed: " + e.what());
    }
  }
  const bool segmented = std::count_if(fit_.segments.begin(), fit_.segments.end(),
                                       [&](auto& g) { return g.seq == static_cast<int>(q); }) > 1;
  if (segmented && sr.x0_final.size() > 0) OnePieceSignals(q, sr.x0_final, &sr);
  KeepFittedColumns(mo.sim->model(), fit_.fitted[q], sq, &sr);
  // fitted states: logged, at the initial values, at the estimate, weighted residuals
  if (!fit_.state_channels[q].empty()) {
    const std::vector<StateChannel>& chans = fit_.state_channels[q];
    const int T = static_cast<int>(sq.measured.rows());
    InitStateResult(chans, sq, &sr);
    StatesAtSamples(mo.sim->model(), chans, sq, initial[q].states, grid.position, 0, 0, T,
                    &sr.state_simulated_initial, nullptr);
    for (size_t s = 0; s < fit_.segments.size(); ++s) {
      const Segment& seg = fit_.segments[s];
      if (seg.seq != static_cast<int>(q)) continue;
      const EvaluationCache::Entry& cached = solve_.cache->Evaluate(
          static_cast<int>(s), zv, fit_.X0(vars_.states, static_cast<int>(s)), false);
      if (cached.failed) continue;  // warned above
      int first = 0, count = 0;
      fit_.SamplesOf(static_cast<int>(s), &first, &count);
      StatesAtSamples(mo.sim->model(), chans, sq, cached.tr.states, grid.position, seg.k0, first,
                      count, &sr.state_simulated_final, &sr.state_residual_final);
    }
    for (size_t i = 0; i < chans.size(); ++i) {
      if (fit_.state_missing[q][i] == 0) continue;
      result_.warnings.push_back("sequence '" + sq.name + "': state '" + chans[i].name +
                                 "': " + std::to_string(fit_.state_missing[q][i]) + " of " +
                                 std::to_string(T) +
                                 " samples not measured (NaN), masked out of the fit");
    }
  }
  // masked samples, sensor by sensor; event windows are said once (FitResult::event_windows), not
  // as unmeasured samples
  for (size_t i = 0, col = 0; i < sr.sensor_names.size(); col += sr.sensor_dims[i++]) {
    int missing = 0;
    for (int c = 0; c < sr.sensor_dims[i]; ++c) missing += sr.missing[col + c];
    for (int c = 0; c < sr.sensor_dims[i] && q < fit_.event_masked.size(); ++c) {
      if (col + c < fit_.event_masked[q].size()) missing -= fit_.event_masked[q][col + c];
    }
    if (missing == 0) continue;
    result_.warnings.push_back("sequence '" + sq.name + "': sensor '" + sr.sensor_names[i] +
                               "': " + std::to_string(missing) + " of " +
                               std::to_string(sr.measured.rows() * sr.sensor_dims[i]) +
                               " values not measured (NaN), masked out of the fit");
  }
  result_.sequences.push_back(std::move(sr));
}

void FitPass::SimulatedAtSamples(size_t q, const Trajectory& tr, int k0, int first, int count,
                                 RowMatrix* out) const {
  const FitSequence& sq = fit_.sequences[q];
  const double dt = fit_.models[fit_.ModelIndex(sq.model)].sim->model().opt.timestep;
  const SampleGrid& grid = fit_.grids[q];
  SensorsAtSamples(tr.sensors, grid, k0, first, count, dt, out);
  // the measurement terms applied to the fitted columns
  for (const Channel& ch : fit_.channels[q]) {
    if (ch.measurement < 0) continue;
    const MeasurementTerms terms = fit_.Terms(ch.measurement, nm_ ? vars_.m.data() : nullptr);
    const Signal simulated{tr.sensors.data() + ch.column, tr.sensors.cols()};
    for (int k = first; k < first + count; ++k) {
      const DelayedSample at(grid.position[k] - k0, tr.T, terms.delay, dt);
      (*out)(k, ch.column) = terms.Apply(at.Value(simulated));
    }
  }
}

// What the identified model gives: the whole sequence from its first state at the estimate (the
// simulator holds the estimate's parameters, the grid its fitted delays), without the later
// segments' fitted states; chaotic or unstable motion may leave it far from the data, which is
// what the user would see
void FitPass::OnePieceSignals(size_t q, const Eigen::VectorXd& x0, SequenceResult* sr) {
  const FitSequence& sq = fit_.sequences[q];
  const FitModel& mo = fit_.models[fit_.ModelIndex(sq.model)];
  const int nq = mo.sim->model().nq, nv = mo.sim->model().nv, na = mo.sim->model().na;
  const int T = static_cast<int>(sq.measured.rows());
  sr->simulated_one_piece =
      RowMatrix::Constant(T, sq.measured.cols(), std::numeric_limits<double>::quiet_NaN());
  SequenceInput in;
  in.x0.qpos = x0.segment(0, nq);
  in.x0.qvel = x0.segment(nq, nv);
  in.x0.act = x0.segment(nq + nv, na);
  in.x0.time = sq.x0.time;
  in.ctrl = fit_.grids[q].ctrl;
  const std::vector<StateChannel>& chans = fit_.state_channels[q];
  int width = 0;
  for (const StateChannel& ch : chans) width += ch.width();
  if (!chans.empty()) {
    sr->state_simulated_one_piece =
        RowMatrix::Constant(T, width, std::numeric_limits<double>::quiet_NaN());
  }
  try {
    const Trajectory tr = mo.sim->Rollout(in);
    SimulatedAtSamples(q, tr, 0, 0, T, &sr->simulated_one_piece);
    if (!chans.empty()) {
      StatesAtSamples(mo.sim->model(), chans, sq, tr.states, fit_.grids[q].position, 0, 0, T,
                      &sr->state_simulated_one_piece, nullptr);
    }
  } catch (const std::exception& e) {
    result_.warnings.push_back(
        "sequence '" + sq.name +
        "': the estimate simulated in one piece failed (its % fit is NaN): " + e.what());
  }
}

}  // namespace mjsysid
