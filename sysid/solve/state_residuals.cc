#include "sysid/solve/state_residuals.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/text.h"
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/fit_state.h"

namespace mjsysid {
namespace {

// names of the objects of type `type` in m (unnamed ones skipped)
std::vector<std::string> NamesOf(const mjModel& m, mjtObj type, int n) {
  std::vector<std::string> names;
  for (int i = 0; i < n; ++i) {
    const char* nm = mj_id2name(&m, type, i);
    if (nm && *nm) names.push_back(nm);
  }
  return names;
}

// the part's name and sigma; throws for a bad sigma or count
void CheckSigma(const FitStates::Part& part, const char* what, const std::string& where) {
  const size_t n = part.sigma.size();
  if (n == 0 || (n != 1 && n != part.names.size())) {
    throw std::invalid_argument(
        where + "states." + what + ": sigma needs one shared value or one per name (" +
        std::to_string(part.names.size()) + " names), got " + std::to_string(n));
  }
  for (double s : part.sigma) {
    if (!(s > 0) || !std::isfinite(s)) {
      throw std::invalid_argument(where + "states." + what +
                                  ": sigma must be positive and finite, got " + FormatShortest(s));
    }
  }
}

}  // namespace

std::vector<StateChannel> BuildStateChannels(const mjModel& m, const FitStates& states,
                                             const std::string& where) {
  std::vector<StateChannel> out;
  const int nq = m.nq, nv = m.nv;
  const char* what[3] = {"qpos", "qvel", "act"};
  const FitStates::Part* parts[3] = {&states.qpos, &states.qvel, &states.act};
  for (int part = 0; part < 3; ++part) {
    const FitStates::Part& p = *parts[part];
    if (!p.fit) continue;
    CheckSigma(p, what[part], where);
    const bool act = part == 2;
    const mjtObj type = act ? mjOBJ_ACTUATOR : mjOBJ_JOINT;
    const int count = act ? m.nu : m.njnt;
    // the objects: the names given, else every one (with an activation for act)
    std::vector<int> ids;
    if (p.names.empty()) {
      for (int i = 0; i < count; ++i) {
        if (!act || m.actuator_actadr[i] >= 0) ids.push_back(i);
      }
    }
    for (const std::string& name : p.names) {
      const int id = mj_name2id(&m, type, name.c_str());
      if (id < 0) {
        throw std::invalid_argument(
            where + "states." + what[part] + ": no " + (act ? "actuator" : "joint") + " named " +
            Quote(name) + "; " +
            NamesHint(name, NamesOf(m, type, count), act ? "actuators" : "joints"));
      }
      if (act && m.actuator_actadr[id] < 0) {
        throw std::invalid_argument(where + "states.act: actuator " + Quote(name) +
                                    " has no activation (actdim 0)");
      }
      ids.push_back(id);
    }
    if (ids.empty()) {
      throw std::invalid_argument(where + "states." + what[part] + ": the model has no " +
                                  (act ? "actuator with an activation" : "joint") + " to fit");
    }
    for (size_t i = 0; i < ids.size(); ++i) {
      const int id = ids[i];
      StateChannel ch;
      const char* nm = mj_id2name(&m, type, id);
      ch.name = std::string(what[part]) + ":" + (nm ? nm : std::to_string(id));
      ch.part = part;
      ch.weight = 1.0 / (p.sigma.size() == 1 ? p.sigma[0] : p.sigma[i]);
      if (act) {
        ch.column = m.actuator_actadr[id];
        ch.scalars = m.actuator_actnum[id];
        ch.phys = nq + nv + ch.column;
        ch.tangent = 2 * nv + ch.column;
      } else if (part == 1) {
        const int type_j = m.jnt_type[id];
        ch.column = m.jnt_dofadr[id];
        ch.scalars = type_j == mjJNT_FREE ? 6 : type_j == mjJNT_BALL ? 3 : 1;
        ch.phys = nq + ch.column;
        ch.tangent = nv + ch.column;
      } else {
        const int type_j = m.jnt_type[id];
        ch.column = m.jnt_qposadr[id];
        ch.scalars = type_j == mjJNT_FREE ? 3 : type_j == mjJNT_BALL ? 0 : 1;
        ch.quat = type_j == mjJNT_FREE || type_j == mjJNT_BALL;
        ch.phys = ch.column;
        ch.tangent = m.jnt_dofadr[id];
      }
      out.push_back(ch);
    }
  }
  return out;
}

std::vector<int> CheckLoggedStates(const mjModel& m, const std::vector<StateChannel>& channels,
                                   int T, const std::string& where, FitSequence* sq) {
  RowMatrix* logged[3] = {&sq->qpos, &sq->qvel, &sq->act};
  const Eigen::Index cols[3] = {m.nq, m.nv, m.na};
  const char* what[3] = {"qpos", "qvel", "act"};
  bool used[3] = {false, false, false};
  for (const StateChannel& ch : channels) used[ch.part] = true;
  for (int part = 0; part < 3; ++part) {
    if (!used[part]) continue;
    const RowMatrix& x = *logged[part];
    if (x.rows() == 0) {
      throw std::invalid_argument(where + "states." + what[part] +
                                  " are fitted but the log has no " + what[part]);
    }
    if (x.rows() != T || x.cols() != cols[part]) {
      throw std::invalid_argument(where + "logged " + std::string(what[part]) + " must be " +
                                  std::to_string(T) + " x " + std::to_string(cols[part]) +
                                  " (one row per sample), got " + std::to_string(x.rows()) + " x " +
                                  std::to_string(x.cols()));
    }
  }
  std::vector<int> missing;
  for (const StateChannel& ch : channels) {
    RowMatrix& x = *logged[ch.part];
    int masked = 0;
    for (int k = 0; k < T; ++k) {
      bool nan = false;
      for (int c = 0; c < ch.width(); ++c) {
        const double v = x(k, ch.column + c);
        if (std::isinf(v)) {
          throw std::invalid_argument(where + "logged " + ch.name + " is not finite at row " +
                                      std::to_string(k));
        }
        nan = nan || std::isnan(v);
      }
      masked += nan ? 1 : 0;
      if (!nan && ch.quat) {
        double* q = &x(k, ch.column + ch.scalars);
        if (mju_normalize4(q) < mjMINVAL) {
          throw std::invalid_argument(where + "logged " + ch.name +
                                      " has a zero quaternion at row " + std::to_string(k));
        }
      }
    }
    if (masked == T) {
      throw std::invalid_argument(where + "logged " + ch.name + " has no measured sample (all " +
                                  std::to_string(T) + " are NaN): nothing to fit");
    }
    missing.push_back(masked);
  }
  return missing;
}

const double* LoggedState(const StateChannel& ch, const FitSequence& sq, int k) {
  const RowMatrix& x = ch.part == 0 ? sq.qpos : ch.part == 1 ? sq.qvel : sq.act;
  return x.data() + static_cast<Eigen::Index>(k) * x.cols() + ch.column;
}

int StateRows(const std::vector<StateChannel>& channels, const FitSequence& sq, int first,
              int count) {
  int rows = 0;
  for (int k = first; k < first + count; ++k) {
    for (const StateChannel& ch : channels) {
      const double* v = LoggedState(ch, sq, k);
      bool nan = false;
      for (int c = 0; c < ch.width(); ++c) nan = nan || std::isnan(v[c]);
      rows += nan ? 0 : ch.rows();
    }
  }
  return rows;
}

void StateAtPosition(const mjModel& m, const RowMatrix& states, double position, double* scratch,
                     double* x) {
  const int i = static_cast<int>(std::floor(position));
  const double a = position - i;
  const Eigen::Index n = states.cols();
  std::copy(states.row(i).data(), states.row(i).data() + n, x);
  if (a == 0 || i + 1 >= states.rows()) return;
  // x_i (+) a (x_{i+1} (-) x_i): positions through mj_integratePos, the rest linearly
  TangentDifference(m, states.row(i).data(), states.row(i + 1).data(), 1.0, scratch);
  mj_integratePos(&m, x, scratch, a);
  for (int t = 0; t < m.nv + m.na; ++t) x[m.nq + t] += a * scratch[m.nv + t];
}

bool StateDifference(const StateChannel& ch, const double* x, const double* logged, double* e,
                     double* de) {
  for (int c = 0; c < ch.width(); ++c) {
    if (std::isnan(logged[c])) return false;
  }
  const int rows = ch.rows();
  if (de) std::fill(de, de + rows * rows, 0.0);
  for (int c = 0; c < ch.scalars; ++c) {
    e[c] = ch.weight * (x[ch.phys + c] - logged[c]);
    if (de) de[c * rows + c] = ch.weight;
  }
  if (ch.quat) {
    // log(q_meas^-1 q): mju_subQuat(res, qa, qb) gives qb * quat(res) = qa
    double phi[3];
    mju_subQuat(phi, x + ch.phys + ch.scalars, logged + ch.scalars);
    for (int c = 0; c < 3; ++c) e[ch.scalars + c] = ch.weight * phi[c];
    if (de) {
      double J[9];
      InverseRightJacobianSO3(phi, ch.weight, J);
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) de[(ch.scalars + i) * rows + ch.scalars + j] = J[i * 3 + j];
      }
    }
  }
  return true;
}

