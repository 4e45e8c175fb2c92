#include "sysid/solve/evaluation_cache.h"

#include <algorithm>
#include <cstdlib>
#include <exception>
#include <string>
#include <utility>

#include "core/invariant.h"

namespace mjsysid {

void ApplyVariables(const std::vector<FitParameter>& parameters, const std::vector<int>& variables,
                    const double* z, Simulator* sim) {
  const int n = sim->parameters().size();
  if (n == 0) return;
  Eigen::VectorXd p(n);
  for (int j = 0; j < n; ++j) p[j] = parameters[variables[j]].FromVariable(z[variables[j]]);
  if (p != sim->GetParameters()) sim->SetParameters(p);
}

EvaluationCache::EvaluationCache(std::vector<Model> models,
                                 const std::vector<FitParameter>* parameters,
                                 const std::vector<FitSequence>* sequences,
                                 const std::vector<Segment>* segments,
                                 const JacobianOptions& jacobian)
    : models_(std::move(models)),
      parameters_(parameters),
      sequences_(sequences),
      segments_(segments),
      jacobian_(jacobian),
      entries_(segments->size()),
      kept_(segments->size()),
      spare_(segments->size()),
      owner_(std::this_thread::get_id()) {}

EvaluationCache::EvaluationCache(std::vector<Model> models,
                                 const std::vector<FitParameter>* parameters,
                                 const std::vector<FitSequence>* sequences,
                                 const std::vector<Segment>* segments,
                                 const JacobianOptions& jacobian,
                                 const std::vector<SampleGrid>* grids)
    : EvaluationCache(std::move(models), parameters, sequences, segments, jacobian) {
  grids_ = grids;
}

// a second thread would race on the entries and the simulators: a broken invariant, not an error
void EvaluationCache::CheckThread(const char* where) const {
  if (std::this_thread::get_id() == owner_) return;
  BrokenInvariant((std::string("EvaluationCache::") + where +
                   " called from a thread other than the one that built the cache (the cache is "
                   "single-threaded: Ceres must run with num_threads = 1)")
                      .c_str(),
                  __FILE__, __LINE__);
}

// [z, x_0, control delays]; z only when the fit has parameters; the delays its grid's controls
// were held with (SampleGrid::delay: a fitted control delay changes the controls)
std::vector<double> EvaluationCache::KeyOf(int segment, const double* z, const double* x0) const {
  const Model& mo = models_[(*segments_)[segment].model];
  std::vector<double> key(z, z + (z ? parameters_->size() : 0));
  key.insert(key.end(), x0, x0 + mo.sim->dims().nphys);
  if (grids_) {
    const std::vector<double>& delay = (*grids_)[(*segments_)[segment].seq].delay;
    key.insert(key.end(), delay.begin(), delay.end());
  }
  return key;
}

// the segment's controls from x0 at its start time
SequenceInput EvaluationCache::InputOf(int segment, const double* x0) const {
  const Segment& seg = (*segments_)[segment];
  const Simulator& sim = *models_[seg.model].sim;
  const StateDims& d = sim.dims();
  SequenceInput in;
  in.x0.qpos = Eigen::Map<const Eigen::VectorXd>(x0, d.nq);
  in.x0.qvel = Eigen::Map<const Eigen::VectorXd>(x0 + d.nq, d.nv);
  in.x0.act = Eigen::Map<const Eigen::VectorXd>(x0 + d.nq + d.nv, d.na);
  in.x0.time = seg.k0 * sim.model().opt.timestep;
  if (grids_) {
    const SampleGrid& grid = (*grids_)[seg.seq];
    in.ctrl = grid.ctrl.middleRows(seg.k0, grid.SimulatedSteps(seg.k0, seg.T));
  } else {
    in.ctrl = (*sequences_)[seg.seq].ctrl.middleRows(seg.k0, seg.T);
  }
  return in;
}

// the core's options for the Jacobians of a segment: initial-state columns when x_0 is a
// variable, state rows for continuity and fitted states
JacobianOptions EvaluationCache::GroupOptions(int segment) const {
  const Segment& seg = (*segments_)[segment];
  JacobianOptions jo = jacobian_;
  jo.initial_state = seg.block >= 0;
  jo.state_jacobians = seg.next >= 0 || seg.state_rows;
  jo.zero_column_is_error = false;
  return jo;
}

// Columns ahead for the rollouts of segs (one model), where they pay by the task model: the batch
// leaves idle = ceil(n / W) W - n slots; a columns ahead shorten the Jacobian batch of n c columns
// from ceil(n c / W) rounds to ceil((n c - a) / W), so the fewest a <= idle that reach the fewest
// rounds, given to the segments in order, at most c each (3 sequences x 3 columns on 2 workers:
// 1; 1 sequence x 2 columns: none, the 2 columns are one round already). None when the segments'
// Jacobians differ in kind (one options for the pass), with one worker, or outside the solve.
std::vector<int> EvaluationCache::AheadColumns(int mo, const std::vector<int>& segs) const {
  const Simulator& sim = *models_[mo].sim;
  const int workers = sim.threads(), n = static_cast<int>(segs.size());
  int idle = (n + workers - 1) / workers * workers - n;
  if (!columns_ahead_ || workers <= 1 || idle == 0) return {};
  const JacobianOptions jo = GroupOptions(segs[0]);
  for (int s : segs) {
    const JacobianOptions other = GroupOptions(s);
    if (other.initial_state != jo.initial_state || other.state_jacobians != jo.state_jacobians) {
      return {};
    }
  }
  const int ncol = sim.parameters().size() + (jo.initial_state ? sim.dims().nx : 0);
  const int total = n * ncol, rounds = (std::max(total - idle, 0) + workers - 1) / workers;
  if (rounds == (total + workers - 1) / workers) return {};  // no round saved
  idle = std::max(total - rounds * workers, 0);
  std::vector<int> columns(n, 0);
  for (int i = 0; i < n && idle > 0; ++i) {
    columns[i] = std::min(idle, ncol);
    idle -= columns[i];
  }
  return columns;
}

void EvaluationCache::Simulate(int mo, const std::vector<int>& segs, const double* z,
                               const std::vector<const double*>& x0s, bool jacobians) {
  Simulator& sim = *models_[mo].sim;
  if (z) ApplyVariables(*parameters_, models_[mo].variables, z, &sim);

  // rollouts of the segments whose key changed, in one batch; a throw marks them all failed
  std::vector<int> roll;
  std::vector<SequenceInput> ins;
  for (size_t i = 0; i < segs.size(); ++i) {
    Entry& c = entries_[segs[i]];
    std::vector<double> key = KeyOf(segs[i], z, x0s[i]);
    if (key == c.key) continue;
    // the last point with Jacobians (the iterate) waits aside while trial points are simulated;
    // asked for again (the evaluation at the estimate after the solve), it is not simulated anew
    Entry& kept = kept_[segs[i]];
    if (!kept.key.empty() && key == kept.key) {
      c = std::move(kept);
      kept = Entry();
      continue;
    }
    // a point PrefetchPoints simulated with others
    std::vector<Entry>& spare = spare_[segs[i]];
    auto held =
        std::find_if(spare.begin(), spare.end(), [&](const Entry& e) { return e.key == key; });
    if (held != spare.end()) {
      if (c.has_jacobians) kept = std::move(c);
      c = std::move(*held);
      spare.erase(held);
      continue;
    }
    if (c.has_jacobians) kept = std::move(c);
    c = Entry();
    c.key = std::move(key);
    roll.push_back(segs[i]);
    ins.push_back(InputOf(segs[i], x0s[i]));
  }
  if (!roll.empty()) {
    std::vector<Trajectory> trs;
    try {
      // a trial point: its first Jacobian columns on the workers its rollouts leave idle
      const std::vector<int> columns = jacobians ? std::vector<int>() : AheadColumns(mo, roll);
      if (columns.empty()) {
        sim.Rollout(ins, &trs);
      } else {
        std::vector<ColumnsAhead> ahead;
        sim.RolloutWithColumnsAhead(ins, GroupOptions(roll[0]), columns, &trs, &ahead);
        for (size_t i = 0; i < roll.size(); ++i) {
          ahead_steps_ += ahead[i].steps;
          entries_[roll[i]].ahead = std::move(ahead[i]);
        }
      }
      for (size_t i = 0; i < roll.size(); ++i) entries_[roll[i]].tr = std::move(trs[i]);
    } catch (const std::exception& e) {
      // a divergent trial point: rejected; cancelled: failed now, simulated again when asked
      const bool cancelled = dynamic_cast<const Cancelled*>(&e) != nullptr;
      for (int s : roll) {
        if (cancelled) entries_[s].key.clear();
        entries_[s].failed = true;
        entries_[s].error = e.what();
      }
    }
  }
  if (!jacobians) return;

  // the missing Jacobians, one batch per group: initial-state columns (x_0 is a variable) x
  // state rows (continuity and fitted states need them); the nominal rollouts are lent to the core
  // and moved back
  for (int group = 0; group < 4; ++group) {
    const bool with_x0 = group & 1, with_states = group & 2;
    std::vector<int> jac;
    std::vector<SequenceInput> jins;
    std::vector<Trajectory> nominal;
    std::vector<ColumnsAhead> ahead;
    for (size_t i = 0; i < segs.size(); ++i) {
      Entry& c = entries_[segs[i]];
      const Segment& seg = (*segments_)[segs[i]];
      if (c.failed || c.has_jacobians || c.jacobians_failed) continue;
      if ((seg.block >= 0) != with_x0 || (seg.next >= 0 || seg.state_rows) != with_states) continue;
      kept_[segs[i]] = Entry();  // one Jacobian per segment in memory: the new one replaces it
      jac.push_back(segs[i]);
      jins.push_back(InputOf(segs[i], x0s[i]));
      nominal.push_back(std::move(c.tr));
      ahead.push_back(std::move(c.ahead));
      c.ahead = ColumnsAhead();
    }
    if (jac.empty()) continue;
    const JacobianOptions jo = GroupOptions(jac[0]);
    std::vector<Sensitivity> sens;
    bool ok = true, cancelled = false;
    std::string error;
    try {
      // the columns computed ahead that the simulator takes (left empty) are work used
      std::vector<long long> steps(ahead.size());
      for (size_t i = 0; i < ahead.size(); ++i) steps[i] = ahead[i].steps;
      sim.Jacobians(jins, nominal, jo, &ahead, &sens);
      for (size_t i = 0; i < ahead.size(); ++i) {
        if (ahead[i].columns == 0) ahead_used_steps_ += steps[i];
      }
    } catch (const Cancelled& e) {
      ok = false;
      cancelled = true;  // not a property of the point: computed again when asked
      error = e.what();
    } catch (const std::exception& e) {
      ok = false;
      error = e.what();
    }
    for (size_t i = 0; i < jac.size(); ++i) {
      Entry& c = entries_[jac[i]];
      c.tr = std::move(nominal[i]);
      c.has_jacobians = ok;
      c.jacobians_failed = !ok && !cancelled;
      c.error = error;
      if (ok) c.s = std::move(sens[i]);
    }
  }
}

const EvaluationCache::Entry& EvaluationCache::Evaluate(int segment, const double* z,
                                                        const double* x0, bool jacobians) {
  CheckThread("Evaluate");
  const Entry& c = entries_[segment];
  if (c.key != KeyOf(segment, z, x0) || (jacobians && !c.has_jacobians && !c.failed)) {
    Simulate((*segments_)[segment].model, {segment}, z, {x0}, jacobians);
  }
  return c;
}

const EvaluationCache::Entry* EvaluationCache::Ready(int segment, const double* z, const double* x0,
                                                     bool jacobians) const {
  CheckThread("Ready");
  const Entry& c = entries_[segment];
  if (c.failed || (jacobians && !c.has_jacobians) || c.key != KeyOf(segment, z, x0)) return nullptr;
  return &c;
}

void EvaluationCache::Prefetch(const double* z, const std::vector<const double*>& x0,
                               bool jacobians) {
  CheckThread("Prefetch");
  for (int mo = 0; mo < static_cast<int>(models_.size()); ++mo) {
    std::vector<int> segs;
    std::vector<const double*> x0s;
    for (int s = 0; s < static_cast<int>(segments_->size()); ++s) {
      if ((*segments_)[s].model != mo || x0[s] == nullptr) continue;
      segs.push_back(s);
      x0s.push_back(x0[s]);
    }
    if (!segs.empty()) Simulate(mo, segs, z, x0s, jacobians);
  }
}

void EvaluationCache::PrefetchPoints(const std::vector<const double*>& zs,
                                     const std::vector<const double*>& x0) {
  CheckThread("PrefetchPoints");
  for (std::vector<Entry>& spare : spare_) spare.clear();
  for (int mo = 0; mo < static_cast<int>(models_.size()); ++mo) {
    std::vector<int> segs;
    std::vector<SequenceInput> ins;
    for (int s = 0; s < static_cast<int>(segments_->size()); ++s) {
      if ((*segments_)[s].model != mo || x0[s] == nullptr) continue;
      segs.push_back(s);
      ins.push_back(InputOf(s, x0[s]));
    }
    if (segs.empty()) continue;
    // the simulator's parameter values at each point (as ApplyVariables writes them)
    Simulator& sim = *models_[mo].sim;
    const std::vector<int>& variables = models_[mo].variables;
    std::vector<Eigen::VectorXd> values(zs.size(), Eigen::VectorXd(sim.parameters().size()));
    for (size_t k = 0; k < zs.size(); ++k) {
      for (int j = 0; j < values[k].size(); ++j) {
        values[k][j] = (*parameters_)[variables[j]].FromVariable(zs[k][variables[j]]);
      }
    }
    std::vector<std::vector<Trajectory>> trs;
    try {
      sim.RolloutAt(ins, values, &trs);
    } catch (const std::exception&) {
      continue;  // simulated one by one when asked, failing there as before
    }
    for (size_t k = 0; k < zs.size(); ++k) {
      for (size_t i = 0; i < segs.size(); ++i) {
        Entry e;
        e.key = KeyOf(segs[i], zs[k], x0[segs[i]]);
        e.tr = std::move(trs[k][i]);
        spare_[segs[i]].push_back(std::move(e));
      }
    }
  }
}

void EvaluationCache::Seed(int segment, const double* z, const double* x0, Trajectory tr,
                           Sensitivity s) {
  CheckThread("Seed");
  Entry& c = entries_[segment];
  c = Entry();
  kept_[segment] = Entry();
  c.key = KeyOf(segment, z, x0);
  c.tr = std::move(tr);
  c.s = std::move(s);
  // state rows only where a continuity or state residual reads them (the caller's Jacobian had
  // them for its own checks): (T+1) nx ncol numbers per segment not kept
  const Segment& seg = (*segments_)[segment];
  if (seg.next < 0 && !seg.state_rows) c.s.DxDp = RowMatrix();
  const int np = models_[(*segments_)[segment].model].sim->parameters().size();
  c.has_jacobians = c.s.ncol == np && c.s.ncol > 0;
}

}  // namespace mjsysid
