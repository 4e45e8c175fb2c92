"""The options of mjsysid.fit that mirror the experiment file's keys (docs/experiment-schema.md):
multiple shooting's continuity_scale and jumping_sensors, the Jacobian (jacobian, differences,
relative_step), reduce_model, the controls' ctrl_time / ctrl_hold / ctrl_delay, the measurement
terms, logged states as residuals, a fitted control delay, several models; each set and seen in
a real fit. And the options docs/python.md lists are the ones the module accepts.

Data: the pendulum experiment's simulated log (truth damping 0.08, frictionloss 0.03, bob_mass
1.2; noise 0.001 rad, 0.01 rad/s; start 0.2, 0.01, 0.8), and a ball on a vertical slide
dropped onto the floor and pushed by a sine (12 N, 1.1 Hz; it lands and lifts off: the contact
count changes 4 times in 1000 steps), noise-free, truth slide damping 0.5 from 0.3.
"""

import pickle
import re

import numpy as np
import pytest

import mjsysid
from test_fit_api import PARAMETERS, SIGMAS, TRUTH, frames, sequences_of  # noqa: F401 (a fixture)


def expect_truth(result, truth):
    """converged, the estimates named as `truth` (in order), each within 4 standard errors"""
    assert result.status == "converged", result.status
    assert [p.name for p in result.parameters] == list(truth)
    for p in result.parameters:
        assert abs(p.value - truth[p.name]) < 4 * p.std_error, p


BALL_XML = """<mujoco model="ball">
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="ball" pos="0 0 0.3">
      <joint name="z" type="slide" axis="0 0 1" damping="0.5"/>
      <geom name="ball" type="sphere" size="0.05" mass="1"/>
      <site name="foot" pos="0 0 -0.04" size="0.03"/>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="z"/></actuator>
  <sensor>
    <jointpos name="height" joint="z"/>
    <jointvel name="speed" joint="z"/>
    <touch name="touch" site="foot"/>
  </sensor>
</mujoco>
"""

BALL_EXPERIMENT = """name: ball
model: {model}
parameters:
  - {{name: damping, target: joint_damping, object: z, initial: 0.3, bounds: [0.01, 5.0]}}
simulate:
  truth: {{damping: 0.5}}
  sequences: 1
  steps: 1000
  seed: 3
  excitation: {{type: sines, amplitude: 12.0, frequencies: [1.1]}}
"""


@pytest.fixture
def ball(tmp_path):
    """(model path, [sequence dict]) of the ball's simulated log"""
    model = tmp_path / "ball.xml"
    model.write_text(BALL_XML)
    exp = tmp_path / "ball.yaml"
    exp.write_text(BALL_EXPERIMENT.format(model=model))
    log = mjsysid.simulate(str(exp), write=False)
    s = log.sequences[0]
    assert s.sensor_names == ["height", "speed", "touch"]
    return str(model), [{"time": s.time, "ctrl": s.ctrl, "measured": s.sensordata,
                         "qpos": s.qpos[0], "qvel": s.qvel[0]}]


BALL_PARAMETERS = [{"name": "damping", "kind": "joint_damping", "object": "z", "initial": 0.3,
                    "lower": 0.01, "upper": 5.0}]


def test_jumping_sensors_omit_or_fit(ball):
    # auto's contact segments (started on the jointpos + jointvel sensors) leave the touch sensor
    # out by default and with "omit"; "fit" keeps it. Both recover the damping of the
    # noise-free log to 1e-4 relative.
    model, seqs = ball
    fits = {}
    for choice in (None, "omit", "fit"):
        options = {"max_iterations": 30}
        if choice:
            options["jumping_sensors"] = choice
        fits[choice] = r = mjsysid.fit(model, BALL_PARAMETERS, seqs, options=options)
        assert "contact count" in r.segment_reason and r.segment_steps_used == 10, r.segment_reason
        assert r.estimates["damping"] == pytest.approx(0.5, rel=1e-4), (choice, r.estimates)
    for choice in (None, "omit"):
        assert fits[choice].sequences[0].sensor_names == ["height", "speed"]
        assert any("sensor 'touch' (touch) left out" in w for w in fits[choice].warnings)
    assert fits[None].estimates == fits["omit"].estimates
    assert fits["fit"].sequences[0].sensor_names == ["height", "speed", "touch"]
    assert not any("left out" in w for w in fits["fit"].warnings)
    with pytest.raises(ValueError, match="jumping_sensors 'drop': expected omit, fit"):
        mjsysid.fit(model, BALL_PARAMETERS, seqs, options={"jumping_sensors": "drop"})


