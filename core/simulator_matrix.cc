// Matrix-mode Jacobians: per time step the state blocks A_k, C_k from mjd_transitionFD and the
// parameter blocks F_k, G_k from one perturbed step per parameter that skips the stages the
// parameter cannot affect (in parallel over the time steps of a chunk), then the chain
// S_{k+1} = A_k S_k + F_k, dy_k = C_k S_k + G_k (in order, on the calling thread).
#include <algorithm>
#include <string>
#include <vector>

#include "core/simulator.h"
#include "core/simulator_internal.h"
#include "core/text.h"

namespace mjsysid {

using internal::CombineSides;
using internal::CopyModelInto;
using internal::kGrowthLimit;
using internal::Tenths;

// The per-step blocks of one chunk of time steps, row-major stacks as StepBlocks (A, C, B, D: the
// state and control columns, B and D with nu columns only when the controls are differentiated;
// F, G: the parameter columns), step kk of the chunk at rows kk times the block's rows; with the
// kinks and constraint solves of each step. The backward sides of a step are worker scratch.
struct Simulator::MatrixChunk {
  MatrixChunk(int chunk, int nx, int ns, int np, int nu)
      : A(static_cast<Eigen::Index>(chunk) * nx, nx),
        C(static_cast<Eigen::Index>(chunk) * ns, nx),
        B(A.rows(), nu),
        D(C.rows(), nu),
        F(A.rows(), np),
        G(C.rows(), np),
        kinks(chunk, 0),
        solver(chunk) {}
  RowMatrix A, C, B, D;
  RowMatrix F, G;
  std::vector<int> kinks;
  std::vector<SolverStats> solver;
};

namespace {

// How far each column's sensitivity has grown, h*|S| as in DirectionalColumn: the chain of one-step
// linearisations stays finite where directional differences stop being local, but past
// kGrowthLimit the derivative describes the trajectory only for parameter changes far below any
// useful step (a chaotic horizon): warn the same way instead of returning huge values silently.
struct ColumnGrowth {
  Eigen::VectorXd col_step, max_growth;
  std::vector<int> growth_step;
};

// chain through the chunk that starts at step k0 (kn steps): dy_k = C_k S_k + G_k,
// S_{k+1} = A_k S_k + F_k
void ChainChunk(const RowMatrix& A, const RowMatrix& C, const RowMatrix& F, const RowMatrix& G,
                int k0, int kn, int np, int nx, int ns, int ncol, const JacobianOptions& opt,
                RowMatrix* S_in, RowMatrix* S_next_in, ColumnGrowth* g, Sensitivity* out) {
  RowMatrix& S = *S_in;
  RowMatrix& S_next = *S_next_in;
  for (int kk = 0; kk < kn; ++kk) {
    const int k = k0 + kk;
    const auto Ak = A.middleRows(static_cast<Eigen::Index>(kk) * nx, nx);
    if (opt.state_jacobians) out->DxDp.middleRows(k * nx, nx) = S;
    if (ns) {
      const auto Ck = C.middleRows(static_cast<Eigen::Index>(kk) * ns, ns);
      auto dy = out->DyDp.middleRows(k * ns, ns);
      dy.noalias() = Ck * S;
      dy.leftCols(np) += G.middleRows(kk * ns, ns);
    }
    S_next.noalias() = Ak * S;
    S_next.leftCols(np) += F.middleRows(kk * nx, nx);
    S.swap(S_next);
    for (int col = 0; col < ncol; ++col) {
      const double growth = g->col_step[col] * S.col(col).lpNorm<Eigen::Infinity>();
      if (growth > g->max_growth[col]) {
        g->max_growth[col] = growth;
        if (growth > kGrowthLimit && g->growth_step[col] < 0) g->growth_step[col] = k + 1;
      }
    }
  }
}

}  // namespace

// the workers' scratch of MatrixStep for nu control columns: a perturbed step's vectors and the
// backward side's blocks (before the parallel steps: no allocation inside them)
void Simulator::SizeMatrixScratch(int nu) {
  const int nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  SizeColumnScratch();
  for (auto& w : workers_) {
    w->Ab.resize(nx, nx);
    w->Cb.resize(ns, nx);
    w->Bb.resize(nx, nu);
    w->Db.resize(ns, nu);
  }
}

// one perturbed model per parameter and side, per worker (mj_setConst uses its mjData)
void Simulator::PrepareMatrixModels(const Eigen::VectorXd& steps) {
  const int np = params_.size();
  for (auto& w : workers_) {
    OnWorker(*w, [&] {
      w->param_plus.resize(np);
      w->param_minus.resize(np);
      for (int j = 0; j < np; ++j) {
        const double p = params_[j].Read(*model_);
        if (!w->param_plus[j]) w->param_plus[j] = CopyModel(*model_);
        CopyModelInto(w->param_plus[j].get(), model_.get());
        params_.WriteOne(w->param_plus[j].get(), w->data.get(), j, p + steps[j]);
        if (!w->param_minus[j]) w->param_minus[j] = CopyModel(*model_);
        CopyModelInto(w->param_minus[j].get(), model_.get());
        params_.WriteOne(w->param_minus[j].get(), w->data.get(), j, p - steps[j]);
      }
    });
  }
}

// the blocks of time step k (step kk of the chunk) on worker w
void Simulator::MatrixStep(Worker& w, const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                           const JacobianOptions& opt, const Eigen::VectorXd& steps,
                           const std::vector<int>& order, int k, int kk, MatrixChunk* c) const {
  const int nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int T = nom.T;
  const bool both_sides = opt.central;
  mjData* d = w.data.get();
  CheckCancel();
  const double t = nom.step(k, 0);
  const double* u = ctrl.row(k).data();
  ClearSimulationWarnings(d);
  RestoreInputs(*model_, dims_, nom, d);
  c->kinks[kk] = 0;
  c->solver[kk] = SolverStats();

  // state (and control) columns: forward differences (eps), and backward ones (-eps) for
  // central, so that each column can be checked for a kink (centered mjd_transitionFD cannot)
  const int nu = static_cast<int>(c->B.cols());
  auto block = [&](RowMatrix& M, int rows) {
    return rows && M.cols() ? M.data() + static_cast<size_t>(kk) * rows * M.cols() : nullptr;
  };
  double* Ak = block(c->A, nx);
  double* Ck = block(c->C, ns);
  double* Bk = block(c->B, nx);
  double* Dk = block(c->D, ns);
  CallMujoco([&] {
    RestoreStep(*model_, dims_, nom, k, u, d);
    mjd_transitionFD(model_.get(), d, opt.state_step, 0, Ak, Bk, Ck, Dk);
  });
  w.steps += 1 + nx + nu;
  CheckStep(*d, t, seq_index, k, "mjd_transitionFD");
  // forward differences are checked too where the contact set may change near x_k
  const bool contact_near = nom.ncon[k] > 0 || (k + 1 < T && nom.ncon[k + 1] != nom.ncon[k]) ||
                            (k > 0 && nom.ncon[k - 1] != nom.ncon[k]);
  if (both_sides || (contact_near && opt.kink_check)) {
    // the backward side in the worker's scratch (SizeMatrixScratch)
    double* Abk = w.Ab.data();
    double* Cbk = ns ? w.Cb.data() : nullptr;
    double* Bbk = nu ? w.Bb.data() : nullptr;
    double* Dbk = ns && nu ? w.Db.data() : nullptr;
    CallMujoco([&] {
      RestoreStep(*model_, dims_, nom, k, u, d);
      mjd_transitionFD(model_.get(), d, -opt.state_step, 0, Abk, Bbk, Cbk, Dbk);
    });
    w.steps += 1 + nx + nu;
    CheckStep(*d, t, seq_index, k, "mjd_transitionFD");
    // each column of [A | B] with its sensor column of [C | D]
    auto combine = [&](double* f, double* b, double* fy, double* by, int cols) {
      Eigen::Map<RowMatrix> Mf(f, nx, cols), Mb(b, nx, cols);
      Eigen::Map<RowMatrix> Yf(fy, ns, cols), Yb(by, ns, cols);
      for (int col = 0; col < cols; ++col) {
        if (CombineSides(Mf.col(col), Mb.col(col), Yf.col(col), Yb.col(col), opt.central,
                         Mf.col(col), Yf.col(col))) {
          ++c->kinks[kk];
        }
      }
    };
    combine(Ak, Abk, Ck, Cbk, nx);
    if (nu) combine(Bk, Bbk, Dk, Dbk, nu);
  }
  if (order.empty()) return;

  // parameter columns: base pass at x_k with the nominal model, then one step per parameter
  // that skips the stages before the one the parameter enters
  CallMujoco([&] {
    RestoreStep(*model_, dims_, nom, k, u, d);
    mj_forward(model_.get(), d);
  });
  ++w.steps;
  auto side = [&](mjModel* m, int skip, double sign, double h, Eigen::VectorXd& dx,
                  Eigen::VectorXd& dy) {
    RestoreStep(*m, dims_, nom, k, u, d);
    Step(m, d, skip);
    ++w.steps;
    CheckStep(*d, t, seq_index, k, "perturbed step");
    CountSolve(*m, *d, &c->solver[kk]);
    GetPhysics(*model_, *d, w.xp.data());
    TangentDifference(*model_, nom.states.row(k + 1).data(), w.xp.data(), sign / h, dx.data());
    for (int i = 0; i < ns; ++i) dy[i] = (d->sensordata[i] - nom.sensors(k, i)) * (sign / h);
    return d->ncon;
  };
  for (int j : order) {
    const double h = steps[j];
    const int skip = params_[j].stage();
    const int ncon = side(w.param_plus[j].get(), skip, 1.0, h, w.s_next, w.yp);
    if (opt.central || (opt.kink_check && ncon != nom.ncon[k])) {
      side(w.param_minus[j].get(), skip, -1.0, h, w.e, w.ym);
      if (CombineSides(w.s_next, w.e, w.yp, w.ym, opt.central, w.xm.head(nx), w.yp)) {
        ++c->kinks[kk];
      }
      w.s_next = w.xm.head(nx);
    }
    c->F.block(static_cast<Eigen::Index>(kk) * nx, j, nx, 1) = w.s_next;
    if (ns) c->G.block(static_cast<Eigen::Index>(kk) * ns, j, ns, 1) = w.yp;
  }
}

// the Jacobians of one sequence, chunk by chunk: the blocks in parallel, then their chain
void Simulator::MatrixJacobian(const RowMatrix& ctrl, int seq_index, const Trajectory& nom,
                               const JacobianOptions& opt, const Eigen::VectorXd& steps,
                               Sensitivity* out, SolverStats* solver) {
  const int np = params_.size(), nx = dims_.nx, ns = options_.sensors ? dims_.ns : 0;
  const int ncol = out->ncol, T = nom.T;
  const int chunk = std::min(T, 64 * pool_.size());

  // parameters ordered so that each group's skipped stages were computed by the base forward or
  // recomputed by an earlier group: actuation first, then velocity, then position parameters
  std::vector<int> order(np);
  for (int j = 0; j < np; ++j) order[j] = j;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return params_[a].stage() > params_[b].stage(); });

  MatrixChunk blocks(chunk, nx, ns, np, 0);
  SizeMatrixScratch(0);

  // S_0 = [0 | I]
  RowMatrix S = RowMatrix::Zero(nx, ncol), S_next(nx, ncol);
  if (opt.initial_state) S.rightCols(nx).setIdentity();

  ColumnGrowth growth;
  growth.col_step.resize(ncol);
  growth.max_growth = Eigen::VectorXd::Zero(ncol);
  growth.growth_step.assign(ncol, -1);
  for (int c = 0; c < ncol; ++c) growth.col_step[c] = c < np ? steps[c] : opt.state_step;

  Tenths tenths(step_progress_, "Jacobians", T);
  for (int k0 = 0; k0 < T; k0 += chunk) {
    tenths.At(k0);
    const int kn = std::min(chunk, T - k0);
    // step Jacobians of this chunk, in parallel over time steps
    pool_.ParallelFor(kn, [&](int worker, int kk) {
      Worker& w = *workers_[worker];
      OnWorker(
          w, [&] { MatrixStep(w, ctrl, seq_index, nom, opt, steps, order, k0 + kk, kk, &blocks); });
    });
    for (int kk = 0; kk < kn; ++kk) {
      out->kinks += blocks.kinks[kk];
      *solver += blocks.solver[kk];
    }
    ChainChunk(blocks.A, blocks.C, blocks.F, blocks.G, k0, kn, np, nx, ns, ncol, opt, &S, &S_next,
               &growth, out);
  }
  for (int c = 0; c < ncol; ++c) {
    if (growth.growth_step[c] < 0) continue;
    out->warnings.push_back(
        "column " + std::to_string(c) +
        ": sensitivity grew so that h*|S| = " + FormatDigits(growth.max_growth[c], 6) + " (> " +
        FormatDigits(kGrowthLimit, 6) + ") from step " + std::to_string(growth.growth_step[c]) +
        ": the linearisation holds only for far smaller changes; shorten the horizon (multiple "
        "shooting)");
  }
  if (opt.state_jacobians) out->DxDp.middleRows(T * nx, nx) = S;
  if (!S.allFinite()) {
    throw SimulationError(
        "matrix chain: sequence " + std::to_string(seq_index) + ": non-finite sensitivity",
        seq_index, T);
  }
}

