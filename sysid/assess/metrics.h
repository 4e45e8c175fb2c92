// How well a simulation reproduces measured data, per channel (one sensor column), as MATLAB's
// System Identification Toolbox `compare` reports it:
//
//   NRMSE = |y - yhat| / |y - mean(y)| = RMS(yhat - y) / std(y)   (std: population, 1/T)
//   % fit = 100 (1 - NRMSE)
//
// y the measured column (T samples), yhat the simulated one, over the measured cells only (NaN in
// y: not measured, left out as the fit leaves it out). 100 % is a perfect match, 0 % is no better
// than the constant mean(y), negative is worse than it. A measured column with no variation
// (std(y) = 0) or no measured cell has no fit to speak of: NaN for both; so has a simulation with
// NaN at a measured cell (failed). No Ceres, no MuJoCo: Eigen only.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid {

// NRMSE of simulated against measured (both length T >= 1) over measured's non-NaN cells; NaN when
// those are constant or none, or the lengths differ
double Nrmse(const Eigen::Ref<const Eigen::VectorXd>& measured,
             const Eigen::Ref<const Eigen::VectorXd>& simulated);

// % fit = 100 (1 - NRMSE)
double FitPercent(double nrmse);

// the names of s's sensor columns, in order: the sensor's name, with [i] for each column of a
// multi-column sensor ("accel[2]"); at most sum(sensor_dims) names (the channel names everywhere:
// ChannelFit::channel, ResidualDiagnostics::channel, the report's plots)
std::vector<std::string> ChannelNames(const SequenceResult& s);

// one ChannelFit per column of s.measured (sensor_names/sensor_dims name them): the initial and
// the final simulation against the measured data; with s.simulated_one_piece (multiple shooting)
// the final is that, and the segments' (s.simulated_final) fill nrmse_segments and fit_segments
std::vector<ChannelFit> ChannelFits(const SequenceResult& s);

// the worst (lowest) and the median of the final % fit of a sequence's channels, NaN channels left
// out (NaN when none is left); initial = true: of the initial simulation
struct FitSummary {
  double worst = 0, median = 0;
};
FitSummary SummarizeFits(const std::vector<ChannelFit>& fits, bool initial);

}  // namespace mjsysid
