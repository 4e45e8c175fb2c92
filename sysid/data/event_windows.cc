// Event windows: see sysid/event_windows.h.
#include "sysid/data/event_windows.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace mjsysid {

std::string EventWindowMask::Summary() const {
  std::string names;
  for (const std::string& s : sensors) names += (names.empty() ? "'" : ", '") + s + "'";
  return "event windows: " + std::to_string(events) + " contact events in " +
         std::to_string(samples) + " samples (from " + source + "): " + std::to_string(masked) +
         " cells of the velocity- and acceleration-level sensors " +
         (names.empty() ? std::string("(none fitted)") : names) +
         " next to them left out of the fit (multiple_shooting: {event_window: 0} keeps them)";
}

// the sensor of a sensordata column
static int SensorOfColumn(const mjModel& m, int column) {
  int id = 0;
  while (id + 1 < m.nsensor && m.sensor_adr[id + 1] <= column) ++id;
  return id;
}

EventWindowMask MaskEventWindows(PreparedFit& fit, const std::vector<Trajectory>& initial,
                                 int window) {
  EventWindowMask out;
  fit.event_masked.assign(fit.sequences.size(), {});
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    fit.event_masked[q].assign(fit.channels[q].size(), 0);
  }
  if (window <= 0) return out;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    FitSequence& sq = fit.sequences[q];
    const mjModel& m = fit.models[fit.ModelIndex(sq.model)].sim->model();
    const int T = static_cast<int>(sq.measured.rows());
    out.samples += T;
    // the contact count at each sample: of the logged positions, else of the initial rollout at
    // the sample's step
    std::vector<int> ncon(T, 0);
    const bool logged = sq.qpos.rows() == T && sq.qpos.cols() == m.nq && sq.qpos.allFinite();
    if (logged) {
      std::unique_ptr<mjData, void (*)(mjData*)> d(mj_makeData(&m), mj_deleteData);
      for (int k = 0; k < T; ++k) {
        mju_copy(d->qpos, sq.qpos.row(k).data(), m.nq);
        mj_fwdPosition(&m, d.get());
        ncon[k] = d->ncon;
      }
      out.source = "the logged qpos";
    } else {
      const Trajectory& tr = initial[q];
      if (tr.ncon.empty()) continue;  // not simulated here: no events known
      const std::vector<double>& position = fit.grids[q].position;
      for (int k = 0; k < T; ++k) {
        const int step = std::min(static_cast<int>(std::lround(position[k])),
                                  static_cast<int>(tr.ncon.size()) - 1);
        ncon[k] = tr.ncon[std::max(step, 0)];
      }
      if (out.source.empty()) out.source = "the rollouts at the initial values";
    }
    // the window's samples: k - window .. k + window - 1 around each change between k - 1 and k
    std::vector<bool> in_window(T, false);
    for (int k = 1; k < T; ++k) {
      if (ncon[k] == ncon[k - 1]) continue;
      ++out.events;
      for (int j = std::max(0, k - window); j < std::min(T, k + window); ++j) in_window[j] = true;
    }
    // the velocity- and acceleration-level channels, masked there (never down to no sample)
    for (size_t c = 0; c < fit.channels[q].size(); ++c) {
      const int column = fit.channels[q][c].column;
      const int id = SensorOfColumn(m, column);
      if (m.sensor_needstage[id] < mjSTAGE_VEL) continue;
      int left = 0, masked = 0;
      for (int k = 0; k < T; ++k) {
        if (std::isnan(sq.measured(k, column))) continue;
        (in_window[k] ? masked : left) += 1;
      }
      if (masked == 0 || left == 0) continue;
      for (int k = 0; k < T; ++k) {
        if (!in_window[k] || std::isnan(sq.measured(k, column))) continue;
        fit.event_cells.emplace_back(static_cast<int>(q), k, column, sq.measured(k, column));
        sq.measured(k, column) = nan;
      }
      fit.missing[q][c] += masked;
      fit.event_masked[q][c] += masked;
      out.masked += masked;
      const char* name = mj_id2name(&m, mjOBJ_SENSOR, id);
      const std::string sensor = name ? name : "sensor " + std::to_string(id);
      if (std::find(out.sensors.begin(), out.sensors.end(), sensor) == out.sensors.end()) {
        out.sensors.push_back(sensor);
      }
    }
  }
  if (out.source.empty()) out.source = "no contact counts";
  return out;
}

void RestoreEventWindows(PreparedFit& fit) {
  for (const auto& [q, k, column, value] : fit.event_cells)
    fit.sequences[q].measured(k, column) = value;
  fit.event_cells.clear();
}

}  // namespace mjsysid
