#include "core/state.h"

#include <cmath>

#include "core/mujoco_env.h"

namespace mjsysid {

namespace {

int StateSize(const mjModel& m, unsigned int sig) {
  if (sig == 0) return 0;
  int size = 0;
  CallMujoco([&] { size = mj_stateSize(&m, static_cast<int>(sig)); });
  return size;
}

}  // namespace

StateDims::StateDims(const mjModel& m)
    : nq(static_cast<int>(m.nq)),
      nv(static_cast<int>(m.nv)),
      na(static_cast<int>(m.na)),
      nu(static_cast<int>(m.nu)),
      ns(static_cast<int>(m.nsensordata)),
      nphys(nq + nv + na),
      nx(2 * nv + na),
      nfull(StateSize(m, kFullStateSig)),
      step_extra_sig(m.nplugin > 0 ? kStepExtraSig | kInputSig : kStepExtraSig),
      input_sig(m.nplugin > 0 ? 0 : kInputSig),
      nstep(1 + nv + StateSize(m, step_extra_sig)),
      ninput(StateSize(m, input_sig)) {}

void GetFullState(const mjModel* m, const mjData* d, double* state) {
  CallMujoco([=] { mj_getState(m, d, state, kFullStateSig); });
}

void SetFullState(const mjModel* m, mjData* d, const double* state) {
  CallMujoco([=] { mj_setState(m, d, state, kFullStateSig); });
}

void GetStepExtras(const mjModel& m, const StateDims& dims, const mjData& d, double* extras) {
  CallMujoco([&] { mj_getState(&m, &d, extras, static_cast<int>(dims.step_extra_sig)); });
}

void SetStepExtras(const mjModel& m, const StateDims& dims, mjData* d, const double* extras) {
  CallMujoco([&] { mj_setState(&m, d, extras, static_cast<int>(dims.step_extra_sig)); });
}

void InverseRightJacobianSO3(const double* phi, double w, double* out) {
  const double theta2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2];
  const double theta = std::sqrt(theta2);
  // the coefficient of [phi]x^2: 1/theta^2 - (1 + cos theta) / (2 theta sin theta), its series
  // 1/12 + theta^2/720 near 0
  const double c = theta < 1e-4
                       ? 1.0 / 12 + theta2 / 720
                       : 1.0 / theta2 - (1 + std::cos(theta)) / (2 * theta * std::sin(theta));
  const double K[9] = {0, -phi[2], phi[1], phi[2], 0, -phi[0], -phi[1], phi[0], 0};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double k2 = 0;
      for (int t = 0; t < 3; ++t) k2 += K[i * 3 + t] * K[t * 3 + j];
      out[i * 3 + j] = w * ((i == j ? 1.0 : 0.0) + 0.5 * K[i * 3 + j] + c * k2);
    }
  }
}

void StepSkip(const mjModel* m, mjData* d, int skipstage, bool skipsensor) {
  // the calls of mj_step, with the forward pass skipping what is already computed; MuJoCo errors
  // come back through CallMujoco (no C++ object lives in between)
  CallMujoco([=] {
    mj_checkPos(m, d);
    mj_checkVel(m, d);
    mj_forwardSkip(m, d, skipstage, skipsensor ? 1 : 0);
    mj_checkAcc(m, d);
    switch (m->opt.integrator) {
      case mjINT_EULER:
        mj_Euler(m, d);
        break;
      case mjINT_RK4:
        mj_RungeKutta(m, d, 4);
        break;
      case mjINT_IMPLICIT:
      case mjINT_IMPLICITFAST:
        mj_implicit(m, d);
        break;
      default:
        mju_error("StepSkip: invalid integrator %d", m->opt.integrator);
    }
  });
}

}  // namespace mjsysid
