"""mjsysid.torch: autograd through RolloutModel rollouts, checked by torch.autograd.gradcheck and
against whole-rollout central differences of mujoco.mj_step alone (rollout_oracle.py)."""

import mujoco
import numpy as np
import pytest

import mjsysid
from rollout_oracle import (ACTIVATION, ARM7_PARAMETERS, FREE_BODY, PENDULUM, central_gradient,
                            loss, loss_weights, quaternion)

torch = pytest.importorskip("torch")

import mjsysid.torch as mjt  # noqa: E402

PENDULUM_DAMPING = [{"name": "damping", "target": "joint_damping", "object": "hinge"}]


def case(name, root, central=False):
    """(MjModel, RolloutModel, parameters, x0, ctrl, params) of one test case; T of 10-20 steps
    keeps each gradcheck under a second."""
    rng = np.random.default_rng(1)
    if name == "pendulum":
        model, parameters = mujoco.MjModel.from_xml_string(PENDULUM), PENDULUM_DAMPING
        x0, ctrl = np.array([0.4, -0.3]), rng.uniform(-1, 1, (15, 1))
    elif name == "arm7":
        model = mujoco.MjModel.from_xml_path(str(root / "models/arm7.xml"))
        parameters = ARM7_PARAMETERS
        # j1 turns at 1 rad/s: its friction loss stays saturated (a smooth regime)
        x0 = np.concatenate([rng.uniform(-0.3, 0.3, 7), [1.0], rng.uniform(-1, 1, 6)])
        ctrl = rng.uniform(-0.5, 0.5, (10, 7))
    elif name == "free_body":
        model, parameters = mujoco.MjModel.from_xml_string(FREE_BODY), []
        x0 = np.concatenate([[0.1, -0.2, 1.0], quaternion(2.0, [1, -2, 0.5]),
                             [0.3, 0.1, -0.2], [1.5, -2.0, 3.0]])
        ctrl = rng.uniform(-1, 1, (20, 1))
    else:  # activation
        model, parameters = mujoco.MjModel.from_xml_string(ACTIVATION), []
        x0 = np.array([0.3, -0.5, 0.2, 0.4, 0.8, -0.6])  # qpos, qvel, act (filter, integrator)
        ctrl = rng.uniform(-1, 1, (20, 2))
    rm = mjsysid.RolloutModel(model, parameters=parameters, central=central)
    return model, rm, parameters, x0, ctrl, rm.parameter_values()


def tensors(*arrays, grad=True):
    return [torch.tensor(a, dtype=torch.float64, requires_grad=grad) for a in arrays]


CASES = ["pendulum", "arm7", "free_body", "activation"]


