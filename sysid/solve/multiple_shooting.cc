// Multiple shooting (sysid/solve/multiple_shooting.h): the automatic segment length, the segments'
// initial states from the data, the Schur-complement linear solver and the Jacobian split for
// the reduced uncertainty.
#include "sysid/solve/multiple_shooting.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "core/state.h"
#include "core/text.h"
#include "sysid/data/contact_channels.h"

namespace mjsysid {

// Multiple shooting has the structure of bundle adjustment: each segment's residuals touch the
// global variables (z, m) and its own initial state (plus the next segment's, by continuity).
// The linear solver is then Ceres' Schur complement: state blocks are eliminated first, as
// many as form an independent set (no residual block holds two of them: along each sequence's
// chain of segments every other block), and the reduced system of the
// global variables and the remaining states is solved dense (<= 200 tangent dimensions) or
// sparse (SuiteSparse). Single shooting keeps dense QR (sparse normal Cholesky past 200).
void ChooseLinearSolver(const PreparedFit& fit, FitVariables& vars, int tangent,
                        ceres::Solver::Options* so) {
  bool multiple = false;
  for (const Segment& seg : fit.segments) multiple = multiple || seg.next >= 0;
  // sharded (sysid/mpi/): the states are eliminated by the shards, Ceres sees z and m (tangent)
  if (!multiple || fit.shards) {
    so->linear_solver_type = tangent <= 200 ? ceres::DENSE_QR : ceres::SPARSE_NORMAL_CHOLESKY;
    return;
  }
  // the state blocks of a sequence in segment order form a chain (a segment's residual holds its
  // own block and the next one): every other one of it is eliminated
  std::vector<bool> eliminated(vars.states.size(), false);
  int position = 0, seq = -1;
  for (const Segment& seg : fit.segments) {
    if (seg.seq != seq) seq = seg.seq, position = 0;
    if (seg.block >= 0) eliminated[seg.block] = position++ % 2 == 0;
  }
  // Ceres orders the blocks of one group by memory address: the kept states, z and m each get
  // their own group (the states are contiguous in block order, sysid/solve/fit_state.h
  // StateBlocks), so the reduced system's column order, and every sum over it, is the same in every
  // run. The sparse Cholesky factorises the groups in this order (a constrained minimum-degree
  // ordering), so z and m, which every residual touches, come last: first, they would fill the
  // whole factor (a humanoid's 1000 kept states of 54: CHOLMOD "problem too large")
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  int reduced = tangent;
  for (size_t b = 0; b < vars.states.size(); ++b) {
    ordering->AddElementToGroup(vars.states[b].data(), eliminated[b] ? 0 : 1);
    if (eliminated[b]) reduced -= static_cast<int>(vars.states[b].size());
  }
  if (!vars.z.empty()) ordering->AddElementToGroup(vars.z.data(), 2);
  if (!vars.m.empty()) ordering->AddElementToGroup(vars.m.data(), 3);
  so->linear_solver_ordering = ordering;
  so->linear_solver_type = reduced <= 200 ? ceres::DENSE_SCHUR : ceres::SPARSE_SCHUR;
}

// Ceres' Jacobian (CRS, columns: z, m, then the state blocks in tangent space) split into the
// dense columns of the first nvar variables (A, m x nvar) and the sparse state columns (B)
void SplitJacobian(const ceres::CRSMatrix& crs, int nvar, RowMatrix* A,
                   Eigen::SparseMatrix<double>* B) {
  *A = RowMatrix::Zero(crs.num_rows, nvar);
  std::vector<Eigen::Triplet<double>> entries;
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int i = crs.rows[r]; i < crs.rows[r + 1]; ++i) {
      const int c = crs.cols[i];
      if (c < nvar) {
        (*A)(r, c) = crs.values[i];
      } else {
        entries.emplace_back(r, c - nvar, crs.values[i]);
      }
    }
  }
  B->resize(crs.num_rows, crs.num_cols - nvar);
  B->setFromTriplets(entries.begin(), entries.end());
}

