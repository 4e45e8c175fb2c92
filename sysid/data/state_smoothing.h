// Logged states smoothed for differentiation: the equation-error start's states and
// accelerations on logs whose states are not the integrator's own (noisy, quantized, jittered,
// or joint encoders only).
//
// The filter F: at every sample k a cubic fitted by weighted least squares (tricube weights,
// which taper to zero at the window's ends) to the finite samples within +-h samples of k at
// their logged times (so uneven stamps are handled; where NaN cells leave fewer than five, the
// window widens by up to 4 samples), read at t_k. The same F is applied to every state channel
// and to the control each sample applied (clamped to ctrlrange as mj_fwdActuation would), so the
// equations of motion hold for the filtered signals up to how M(q) and the bias forces vary
// within a window: a jump of a PRBS command and the jump of the acceleration it causes are
// blurred alike, instead of a sharp command meeting a blurred acceleration.
// The accelerations (and the velocities, for encoders only) are central differences of the
// filtered sequences at the logged times: d/dt F[qvel] is F[qacc] to O(dt^2), the same filter.
//
// The half-width h, one per sequence, is chosen from the data: each channel's noise sigma from
// the residuals of the narrowest fits (h = 3; E r_k^2 = sigma^2 (1 - 2 H_kk + sum_j w_kj^2) for
// white noise), at least a quantized channel's rounding noise quantum / sqrt(12); then the h of a
// fixed grid (2 .. 64 samples) that minimises Mallows' Cp summed over the channels that are
// differentiated (qvel, else qpos), each in units of its sigma:
//   Cp_c(h) = sum_k (x_k - F_h[x]_k)^2 / sigma_c^2 + 2 sum_k H_kk(h),
// H_kk the weight of x_k in its own fit (the filter's degrees of freedom); both sums over every
// 4th sample. Noise-free states choose the smallest h.
//
// Time alignment. A logged qvel may lag its positions (a simulator's semi-implicit Euler and a
// drive's backward differences put it half a sample behind): the lag, one per sequence, is fitted
// by least squares against the central differences of the filtered positions and removed. The
// velocities are then put in the model integrator's convention, which the discrete-time inverse
// (mjENBL_INVDISCRETE) expects: Euler, implicit and implicitfast carry qvel_k half a timestep
// behind the positions, with the one-step acceleration centred on t_k; RK4's are aligned.
// On a MuJoCo log without noise this reproduces the integrator's own velocities and
// accelerations to O(dt^2) (tests/sysid/data/state_smoothing_test.cc).
//
// Which coordinates are filtered: hinge and slide joints' qpos, every qvel, act. The qpos of ball
// and free joints (quaternions) stay as logged. Without logged qvel the velocities come from qpos,
// which needs every joint to be a hinge or slide (nq == nv): else nothing is smoothed (`why`).
#pragma once

#include <mujoco/mujoco.h>

#include <string>

#include "sysid/types.h"

namespace mjsysid {

// the time of sample k of s (s.time, else x0.time + k * timestep)
double LogSampleTime(const mjModel& m, const FitSequence& s, int k);

// the row of s.ctrl held at time t (zero-order hold on ctrl_time; without it sample k's row)
int HeldControlRow(const FitSequence& s, int k, double t);

struct SmoothedStates {
  // s's time, x0 and ctrl_before; qpos (T x nq), qvel (T x nv), act (T x na) filtered; ctrl
  // (T x nu) the control applied at each sample (clamped to ctrlrange where limited) filtered,
  // ctrl_time empty. measured is empty. NaN where a sample's window has too few finite samples.
  FitSequence states;
  RowMatrix qacc;      // T x nv: central differences of the filtered qvel; NaN at the ends
  int half_width = 0;  // h, samples each side
  bool velocities_from_positions = false;  // the log has no qvel (encoders only)
  double qvel_lag = 0;  // s, the logged qvel's lag behind the positions (read at t + lag)
};

// s's states filtered as above. Returns false (why says what is missing) when s has no qpos, no
// act where the model has activations, or no qvel and a ball or free joint; s must have at
// least 16 samples with finite states.
bool SmoothLoggedStates(const mjModel& m, const FitSequence& s, SmoothedStates* out,
                        std::string* why);

}  // namespace mjsysid