@pytest.mark.parametrize("name", CASES)
def test_gradcheck(name, root):
    # gradcheck compares our vjp's Jacobian, row by row, with central differences (eps 1e-6) of
    # the forward rollout. Our Jacobian is itself a chain of per-step forward differences
    # (state_step 1e-6): its truncation error is ~1e-6 x the step map's curvature, accumulated
    # over T steps; the numerical one's rounding error ~1e-16 |output| / 1e-6 = 1e-10. Measured:
    # at most 4e-6 absolute (arm7's armature columns, entries up to 7), and at most 2.5 % of the
    # tolerance atol 1e-5 + rtol 1e-4 |entry| anywhere (free body, activation model). A sign
    # error, a missing quaternion map or a block one step off are errors of the size of the
    # entries themselves (0.01..10).
    model, rm, parameters, x0, ctrl, params = case(name, root)
    x0_t, ctrl_t, params_t = tensors(x0, ctrl, params)
    if name == "arm7":
        x0_t.requires_grad_(False)  # w.r.t. armature, damping and ctrl
    inputs = (x0_t, ctrl_t, params_t if rm.np else None)
    assert torch.autograd.gradcheck(lambda *a: mjt.rollout(rm, *a), inputs, eps=1e-6,
                                    atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize("central", [False, True], ids=["forward", "central"])
@pytest.mark.parametrize("name", CASES)
def test_backward_equals_mujoco_central_differences(name, central, root):
    # the independent oracle: d loss / d inputs of the mj_step rollout by central differences
    # (good to ~1e-9, rollout_oracle.central_gradient) against backward(). Tolerance, per input
    # (x0, ctrl, params), relative to the largest entry of its gradient: per-step forward
    # differences (test_gradcheck) 1e-5, rtol 1e-4 (measured at most 8e-7 of the largest entry);
    # central ones (truncation ~1e-12, rounding ~1e-16 / 1e-6; a parameter's step is 1e-6 of
    # its value: rounding ~1e-8 of the gradient) 1e-6, rtol 1e-5 (measured at most 6e-8)
    model, rm, parameters, x0, ctrl, params = case(name, root, central)
    tol = 1e-5 if central else 1e-4
    if name == "free_body":
        x0[3:7] *= 1.3  # a quaternion off the unit sphere: the gradient of the normalised rollout
    ws, wy = loss_weights(model, len(ctrl))
    x0_t, ctrl_t, params_t = tensors(x0, ctrl, params)
    states, sensors = mjt.rollout(rm, x0_t, ctrl_t, params_t if rm.np else None)
    loss(states, sensors, torch.tensor(ws), torch.tensor(wy)).backward()
    expected = central_gradient(model, parameters, x0, ctrl, params, ws, wy)
    got = [x0_t.grad, ctrl_t.grad, params_t.grad if rm.np else torch.zeros(0)]
    for what, g, e in zip(("x0", "ctrl", "params"), got, expected):
        assert g is not None and g.shape == e.shape, what
        scale = np.abs(e).max() if e.size else 0.0
        np.testing.assert_allclose(g.numpy(), e, rtol=tol, atol=0.1 * tol * scale, err_msg=what)
    if name == "free_body":
        # the normalisation's Jacobian: no component along the quaternion itself
        q, gq = x0[3:7], x0_t.grad[3:7].numpy()
        assert abs(q @ gq) < 1e-6 * np.linalg.norm(q) * np.linalg.norm(gq)


def test_batched_gradients_are_the_per_sequence_ones(root):
    # (B, nstate) and (B, T, nu): each row's gradient is the unbatched one; params' is summed;
    # an unbatched x0 under batched ctrl is broadcast and its gradient summed over the batch
    model, rm, parameters, x0, ctrl, params = case("pendulum", root)
    ws, wy = loss_weights(model, len(ctrl))
    xs = np.stack([x0, x0 + [0.2, 0.1], x0 - [0.1, 0.5]])
    cs = np.stack([ctrl, -ctrl, 0.5 * ctrl])

    def grads(x, c):
        x_t, c_t, p_t = tensors(x, c, params)
        states, sensors = mjt.rollout(rm, x_t, c_t, p_t)
        batch = (len(c),) if c.ndim == 3 else ()
        assert states.shape == batch + (len(ctrl) + 1, 2)
        assert sensors.shape == batch + (len(ctrl), 2)
        loss(states, sensors, torch.tensor(ws), torch.tensor(wy)).backward()
        return x_t.grad.numpy(), c_t.grad.numpy(), p_t.grad.numpy()

    single = [grads(x, c) for x, c in zip(xs, cs)]
    gx, gc, gp = grads(xs, cs)
    for b, (sx, sc, sp) in enumerate(single):
        np.testing.assert_allclose(gx[b], sx, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(gc[b], sc, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(gp, sum(s[2] for s in single), rtol=1e-12)
    gx, gc, gp = grads(x0, cs)
    assert gx.shape == x0.shape
    single = [grads(x0, c) for c in cs]
    np.testing.assert_allclose(gx, sum(s[0] for s in single), rtol=1e-12, atol=1e-14)


def test_no_grad_and_dtypes(root):
    model, rm, parameters, x0, ctrl, params = case("pendulum", root)
    x0_t, ctrl_t, params_t = tensors(x0, ctrl, params)
    with torch.no_grad():
        states, sensors = mjt.rollout(rm, x0_t, ctrl_t, params_t)
    assert not states.requires_grad and states.dtype == torch.float64
    expected = rm.rollout(x0, ctrl, params)
    np.testing.assert_array_equal(states.numpy(), expected[0])
    np.testing.assert_array_equal(sensors.numpy(), expected[1])
    # float32 is refused, naming the argument, not converted
    with pytest.raises(TypeError, match="ctrl"):
        mjt.rollout(rm, x0_t, ctrl_t.float(), params_t)
    # a gradient of the sensors alone (no cotangent reaches the states)
    _, sensors = mjt.rollout(rm, x0_t, ctrl_t, params_t)
    sensors[:, 0].sum().backward()
    assert x0_t.grad.shape == (2,) and ctrl_t.grad.shape == ctrl.shape


def test_module_fits_pendulum_damping():
    # truth: PENDULUM's damping 0.1 N m s/rad; start 0.13 (30 % off); LBFGS on the noise-free
    # angle of a 1 s rollout. At the truth the residuals vanish, and with them the gradient
    # whatever its finite-difference error: the estimate is exact up to the optimiser's stop
    # (measured: 1e-13 relative, the loss 42 -> 5e-24 in 10 evaluations); asked: 1e-8 relative
    # and the loss cut by 1e12
    rm = mjsysid.RolloutModel(PENDULUM, parameters=PENDULUM_DAMPING)
    truth = rm.parameter_values()[0]
    assert truth == pytest.approx(0.1)
    module = mjt.RolloutModule(rm)
    x0 = torch.tensor([0.5, 0.0], dtype=torch.float64)
    ctrl = torch.tensor(np.sin(np.linspace(0, 6, 100))[:, None])
    with torch.no_grad():
        measured = module(x0, ctrl)[1][:, 0]
        module.params.fill_(1.3 * truth)
    optimizer = torch.optim.LBFGS(module.parameters(), max_iter=30, tolerance_grad=1e-12,
                                  tolerance_change=1e-16, line_search_fn="strong_wolfe")

    def closure():
        optimizer.zero_grad()
        residual = (module(x0, ctrl)[1][:, 0] - measured) / 1e-3  # sigma 1 mrad
        value = (residual**2).mean()
        value.backward()
        return value

    initial = closure().item()
    optimizer.step(closure)
    final = closure().item()
    assert final < 1e-12 * initial, (initial, final)
    assert abs(module.params.item() / truth - 1) < 1e-8, module.params.item()