def test_continuity_scale_relative_or_absolute(root, frames):  # noqa: F811
    # segments of 500 steps (4 per sequence) with continuity_weight 1: relative to the sensors
    # (the default; measured: 236 .. 1010 per state coordinate) and absolute (1) are different
    # weights, so different costs at the same start (the segments start on the noisy sensors:
    # gaps from the first evaluation; measured 3.781e6 and 3.770e6); both recover the truth
    # within 4 standard errors
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    fits = {}
    for choice in (None, "relative", "absolute"):
        options = {"sensor_sigmas": SIGMAS, "segment_steps": 500, "continuity_weight": 1.0}
        if choice:
            options["continuity_scale"] = choice
        fits[choice] = r = mjsysid.fit(model, PARAMETERS, seqs, options=options)
        expect_truth(r, TRUTH)
        assert r.segment_steps_used == 500, choice
    assert fits[None].initial_cost == fits["relative"].initial_cost
    assert fits[None].estimates == fits["relative"].estimates
    assert "continuity weights 1 x S / state spread" in fits["relative"].segment_reason
    assert "continuity weight 1 (absolute)" in fits["absolute"].segment_reason
    rel, ab = fits["relative"].initial_cost, fits["absolute"].initial_cost
    assert abs(rel - ab) > 1e-3 * max(rel, ab), (rel, ab)
    with pytest.raises(ValueError, match="continuity_scale 'sensors': expected relative, abs"):
        mjsysid.fit(model, PARAMETERS, seqs, options={"continuity_scale": "sensors"})


def test_jacobian_options(root, frames):  # noqa: F811
    # the mode is the one asked for; central differences step twice per column (more simulation
    # steps than forward); another relative_step moves the estimate by rounding only (1e-6
    # relative) but not by nothing; reduce_model false is recorded as off
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    base = {"sensor_sigmas": SIGMAS, "max_iterations": 30, "threads": 1}
    fits = {name: mjsysid.fit(model, PARAMETERS, seqs, options=dict(base, **extra))
            for name, extra in {
                "forward": {"jacobian": "matrix"},
                "central": {"jacobian": "matrix", "differences": "central"},
                "step": {"jacobian": "matrix", "relative_step": 1e-5},
                "directional": {"jacobian": "directional"},
                "full": {"reduce_model": False}}.items()}
    assert fits["forward"].diagnostics.jacobian_mode == "matrix"
    assert fits["directional"].diagnostics.jacobian_mode == "directional"
    assert (fits["central"].diagnostics.simulation_steps
            > fits["forward"].diagnostics.simulation_steps)
    for name in ("central", "step"):
        assert fits[name].estimates != fits["forward"].estimates, name
        for key, value in fits["forward"].estimates.items():
            assert fits[name].estimates[key] == pytest.approx(value, rel=1e-6), (name, key)
    assert fits["forward"].diagnostics.reduction["used"]
    assert not fits["full"].diagnostics.reduction["used"]
    assert fits["full"].diagnostics.reduction["text"].startswith("off")
    with pytest.raises(ValueError, match="jacobian 'fd': expected auto, directional, matrix"):
        mjsysid.fit(model, PARAMETERS, seqs, options={"jacobian": "fd"})
    with pytest.raises(ValueError, match="relative_step must be > 0"):
        mjsysid.fit(model, PARAMETERS, seqs, options={"relative_step": 0.0})


