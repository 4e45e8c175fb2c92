#include "sysid/io/time_base.h"

#include <algorithm>
#include <cmath>

#include "core/text.h"
#include "sysid/io/log.h"

namespace mjsysid::io {
namespace {

// a sample period this far from the median (relative) is "varying"
constexpr double kPeriodVariation = 0.5;
// a gap longer than this many median periods is reported
constexpr double kGapPeriods = 10;
// a median period below this fraction of the model timestep is a unit error
constexpr double kMinPeriodOfTimestep = 0.01;
// a median period (of the sample times) above this many model timesteps is a unit error
constexpr double kMaxPeriodOfTimestep = 100;
// a time dataset longer than this (s, one day) is a unit error
constexpr double kMaxSpan = 86400;

// the fix of a unit error, for a log imported or written by the user; factor: the likely unit's
// --time-scale factor, nullptr when no unit is likely
std::string UnitFix(const char* factor) {
  return std::string(
             "time must be in seconds: write it in seconds, or (re-)import the CSV or "
             "bag with `sysid import --time-scale ") +
         (factor ? std::string(factor) + "`"
                 : "FACTOR` (0.001 for milliseconds, 1e-9 for nanoseconds)");
}

// "time looks like milliseconds: periods of 2 'seconds' on a 0.002 s model; " when a smaller unit
// (ms, us, ns) brings the median period closer to the timestep than seconds do (log scale);
// example_factor: that unit's --time-scale factor, else nullptr
std::string LikelyUnit(double period, double timestep, const char** example_factor) {
  struct Unit {
    const char* name;
    double factor;
    const char* text;
  };
  static const Unit kUnits[] = {{"milliseconds", 1e-3, "0.001"},
                                {"microseconds", 1e-6, "1e-6"},
                                {"nanoseconds", 1e-9, "1e-9"}};
  const Unit* best = nullptr;
  double best_distance = std::abs(std::log10(period / timestep));
  for (const Unit& u : kUnits) {
    const double d = std::abs(std::log10(period * u.factor / timestep));
    if (d < best_distance) {
      best = &u;
      best_distance = d;
    }
  }
  *example_factor = best ? best->text : nullptr;
  if (!best) return "";
  return std::string("time looks like ") + best->name + ": periods of " + FormatDigits(period, 6) +
         " 'seconds' on a " + FormatDigits(timestep, 6) + " s model; ";
}

[[noreturn]] void Fail(const std::string& file, const std::string& object,
                       const std::string& what) {
  throw LogError(file + ": " + object + ": " + what);
}

// finite and strictly increasing
void CheckIncreasing(const Eigen::VectorXd& t, const std::string& file, const std::string& object) {
  for (Eigen::Index k = 0; k < t.size(); ++k) {
    if (!std::isfinite(t[k])) {
      Fail(file, object,
           "row " + std::to_string(k) + ": time " + FormatShortest(t[k]) + " is not finite");
    }
    if (k > 0 && !(t[k] > t[k - 1])) {
      Fail(file, object,
           "row " + std::to_string(k) + ": time " + FormatShortest(t[k]) +
               " is not greater than row " + std::to_string(k - 1) + "'s " +
               FormatShortest(t[k - 1]) + " (time must be strictly increasing)");
    }
  }
}

}  // namespace

double MedianPeriod(const Eigen::VectorXd& time) {
  std::vector<double> d(static_cast<size_t>(time.size() - 1));
  for (Eigen::Index k = 1; k < time.size(); ++k) d[k - 1] = time[k] - time[k - 1];
  const size_t mid = d.size() / 2;
  std::nth_element(d.begin(), d.begin() + mid, d.end());
  if (d.size() % 2) return d[mid];
  const double hi = d[mid];
  return 0.5 * (*std::max_element(d.begin(), d.begin() + mid) + hi);
}

std::vector<std::string> CheckTimeBase(const Eigen::VectorXd& time, double timestep,
                                       const std::string& file, const std::string& object,
                                       const Eigen::VectorXd* ctrl_time, TimeDataset kind) {
  std::vector<std::string> warnings;
  const Eigen::Index T = time.size();
  if (T < 2) {
    Fail(
        file, object,
        "has " + std::to_string(T) + " sample(s): at least 2 are needed to know the sample period");
  }
  CheckIncreasing(time, file, object);
  const double period = MedianPeriod(time);

  // a unit error: far more samples than simulation steps
  if (period < kMinPeriodOfTimestep * timestep) {
    Fail(file, object,
         "the median sample period " + FormatDigits(period, 6) +
             " s is below 1/100 of the model "
             "timestep " +
             FormatDigits(timestep, 6) +
             " s: time must be in seconds (are these "
             "milliseconds or clock ticks, or is the model's timestep in other units?)");
  }
  // the other unit error: far fewer samples than steps, or a log of days
  const char* factor = nullptr;
  if (kind == TimeDataset::kSamples && period > kMaxPeriodOfTimestep * timestep) {
    const std::string unit = LikelyUnit(period, timestep, &factor);
    Fail(file, object,
         "the median sample period " + FormatDigits(period, 6) + " s is more than " +
             FormatDigits(kMaxPeriodOfTimestep, 6) + " x the model timestep " +
             FormatDigits(timestep, 6) + " s: " + unit + UnitFix(factor));
  }
  const double span = time[T - 1] - time[0];
  if (span > kMaxSpan) {
    const std::string unit = LikelyUnit(period, timestep, &factor);
    Fail(file, object,
         "the log spans " + FormatDigits(span, 6) + " s (" + FormatDigits(time[0], 9) + " .. " +
             FormatDigits(time[T - 1], 9) + "), more than one day (86400 s): " + unit +
             UnitFix(factor));
  }

  // varying periods and gaps: warnings naming the first place
  Eigen::Index varying = 0, first_varying = -1, gaps = 0, first_gap = -1;
  for (Eigen::Index k = 1; k < T; ++k) {
    const double d = time[k] - time[k - 1];
    if (std::abs(d - period) > kPeriodVariation * period) {
      if (varying++ == 0) first_varying = k;
    }
    if (d > kGapPeriods * period) {
      if (gaps++ == 0) first_gap = k;
    }
  }
  if (varying > gaps) {
    warnings.push_back(file + ": " + object +
                       ": the sample period varies by more than 50 % of its "
                       "median " +
                       FormatDigits(period, 6) + " s at " + std::to_string(varying) + " of " +
                       std::to_string(T - 1) + " steps (first between rows " +
                       std::to_string(first_varying - 1) + " and " + std::to_string(first_varying) +
                       "); each sample is fitted at its own time");
  }
  if (gaps > 0) {
    const double len = time[first_gap] - time[first_gap - 1];
    warnings.push_back(file + ": " + object + ": " + std::to_string(gaps) + " gap(s) longer than " +
                       "10 sample periods (first between rows " + std::to_string(first_gap - 1) +
                       " and " + std::to_string(first_gap) + ", " + FormatDigits(len, 6) + " s = " +
                       FormatDigits(len / period, 3) + " periods); the simulation runs through it");
  }

  // controls at their own times: finite, increasing, overlapping the sensor samples
  if (ctrl_time) {
    const std::string cobject = object + " (controls)";
    if (ctrl_time->size() < 1) Fail(file, cobject, "has no control sample");
    CheckIncreasing(*ctrl_time, file, cobject);
    const double c0 = (*ctrl_time)[0], c1 = (*ctrl_time)[ctrl_time->size() - 1];
    if (c0 > time[T - 1] || c1 < time[0]) {
      Fail(file, cobject,
           "the controls (" + FormatDigits(c0, 9) + " .. " + FormatDigits(c1, 9) +
               " s) do not overlap the sensor samples (" + FormatDigits(time[0], 9) + " .. " +
               FormatDigits(time[T - 1], 9) + " s): both must be on the same clock, in seconds");
    }
  }
  return warnings;
}

void ScaleTime(double factor, const std::string& source, Sequence* seq) {
  if (!(std::isfinite(factor) && factor > 0)) {
    throw LogError(source + ": the time scale " + FormatShortest(factor) +
                   " must be a finite number > 0 (0.001: milliseconds to seconds, 1e-9: "
                   "nanoseconds)");
  }
  seq->time *= factor;
  seq->ctrl_time *= factor;
  for (auto& [object, times] : seq->own_times) times *= factor;
}

}  // namespace mjsysid::io