void InitStateResult(const std::vector<StateChannel>& channels, const FitSequence& sq,
                     SequenceResult* sr) {
  const Eigen::Index T = sq.measured.rows();
  int width = 0, rows = 0;
  for (const StateChannel& ch : channels) {
    sr->state_names.push_back(ch.name);
    sr->state_dims.push_back(ch.width());
    sr->state_residual_dims.push_back(ch.rows());
    width += ch.width();
    rows += ch.rows();
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  sr->state_measured.resize(T, width);
  for (Eigen::Index k = 0; k < T; ++k) {
    int col = 0;
    for (const StateChannel& ch : channels) {
      const double* v = LoggedState(ch, sq, static_cast<int>(k));
      for (int c = 0; c < ch.width(); ++c) sr->state_measured(k, col++) = v[c];
    }
  }
  sr->state_simulated_initial = RowMatrix::Constant(T, width, nan);
  sr->state_simulated_final = RowMatrix::Constant(T, width, nan);
  sr->state_residual_final = RowMatrix::Constant(T, rows, nan);
}

void StatesAtSamples(const mjModel& m, const std::vector<StateChannel>& channels,
                     const FitSequence& sq, const RowMatrix& states,
                     const std::vector<double>& position, int k0, int first, int count,
                     RowMatrix* simulated, RowMatrix* residual) {
  std::vector<double> x(states.cols()), scratch(2 * m.nv + m.na), e(2 * m.nv + m.na);
  for (int k = first; k < first + count; ++k) {
    StateAtPosition(m, states, position[k] - k0, scratch.data(), x.data());
    int col = 0, rcol = 0;
    for (const StateChannel& ch : channels) {
      for (int c = 0; c < ch.width(); ++c) (*simulated)(k, col++) = x[ch.phys + c];
      if (residual) {
        const bool measured =
            StateDifference(ch, x.data(), LoggedState(ch, sq, k), e.data(), nullptr);
        for (int r = 0; r < ch.rows(); ++r) {
          (*residual)(k, rcol + r) = measured ? e[r] : std::numeric_limits<double>::quiet_NaN();
        }
      }
      rcol += ch.rows();
    }
  }
}

// -----------------------------------------------------------------------------------------------
// the cost function

StateCost::StateCost(const FitParts& parts, int segment)
    : fit_(parts.fit),
      vars_(parts.vars),
      diag_(parts.diag),
      solve_(parts.solve),
      segment_(segment) {
  const Segment& seg = fit_->segments[segment];
  const StateDims& dims = fit_->models[seg.model].sim->dims();
  int first = 0, count = 0;
  fit_->SamplesOf(segment, &first, &count);
  set_num_residuals(
      StateRows(fit_->state_channels[seg.seq], fit_->sequences[seg.seq], first, count));
  if (!vars_->z.empty()) mutable_parameter_block_sizes()->push_back(vars_->z.size());
  if (seg.block >= 0) mutable_parameter_block_sizes()->push_back(dims.nphys);
}

bool StateCost::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  return diag_->EvaluateOrReject("non-finite state residual",
                                 [&] { return EvaluateOrThrow(parameters, residuals, jacobians); });
}