// Automatic multiple shooting (FitOptions::segment_steps = -1), decided by a probe at the
// initial values: each sequence is simulated once more from its x0 with every velocity raised by
// h = kProbeStep (1 + |qvel|_inf), and the perturbation's growth P_k = |x'_k (-) x_k|_inf / h
// (tangent space, state units) is measured along the rollout. A velocity perturbation moves
// positions linearly in time, so the growth beyond that, E_k = P_k / (1 + t_k) (t_k in seconds
// from the start), is the exponential part: bounded or oscillating (E ~ 1) on stable and
// dissipative systems, e^(lambda k) on chaotic ones. Single shooting is kept while
// E_k <= kExponentialGrowth over every sequence. Otherwise, at the first step k* where E passes
// it, the rate per step is lambda = ln(E_k*) / k* and segments are ln(2) / lambda steps long (the
// perturbation at most doubles beyond linear in each), at least kMinSegmentSteps. The probe stops
// where its perturbation reaches kSensitivityGrowthLimit (still local) or the horizon ends.
constexpr double kProbeStep = 1e-8;
constexpr double kExponentialGrowth = 1e2;
constexpr int kMinSegmentSteps = 10;
// growth beyond linear allowed within one segment (measured: with 10, 1090-step segments on the
// high-energy chaotic double pendulum did not recover, tests/stress/horizon_stress_test.cc)
constexpr double kSegmentGrowth = 2;

// The probe of ChooseHorizon: every sequence from its x0 with every qvel raised by h (*h_out[q]),
// on the simulation grid's controls, at the current parameters. Simulated in one batch per model
// (in parallel across sequences, as the fit's rollouts); a batch that throws is simulated again
// one sequence at a time, and a probe that still throws stays empty (T = 0: it decides nothing).
static std::vector<Trajectory> ProbeRollouts(const PreparedFit& fit, std::vector<double>* h_out) {
  std::vector<Trajectory> probes(fit.sequences.size());
  h_out->assign(fit.sequences.size(), 0.0);
  for (size_t mi = 0; mi < fit.models.size(); ++mi) {
    Simulator& sim = *fit.models[mi].sim;
    std::vector<SequenceInput> ins;
    std::vector<size_t> which;
    for (size_t q = 0; q < fit.sequences.size(); ++q) {
      const FitSequence& sq = fit.sequences[q];
      if (fit.ModelIndex(sq.model) != static_cast<int>(mi)) continue;
      SequenceInput in{sq.x0, fit.grids[q].ctrl};  // the controls on the simulation grid
      if (in.x0.qvel.size() != sim.model().nv) in.x0.qvel = Eigen::VectorXd::Zero(sim.model().nv);
      (*h_out)[q] = kProbeStep * (1 + in.x0.qvel.lpNorm<Eigen::Infinity>());
      in.x0.qvel.array() += (*h_out)[q];
      ins.push_back(std::move(in));
      which.push_back(q);
    }
    if (ins.empty()) continue;
    std::vector<Trajectory> trs;
    try {
      sim.Rollout(ins, &trs);
      for (size_t i = 0; i < which.size(); ++i) probes[which[i]] = std::move(trs[i]);
    } catch (const std::exception&) {
      for (size_t i = 0; i < which.size(); ++i) {
        try {
          probes[which[i]] = sim.Rollout(ins[i]);
        } catch (const std::exception&) {
          // a probe that diverges decides nothing; the fit reports its own failures
        }
      }
    }
  }
  return probes;
}

