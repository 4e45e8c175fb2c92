"""mjsysid.RolloutModel and Linearization (python/src/rollout_api.cc): rollouts equal MuJoCo's own
steps bit for bit with the model's options untouched; vector-Jacobian and Jacobian-vector products
and full Jacobians agree with central differences of whole rollouts done with the `mujoco`
package (hinges with parameters, a free body's quaternion in x0, activation states); batches and
broadcasting; bad input is a ValueError naming the argument."""

import mujoco
import numpy as np
import pytest

import mjsysid
from conftest import ROOT
from rollout_oracle import (ACTIVATION, ARM7_PARAMETERS, FREE_BODY, central_gradient,
                            mj_rollout)

PENDULUM = str(ROOT / "models/pendulum.xml")
ARM7 = str(ROOT / "models/arm7.xml")



def controls(T, nu, seed, amplitude=1.0):
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, nu)
    k = np.arange(T)[:, None]
    return amplitude * np.sin(0.09 * k + phase)


def test_rollout_is_mujocos_own_steps_with_the_models_options():
    # a solver tolerance and a disable flag of the user's: kept (bit for bit with mj_step)
    spec = mujoco.MjSpec.from_file(ARM7)
    spec.option.tolerance = 1e-5
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_GRAVITY
    m = spec.compile()
    rm = mjsysid.RolloutModel(m)
    x0 = np.zeros(rm.nstate)
    x0[:7] = 0.1
    u = controls(50, rm.nu, 1, 3.0)
    states, sensors = rm.rollout(x0, u)
    ref_states, ref_sensors = mj_rollout(m, x0, u)
    np.testing.assert_array_equal(states, ref_states)
    np.testing.assert_array_equal(sensors, ref_sensors)
    assert m.opt.tolerance == 1e-5  # the caller's model is not changed


