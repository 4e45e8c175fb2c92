"""PyTorch autograd through MuJoCo rollouts (`import mjsysid.torch`; needs `pip install
"mjsysid[torch]"`).

The forward pass is `RolloutModel.rollout`, or `RolloutModel.linearize` when an input needs a
gradient; the backward pass is that `Linearization`'s `vjp` (finite-difference step Jacobians
chained backwards in C++; docs/python.md, "Gradients through physics"). Everything is float64
on the CPU: tensors on another device are copied there and the results copied back.
"""

import numpy as np
import torch
from torch.autograd.function import once_differentiable

__all__ = ["RolloutFunction", "rollout", "RolloutModule"]

_WRT = ("x0", "ctrl", "params")


def _numpy(name, t):
    """The float64 numpy array of a tensor argument; TypeError for another dtype (a silent
    float32 -> float64 conversion would hide that the rollout is not float32)."""
    if t is None:
        return None
    if not torch.is_tensor(t):
        t = torch.as_tensor(t, dtype=torch.float64)
    if t.dtype != torch.float64:
        raise TypeError(f"mjsysid.torch.rollout: {name} must be float64, got {t.dtype} "
                        f"(convert it with {name}.double())")
    return np.ascontiguousarray(t.detach().cpu().numpy())


class RolloutFunction(torch.autograd.Function):
    """`(states, sensors) = RolloutFunction.apply(rm, x0, ctrl, params)`: an autograd node.

    Shapes as `RolloutModel.rollout`: x0 (nstate,) or (B, nstate) in qpos, qvel, act
    coordinates; ctrl (T, nu) or (B, T, nu); params (np,) in the units of the parameters' kinds,
    or None for the model's values (then without a gradient). Returns states (B?, T+1, nstate)
    and sensors (B?, T, nsensordata), float64 on x0's device. Not twice differentiable.
    """

    @staticmethod
    def forward(ctx, rm, x0, ctrl, params):
        args = [_numpy(n, t) for n, t in zip(_WRT, (x0, ctrl, params))]
        # only the inputs that need a gradient get their derivative blocks (the cost of ctrl:
        # nu more steps per time step, of params: one per parameter)
        wrt = tuple(n for n, need, a in zip(_WRT, ctx.needs_input_grad[1:], args)
                    if need and a is not None)
        ctx.lin = rm.linearize(*args, wrt=wrt) if wrt else None
        ctx.devices = [t.device if torch.is_tensor(t) else None for t in (x0, ctrl, params)]
        # a cotangent that no loss term reaches arrives as None, and vjp takes None as zeros
        ctx.set_materialize_grads(False)
        if ctx.lin is None:
            return _tensors(rm.rollout(*args), ctx.devices[0])
        return _tensors((ctx.lin.states, ctx.lin.sensors), ctx.devices[0])

    @staticmethod
    @once_differentiable
    def backward(ctx, states_grad, sensors_grad):
        if ctx.lin is None:
            return None, None, None, None
        grads = ctx.lin.vjp(_numpy("states_grad", states_grad),
                            _numpy("sensors_grad", sensors_grad))
        # entries not in wrt are None; params_grad is summed over the batch
        return (None,) + tuple(
            None if g is None or not need else torch.tensor(np.asarray(g), device=dev)
            for g, need, dev in zip(grads, ctx.needs_input_grad[1:], ctx.devices))


def _tensors(arrays, device):
    # copies: the arrays may be read-only views of the Linearization's data
    return tuple(torch.tensor(np.asarray(a), device=device) for a in arrays)


def rollout(rm, x0, ctrl, params=None):
    """Differentiable `rm.rollout(x0, ctrl, params)` (shapes: `RolloutFunction`).

    Outside grad mode (`torch.no_grad()`), or when no input requires a gradient, this is a plain
    `rm.rollout` (no derivative blocks computed). `RolloutFunction.apply` itself cannot tell
    (autograd reports the inputs' requires_grad to it even under no_grad): call this instead.
    """
    inputs = (x0, ctrl, params)
    if torch.is_grad_enabled() and any(torch.is_tensor(t) and t.requires_grad for t in inputs):
        return RolloutFunction.apply(rm, x0, ctrl, params)
    args = [_numpy(n, t) for n, t in zip(_WRT, inputs)]
    return _tensors(rm.rollout(*args), x0.device if torch.is_tensor(x0) else None)


class RolloutModule(torch.nn.Module):
    """A RolloutModel whose parameters are a trainable `nn.Parameter`.

    `params` (np,) float64 starts at `rm.parameter_values()` (the model's values, in the units of
    the kinds: kg, N m s/rad, ...); `forward(x0, ctrl)` -> (states, sensors) as `rollout`.
    """

    def __init__(self, rm):
        super().__init__()
        self.rm = rm
        self.params = torch.nn.Parameter(
            torch.as_tensor(np.array(rm.parameter_values(), dtype=np.float64)))

    def forward(self, x0, ctrl):
        return rollout(self.rm, x0, ctrl, self.params)

    def extra_repr(self):
        return f"parameters={list(self.rm.parameter_names)}"