HorizonChoice ChooseHorizon(const PreparedFit& fit, const std::vector<Trajectory>& initial,
                            const FitOptions& options) {
  HorizonChoice out;
  if (options.segment_steps >= 0) {
    out.steps = options.segment_steps;
    out.reason = out.steps == 0
                     ? "single shooting: segment_steps 0 (set)"
                     : "multiple shooting: segment_steps " + std::to_string(out.steps) + " (set)";
    // a global-stage pass repeating a local fit's contact segments (sysid/fit/global_stage.h)
    out.contacts = out.steps > 0 && options.continuation.contact_segments;
    return out;
  }
  double worst_e = 0, rate = 0;  // largest E; lambda of the earliest crossing
  int first = -1;                // the earliest k*
  std::string where;             // its sequence
  std::vector<double> hs;
  const std::vector<Trajectory> probes = ProbeRollouts(fit, &hs);
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    const FitSequence& sq = fit.sequences[q];
    const Simulator& sim = *fit.models[fit.ModelIndex(sq.model)].sim;
    const mjModel& m = sim.model();
    const StateDims& d = sim.dims();
    const double h = hs[q];
    const Trajectory& probe = probes[q];
    if (probe.states.rows() == 0) continue;  // diverged: decides nothing
    const Trajectory& nominal = initial[q];
    Eigen::VectorXd diff(d.nx);
    for (int k = 0; k <= nominal.T; ++k) {
      TangentDifference(m, probe.states.row(k).data(), nominal.states.row(k).data(), 1.0,
                        diff.data());
      const double p = diff.lpNorm<Eigen::Infinity>();
      const double e = p / h / (1 + k * m.opt.timestep);
      worst_e = std::max(worst_e, e);
      if (k >= kMinSegmentSteps && e > 1) out.rate = std::max(out.rate, std::log(e) / k);
      if (e > kExponentialGrowth && (first < 0 || k < first)) {
        first = k;
        rate = std::log(e) / k;
        where = sq.name;
      }
      if (e > kExponentialGrowth || p > kSensitivityGrowthLimit) break;
    }
  }
  out.growth = worst_e;
  // contacts: the nominal rollouts change their contact count, and a segment at step
  // kContactSegmentSteps of the first long enough sequence starts on the data
  long long changes = 0, steps = 0;
  for (const Trajectory& t : initial) {
    for (size_t k = 1; k < t.ncon.size(); ++k) changes += t.ncon[k] != t.ncon[k - 1] ? 1 : 0;
    steps += static_cast<long long>(t.ncon.size());
  }
  // events (impacts, touch-downs) rather than chatter: at most kContactEventRate of the steps
  const bool events = changes > 0 && changes <= kContactEventRate * static_cast<double>(steps);
  std::string contact_source;
  for (size_t q = 0; events && q < fit.sequences.size() && contact_source.empty(); ++q) {
    if (fit.grids[q].steps < 2 * kContactSegmentSteps ||
        initial[q].states.rows() <= kContactSegmentSteps) {
      continue;  // too short, or not simulated here (a sharded start)
    }
    std::vector<double> x;
    const std::string source =
        SegmentStart(fit, static_cast<int>(q), kContactSegmentSteps, initial[q], &x);
    if (source != "the rollout") contact_source = source;
  }
  const std::string contacts = "the rollouts change their contact count " +
                               std::to_string(changes) + " times in " + std::to_string(steps) +
                               " steps and the segments start on the " + contact_source;
  if (first < 0) {
    if (!contact_source.empty()) {
      out.steps = kContactSegmentSteps;
      out.contacts = true;
      out.reason = "multiple shooting: " + contacts + ": segments of " + std::to_string(out.steps) +
                   " steps";
      return out;
    }
    out.reason = "single shooting: sensitivity bounded (growth beyond linear x" +
                 FormatDigits(worst_e, 3) + " <= " + FormatDigits(kExponentialGrowth, 3) + ")";
    if (changes > 0 && !events) {
      out.reason +=
          "; the contact count changes at " +
          FormatDigits(100.0 * static_cast<double>(changes) / static_cast<double>(steps), 3) +
          " % of the steps (> " + FormatDigits(100 * kContactEventRate, 3) +
          " %: chatter, which segments do not isolate)";
    }
    return out;
  }
  out.steps =
      std::max(static_cast<int>(std::ceil(std::log(kSegmentGrowth) / rate)), kMinSegmentSteps);
  out.reason = "multiple shooting: sensitivity grows exponentially, rate " + FormatDigits(rate, 3) +
               " per step (x" + FormatDigits(kExponentialGrowth, 3) + " beyond linear at step " +
               std::to_string(first) + " of sequence '" + where + "')";
  if (!contact_source.empty() && kContactSegmentSteps <= out.steps) {
    out.steps = kContactSegmentSteps;
    out.contacts = true;
    out.reason += " and " + contacts;
  }
  out.reason += ": segments of " + std::to_string(out.steps) + " steps";
  return out;
}

