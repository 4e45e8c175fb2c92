// The verdict on a finished fit (FitStatus, sysid/types.h): see sysid/fit_status.h.
#include "sysid/assess/fit_status.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/assess/metrics.h"
#include "sysid/assess/noise_estimate.h"

namespace mjsysid {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// A Jacobian flagged unreliable while the cost fell by less than this fraction: the solver could
// not find a descent direction; the estimate is the start, not a fit.
constexpr double kSmallCostDecrease = 0.05;
// With sigmas given, the weighted residuals r = (measured - simulated) / sigma of those sensors
// have sum(r^2) ~ chi-square with m - p degrees of freedom when the model explains the data. A
// one-sided test at a false-alarm rate of 1e-6 (z = 4.753) flags sum(r^2) above the chi-square
// quantile (Wilson-Hilferty). Sigmas are rarely known better than a few tens of %, and for large m
// that quantile is barely above m (1.03 m at m = 100000), so the ratio must also exceed 2 (a sigma
// stated 29 % too small stays below it): "far above" is both. The same test per sensor, with the
// sensor's share of the m - p degrees of freedom.
constexpr double kChi2FalseAlarmZ = 4.753424308822899;
constexpr double kChi2MinRatio = 2.0;

// the largest ratio sum(r^2) / dof that the test above accepts
double Chi2RatioLimit(double dof) {
  if (!(dof > 0)) return kInf;
  const double a = 2.0 / (9.0 * dof);
  const double q = dof * std::pow(1.0 - a + kChi2FalseAlarmZ * std::sqrt(a), 3);
  return std::max(q / dof, kChi2MinRatio);
}

// the sensor's residuals are weighted by a stated sigma (the chi-square test applies)
bool HasSigma(const FitOptions& options, const std::string& sensor) {
  const auto& sig = options.sensors_with_sigma;
  return std::find(sig.begin(), sig.end(), sensor) != sig.end();
}

// Sensors without a sigma: each column's residual at the estimate against the noise estimated
// from the log itself, pooled over sequences (sysid/assess/noise_estimate.h). Sets
// r->sensor_noise_ratio, appends the warning naming the columns that fail the test; true when one
// does. A sensor none of whose columns can be tested (its noise cannot be estimated: too few
// consecutive measured samples, or a constant column) has no ratio and gets a warning of its own:
// the model check was not possible, the status says nothing about it (its % fit, and whether that
// is below kUnexplainedFitPercent, in the warning).
bool UnexplainedWithoutSigmas(const FitOptions& options, FitResult* result) {
  FitResult& r = *result;
  struct Pooled {
    double residual2 = 0, noise2 = 0, spread2 = 0;        // sums over measured rows
    double untested_residual2 = 0, untested_spread2 = 0;  // the rows without a noise estimate
    double rows = 0;                                      // measured rows, tested or not
  };
  std::map<std::string, std::vector<Pooled>> columns;  // sensor -> its columns
  for (const SequenceResult& sr : r.sequences) {
    Eigen::Index col = 0;
    for (size_t i = 0; i < sr.sensor_names.size(); ++i) {
      const std::string& name = sr.sensor_names[i];
      const int dim = sr.sensor_dims[i];
      if (!HasSigma(options, name) && sr.simulated_final.cols() >= col + dim &&
          sr.simulated_final.rows() == sr.measured.rows()) {
        std::vector<Pooled>& pooled = columns[name];
        pooled.resize(static_cast<size_t>(dim));
        for (int c = 0; c < dim; ++c) {
          const Eigen::VectorXd y = sr.measured.col(col + c);
          const double noise = EstimateNoiseStd(y, sr.time);
          const auto measured = !y.array().isNaN();
          const double rows = static_cast<double>(measured.count());
          if (rows == 0) continue;
          const double mean = measured.select(y.array(), 0.0).sum() / rows;
          const auto diff = y.array() - sr.simulated_final.col(col + c).array();
          const double residual2 = measured.select(diff, 0.0).square().sum();
          const double spread2 = measured.select(y.array() - mean, 0.0).square().sum();
          Pooled& p = pooled[static_cast<size_t>(c)];
          p.rows += rows;
          if (!std::isfinite(noise)) {
            p.untested_residual2 += residual2;
            p.untested_spread2 += spread2;
            continue;
          }
          p.residual2 += residual2;
          p.spread2 += spread2;
          p.noise2 += noise * noise * rows;
        }
      }
      col += dim;
    }
  }
  std::string unexplained, untested;
  bool untested_low_fit = false;
  for (const auto& [name, pooled] : columns) {
    // the sensor's worst column, and its worst column that fails the test
    double worst = -1, flagged_ratio = -1, flagged_fit = 0;
    for (const Pooled& p : pooled) {
      if (!(p.noise2 > 0 && p.spread2 > 0)) continue;
      const double ratio = std::sqrt(p.residual2 / p.noise2);
      const double fit = FitPercent(std::sqrt(p.residual2 / p.spread2));
      worst = std::max(worst, ratio);
      if (ratio > kUnexplainedNoiseFactor && fit < kUnexplainedFitPercent &&
          ratio > flagged_ratio) {
        flagged_ratio = ratio;
        flagged_fit = fit;
      }
    }
    if (worst >= 0) r.sensor_noise_ratio[name] = worst;
    double rows = 0;
    for (const Pooled& p : pooled) rows += p.rows;
    if (worst < 0 && rows > 0) {
      // no column tested: the sensor's worst % fit over all its rows (NaN: constant columns)
      double fit = std::numeric_limits<double>::quiet_NaN();
      for (const Pooled& p : pooled) {
        const double spread2 = p.spread2 + p.untested_spread2;
        if (!(spread2 > 0)) continue;
        const double f = FitPercent(std::sqrt((p.residual2 + p.untested_residual2) / spread2));
        fit = std::isnan(fit) ? f : std::min(fit, f);
      }
      untested_low_fit = untested_low_fit || fit < kUnexplainedFitPercent;
      untested += (untested.empty() ? "" : ", ") + name + " (% fit " +
                  (std::isnan(fit) ? std::string("undefined: constant") : FormatDigits(fit, 3)) +
                  ")";
    }
    if (flagged_ratio >= 0) {
      unexplained += (unexplained.empty() ? "" : ", ") + name + " " +
                     FormatDigits(flagged_ratio, 3) + " x (% fit " + FormatDigits(flagged_fit, 3) +
                     ")";
    }
  }
  if (!unexplained.empty()) {
    r.warnings.push_back(
        "model mismatch: the fit does not explain the data: the residuals are far above the "
        "noise estimated from the log itself (sensors without a sigma): " +
        unexplained +
        ": the start is in another minimum (try other starts or multiple_shooting) or the "
        "model lacks an effect in the data; give the sensors' sigmas if their noise is "
        "filtered or known; the intervals are not valid");
  }
  if (!untested.empty()) {
    r.warnings.push_back(
        "model check not possible: no sigma, and the noise of the log cannot be estimated (fewer "
        "than 8 triples of consecutive measured samples, or a constant column), for " +
        untested + ": the status does not say whether the model explains these sensors" +
        (untested_low_fit ? "; a % fit below " + FormatDigits(kUnexplainedFitPercent, 3) +
                                " leaves a visible part of the motion unexplained"
                          : std::string()) +
        "; give their sigmas (or longer sequences) for the model check");
  }
  return !unexplained.empty();
}

}  // namespace