def test_batches_broadcast_and_thread_counts_agree():
    rm1 = mjsysid.RolloutModel(ARM7, ARM7_PARAMETERS, threads=1)
    rm2 = mjsysid.RolloutModel(ARM7, ARM7_PARAMETERS, threads=2)
    x0 = np.zeros((3, rm1.nstate))
    x0[:, 0] = [0.0, 0.2, -0.3]
    u = np.stack([controls(20, rm1.nu, s, 2.0) for s in range(3)])
    s1, y1 = rm1.rollout(x0, u)
    s2, y2 = rm2.rollout(x0, u)
    assert s1.shape == (3, 21, rm1.nstate) and y1.shape == (3, 20, rm1.nsensordata)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_array_equal(y1, y2)
    # one x0 for every control sequence: the same as repeating it; its gradient is the sum
    lin = rm2.linearize(x0[1], u)
    assert lin.states.shape == (3, 21, rm1.nstate)
    gs = np.ones_like(lin.states)
    gx0, gu, gp = lin.vjp(gs)
    lin3 = rm2.linearize(np.repeat(x0[1:2], 3, axis=0), u)
    gx0_3, gu_3, gp_3 = lin3.vjp(gs)
    np.testing.assert_allclose(gx0, gx0_3.sum(axis=0), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(gu, gu_3, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(gp, gp_3, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("case", ["arm7", "free_body", "activation"])
def test_vjp_matches_whole_rollout_differences(case):
    # truth: central differences of a linear loss over whole mj_step rollouts (rollout_oracle.py,
    # good to ~1e-9); the numpy-level vjp from central-difference blocks (state step 1e-6) agrees
    # to 1e-6 of the largest entry (measured: 4e-8 at most, arm7's params; a wrong map or block
    # is off by O(1))
    rng = np.random.default_rng(5)
    parameters, T = [], 15
    if case == "arm7":
        model, parameters, T = mujoco.MjModel.from_xml_path(ARM7), ARM7_PARAMETERS, 12
        x0 = np.concatenate([rng.normal(0, 0.3, 7), [1.0], rng.uniform(-1, 1, 6)])
    elif case == "free_body":
        model = mujoco.MjModel.from_xml_string(FREE_BODY)
        x0 = np.concatenate([[0.1, -0.2, 1.0], np.array([0.9, 0.3, -0.2, 0.25]) * 1.2,
                             rng.normal(0, 1, 6)])  # a quaternion of norm 1.2: normalised
    else:
        model = mujoco.MjModel.from_xml_string(ACTIVATION)
        x0 = np.array([0.3, -0.5, 0.2, 0.4, 0.8, -0.6])
    rm = mjsysid.RolloutModel(model, parameters, central=True)
    u = controls(T, rm.nu, 2, 1.0)
    p = rm.parameter_values()
    lin = rm.linearize(x0, u, p)
    # the oracle's loss, sum(ws * states) + sum(wy * sensors^2) / 2: cotangents ws and wy y
    ws, wy = rng.normal(size=lin.states.shape), rng.normal(size=lin.sensors.shape)
    gx0, gu, gp = lin.vjp(ws, wy * lin.sensors)
    ref = central_gradient(model, parameters, x0, u, p, ws, wy)
    for got, want, name in zip((gx0, gu, gp), ref, ("x0", "ctrl", "params")):
        assert got.shape == want.shape, name
        if want.size == 0:
            continue
        scale = np.abs(want).max()
        assert np.abs(got - want).max() < 1e-6 * scale, (name, got, want)
    if case == "free_body":
        # the quaternion's radial direction moves nothing: the rollout normalises it
        q = x0[3:7]
        assert abs(gx0[3:7] @ q) < 1e-9 * np.abs(gx0).max()


def test_jvp_is_the_transpose_of_vjp_and_jacobians_agree():
    rm = mjsysid.RolloutModel(FREE_BODY)
    x0 = np.zeros(rm.nstate)
    x0[2] = 1
    x0[3:7] = [0.8, 0.1, 0.5, -0.3]
    x0[7:] = [0.1, 0.0, -0.2, 1.0, 0.5, -0.4]
    u = controls(25, rm.nu, 3)
    lin = rm.linearize(x0, u)
    rng = np.random.default_rng(1)
    dx0, du = rng.normal(size=x0.shape), rng.normal(size=u.shape)
    ws, wy = rng.normal(size=lin.states.shape), rng.normal(size=lin.sensors.shape)
    ds, dy = lin.jvp(dx0, du)
    gx0, gu, gp = lin.vjp(ws, wy)
    lhs = np.sum(ws * ds) + np.sum(wy * dy)
    rhs = gx0 @ dx0 + np.sum(gu * du)
    assert abs(lhs - rhs) < 1e-10 * abs(lhs)
    assert gp.shape == (0,)
    # full Jacobians (tangent rows): the sensors' ctrl block times du is the jvp's sensors
    # without the x0 direction
    jac = lin.jacobians()
    assert jac["states_ctrl"].shape == (26, rm.ntangent, 25, rm.nu)
    assert jac["sensors_x0"].shape == (25, rm.nsensordata, rm.ntangent)
    _, dy_u = lin.jvp(None, du)
    np.testing.assert_allclose(np.einsum("kitj,tj->ki", jac["sensors_ctrl"], du), dy_u,
                               rtol=1e-10, atol=1e-12)
    # the blocks: A is (T, nx, nx), sensors' C (T, ns, nx)
    assert lin.A.shape == (25, rm.ntangent, rm.ntangent)
    assert lin.D.shape == (25, rm.nsensordata, rm.nu)


def test_only_what_wrt_names_is_differentiated():
    rm = mjsysid.RolloutModel(ARM7, ARM7_PARAMETERS)
    x0 = np.zeros(rm.nstate)
    u = controls(10, rm.nu, 4)
    lin = rm.linearize(x0, u, wrt=["params"])
    gx0, gu, gp = lin.vjp(sensors_grad=np.ones_like(lin.sensors))
    assert gx0 is None and gu is None and gp.shape == (4,)
    assert lin.B.shape == (10, rm.ntangent, 0)
    with pytest.raises(ValueError, match="ctrl: linearize\\(\\) was called without 'ctrl'"):
        lin.jvp(ctrl_dot=u)
    # params moves the rollout, and the model's values are restored for params=None
    s_default, _ = rm.rollout(x0, u)
    s_moved, _ = rm.rollout(x0, u, params=[0.5, 0.5, 2.0, 2.0])
    assert np.abs(s_moved - s_default).max() > 1e-6
    np.testing.assert_array_equal(rm.rollout(x0, u)[0], s_default)


def test_bad_input_names_the_argument():
    rm = mjsysid.RolloutModel(PENDULUM)
    x0 = np.zeros(rm.nstate)
    u = np.zeros((5, rm.nu))
    with pytest.raises(ValueError, match=r"x0: expected shape \(2,\) or \(B, 2\).*got \(3,\)"):
        rm.rollout(np.zeros(3), u)
    with pytest.raises(ValueError, match=r"ctrl: expected shape \(T, 1\)"):
        rm.rollout(x0, np.zeros(5))
    with pytest.raises(ValueError, match="ctrl: no steps"):
        rm.rollout(x0, np.zeros((0, 1)))
    with pytest.raises(ValueError, match="batch sizes differ"):
        rm.rollout(np.zeros((2, 2)), np.zeros((3, 5, 1)))
    with pytest.raises(ValueError, match="x0: not finite"):
        rm.rollout(np.array([np.nan, 0]), u)
    with pytest.raises(ValueError, match=r"params: expected shape \(0,\)"):
        rm.rollout(x0, u, params=[1.0])
    with pytest.raises(ValueError, match="wrt: unknown 'qpos'"):
        rm.linearize(x0, u, wrt=["qpos"])
    with pytest.raises(ValueError, match="x0: not an array of numbers"):
        rm.rollout("abc", u)
    with pytest.raises(ValueError, match=r"parameters\[0\]: unknown key 'lower'"):
        mjsysid.RolloutModel(PENDULUM, [{"target": "joint_damping", "object": "hinge",
                                         "lower": 0}])
    with pytest.raises(ValueError, match="unknown parameter kind"):
        mjsysid.RolloutModel(PENDULUM, [{"target": "dof_damping", "object": "hinge"}])
    with pytest.raises(ValueError, match="threads"):
        mjsysid.RolloutModel(PENDULUM, threads=-3)
    lin = rm.linearize(x0, u)
    with pytest.raises(ValueError, match=r"states_grad: expected shape \(6, 2\)"):
        lin.vjp(np.zeros((5, 2)))


def test_memory_bound_of_full_control_jacobians():
    # 8000 steps of arm7: the control Jacobian alone would be (T+1) (nx+ns) T nu doubles, about
    # 8001 * 28 * 8000 * 7 * 8 = 100 GB: refused before anything is allocated
    rm = mjsysid.RolloutModel(ARM7)
    lin = rm.linearize(np.zeros(rm.nstate), controls(8000, rm.nu, 5), wrt=["ctrl"])
    with pytest.raises(ValueError, match="of the available memory"):
        lin.jacobians()


def test_models_without_one_step_derivatives_are_refused_by_linearize_only():
    # RK4: mjd_transitionFD supports it not; the rollout runs, linearize names the reason
    spec = mujoco.MjSpec.from_file(PENDULUM)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    rm = mjsysid.RolloutModel(spec)
    x0, u = np.array([0.2, 0.0]), np.zeros((5, 1))
    assert rm.rollout(x0, u)[0].shape == (6, 2)
    with pytest.raises(ValueError, match="linearize: .*no RK4 integrator"):
        rm.linearize(x0, u)


def test_kink_check_differences_both_sides_near_contacts():
    # the humanoid falls onto the floor: with kink_check the steps near contacts also difference
    # the backward side (kinks counted where the sides disagree); both gradients stay close
    model = str(ROOT / "models/outside/humanoid27.xml")
    plain = mjsysid.RolloutModel(model)
    checked = mjsysid.RolloutModel(model, kink_check=True)
    x0 = np.concatenate([mujoco.MjModel.from_xml_path(model).qpos0, np.zeros(plain.nv)])
    u = controls(40, plain.nu, 6, 0.3)
    lin_plain, lin_checked = plain.linearize(x0, u), checked.linearize(x0, u)
    assert lin_plain.kinks == [0]
    assert lin_checked.kinks[0] > 0
    np.testing.assert_array_equal(lin_plain.states, lin_checked.states)