bool StateCost::EvaluateOrThrow(double const* const* parameters, double* residuals,
                                double** jacobians) const {
  const auto [seg, sq, mo] = fit_->SegmentRefs(segment_);
  const Simulator& sim = *mo.sim;
  const StateDims& dims = sim.dims();
  const int nx = dims.nx, npm = sim.parameters().size();
  const std::vector<StateChannel>& chans = fit_->state_channels[seg.seq];

  // unpack blocks: z, then x_0 when it is a variable
  int b = 0;
  const double* zv = vars_->z.empty() ? nullptr : parameters[b++];
  const int zb = vars_->z.empty() ? -1 : b - 1;
  const double* x0 = seg.block >= 0 ? parameters[b++] : fit_->fixed_x0[seg.seq].data();
  const int xb = seg.block >= 0 ? b - 1 : -1;

  // the segment's rollout and Jacobians from the evaluation cache (shared with SegmentCost)
  const bool want = jacobians != nullptr;
  const Sensitivity* sens = nullptr;
  const Trajectory& tr = solve_->CostEntry(segment_, zv, x0, want, &sens).tr;
  const Sensitivity& s = *sens;
  const int ncol = want ? s.ncol : 0;
  if (want) ZeroJacobians(*this, jacobians);
  // P^+ at x_0: tangent columns to the ambient block
  const std::vector<double> pinv = want && xb >= 0 && jacobians[xb]
                                       ? mo.manifold->PlusJacobianPseudoInverse(x0)
                                       : std::vector<double>();

  // scratch, sized once: the state at a sample, its tangent rows S (nx x ncol), one channel's
  // e and de/dx, one residual's row over the core's columns
  int max_rows = 0;
  for (const StateChannel& ch : chans) max_rows = std::max(max_rows, ch.rows());
  std::vector<double> x(dims.nphys), scratch(nx), e(max_rows), de(max_rows * max_rows), row_t(ncol);
  RowMatrix S(want ? nx : 0, ncol);
  // dp/dz of the model's parameters at this point, once per evaluation (not per row)
  std::vector<double> dpdz(want && zv ? npm : 0);
  for (int j = 0; j < static_cast<int>(dpdz.size()); ++j) {
    dpdz[j] = fit_->DpDz(mo.global[j], zv[mo.global[j]]);
  }
  int first = 0, count = 0;
  fit_->SamplesOf(segment_, &first, &count);
  const std::vector<double>& position = fit_->grids[seg.seq].position;
  int row = 0;
  for (int k = first; k < first + count; ++k) {
    const double q = position[k] - seg.k0;
    StateAtPosition(sim.model(), tr.states, q, scratch.data(), x.data());
    if (want) {
      // rows of DxDp at the sample, interpolated like the state
      const int i0 = static_cast<int>(std::floor(q));
      const double a = q - i0;
      S = s.DxDp.middleRows(static_cast<Eigen::Index>(i0) * nx, nx);
      if (a != 0 && i0 + 1 <= tr.T) {
        S = (1 - a) * S + a * s.DxDp.middleRows(static_cast<Eigen::Index>(i0 + 1) * nx, nx);
      }
    }
    for (const StateChannel& ch : chans) {
      if (!StateDifference(ch, x.data(), LoggedState(ch, sq, k), e.data(),
                           want ? de.data() : nullptr)) {
        continue;
      }
      const int rows = ch.rows();
      for (int r = 0; r < rows; ++r, ++row) {
        double d_e = 1;
        residuals[row] = RobustResidual(fit_->options.loss, fit_->options.loss_scale, e[r], &d_e);
        if (!want) continue;
        // d r / d column = rho' * sum_t de(r, t) S(tangent + t, column)
        for (int j = 0; j < ncol; ++j) {
          double v = 0;
          for (int t = 0; t < rows; ++t) v += de[r * rows + t] * S(ch.tangent + t, j);
          row_t[j] = d_e * v;
        }
        if (zb >= 0 && jacobians[zb]) {
          const int nz = static_cast<int>(vars_->z.size());
          for (int j = 0; j < npm; ++j) {
            const int g = mo.global[j];
            jacobians[zb][row * nz + g] = row_t[j] * dpdz[j];
          }
        }
        if (xb >= 0 && jacobians[xb]) {
          for (int c = 0; c < dims.nphys; ++c) {
            double v = 0;
            for (int i = 0; i < nx; ++i) v += row_t[npm + i] * pinv[i * dims.nphys + c];
            jacobians[xb][row * dims.nphys + c] = v;
          }
        }
      }
    }
  }
  for (int i = 0; i < num_residuals(); ++i) {
    if (!std::isfinite(residuals[i])) return false;
  }
  return true;
}

}  // namespace mjsysid