def test_controls_hold_delay_and_own_clock(root, frames):  # noqa: F811
    # the controls at their own times: every 2nd sample held (zoh) gives another fit than every
    # sample; linear hold another again; a known transport delay another; the ones given as
    # explicit defaults (zoh, delay 0, ctrl_time = time) the same bits as none
    model = str(root / "models/pendulum.xml")
    seq = sequences_of(frames)[0]
    time = np.asarray(seq["time"])
    options = {"sensor_sigmas": SIGMAS, "max_iterations": 30, "threads": 1}
    plain = mjsysid.fit(model, PARAMETERS, [seq], options=options)
    same = mjsysid.fit(model, PARAMETERS, [dict(seq, ctrl_time=time, ctrl_hold="zoh",
                                                ctrl_delay=0.0)], options=options)
    assert same.estimates == plain.estimates
    variants = {
        "coarse": dict(seq, ctrl_time=time[::2], ctrl=seq["ctrl"][::2]),
        "linear": dict(seq, ctrl_time=time[::2], ctrl=seq["ctrl"][::2], ctrl_hold=["linear"]),
        "delay": dict(seq, ctrl_delay=[0.01]),
    }
    costs = {"plain": plain.initial_cost}
    for name, s in variants.items():
        costs[name] = mjsysid.fit(model, PARAMETERS, [s], options=options).initial_cost
    assert len(set(costs.values())) == len(costs), costs
    with pytest.raises(ValueError, match="ctrl_hold 'cubic': expected zoh or linear"):
        mjsysid.fit(model, PARAMETERS, [dict(seq, ctrl_hold="cubic")])
    with pytest.raises(ValueError, match="one entry per actuator"):
        mjsysid.fit(model, PARAMETERS, [dict(seq, ctrl_delay=[0.0, 0.0])])


def test_measurement_bias_is_fitted(root, frames):  # noqa: F811
    # the angle logged 0.05 rad too high (both sequences): without a measurement term the fit
    # cannot explain it (model_mismatch; measured chi2 ratio 1231); with a fitted bias (start 0,
    # bounds +-1) it converges with the bias and the physical parameters within 4 standard errors
    # of the truth (measured: bias 0.049977 +- 1.3e-5)
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)
    for s in seqs:
        s["measured"] = s["measured"] + np.array([0.05, 0.0])
    options = {"sensor_sigmas": SIGMAS}
    assert mjsysid.fit(model, PARAMETERS, seqs, options=options).status == "model_mismatch"
    bias = {"sensor": "angle", "bias": {"initial": 0.0, "fit": True, "lower": -1.0, "upper": 1.0}}
    r = mjsysid.fit(model, PARAMETERS, seqs, options=options, measurements=[bias])
    expect_truth(r, dict(TRUTH, **{"angle.bias": 0.05}))
    with pytest.raises(ValueError, match="measurements\\[0\\].bias: unknown key 'start'"):
        mjsysid.fit(model, PARAMETERS, seqs, measurements=[{"sensor": "angle",
                                                            "bias": {"start": 0.0}}])
    with pytest.raises(ValueError, match="measurements\\[0\\]: 'sensor' is required"):
        mjsysid.fit(model, PARAMETERS, seqs, measurements=[{"bias": {"fit": True}}])


def test_logged_states_fitted_without_sensors(root, pendulum):
    # the simulated log's qpos and qvel (T x 1 each: logged states, noise-free) fitted alone
    # (no_sensors; sigma 1e-3 rad and 1e-2 rad/s, the experiment's `states:`): converged at the
    # truth to 1e-6 relative (measured 3e-11), the states named in the result, no sensor
    s = mjsysid.simulate(str(pendulum), write=False).sequences[0]
    model = str(root / "models/pendulum.xml")
    seq = {"time": s.time, "ctrl": s.ctrl, "measured": s.sensordata, "qpos": s.qpos,
           "qvel": s.qvel, "no_sensors": True}
    states = {"qpos": {"sigma": 1e-3}, "qvel": {"sigma": [1e-2], "joints": ["hinge"]}}
    r = mjsysid.fit(model, PARAMETERS, [seq], options={"states": states})
    assert r.status == "converged"
    for name, value in TRUTH.items():
        assert r.estimates[name] == pytest.approx(value, rel=1e-6), name
    assert r.sequences[0].sensor_names == []
    assert r.sequences[0].state_names == ["qpos:hinge", "qvel:hinge"]
    assert r.sequences[0].state_measured.shape == (2000, 2)
    with pytest.raises(ValueError, match="options.states.qpos: 'sigma' is required"):
        mjsysid.fit(model, PARAMETERS, [seq], options={"states": {"qpos": {}}})