bool ResidualsAboveNoise(const FitOptions& options, FitResult* result) {
  FitResult& r = *result;
  // with sigmas: the weighted residuals of those sensors (and of the fitted states) at the
  // estimate against chi-square
  std::vector<std::string> mismatched;
  bool mismatch = false;
  if (!options.sensors_with_sigma.empty() || options.states.any()) {
    std::map<std::string, std::pair<double, long long>> per_sensor;  // sum r^2, rows
    for (const SequenceResult& sr : r.sequences) {
      Eigen::Index col = 0;
      for (size_t i = 0; i < sr.sensor_names.size(); ++i) {
        const std::string& name = sr.sensor_names[i];
        const int dim = sr.sensor_dims[i];
        if (HasSigma(options, name)) {
          const auto w = options.sensor_weights.find(name);
          const double weight = w != options.sensor_weights.end() ? w->second : 1.0;
          // samples not measured (NaN) were masked out of the fit: left out here too
          const auto diff =
              (sr.measured.middleCols(col, dim) - sr.simulated_final.middleCols(col, dim)).array();
          const auto measured = !sr.measured.middleCols(col, dim).array().isNaN();
          auto& [sum, rows] = per_sensor[name];
          sum += weight * weight * measured.select(diff, 0.0).square().sum();
          rows += static_cast<long long>(measured.count());
        }
        col += dim;
      }
      // fitted states always have a sigma (sysid/solve/state_residuals.h): their weighted residuals
      col = 0;
      for (size_t i = 0; i < sr.state_names.size(); ++i) {
        const int dim = sr.state_residual_dims[i];
        const auto res = sr.state_residual_final.middleCols(col, dim).array();
        const auto measured = !res.isNaN();
        auto& [sum, rows] = per_sensor[sr.state_names[i]];
        sum += measured.select(res, 0.0).square().sum();
        rows += static_cast<long long>(measured.count());
        col += dim;
      }
    }
    double total = 0;
    long long m = 0;
    for (const auto& [name, sr] : per_sensor) {
      total += sr.first;
      m += sr.second;
    }
    // the fitted dimensions: the rank of the Jacobian at the estimate (parameters and states)
    const int p =
        r.uncertainty.rank > 0 ? r.uncertainty.rank : static_cast<int>(r.parameters.size());
    const double dof = static_cast<double>(m - p);
    if (m > 0 && dof > 0) {
      r.chi2_ratio = total / dof;
      mismatch = r.chi2_ratio > Chi2RatioLimit(dof);
      for (const auto& [name, sr] : per_sensor) {
        const double share = dof * static_cast<double>(sr.second) / static_cast<double>(m);
        const double ratio = sr.first / share;
        r.sensor_chi2_ratio[name] = ratio;
        if (ratio > Chi2RatioLimit(share)) {
          mismatch = true;
          mismatched.push_back(name + " " + FormatDigits(ratio, 3));
        }
      }
      if (mismatch) {
        std::string sensors;
        for (const std::string& s : mismatched) sensors += (sensors.empty() ? "" : ", ") + s;
        r.warnings.push_back(
            "model mismatch: the residuals are larger than the sigmas explain: weighted residual "
            "variance " +
            FormatDigits(r.chi2_ratio, 3) + " (expected 1; limit " +
            FormatDigits(Chi2RatioLimit(dof), 3) + ", chi-square with " + std::to_string(m - p) +
            " degrees of freedom)" +
            (sensors.empty() ? std::string() : "; per sensor: " + sensors) +
            ": the model lacks an effect in the data, the start is in another minimum, " +
            (options.estimate_initial_state
                 ? std::string()
                 : "the initial states (taken from the log or the model, not estimated) are "
                   "off, ") +
            "or the sigmas are too small; the intervals are not valid");
      }
    }
  }

  // without sigmas: the residuals against the noise the log itself shows
  if (UnexplainedWithoutSigmas(options, &r)) mismatch = true;
  return mismatch;
}

