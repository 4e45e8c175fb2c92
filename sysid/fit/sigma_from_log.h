// Sigma from the log (the experiment's `sigma: auto`, FitOptions::sensors_sigma_from_log): each
// listed sensor's noise standard deviation estimated from the fitted sequences' own measured
// columns before the fit starts, so that the status judges the model against the sensor's noise
// rather than against a guess, and the chi-square test, the residual diagnostics and the timestep
// check work as with a stated sigma.
//
// The estimate is the log's high-frequency content (sysid/assess/noise_estimate.h,
// EstimateNoiseStd: the median absolute second difference, at least an encoder's quantum /
// sqrt(12)): independent of the model, so a model that cannot explain the data still fails the
// test. Per sensor, pooled over its columns and the sequences that fit it: sigma^2 = the mean of
// the columns' sigma_hat^2 weighted by their measured samples. Noise filtered before logging
// (correlated over many samples) is underestimated by any such estimate: the status then says
// model_mismatch and the residual diagnostics show the correlation (docs/real-logs.md).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "sysid/solve/fit_state.h"

namespace mjsysid {

// sensor `name`'s sigma_hat from the sequences that fit it (their models by name through
// model_of; nullptr: skipped), pooled as above; throws std::invalid_argument naming the sensor as
// WithSigmasFromLog does (run::BuildProblem calls it to refuse an experiment before the fit)
double SigmaFromLog(const std::string& name, const std::vector<FitSequence>& sequences,
                    const std::function<const mjModel*(const std::string&)>& model_of);

// options with every sensor of options.sensors_sigma_from_log given the weight 1 / sigma_hat and
// listed in sensors_with_sigma (sensors_sigma_from_log then empty); *sigmas (may be nullptr)
// receives sensor -> sigma_hat. A sigma_hat below 1e-9 of the sensor's largest |reading| (a log
// without noise) is raised to it. Throws std::invalid_argument naming the sensor when it is not in
// any fitted sequence's model, is given a sigma or weight too, has fewer than 8 runs of three
// consecutive measured samples, or reads 0 throughout.
FitOptions WithSigmasFromLog(const PreparedFit& fit, const FitOptions& options,
                             std::map<std::string, double>* sigmas);

}  // namespace mjsysid
