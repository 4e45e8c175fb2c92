// The kinds' recovery cases that both tests/sysid/kinds_recovery_test.cc (noise-free) and
// tests/sysid/kinds_coverage_recovery_test.cc (noisy) fit: one factory per case, the only place
// its model, truth, start, bounds, excitation and noise are written (tests/sysid/kind_case.h).
#pragma once

#include <string>

#include "core/mujoco_env.h"
#include "tests/fit_test_util.h"
#include "tests/sysid/kind_case.h"
#include "tests/test_util.h"

namespace mjsysid::test {

// the press force of tests/sysid/kind_case.h as a case's controls (the seed is not used)
inline RowMatrix PressControls(const mjModel& m, int T, int /*seed*/) { return PressForce(m, T); }

// c with d's parameters after its own (truth, start, bounds); c's excitation and noise
inline KindCase WithParametersOf(KindCase c, const KindCase& d) {
  c.truth.insert(c.truth.end(), d.truth.begin(), d.truth.end());
  c.start.insert(c.start.end(), d.start.begin(), d.start.end());
  c.lower.insert(c.lower.end(), d.lower.begin(), d.lower.end());
  c.upper.insert(c.upper.end(), d.upper.begin(), d.upper.end());
  return c;
}

// ---------------------------------------------------------------------------------------------
// servo gains and tendons (models/pid_tendon.xml, models/tendon_deadband.xml)

// a pid's kp and ki and the coupling tendon's stiffness and damping (models/pid_tendon.xml) under
// the pid's and the velocity servo's multi-sine targets. Truth: kp 35, ki 12, stiffness 4, damping
// 0.3; start: the model's 40, 10, 3, 0.2. Noise: 1 mrad on each angle, 10 mrad/s on the rate.
inline KindCase PidTendonCase() {
  KindCase c;
  c.model = "pid_tendon.xml";
  c.truth = {{"kp", Spec("actuator_kp", "shoulder_pid"), 35},
             {"ki", Spec("actuator_ki", "shoulder_pid"), 12},
             {"k", Spec("tendon_stiffness", "coupling"), 4},
             {"b", Spec("tendon_damping", "coupling"), 0.3}};
  c.start = {40, 10, 3, 0.2};
  c.lower = {1, 0.1, 0.01, 1e-3};
  c.upper = {200, 100, 100, 10};
  c.sigma = {{"q_shoulder", 0.001}, {"q_elbow", 0.001}, {"v_shoulder", 0.01}};
  return c;
}

// a velocity servo's kv (models/pid_tendon.xml, elbow_vel: the kind writes both its gain and its
// bias) under multi-sine velocity targets, with the pid's kv on the shoulder. Truth: elbow kv 2.6,
// pid kv 3.9; start: the model's 2, 3 (23 % off each). Noise: 1 mrad on each angle, 10 mrad/s on
// the rate.
inline KindCase VelocityServoKvCase() {
  KindCase c;
  c.model = "pid_tendon.xml";
  c.truth = {{"kv_elbow", Spec("actuator_kv", "elbow_vel"), 2.6},
             {"kv_shoulder", Spec("actuator_kv", "shoulder_pid"), 3.9}};
  c.start = {2.0, 3.0};
  c.lower = {0.01, 0.01};
  c.upper = {50.0, 50.0};
  c.sigma = {{"q_shoulder", 0.001}, {"q_elbow", 0.001}, {"v_shoulder", 0.01}};
  return c;
}

// the ends of a tendon spring's dead band (models/tendon_deadband.xml, the coupling tendon,
// tendon_lengthspring index 1 and 2) under +-1 N m multi-sine motor torques. Truth: band
// [0.125, 0.38]; start: the model's [0.1, 0.3] (20 %, 21 % off). Noise: 1 mrad on each angle,
// 0.5 mm on the tendon length.
inline KindCase TendonDeadBandCase() {
  KindCase c;
  c.model = "tendon_deadband.xml";
  c.truth = {{"lower_end", Spec("tendon_lengthspring", "coupling", 1), 0.125},
             {"upper_end", Spec("tendon_lengthspring", "coupling", 2), 0.38}};
  c.start = {0.1, 0.3};
  c.lower = {-1.0, -1.0};
  c.upper = {1.0, 1.0};
  c.sigma = {{"q_shoulder", 0.001}, {"q_elbow", 0.001}, {"l_coupling", 0.0005}};
  return c;
}

// ---------------------------------------------------------------------------------------------
// DC motor (models/dcmotor.xml, models/dcmotor_lugre.xml)

// the DC motor's inductance and cogging amplitude and phase (models/dcmotor.xml) with its motor
// constant, under +-6 V multi-sine voltages. Truth: inductance 0.026 H, cogging amplitude
// 0.0026 N m, phase 0.26 rad, motorconst 0.045 N m/A; start: the model's 0.02, 0.002, 0.2, 0.05
// (23 %, 23 %, 23 %, 11 % off). Noise: 1 mrad, 10 mrad/s.
inline KindCase DcMotorInductanceCoggingCase() {
  KindCase c;
  c.model = "dcmotor.xml";
  c.truth = {{"inductance", Spec("dcmotor_inductance", "motor"), 0.026},
             {"cog_amp", Spec("dcmotor_cogging", "motor", 0), 0.0026},
             {"cog_phase", Spec("dcmotor_cogging", "motor", 2), 0.26},
             {"motorconst", Spec("dcmotor_motorconst", "motor"), 0.045}};
  c.start = {0.02, 0.002, 0.2, 0.05};
  c.lower = {1e-3, 1e-4, 0.01, 1e-3};
  c.upper = {0.5, 0.1, 3.0, 1.0};
  c.amplitude = 6;
  c.sigma = {{"angle", 0.001}, {"rate", 0.01}};
  return c;
}

// the DC motor's LuGre friction (models/dcmotor_lugre.xml): Coulomb friction and Stribeck
// velocity (dcmotor_lugre index 2 and 4) with the motor constant, under +-6 V multi-sine
// voltages. Truth: Coulomb 0.026 N m, Stribeck velocity 0.13 rad/s, motorconst 0.045 N m/A;
// start: the model's 0.02, 0.1, 0.05 (23 %, 23 %, 11 % off). Noise: 1 mrad, 10 mrad/s.
inline KindCase LugreCoulombStribeckCase() {
  KindCase c;
  c.model = "dcmotor_lugre.xml";
  c.truth = {{"coulomb", Spec("dcmotor_lugre", "motor", 2), 0.026},
             {"stribeck", Spec("dcmotor_lugre", "motor", 4), 0.13},
             {"motorconst", Spec("dcmotor_motorconst", "motor"), 0.045}};
  c.start = {0.02, 0.1, 0.05};
  c.lower = {1e-4, 1e-3, 1e-3};
  c.upper = {1.0, 10.0, 1.0};
  c.amplitude = 6;
  c.sigma = {{"angle", 0.001}, {"rate", 0.01}};
  return c;
}

// ---------------------------------------------------------------------------------------------
// contact softness on the pressed sphere (models/sphere_press*.xml: one contact at every step,
// under PressControls). Noise: 10 um on the height, 1 mm/s on the rate.

// the sphere's solref time constant and damping ratio (the contact uses the mean of the sphere's
// and the floor's 0.02, 1) from its height and rate. Truth: 0.03 s, 0.8; start: 30% above,
// 0.039 s, 1.04.
inline KindCase GeomSolrefCase() {
  KindCase c;
  c.model = "sphere_press.xml";
  c.truth = {{"timeconst", Spec("geom_solref", "sphere", 0), 0.03},
             {"dampratio", Spec("geom_solref", "sphere", 1), 0.8}};
  c.start = {0.039, 1.04};
  c.lower = {0.005, 0.1};
  c.upper = {0.2, 5.0};
  c.controls = PressControls;
  c.sigma = {{"height", 1e-5}, {"rate", 1e-3}};
  return c;
}

// the sphere's solimp dmax (index 1; the contact uses the mean of the sphere's and the floor's
// 0.95). Truth: 0.7; start: 0.9 (29 % off).
inline KindCase GeomSolimpDmaxCase() {
  KindCase c;
  c.model = "sphere_press.xml";
  c.truth = {{"dmax", Spec("geom_solimp", "sphere", 1), 0.7}};
  c.start = {0.9};
  c.lower = {0.1};
  c.upper = {0.999};
  c.controls = PressControls;
  c.sigma = {{"height", 1e-5}, {"rate", 1e-3}};
  return c;
}

// the sphere's solimp width (index 2; the contact uses the mean of the sphere's and the floor's
// 1 mm). Truth: 1.3 mm; start: 1 mm (23 % off).
inline KindCase GeomSolimpWidthCase() {
  KindCase c;
  c.model = "sphere_press.xml";
  c.truth = {{"width", Spec("geom_solimp", "sphere", 2), 0.0013}};
  c.start = {0.001};
  c.lower = {1e-4};
  c.upper = {0.01};
  c.controls = PressControls;
  c.sigma = {{"height", 1e-5}, {"rate", 1e-3}};
  return c;
}

// an explicit <pair>'s solref and solimp dmax (models/sphere_press_pair.xml; the pair's values
// are the contact's, unmixed). Truth: time constant 0.022 s, damping ratio 0.6, dmax 0.72; start:
// the model's 0.03, 0.8, 0.95 (36 %, 33 %, 32 % off).
inline KindCase PairSolrefDmaxCase() {
  KindCase c;
  c.model = "sphere_press_pair.xml";
  c.truth = {{"timeconst", Spec("pair_solref", "press", 0), 0.022},
             {"dampratio", Spec("pair_solref", "press", 1), 0.6},
             {"dmax", Spec("pair_solimp", "press", 1), 0.72}};
  c.start = {0.03, 0.8, 0.95};
  c.lower = {0.005, 0.1, 0.1};
  c.upper = {0.2, 5.0, 0.999};
  c.controls = PressControls;
  c.sigma = {{"height", 1e-5}, {"rate", 1e-3}};
  return c;
}

}  // namespace mjsysid::test