void DecideFitStatus(const FitOptions& options, int accepted_steps, bool jacobian_warned,
                     FitResult* result, bool cost_not_local, bool jacobian_warned_at_estimate) {
  FitResult& r = *result;

  // did the estimate leave its start: an accepted step that changed some estimated value
  bool moved = accepted_steps > 0 && r.parameters.empty();  // only initial states estimated
  for (const ParameterEstimate& e : r.parameters) {
    moved = moved || (accepted_steps > 0 && e.value != e.initial);
  }
  // the statistical stop at the start: the start is the estimate, within the stop's fraction of
  // every standard error of the Gauss-Newton optimum (a full-rank Jacobian: every value moves
  // the data), so not having moved is right
  moved = moved || r.gauss_newton_converged;
  const double decrease = r.initial_cost > 0 ? (r.initial_cost - r.final_cost) / r.initial_cost : 0;
  const bool jacobian_bad = jacobian_warned && decrease < kSmallCostDecrease;

  const bool mismatch = !r.interrupted && ResidualsAboveNoise(options, &r);

  // the verdict, the first that applies
  if (r.interrupted) {
    r.outcome = FitStatus::kInterrupted;
  } else if (r.termination.kind == FitTermination::Kind::kSolverFailure) {
    r.outcome = FitStatus::kSolverFailed;
    std::string message = r.termination.solver_message;
    while (!message.empty() && std::isspace(static_cast<unsigned char>(message.back()))) {
      message.pop_back();  // Ceres ends some messages with a space
    }
    r.warnings.push_back(
        "solver failed: Ceres stopped with a failure (" + message + ") after " +
        std::to_string(accepted_steps) +
        " accepted steps: the estimate is the last accepted point, not a fit, and its intervals "
        "are not valid; " +
        (r.termination.solver_message.find("Linear solver") != std::string::npos
             ? std::string("the linear solver failed (what its library said, if anything, is "
                           "among the warnings): fewer state variables (longer segments: "
                           "multiple_shooting segment_steps) or fewer parameters")
             : std::string("the cost could not be evaluated (the warnings say where): the data's "
                           "values, the sigmas and the start")) +
        " are the ways out");
  } else if (!moved && !r.parameters.empty()) {
    r.outcome = FitStatus::kDidNotMove;
    r.warnings.push_back("did not move: no estimated value left its start (" +
                         std::to_string(accepted_steps) +
                         " accepted steps): the Jacobian gave no descent direction; the estimate "
                         "is the start and its intervals are not valid");
  } else if (jacobian_bad) {
    r.outcome = FitStatus::kJacobianUnreliable;
    r.warnings.push_back(
        "Jacobian unreliable: the cost fell by only " + FormatDigits(100 * decrease, 3) +
        " % while the Jacobian was not reliable: no fit was found (shorten the "
        "horizon: multiple_shooting, or start closer); the intervals are not valid");
  } else if (!r.converged) {
    r.outcome = FitStatus::kNotConverged;
  } else if (jacobian_warned_at_estimate) {
    // converged where the core flags the Jacobian: the rollouts are so sensitive that its linear
    // model holds only for changes far below a step, so the last step was a guess, the intervals
    // too
    // (measured: a chaotic 5000-step single-shooting fit without sigmas stopped 44 % off the truth
    // with the cost 12 % down and intervals 2e-5 wide; since the core splits its columns past
    // h*|S| = 1e-2 that fit runs into its iteration cap instead, tests/sysid/status_test.cc)
    r.outcome = FitStatus::kJacobianUnreliable;
    r.warnings.push_back(
        "Jacobian unreliable at the estimate: the rollouts there are so sensitive to the "
        "parameters (h*|S| > 1e-2 at the estimate) that the Jacobian's linear model holds only "
        "for changes far below a step, so the estimate may be no minimum and its "
        "intervals are not valid; shorten the horizon (multiple_shooting: auto or segment_steps) "
        "or start closer");
  } else if (mismatch) {
    // the residuals are not noise (their warning says which test): after the Jacobian's flag,
    // whose way out (a shorter horizon) comes first when both apply
    r.outcome = FitStatus::kModelMismatch;
  } else if (cost_not_local) {
    // converged on a cost that jumps within the intervals (the warning says where)
    r.outcome = FitStatus::kJacobianUnreliable;
  } else {
    r.outcome = FitStatus::kConverged;
  }
  r.intervals_valid = r.outcome == FitStatus::kConverged && r.uncertainty.std_error.size() > 0;

  // a parameter stopped on a bound has no interval, and the others' are conditional on it being
  // fixed there: too narrow when the data pull it past the bound (measured: a noisy LuGre fit with
  // the Stribeck velocity on its lower bound left the Coulomb level 3 standard errors off)
  std::string on_bound;
  for (const ParameterEstimate& e : r.parameters) {
    if (e.at_lower || e.at_upper) on_bound += (on_bound.empty() ? "" : ", ") + e.name;
  }
  if (r.intervals_valid && !on_bound.empty()) {
    r.intervals_valid = false;
    r.warnings.push_back("intervals not valid: they are conditional on " + on_bound +
                         " fixed on a bound; widen the bounds or fix that parameter to its "
                         "known value");
  }
}

}  // namespace mjsysid