// every time step of every sequence in one parallel pass, each step's blocks written in place
void Simulator::StepJacobians(const std::vector<SequenceInput>& sequences,
                              const std::vector<Trajectory>& nominal, const JacobianOptions& opt,
                              bool controls, bool parameters, std::vector<StepBlocks>* out) {
  CheckInputs(sequences);
  if (nominal.size() != sequences.size()) {
    throw std::invalid_argument("StepJacobians: " + std::to_string(sequences.size()) +
                                " sequences but " + std::to_string(nominal.size()) +
                                " nominal trajectories");
  }
  JacobianOptions matrix = opt;
  matrix.mode = JacobianMode::kMatrix;
  CheckedJacobianMode(matrix, 0.0);
  const int np = parameters ? params_.size() : 0, nx = dims_.nx;
  const int ns = options_.sensors ? dims_.ns : 0, nu = controls ? dims_.nu : 0;
  const Eigen::VectorXd steps = ParameterSteps(opt);
  std::vector<int> order;
  if (parameters) {
    // as MatrixJacobian: actuation parameters first, then velocity, then position ones
    for (int j = 0; j < np; ++j) order.push_back(j);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return params_[a].stage() > params_[b].stage(); });
    PrepareMatrixModels(steps);
  }
  SizeMatrixScratch(nu);

  // one chunk per sequence holding all its steps; tasks (i, k) in order of sequences, then steps
  const int n = static_cast<int>(sequences.size());
  std::vector<MatrixChunk> chunks;
  std::vector<int> first(n + 1, 0);
  chunks.reserve(n);
  for (int i = 0; i < n; ++i) {
    const int T = nominal[i].T;
    if (T != sequences[i].ctrl.rows() || nominal[i].states.rows() != T + 1) {
      throw std::invalid_argument("StepJacobians: nominal trajectory " + std::to_string(i) +
                                  " does not match its sequence");
    }
    chunks.emplace_back(T, nx, ns, np, nu);
    first[i + 1] = first[i] + T;
  }
  pool_.ParallelFor(first[n], [&](int worker, int task) {
    const int i =
        static_cast<int>(std::upper_bound(first.begin(), first.end(), task) - first.begin()) - 1;
    const int k = task - first[i];
    Worker& w = *workers_[worker];
    OnWorker(w, [&] {
      MatrixStep(w, sequences[i].ctrl, i, nominal[i], opt, steps, order, k, k, &chunks[i]);
    });
  });

  out->resize(n);
  for (int i = 0; i < n; ++i) {
    MatrixChunk& c = chunks[i];
    StepBlocks& b = (*out)[i];
    b.T = nominal[i].T;
    b.A.swap(c.A);
    b.B.swap(c.B);
    b.C.swap(c.C);
    b.D.swap(c.D);
    b.F.swap(c.F);
    b.G.swap(c.G);
    b.kinks = 0;
    SolverStats perturbed;
    for (int k = 0; k < b.T; ++k) {
      b.kinks += c.kinks[k];
      perturbed += c.solver[k];
    }
    b.warnings = SolverWarnings(*model_, nominal[i].solver, perturbed);
    if (!b.A.allFinite() || !b.B.allFinite() || !b.C.allFinite() || !b.D.allFinite() ||
        !b.F.allFinite() || !b.G.allFinite()) {
      throw SimulationError(
          "step Jacobians: sequence " + std::to_string(i) + ": non-finite derivative", i, b.T);
    }
  }
}

}  // namespace mjsysid
