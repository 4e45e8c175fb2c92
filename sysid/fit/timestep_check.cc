// The timestep check: see sysid/fit/timestep_check.h.
#include "sysid/fit/timestep_check.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <new>
#include <string>

#include "core/mujoco_env.h"
#include "core/text.h"
#include "sysid/assess/fit_status.h"
#include "sysid/assess/interval_check.h"
#include "sysid/assess/noise_estimate.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/problem.h"

namespace mjsysid {
namespace {

// the estimate of variable `name` in r (fallback when r has none), inside [lower, upper]
double StartOf(const FitResult& r, const std::string& name, double fallback, double lower,
               double upper) {
  double v = fallback;
  for (const ParameterEstimate& e : r.parameters) {
    if (e.name == name) v = e.value;
  }
  return std::clamp(v, lower, upper);
}

// one term of a sensor's measurement model started at its estimate
void StartTerm(const FitResult& r, const std::string& name, FitMeasurement::Term* t) {
  if (t->fit) t->initial = StartOf(r, name, t->initial, t->lower, t->upper);
}

// The fit's problem with every model's timestep halved, its variables started at r's estimate:
// samples at their own times (a sequence without times gets those of its model's grid), segments
// of the same duration. *order: the lowest integrator order of the models.
FitResult FitAtHalfStep(const PreparedFit& fit, const FitOptions& options, const FitResult& r,
                        int* order) {
  Problem half;
  *order = 4;
  for (const FitModel& mo : fit.models) {
    ModelPtr m = CopyModel(*mo.model);
    m->opt.timestep /= 2;
    *order = std::min(*order, IntegratorOrder(m->opt.integrator));
    half.AddModel(mo.name, *m);
  }
  for (FitParameter p : fit.params) {
    p.initial = StartOf(r, p.name, p.initial, p.lower, p.upper);
    half.AddParameter(p);
  }
  for (FitMeasurement me : fit.measurements) {
    StartTerm(r, me.sensor + ".delay", &me.delay);
    StartTerm(r, me.sensor + ".gain", &me.gain);
    StartTerm(r, me.sensor + ".bias", &me.bias);
    half.AddMeasurement(me);
  }
  for (FitControlDelay d : fit.control_delays) {
    d.initial = StartOf(r, d.Name(), d.initial, d.lower, d.upper);
    half.AddControlDelay(d);
  }
  for (FitSequence sq : fit.sequences) {
    if (sq.time.size() == 0) {
      const double dt = fit.models[fit.ModelIndex(sq.model)].model->opt.timestep;
      sq.time.resize(sq.measured.rows());
      for (Eigen::Index k = 0; k < sq.time.size(); ++k) {
        sq.time[k] = sq.x0.time + static_cast<double>(k) * dt;
      }
    }
    half.AddSequence(sq);
  }
  FitOptions o = options;
  o.max_iterations = kTimestepCheckIterations;
  o.timestep_check = false;
  o.global_stage = false;
  o.subset_start = false;  // it starts from the estimate
  o.observer = nullptr;
  o.on_iteration = nullptr;
  if (r.segment_steps_used > 0) o.segment_steps = 2 * r.segment_steps_used;
  return half.Fit(o);
}

}  // namespace

int IntegratorOrder(int integrator) { return integrator == mjINT_RK4 ? 4 : 1; }

// The check, then the intervals and the verdict (see the header)
void CheckTimestep(const FitParts& parts, const FitOptions& options, FitResult* result) {
  FitResult& r = *result;
  const PreparedFit& fit = *parts.fit;
  bool white = true;
  for (const ResidualDiagnostics& d : r.residuals) white = white && d.white;
  // (not where contacts or changing constraint rows make the cost rugged: a refit there moves to
  // another point of a rugged cost, whatever the timestep; measured on the box-on-floor stress
  // case; a fitted delay's kinks are smooth enough, measured on the robot with a fitted delay)
  const bool rugged = r.interval_check.kind == IntervalCheckRecord::Kind::kRanRugged &&
                      r.interval_check.dynamics_jump;
  // (nor where the interval check found the cost not smooth at the intervals' scale: the status
  // put model_mismatch before that finding, which a converged fit must not hide)
  const bool not_smooth = r.interval_check.cost_not_smooth;
  if (!options.timestep_check || r.outcome != FitStatus::kModelMismatch || r.interrupted ||
      fit.shards || fit.params.empty() || !std::isfinite(r.chi2_ratio) || white || rugged ||
      not_smooth) {
    return;
  }
  // the mismatch must be this result's own chi-square test (not the one-piece check's of a fit in
  // segments, sysid/fit/policy.cc), and no sensor without sigma may be among the unexplained
  // (the half step tests the sigmas' excess only)
  FitResult tested = r;
  tested.warnings.clear();
  if (!ResidualsAboveNoise(options, &tested)) return;
  for (const auto& [sensor, ratio] : tested.sensor_noise_ratio) {
    if (ratio > kUnexplainedNoiseFactor) return;
  }
  int order = 1;
  FitResult h;
  try {
    h = FitAtHalfStep(fit, options, r, &order);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    r.warnings.push_back(std::string("timestep check: the fit at half the timestep failed (") +
                         e.what() + "); the result is the fit's as it was");
    return;
  }
  r.seconds += h.seconds;
  r.diagnostics.simulation_steps += h.diagnostics.simulation_steps;

  // the timestep's bias of every estimate, and its interval widened to the continuous-time value
  const double richardson = std::pow(2.0, order) / (std::pow(2.0, order) - 1);
  double largest = 0;
  std::string largest_name;
  for (ParameterEstimate& e : r.parameters) {
    double at_half = e.value;
    for (const ParameterEstimate& f : h.parameters) {
      if (f.name == e.name) at_half = f.value;
    }
    const double beta = richardson * (e.value - at_half);
    e.timestep_bias = beta;
    if (e.value != 0 && std::abs(beta / e.value) > largest) {
      largest = std::abs(beta / e.value);
      largest_name = e.name;
    }
    if (!std::isfinite(e.std_error) || e.at_lower || e.at_upper) continue;
    e.ci95_low = std::min(e.value, e.value - beta) - kZ95 * e.std_error;
    e.ci95_high = std::max(e.value, e.value - beta) + kZ95 * e.std_error;
  }

  // is the misfit the timestep's? The excess of the worst measure the chi-square test reads: the
  // overall ratio, or a sensor's (the test fails on either)
  std::string worst;  // "": the overall ratio
  double ratio = r.chi2_ratio, ratio_half = h.chi2_ratio;
  for (const auto& [sensor, value] : r.sensor_chi2_ratio) {
    const auto at_half = h.sensor_chi2_ratio.find(sensor);
    if (value > ratio && at_half != h.sensor_chi2_ratio.end()) {
      worst = sensor;
      ratio = value;
      ratio_half = at_half->second;
    }
  }
  // (the half-step fit starts at the estimate, so its chi-square bounds its own minimum's from
  // above whether or not it converged; a failed or interrupted solve tells nothing). Every measure
  // clearly above the noise (ratio above kClearMisfit), and the worst, must shrink: one sensor's
  // discretisation error must not vouch for another sensor's missing term
  auto shrinks = [](double full, double half) {
    return std::isfinite(half) && half - 1 <= kTimestepExplains * (full - 1);
  };
  std::string unexplained;  // the measures that did not shrink
  if (!shrinks(ratio, ratio_half)) unexplained = worst.empty() ? "overall" : "'" + worst + "'";
  if (r.chi2_ratio > kClearMisfit && !worst.empty() && !shrinks(r.chi2_ratio, h.chi2_ratio)) {
    unexplained += (unexplained.empty() ? "" : ", ") + std::string("overall");
  }
  for (const auto& [sensor, value] : r.sensor_chi2_ratio) {
    const auto at_half = h.sensor_chi2_ratio.find(sensor);
    if (sensor == worst || !(value > kClearMisfit)) continue;
    if (at_half == h.sensor_chi2_ratio.end() || !shrinks(value, at_half->second)) {
      unexplained += (unexplained.empty() ? "'" : ", '") + sensor + "' " + FormatDigits(value, 3) +
                     " -> " +
                     (at_half == h.sensor_chi2_ratio.end() ? std::string("none")
                                                           : FormatDigits(at_half->second, 3));
    }
  }
  const bool explains = unexplained.empty() && h.outcome != FitStatus::kSolverFailed &&
                        h.outcome != FitStatus::kInterrupted;
  const double dt = fit.models.empty() ? 0 : fit.models[0].model->opt.timestep;
  r.timestep_check = "the same fit at half the timestep (" + FormatDigits(dt / 2, 3) + " s, " +
                     std::to_string(h.iterations) + " iterations, " + FitStatusName(h.outcome) +
                     "): chi-square ratio " +
                     (worst.empty() ? std::string()
                                    : "of '" + worst + "' " + FormatDigits(ratio, 3) + " -> " +
                                          FormatDigits(ratio_half, 3) + ", overall ") +
                     FormatDigits(r.chi2_ratio, 3) + " -> " + FormatDigits(h.chi2_ratio, 3) +
                     "; the timestep's bias of the estimates " + "(Richardson, integrator order " +
                     std::to_string(order) + ") at most " + FormatDigits(100 * largest, 2) +
                     " % (" + largest_name + ")";
  r.intervals_from += "; each 95 % interval widened to cover the estimate less the timestep's bias";
  if (explains) {
    r.outcome = FitStatus::kConverged;
    r.intervals_valid = r.uncertainty.rank > 0;
    r.warnings.push_back(
        "the misfit is the model's timestep: " + r.timestep_check +
        ", as a discretisation error shrinks; the model lacks nothing the data show, so the "
        "status is converged; the estimates fit the model at its timestep, and each 95 % "
        "interval is widened to hold the value at a finer one (docs/real-logs.md, \"The model's "
        "timestep\")");
  } else {
    r.warnings.push_back("timestep check: " + r.timestep_check + ": the misfit " +
                         (unexplained.empty() ? std::string() : "of " + unexplained + " ") +
                         "does not shrink as a discretisation error would, so it is not the "
                         "timestep's (model_mismatch stands)");
  }
}

}  // namespace mjsysid
