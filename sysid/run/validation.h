// Held-out validation: a logged sequence that is not fitted, simulated at the start and at the
// estimate so that the per-channel fit metrics (sysid/assess/metrics.h) show whether the model
// generalises beyond the data it was fitted to.
//
// Contract: the sequence is simulated in one piece (single shooting, whatever the fit's
// multiple-shooting setting) from its logged initial state (initial states are never estimated for
// it), with the parameters that apply to its model written by core's Simulator, and the measurement
// terms (gain, bias, delay of each sensor: the estimate where fitted, the experiment's value
// otherwise) applied as in the fit's residuals (sysid/solve/residual_model.h). The result holds the
// fitted sensors' columns, like a fitted sequence's SequenceResult, with channel_fits filled.
// Failure: a simulation that fails at one of the two points (SimulationError, MujocoError, a
// parameter write the model refuses) leaves that simulation NaN (its % fit NaN) and appends a
// warning naming the sequence and the point; it never throws for it. The Simulator's own
// construction (ParameterError) throws: the fit resolved the same parameters before.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid::run {

// m: the sequence's model (as loaded); parameters and measurements: as added to the fit;
// estimates: FitResult::parameters (physical parameters, then the fitted measurement terms
// "<sensor>.delay|gain|bias"); threads: simulator workers. Warnings are appended to *warnings.
SequenceResult SimulateHeldOut(const mjModel& m, const std::vector<FitParameter>& parameters,
                               const std::vector<FitMeasurement>& measurements,
                               const std::vector<ParameterEstimate>& estimates,
                               const FitSequence& sequence, int threads,
                               std::vector<std::string>* warnings);

// The fitted control delays at their estimates in sequence's ctrl_delay: each actuator of m that
// follows one of `delays` (its own, else the shared one: sysid/fit/prepare.h
// ControlDelayOfActuators, the fit's rule) takes the estimate named delays[c].Name(); the other
// actuators keep their given delay (an empty ctrl_delay is first filled with zeros)
void ApplyFittedControlDelays(const mjModel& m, const std::vector<FitControlDelay>& delays,
                              const std::vector<ParameterEstimate>& estimates,
                              FitSequence* sequence);

}  // namespace mjsysid::run
