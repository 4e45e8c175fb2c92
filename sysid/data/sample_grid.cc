#include "sysid/data/sample_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "core/text.h"

namespace mjsysid {
namespace {

// the most simulation steps of one sequence: 1e8 (55 h at a 2 ms timestep; far below the int
// steps are counted in)
constexpr double kMaxSteps = 1e8;

// (t - t0) / dt, a whole number when within the tolerance of one
double Position(double t, double t0, double dt) {
  const double q = (t - t0) / dt;
  const double whole = std::round(q);
  return std::abs(q - whole) <= SampleGrid::kOnGridTolerance ? whole : q;
}

void CheckTimes(const Eigen::VectorXd& t, const std::string& where, const char* what) {
  for (Eigen::Index k = 0; k < t.size(); ++k) {
    if (!std::isfinite(t[k]) || (k > 0 && !(t[k] > t[k - 1]))) {
      // the row and its value (and the one before), to find it in the log
      throw std::invalid_argument(
          where + what + " times must be finite and strictly increasing (row " + std::to_string(k) +
          ": " + FormatDigits(t[k], 9) +
          (k > 0 ? " after " + FormatDigits(t[k - 1], 9) : std::string()) + ")");
    }
  }
}

}  // namespace

void SampleGrid::SamplesOf(int k0, int T, int* first, int* count) const {
  // positions ascend: the samples with k0 <= position < k0 + T
  const auto lo = std::lower_bound(position.begin(), position.end(), static_cast<double>(k0));
  const auto hi = std::lower_bound(lo, position.end(), static_cast<double>(k0) + T);
  *first = static_cast<int>(lo - position.begin());
  *count = static_cast<int>(hi - lo);
}

int SampleGrid::SimulatedSteps(int k0, int T) const {
  if (on_grid || k0 + T >= steps) return T;
  int first = 0, count = 0;
  SamplesOf(k0, T, &first, &count);
  return T + (count > 0 && position[first + count - 1] > k0 + T - 1 ? 1 : 0);
}

SampleGrid BuildSampleGrid(const Eigen::VectorXd& time, int T, double x0_time,
                           const RowMatrix& ctrl, const Eigen::VectorXd& ctrl_time,
                           const std::vector<ControlHold>& hold, const std::vector<double>& delay,
                           double dt, const std::string& where, ControlBefore before) {
  if (!(dt > 0)) throw std::invalid_argument(where + "the model timestep must be positive");
  CheckTimes(time, where, "sample");
  CheckTimes(ctrl_time, where, "control");
  SampleGrid g;

  // measured samples: their positions on the grid from the first one
  const double t0 = time.size() ? time[0] : x0_time;
  g.position.resize(T);
  for (int k = 0; k < T; ++k) {
    g.position[k] = time.size() ? Position(time[k], t0, dt) : k;
    g.on_grid = g.on_grid && g.position[k] == std::floor(g.position[k]);
  }
  // more steps than a fit can simulate: refused before anything is allocated (their count did
  // not fit an int, and std::bad_alloc followed); most often stamps in ms or ns read as seconds
  if (T > 0 && !(g.position[T - 1] < kMaxSteps)) {
    throw std::invalid_argument(
        where + "the sample times span " + FormatDigits(time[T - 1] - t0, 6) + " s, " +
        FormatDigits(g.position[T - 1], 3) + " steps of the model's timestep " +
        FormatDigits(dt, 6) + " s: more than the " + FormatDigits(kMaxSteps, 3) +
        " a fit simulates (times are in seconds: stamps in ms or ns are 1e3 or 1e9 times larger)");
  }
  // steps: through the last sample's step, or the step after it when it lies between two
  g.steps = T ? static_cast<int>(std::ceil(g.position[T - 1])) + 1 : 0;

  // controls: positions of the logged ones, then held (shifted by each actuator's delay)
  const Eigen::Index nu = ctrl.cols(), Tc = ctrl.rows();
  g.ctrl_position.resize(Tc);
  for (Eigen::Index j = 0; j < Tc; ++j) {
    g.ctrl_position[j] = ctrl_time.size() ? Position(ctrl_time[j], t0, dt) : g.position[j];
  }
  g.delay = delay.empty() ? std::vector<double>(nu, 0.0) : delay;
  g.before = before;
  HoldControls(g, ctrl, hold, g.delay, dt, &g.ctrl);
  return g;
}

void HoldControls(const SampleGrid& g, const RowMatrix& ctrl, const std::vector<ControlHold>& hold,
                  const std::vector<double>& delay, double dt, RowMatrix* out, int first,
                  int count) {
  const Eigen::Index nu = ctrl.cols(), Tc = ctrl.rows();
  const std::vector<double>& cpos = g.ctrl_position;
  const int last = count < 0 ? g.steps : first + count;  // one past the last step held
  out->resize(last - first, nu);
  const bool zero_before = g.before == ControlBefore::kZero;
  std::vector<Eigen::Index> valid;
  for (Eigen::Index i = 0; i < nu; ++i) {
    const double shift = delay.empty() ? 0.0 : delay[i] / dt;
    const bool linear = !hold.empty() && hold[i] == ControlHold::kLinear;
    // the valid (not NaN) controls: a NaN one is skipped, i.e. the last valid one held over it
    valid.clear();
    for (Eigen::Index j = 0; j < Tc; ++j) {
      if (!std::isnan(ctrl(j, i))) valid.push_back(j);
    }
    const Eigen::Index nv = static_cast<Eigen::Index>(valid.size());
    // v: the last valid control at or before step n (delayed positions), -1 before the first
    Eigen::Index v = -1;
    for (int n = first; n < last; ++n) {
      const double at = n - shift;
      while (v + 1 < nv && cpos[valid[v + 1]] <= at + SampleGrid::kOnGridTolerance) ++v;
      if (nv == 0) {
        (*out)(n - first, i) = 0;  // PrepareFit rejects a control with no valid value before
      } else if (!linear) {
        // zero-order hold: the average of the held command over the step [at, at + 1], i.e.
        // the command in force at its start weighted by the fraction of the step until the next
        // one, and so on (piecewise linear in the delay; a command within the on-grid tolerance
        // of the step's end belongs to the next step, so commands on the grid give the command
        // in force at the step's start exactly)
        double cur = v < 0 && zero_before ? 0.0 : ctrl(valid[v < 0 ? 0 : v], i), sum = 0, done = 0;
        for (Eigen::Index w = v + 1;
             w < nv && cpos[valid[w]] < at + 1 - SampleGrid::kOnGridTolerance; ++w) {
          const double f = cpos[valid[w]] - at;  // in (tolerance, 1 - tolerance)
          sum += cur * (f - done);
          done = f;
          cur = ctrl(valid[w], i);
        }
        (*out)(n - first, i) = done == 0 ? cur : sum + cur * (1 - done);
      } else if (v < 0) {
        (*out)(n - first, i) = zero_before ? 0.0 : ctrl(valid[0], i);
      } else if (v + 1 >= nv || cpos[valid[v]] >= at) {
        (*out)(n - first, i) = ctrl(valid[v], i);
      } else {
        const Eigen::Index j0 = valid[v], j1 = valid[v + 1];
        const double a = (at - cpos[j0]) / (cpos[j1] - cpos[j0]);
        (*out)(n - first, i) = (1 - a) * ctrl(j0, i) + a * ctrl(j1, i);
      }
    }
  }
}

int StepsBeforeFirstControl(const SampleGrid& g, const RowMatrix& ctrl,
                            const std::vector<double>& delay, double dt, int* actuator) {
  int most = 0, which = -1;
  for (Eigen::Index i = 0; i < ctrl.cols(); ++i) {
    Eigen::Index j = 0;
    while (j < ctrl.rows() && std::isnan(ctrl(j, i))) ++j;
    if (j == ctrl.rows()) continue;  // no valid control: PrepareFit rejects it
    // step n reads from n - shift on (both holds): before the first control while n - shift lies
    // more than the on-grid tolerance before its position
    const double shift = delay.empty() ? 0.0 : delay[i] / dt;
    const double reach = g.ctrl_position[j] + shift - SampleGrid::kOnGridTolerance;
    const int n = reach <= 0 ? 0 : std::min(g.steps, static_cast<int>(std::ceil(reach)));
    if (n > most) {
      most = n;
      which = static_cast<int>(i);
    }
  }
  if (actuator) *actuator = which;
  return most;
}

}  // namespace mjsysid