// Auto's contact segments: the sensors that jump at contact events left out (see the header)
std::vector<std::string> OmitJumpingSensors(PreparedFit& fit) {
  std::vector<std::string> omitted;  // "model/sensor (type)" once each
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    const mjModel& m = fit.models[fit.ModelIndex(fit.sequences[q].model)].sim->model();
    std::vector<bool> jumps(fit.channels[q].size(), false);
    bool any_kept = false;
    for (size_t c = 0; c < fit.channels[q].size(); ++c) {
      // the sensor of the column
      int id = 0;
      while (id + 1 < m.nsensor && m.sensor_adr[id + 1] <= fit.channels[q][c].column) ++id;
      jumps[c] = JumpingSensorType(m, id) != nullptr;
      any_kept = any_kept || !jumps[c];
    }
    if (!any_kept) continue;
    std::vector<Channel> channels;
    std::vector<int> missing;
    for (size_t c = 0; c < jumps.size(); ++c) {
      if (jumps[c]) continue;
      channels.push_back(fit.channels[q][c]);
      missing.push_back(fit.missing[q][c]);
    }
    fit.channels[q] = std::move(channels);
    fit.missing[q] = std::move(missing);
    std::vector<std::string> fitted;
    for (const std::string& name : fit.fitted[q]) {
      const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
      const char* type = id >= 0 ? JumpingSensorType(m, id) : nullptr;
      if (!type) {
        fitted.push_back(name);
        continue;
      }
      const std::string what = "'" + name + "' (" + type + ")";
      if (std::find(omitted.begin(), omitted.end(), what) == omitted.end()) omitted.push_back(what);
    }
    fit.fitted[q] = std::move(fitted);
  }
  std::vector<std::string> warnings;
  for (const std::string& what : omitted) {
    warnings.push_back("sensor " + what +
                       " left out of the fit: auto chose contact segments, and its residuals "
                       "are dominated by the timing of contact events (fitted, it made the robust "
                       "suite's contact fits worse: docs/stress.md); it is not in the chi-square "
                       "test nor in the result's sequences. multiple_shooting: {jumping_sensors: "
                       "fit} keeps it");
  }
  return warnings;
}

// Auto's contact segments, first stage (see the header)
ceres::Solver::Summary SolveWithStatesHeld(FitVariables& vars, ceres::Problem* problem,
                                           ceres::Solver::Options so) {
  std::vector<double*> held;
  for (size_t b = 0; b < vars.states.size(); ++b) {
    double* x = vars.states[b].data();
    if (!problem->HasParameterBlock(x)) continue;
    problem->SetParameterBlockConstant(x);
    held.push_back(x);
  }
  so.linear_solver_type = ceres::DENSE_QR;
  so.linear_solver_ordering.reset();
  ceres::Solver::Summary summary;
  ceres::Solve(so, problem, &summary);
  for (double* x : held) problem->SetParameterBlockVariable(x);
  return summary;
}