def test_control_delay_is_fitted(root, pendulum):
    # the commands logged 20 ms (10 steps) before they reach the motor: each sequence from its
    # 10th sample (its logged state there), the commands at their own times 10 samples earlier
    # (ctrl_time). Without a delay: model_mismatch (measured chi2 ratio 238); with a shared
    # fitted delay (start 0.01 s, bounds [0, 0.05]): converged, the delay and the physical
    # parameters within 4 standard errors of the truth (measured: 0.0200067 +- 1.3e-5 s)
    log = mjsysid.simulate(str(pendulum), write=False)
    model = str(root / "models/pendulum.xml")
    seqs = [{"time": s.time[10:], "measured": s.sensordata[10:], "qpos": s.qpos[10],
             "qvel": s.qvel[10], "ctrl_time": s.time[:-10], "ctrl": s.ctrl[10:]}
            for s in log.sequences]
    options = {"sensor_sigmas": SIGMAS}
    assert mjsysid.fit(model, PARAMETERS, seqs, options=options).status == "model_mismatch"
    r = mjsysid.fit(model, PARAMETERS, seqs, options=options,
                    control_delays=[{"initial": 0.01, "upper": 0.05}])
    expect_truth(r, dict(TRUTH, **{"controls.delay": 0.02}))
    with pytest.raises(ValueError, match="control_delays\\[0\\]: unknown key 'start'"):
        mjsysid.fit(model, PARAMETERS, seqs, control_delays=[{"start": 0.01}])


def test_several_models(root, frames):  # noqa: F811
    # two models (the pendulum as a path and as MJCF text), one sequence each: damping and
    # friction loss shared, the bob's mass fitted per model (`models`); both masses within 4
    # standard errors of the truth 1.2, each sequence fitted with its model
    path = root / "models/pendulum.xml"
    seqs = [dict(q, model=name) for q, name in zip(sequences_of(frames), ["a", "b"])]
    params = PARAMETERS[:2] + [dict(PARAMETERS[2], models=["a"]),
                               dict(PARAMETERS[2], name="bob_mass_b", models=["b"])]
    r = mjsysid.fit({"a": str(path), "b": path.read_text()}, params, seqs,
                    options={"sensor_sigmas": SIGMAS})
    expect_truth(r, dict(TRUTH, bob_mass_b=1.2))
    assert [q.model for q in r.sequences] == ["a", "b"]
    assert r.estimates["bob_mass"] != r.estimates["bob_mass_b"]
    with pytest.raises(ValueError, match="sequences\\[1\\]: 'model' is required with several"):
        mjsysid.fit({"a": str(path), "b": str(path)}, params,
                    [seqs[0], {k: v for k, v in seqs[1].items() if k != "model"}])


def test_docs_list_the_options_the_module_accepts(root):
    # the module's list (its ValueError for an unknown key) against docs/python.md's table of
    # options: the same keys, so that neither changes without the other
    with pytest.raises(ValueError) as err:
        mjsysid.fit("<mujoco/>", [], [], options={"no_such_key": 1})
    accepted = set(str(err.value).split("valid: ", 1)[1].split(", "))
    doc = (root / "docs/python.md").read_text()
    table = doc.split("<!-- options: begin", 1)[1].split("<!-- options: end -->", 1)[0]
    documented = set(re.findall(r"^\| `([a-z_0-9]+)` \|", table, re.MULTILINE))
    assert documented == accepted, documented ^ accepted


