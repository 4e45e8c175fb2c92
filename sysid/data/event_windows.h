// Event windows: the residual samples of velocity- and acceleration-level sensors next to a contact
// event, left out of a multiple-shooting fit (docs/numerics.md, "Contact: event windows").
//
// At an impact or a lift-off the joint velocities, a gyro, an accelerometer or a touch sensor jump
// within one step. When a parameter moves the simulated event by one step, the residuals of those
// sensors at the samples next to it change by the whole jump: the cost is rugged there, at
// parameter changes far below the standard errors, and the Jacobian describes it only over a
// sliver (sysid/assess/interval_check.h). Position-level sensors (encoders, frame positions) are
// continuous through an event and stay fitted everywhere; so do the velocity- and
// acceleration-level sensors away from events.
//
// The events are the samples where the contact count (mj_fwdPosition's ncon) of the logged
// positions (FitSequence::qpos) changes from the previous sample; without logged positions, where
// the contact count of the rollout at the initial values (Trajectory::ncon) changes. The mask is
// decided once, before the fit: the cells of every fitted channel whose sensor needs the velocity
// or acceleration stage (mjModel::sensor_needstage >= mjSTAGE_VEL) at samples k - window .. k +
// window - 1 around each event k (the event falls between samples k - 1 and k) are set to NaN in
// the problem's copy of the measured data (masked like an unmeasured cell: not fitted, not in the
// chi-square test), and counted: the result's sequences show them as NaN, and
// FitResult::event_windows says how many (a warning too).
#pragma once

#include <string>
#include <vector>

#include "core/simulator.h"
#include "sysid/solve/fit_state.h"

namespace mjsysid {

// the default half-width of an event window, in samples (FitOptions::event_window)
constexpr int kEventWindowSamples = 2;

// What MaskEventWindows did (one line of it goes to FitResult::event_windows and stderr)
struct EventWindowMask {
  int events = 0;                    // contact-count changes found, over every sequence
  int masked = 0;                    // measured cells set to NaN
  int samples = 0;                   // samples (rows) of the sequences looked at
  std::vector<std::string> sensors;  // the sensors with masked cells, in order of first masking
  std::string source;                // "logged qpos" or "the rollouts at the initial values"
  std::string Summary() const;  // "event windows: N events (from ...), +-w samples: M cells of ..."
};

// Sets the window's cells of fit.sequences[q].measured to NaN, counts them in fit.missing and
// fit.event_masked (per sequence and channel, as fit.channels; shapes: fit prepared up to the
// channels; initial: the rollouts at the initial values, one per sequence, rows
// may be empty). window <= 0 masks nothing. A channel is never masked down to no measured sample
// (its cells are kept then).
// The masked cells are recorded (fit.event_cells); RestoreEventWindows puts their values back (at
// the start of every Prepare, so that each fit of a Problem decides its own mask from the data).
EventWindowMask MaskEventWindows(PreparedFit& fit, const std::vector<Trajectory>& initial,
                                 int window);
void RestoreEventWindows(PreparedFit& fit);

}  // namespace mjsysid