// Continuity weights (see the header)
std::vector<std::vector<double>> ContinuityWeights(const PreparedFit& fit,
                                                   const std::vector<Trajectory>& initial,
                                                   const FitOptions& options,
                                                   std::string* summary) {
  constexpr double kSpreadFloor = 1e-3;  // of the largest spread of the same part
  std::vector<std::vector<double>> out(fit.models.size());
  double lo = std::numeric_limits<double>::infinity(), hi = 0, shown_scale = 0;
  for (size_t mi = 0; mi < fit.models.size(); ++mi) {
    const Simulator& sim = *fit.models[mi].sim;
    const mjModel& m = sim.model();
    const StateDims& dims = sim.dims();
    out[mi].assign(dims.nx, options.continuity_weight);
    if (!options.continuity_relative) continue;
    // S: the median of weight * spread over the fitted sensor columns of this model's sequences
    std::vector<double> scaled;
    // s_i: running sums of tangent coordinate i (from the sequence's first state) over samples
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(dims.nx), sum2 = sum, d(dims.nx);
    double n = 0;
    for (size_t q = 0; q < fit.sequences.size(); ++q) {
      const FitSequence& sq = fit.sequences[q];
      if (fit.ModelIndex(sq.model) != static_cast<int>(mi) || initial[q].states.rows() == 0)
        continue;
      for (const Channel& ch : fit.channels[q]) {
        double s1 = 0, s2 = 0, c = 0;
        for (Eigen::Index k = 0; k < sq.measured.rows(); ++k) {
          const double y = sq.measured(k, ch.column);
          if (std::isnan(y)) continue;
          s1 += y, s2 += y * y, ++c;
        }
        if (c > 1) scaled.push_back(ch.weight * std::sqrt(std::max(0.0, s2 / c - s1 * s1 / c / c)));
      }
      const Trajectory& tr = initial[q];
      const std::vector<double>& position = fit.grids[q].position;
      const bool logged = sq.qpos.cols() == m.nq && sq.qvel.cols() == m.nv;
      Eigen::VectorXd x(tr.states.cols());
      const Eigen::VectorXd x_ref = tr.states.row(0).transpose();
      for (size_t i = 0; i < position.size(); ++i) {
        const int k = static_cast<int>(std::lround(position[i]));
        if (k < 0 || k > tr.T) continue;
        x = tr.states.row(k).transpose();
        if (logged && static_cast<Eigen::Index>(i) < sq.qpos.rows() && sq.qpos.row(i).allFinite() &&
            sq.qvel.row(i).allFinite()) {
          x.head(m.nq) = sq.qpos.row(i).transpose();
          x.segment(m.nq, m.nv) = sq.qvel.row(i).transpose();
        }
        TangentDifference(m, x.data(), x_ref.data(), 1.0, d.data());
        sum += d, sum2 += d.cwiseAbs2(), n += 1;
      }
    }
    if (scaled.empty() || n < 2) continue;
    std::nth_element(scaled.begin(), scaled.begin() + scaled.size() / 2, scaled.end());
    const double S = scaled[scaled.size() / 2];
    if (!(S > 0)) continue;
    Eigen::VectorXd spread = (sum2 / n - (sum / n).cwiseAbs2()).cwiseMax(0.0).cwiseSqrt();
    // one weight for the 3 rows of a ball or free joint's orientation (the cost functions mix
    // those rows by Jr^-1, which commutes with a multiple of the identity only)
    for (int j = 0; j < m.njnt; ++j) {
      if (m.jnt_type[j] != mjJNT_BALL && m.jnt_type[j] != mjJNT_FREE) continue;
      const int k = m.jnt_dofadr[j] + (m.jnt_type[j] == mjJNT_FREE ? 3 : 0);
      spread.segment(k, 3).setConstant(spread.segment(k, 3).maxCoeff());
    }
    // the parts: positions [0, nv), velocities [nv, 2 nv), activations [2 nv, nx)
    const int part_start[3] = {0, dims.nv, 2 * dims.nv}, part_size[3] = {dims.nv, dims.nv, dims.na};
    for (int p = 0; p < 3; ++p) {
      if (part_size[p] == 0) continue;
      const double largest = spread.segment(part_start[p], part_size[p]).maxCoeff();
      for (int i = part_start[p]; i < part_start[p] + part_size[p]; ++i) {
        const double s_i = std::max(spread[i], kSpreadFloor * largest);
        if (s_i > 0) out[mi][i] = options.continuity_weight * S / s_i;
        lo = std::min(lo, out[mi][i]);
        hi = std::max(hi, out[mi][i]);
      }
    }
    shown_scale = std::max(shown_scale, S);
  }
  if (!options.continuity_relative) {
    *summary = "continuity weight " + FormatDigits(options.continuity_weight, 3) + " (absolute)";
  } else if (hi > 0) {
    *summary = "continuity weights " + FormatDigits(options.continuity_weight, 3) +
               " x S / state spread = " + FormatDigits(lo, 3) + " .. " + FormatDigits(hi, 3) +
               " (S, sensor weight x spread: " + FormatDigits(shown_scale, 3) + ")";
  } else {
    *summary = "continuity weight " + FormatDigits(options.continuity_weight, 3) +
               " (no sensor or state spread to scale it)";
  }
  return out;
}

// Auto, second stage: a single-shooting fit whose Jacobians the core flags as no longer local
// (h*|S| > kSensitivityGrowthLimit from step k*, at some iterate: the sensitivity grew between
// the initial values and there) is stopped and refitted in multiple shooting with segments of
// min(k*/2, ln(2) / lambda) steps, lambda the probe's rate, at least kMinSegmentSteps. Returns
// 0 when the warning names no step.
int WarningStep(const std::string& warning) {
  static const std::regex kStep("from step ([0-9]+)");
  int kstar = -1;
  for (auto it = std::sregex_iterator(warning.begin(), warning.end(), kStep);
       it != std::sregex_iterator(); ++it) {
    kstar = std::stoi((*it)[1]);
  }
  return kstar;
}

int SegmentStepsAfterWarning(const std::string& warning, double rate, std::string* reason) {
  const int kstar = WarningStep(warning);
  if (kstar < 0) return 0;
  int len = kstar / 2;
  if (rate > 0) len = std::min(len, static_cast<int>(std::ceil(std::log(kSegmentGrowth) / rate)));
  len = std::max(len, kMinSegmentSteps);
  *reason = "multiple shooting: the single-shooting Jacobian stopped being local (h*|S| > " +
            FormatDigits(kSensitivityGrowthLimit, 2) + " from step " + std::to_string(kstar) +
            ", probe rate " + FormatDigits(rate, 3) + " per step): segments of " +
            std::to_string(len) + " steps";
  return len;
}