def test_statistical_stop_is_reported(root, frames):  # noqa: F811
    # the pendulum log (truth and start above), 1 thread: with the default gauss_newton_stop (0.03)
    # the fit ends by the statistical stop, and where it fired before the last Jacobian the result
    # names the iteration whose Jacobian the covariance used and the last step (<= 0.5 standard
    # errors, docs/numerics.md "Stopping"); with 0 Ceres' tolerances end it and the covariance is
    # the estimate's own
    model = str(root / "models/pendulum.xml")
    base = {"sensor_sigmas": SIGMAS, "max_iterations": 50, "threads": 1}
    stop = mjsysid.fit(model, PARAMETERS, sequences_of(frames), options=base)
    ceres = mjsysid.fit(model, PARAMETERS, sequences_of(frames),
                        options=dict(base, gauss_newton_stop=0.0))
    assert stop.status == ceres.status == "converged"
    assert stop.gauss_newton_converged and not ceres.gauss_newton_converged
    assert "Gauss-Newton" in stop.termination, stop.termination
    assert stop.termination_kind == "gauss_newton_stop", stop.termination_kind
    assert ceres.termination_kind == "solver_convergence", ceres.termination
    assert ceres.diagnostics.covariance_jacobian_iteration == -1
    assert np.isnan(ceres.diagnostics.last_step_std_errors)
    assert 0 <= stop.diagnostics.covariance_jacobian_iteration == stop.iterations - 1, \
        stop.termination
    assert 0 <= stop.diagnostics.last_step_std_errors <= 0.5
    # the ledger's steps add up to the fit's
    assert sum(row.steps for row in stop.diagnostics.ledger) == stop.diagnostics.simulation_steps
    for p, q in zip(stop.parameters, ceres.parameters):
        assert abs(p.value - q.value) <= 0.03 * q.std_error, (p, q)
        assert p.std_error == pytest.approx(q.std_error, rel=0.005), (p, q)


def test_global_stage_options(root, frames):  # noqa: F811
    # the global stage (docs/numerics.md "Global stage") runs only after a local fit that did not
    # converge: on the pendulum, which converges, it changes nothing (the same bits) and says
    # nothing; global_budget must be positive
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    base = {"sensor_sigmas": SIGMAS, "max_iterations": 30, "threads": 1}
    on = mjsysid.fit(model, PARAMETERS, seqs, options=base)
    off = mjsysid.fit(model, PARAMETERS, seqs, options=dict(base, global_stage=False,
                                                            global_budget=0.5))
    assert on.status == "converged", on.status
    assert on.estimates == off.estimates
    assert not any(w.startswith("global stage") for w in on.warnings), on.warnings
    with pytest.raises(ValueError, match="global_budget must be > 0"):
        mjsysid.fit(model, PARAMETERS, seqs, options={"global_budget": 0.0})


def test_subset_start_option(root, frames):  # noqa: F811
    # the subset start (docs/numerics.md "Subset start") on the pendulum log (truth and start
    # above, two sequences): on, its estimate the start of the fit on all the data,
    # which ends at the estimate of the fit without it within 0.1 standard error with the same
    # standard errors within 1 %, and fewer simulation steps; off: "" and every iteration on all
    # the data
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:2]
    base = {"sensor_sigmas": SIGMAS, "max_iterations": 30, "threads": 1}
    on = mjsysid.fit(model, PARAMETERS, seqs, options=dict(base, subset_start=True))
    off = mjsysid.fit(model, PARAMETERS, seqs, options=base)  # off by default
    assert on.status == off.status == "converged", (on.status, off.status)
    assert on.subset_start.startswith("ran on the first "), on.subset_start
    assert "its estimate was the start" in on.subset_start, on.subset_start
    assert off.subset_start == ""
    for p, q in zip(on.parameters, off.parameters):
        assert abs(p.value - q.value) <= 0.1 * q.std_error, (p, q)
        assert p.std_error == pytest.approx(q.std_error, rel=0.01), (p, q)
        assert p.initial == q.initial, (p, q)
    assert on.diagnostics.simulation_steps < off.diagnostics.simulation_steps
    assert sum(row.steps for row in on.diagnostics.ledger) == on.diagnostics.simulation_steps
    assert pickle.loads(pickle.dumps(on)).subset_start == on.subset_start
