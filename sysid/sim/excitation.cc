#include "sysid/sim/excitation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>

#include "core/text.h"
#include "sysid/io/csv.h"

namespace mjsysid::sim {
namespace {

// splitmix64 (Steele, Lea, Flood 2014): a bijective 64-bit mix
std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// uniform in [0, 1) from the top 53 bits (std::uniform_real_distribution is not the same on
// every standard library; this is)
double Uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// standard normal by Box-Muller, from two uniforms (the first in (0, 1] so the log is finite)
double Normal(std::mt19937_64& rng) {
  const double u1 = static_cast<double>((rng() >> 11) + 1) * 0x1.0p-53;
  const double u2 = Uniform(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

const char* TypeName(io::ExcitationType type) {
  switch (type) {
    case io::ExcitationType::kSines:
      return "sines";
    case io::ExcitationType::kChirp:
      return "chirp";
    case io::ExcitationType::kPrbs:
      return "prbs";
    case io::ExcitationType::kZero:
      return "zero";
    case io::ExcitationType::kFile:
      return "file";
  }
  return "?";
}

// a file excitation's controls at t_k = k * dt: the file's last row at or before t_k
RowMatrix FileControls(const mjModel& m, const std::string& path, int steps) {
  const io::Sequence seq = io::ImportCsv(path, m, "excitation");
  const double dt = m.opt.timestep;
  if (!seq.ctrl.allFinite()) {
    throw io::LogError(path +
                       ": a control cell is empty or NaN; an excitation file gives every "
                       "actuator's control at every row");
  }
  const Eigen::Index rows = seq.time.size();
  const double need = (steps - 1) * dt;
  // a hundredth of a step of slack: times written in decimal
  if (steps > 0 && (seq.time[0] > 0.01 * dt || seq.time[rows - 1] < need - 0.01 * dt)) {
    throw io::LogError(path + ": the controls cover t = " + FormatDigits(seq.time[0], 6) + " .. " +
                       FormatDigits(seq.time[rows - 1], 6) + " s; simulate needs 0 .. " +
                       FormatDigits(need, 6) + " s (steps x the model's timestep)");
  }
  RowMatrix ctrl(steps, m.nu);
  Eigen::Index row = 0;
  for (int k = 0; k < steps; ++k) {
    while (row + 1 < rows && seq.time[row + 1] <= k * dt + 0.01 * dt) ++row;
    ctrl.row(k) = seq.ctrl.row(row);
  }
  return ctrl;
}

}  // namespace

std::uint64_t SeedFor(std::uint64_t seed, std::uint64_t stream) {
  return SplitMix(SplitMix(seed) ^ SplitMix(stream ^ 0x632be59bd9b4e019ULL));
}

Eigen::VectorXd ExcitationSignal(const io::Excitation& e, int steps, double dt,
                                 std::uint64_t seed) {
  if (steps < 0) throw std::invalid_argument("excitation: steps must be >= 0");
  if (!(dt > 0)) throw std::invalid_argument("excitation: the time step must be > 0");
  if (!(e.amplitude >= 0) || !std::isfinite(e.amplitude)) {
    throw std::invalid_argument("excitation: amplitude must be finite and >= 0");
  }
  Eigen::VectorXd u = Eigen::VectorXd::Zero(steps);
  std::mt19937_64 rng(seed);
  switch (e.type) {
    case io::ExcitationType::kSines: {
      // sum of sines with random phases, then scaled to peak |u| = amplitude
      if (e.frequencies.empty()) throw std::invalid_argument("excitation: sines need frequencies");
      std::vector<double> phase(e.frequencies.size());
      for (double& p : phase) p = 2.0 * M_PI * Uniform(rng);
      for (int k = 0; k < steps; ++k) {
        const double t = k * dt;
        double sum = 0;
        for (size_t i = 0; i < phase.size(); ++i) {
          sum += std::sin(2.0 * M_PI * e.frequencies[i] * t + phase[i]);
        }
        u[k] = sum;
      }
      const double peak = steps > 0 ? u.cwiseAbs().maxCoeff() : 0.0;
      if (peak > 0) {
        u *= e.amplitude / peak;
      } else {
        u.setZero();
      }
      break;
    }
    case io::ExcitationType::kChirp: {
      // linear sweep of the instantaneous frequency f0 -> f1 over the horizon D = steps * dt
      const double duration = steps * dt;
      const double phase0 = 2.0 * M_PI * Uniform(rng);
      const double rate = duration > 0 ? (e.f1 - e.f0) / duration : 0.0;
      for (int k = 0; k < steps; ++k) {
        const double t = k * dt;
        u[k] = e.amplitude * std::sin(phase0 + 2.0 * M_PI * (e.f0 * t + 0.5 * rate * t * t));
      }
      break;
    }
    case io::ExcitationType::kPrbs: {
      // one random sign per interval of switch_period seconds; intervals are drawn in order (also
      // those no sample falls in), so the signal at a time does not depend on dt
      if (!(e.switch_period > 0)) {
        throw std::invalid_argument("excitation: switch_period must be > 0");
      }
      long long interval = -1;
      double value = 0;
      for (int k = 0; k < steps; ++k) {
        // the tolerance puts a sample that lies on a multiple of the period in the new interval
        const auto j = static_cast<long long>(std::floor(k * dt / e.switch_period + 1e-9));
        while (interval < j) {
          value = (rng() >> 63) ? e.amplitude : -e.amplitude;
          ++interval;
        }
        u[k] = value;
      }
      break;
    }
    case io::ExcitationType::kZero:
      break;
    case io::ExcitationType::kFile:
      throw std::invalid_argument("excitation: a file excitation has no signal of its own");
  }
  return u;
}

void ClipToCtrlRange(const mjModel& m, RowMatrix* ctrl) {
  const auto nu = static_cast<Eigen::Index>(m.nu);
  if (ctrl->cols() != nu) {
    throw std::invalid_argument("ClipToCtrlRange: ctrl has " + std::to_string(ctrl->cols()) +
                                " columns, the model has nu = " + std::to_string(nu));
  }
  for (Eigen::Index i = 0; i < nu; ++i) {
    if (!m.actuator_ctrllimited[i]) continue;
    const double lo = m.actuator_ctrlrange[2 * i];
    const double hi = m.actuator_ctrlrange[2 * i + 1];
    ctrl->col(i) = ctrl->col(i).cwiseMax(lo).cwiseMin(hi);
  }
}

RowMatrix GenerateControls(const mjModel& m, const std::vector<io::Excitation>& excitation,
                           int steps, std::uint64_t seed) {
  const int nu = static_cast<int>(m.nu);
  if (steps < 0) throw std::invalid_argument("GenerateControls: steps must be >= 0");

  // a file gives every actuator's control
  if (excitation.size() == 1 && excitation[0].type == io::ExcitationType::kFile) {
    RowMatrix ctrl = FileControls(m, excitation[0].path, steps);
    ClipToCtrlRange(m, &ctrl);
    return ctrl;
  }
  // which entry drives each actuator: a named entry, else the entry for all, else none (zero)
  std::vector<const io::Excitation*> source(nu, nullptr);
  for (const io::Excitation& e : excitation) {
    if (!e.actuator.empty()) continue;
    for (int i = 0; i < nu; ++i) source[i] = &e;
  }
  for (const io::Excitation& e : excitation) {
    if (e.actuator.empty()) continue;
    const int id = mj_name2id(&m, mjOBJ_ACTUATOR, e.actuator.c_str());
    if (id < 0) {
      throw std::invalid_argument("excitation: no actuator named '" + e.actuator +
                                  "' in the model");
    }
    source[id] = &e;
  }

  // one stream per actuator, then clipping
  RowMatrix ctrl = RowMatrix::Zero(steps, nu);
  for (int i = 0; i < nu; ++i) {
    if (!source[i]) continue;
    ctrl.col(i) = ExcitationSignal(*source[i], steps, m.opt.timestep, SeedFor(seed, i));
  }
  ClipToCtrlRange(m, &ctrl);
  return ctrl;
}

void AddSensorNoise(const mjModel& m, const std::vector<io::NamedValue>& sigmas, std::uint64_t seed,
                    RowMatrix* sensordata) {
  const auto ns = static_cast<Eigen::Index>(m.nsensordata);
  if (sensordata->cols() != ns) {
    throw std::invalid_argument("AddSensorNoise: sensordata has " +
                                std::to_string(sensordata->cols()) +
                                " columns, the model has nsensordata = " + std::to_string(ns));
  }
  for (const io::NamedValue& s : sigmas) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, s.name.c_str());
    if (id < 0) {
      throw std::invalid_argument("noise: no sensor named '" + s.name + "' in the model");
    }
    if (!(s.value >= 0) || !std::isfinite(s.value)) {
      throw std::invalid_argument("noise: sigma of sensor '" + s.name +
                                  "' must be finite and >= 0");
    }
    if (s.value == 0) continue;
    // one stream per sensor, row by row
    std::mt19937_64 rng(SeedFor(seed, static_cast<std::uint64_t>(id)));
    const int adr = m.sensor_adr[id];
    const int dim = m.sensor_dim[id];
    for (Eigen::Index k = 0; k < sensordata->rows(); ++k) {
      for (int j = 0; j < dim; ++j) (*sensordata)(k, adr + j) += s.value * Normal(rng);
    }
  }
}

std::string DescribeExcitation(const std::vector<io::Excitation>& excitation) {
  std::string out;
  for (const io::Excitation& e : excitation) {
    if (!out.empty()) out += "; ";
    out += (e.actuator.empty() ? std::string("all") : e.actuator) + ": " + TypeName(e.type);
    if (e.type == io::ExcitationType::kZero) continue;
    if (e.type == io::ExcitationType::kFile) {
      out += " path=" + e.path;
      continue;
    }
    out += " amplitude=" + FormatDigits(e.amplitude, 6);
    switch (e.type) {
      case io::ExcitationType::kSines: {
        out += " frequencies=[";
        for (size_t i = 0; i < e.frequencies.size(); ++i) {
          out += (i ? ", " : "") + FormatDigits(e.frequencies[i], 6);
        }
        out += "]";
        break;
      }
      case io::ExcitationType::kChirp:
        out += " f0=" + FormatDigits(e.f0, 6) + " f1=" + FormatDigits(e.f1, 6);
        break;
      case io::ExcitationType::kPrbs:
        out += " switch_period=" + FormatDigits(e.switch_period, 6);
        break;
      case io::ExcitationType::kZero:
      case io::ExcitationType::kFile:
        break;
    }
  }
  return out;
}

}  // namespace mjsysid::sim