// Auto, third stage (see the header): measured on the chaotic double pendulum released at (2.0,
// -1.0) rad from masses (1.2, 0.6) (tests/stress/horizon_stress_test.cc, "moderate_start2"): the
// probe reads x82 beyond linear (below x100), the core never flags a Jacobian, and single shooting
// stops unconverged after 50 iterations; the refit's segments start on the data (SegmentStart).
int SegmentStepsAfterFailure(double growth, double rate, int shortest_steps, std::string* reason) {
  if (!(growth > kRefitGrowth) || !(rate > 0)) return 0;
  const int len =
      std::max(static_cast<int>(std::ceil(std::log(kSegmentGrowth) / rate)), kMinSegmentSteps);
  if (2 * len > shortest_steps) return 0;
  *reason = "multiple shooting: single shooting did not converge and the probe grew x" +
            FormatDigits(growth, 3) + " beyond linear (> " + FormatDigits(kRefitGrowth, 3) +
            ", rate " + FormatDigits(rate, 3) + " per step): segments of " + std::to_string(len) +
            " steps";
  return len;
}

// The initial state of the segment of sequence q starting at simulation step k0 > 0, from the data
// where a measured sample lies on that step (SampleGrid::position; none: the rollout) and
// determines the state there: the sequence's logged qpos and qvel (FitSequence::qpos, qvel), else
// the fitted jointpos/jointvel sensors when every joint is a hinge or slide with one of each
// (sensors without measurement terms), else the rollout at the initial values. act is always the
// rollout's. Returns where it came from.
std::string SegmentStart(const PreparedFit& fit, int q, int k0, const Trajectory& rollout,
                         std::vector<double>* x) {
  const FitSequence& sq = fit.sequences[q];
  const Simulator& sim = *fit.models[fit.ModelIndex(sq.model)].sim;
  const mjModel& m = sim.model();
  const auto row = rollout.states.row(k0);
  x->assign(row.data(), row.data() + row.size());
  const int nq = m.nq, nv = m.nv;
  // the measured sample at step k0, if one lies on it (off-grid logs: often none)
  const std::vector<double>& position = fit.grids[q].position;
  const auto at = std::lower_bound(position.begin(), position.end(), static_cast<double>(k0));
  if (at == position.end() || *at != static_cast<double>(k0)) return kStartFromRollout;
  const Eigen::Index i = at - position.begin();
  if (sq.qpos.rows() > i && sq.qvel.rows() > i && sq.qpos.cols() == nq && sq.qvel.cols() == nv &&
      sq.qpos.row(i).allFinite() && sq.qvel.row(i).allFinite()) {
    std::copy(sq.qpos.row(i).data(), sq.qpos.row(i).data() + nq, x->begin());
    std::copy(sq.qvel.row(i).data(), sq.qvel.row(i).data() + nv, x->begin() + nq);
    return "logged qpos/qvel";
  }
  std::vector<int> pos_col(m.njnt, -1), vel_col(m.njnt, -1);
  for (const std::string& name : fit.fitted[q]) {
    bool has_terms = false;
    for (const FitMeasurement& me : fit.measurements) has_terms = has_terms || me.sensor == name;
    const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
    if (has_terms || id < 0 || m.sensor_objtype[id] != mjOBJ_JOINT) continue;
    if (m.sensor_type[id] == mjSENS_JOINTPOS) pos_col[m.sensor_objid[id]] = m.sensor_adr[id];
    if (m.sensor_type[id] == mjSENS_JOINTVEL) vel_col[m.sensor_objid[id]] = m.sensor_adr[id];
  }
  for (int j = 0; j < m.njnt; ++j) {
    const bool scalar = m.jnt_type[j] == mjJNT_HINGE || m.jnt_type[j] == mjJNT_SLIDE;
    if (!scalar || pos_col[j] < 0 || vel_col[j] < 0) return kStartFromRollout;
  }
  for (int j = 0; j < m.njnt; ++j) {
    const double qj = sq.measured(i, pos_col[j]), vj = sq.measured(i, vel_col[j]);
    if (!std::isfinite(qj) || !std::isfinite(vj)) return kStartFromRollout;  // a masked cell
  }
  for (int j = 0; j < m.njnt; ++j) {
    (*x)[m.jnt_qposadr[j]] = sq.measured(i, pos_col[j]);
    (*x)[nq + m.jnt_dofadr[j]] = sq.measured(i, vel_col[j]);
  }
  return "joint position and velocity sensors";
}

}  // namespace mjsysid
