"""Bad input to mjsysid.fit is a ValueError naming the argument and the sizes expected and found,
never a crash (issue 34 item 1): nothing to fit, nothing to estimate, shapes that disagree with the
model or with each other, times that do not increase, NaN everywhere.

Data: a 200-step pendulum swing (models/pendulum.xml: nq = nv = nu = 1, sensors angle and rate)
simulated from 0.3 rad with zero torque, noise-free; damping fitted from 0.2. No fit here runs to
its end: each call is refused before its first simulation, except the control case.
"""

import re
import subprocess
import sys

import numpy as np
import pytest

import mjsysid

T = 200
DAMPING = [{"name": "damping", "kind": "joint_damping", "object": "hinge", "initial": 0.2,
            "lower": 1e-4, "upper": 5.0}]


@pytest.fixture(scope="module")
def model(root):
    return str(root / "models/pendulum.xml")


@pytest.fixture(scope="module")
def seq(model):
    """One good sequence: the swing's angle and rate as `measured`."""
    log_time = np.arange(T) * 0.002
    angle = 0.3 * np.cos(4.43 * log_time)  # near the truth; the checks do not read the values
    return {"time": log_time, "ctrl": np.zeros((T, 1)),
            "measured": np.column_stack([angle, np.gradient(angle, log_time)]),
            "qpos": [0.3], "qvel": [0.0]}


def sensorless(root):
    """The pendulum's MJCF without its <sensor> block (nsensordata = 0)."""
    return re.sub(r"<sensor>.*</sensor>", "", (root / "models/pendulum.xml").read_text(),
                  flags=re.S)


def fit_error(model, seq, parameters=DAMPING, **kwargs):
    """The ValueError's message of a fit of [seq]; fails when the fit runs."""
    with pytest.raises(ValueError) as e:
        mjsysid.fit(model, parameters, [seq], **kwargs)
    return str(e.value)


def expect(message, *parts):
    for p in parts:
        assert p in message, (p, message)


def in_subprocess(root, code):
    """Runs `code` (with np, mjsysid, XML = the sensorless pendulum, T) in a new interpreter: a
    crash there fails the test instead of killing pytest; returns (returncode, its output)."""
    prelude = (f"import numpy as np, mjsysid, re\nT = {T}\n"
               f"XML = {sensorless(root)!r}\n")
    p = subprocess.run([sys.executable, "-c", prelude + code], capture_output=True, text=True,
                       timeout=120)
    return p.returncode, p.stdout + p.stderr


def test_nothing_to_fit_is_a_value_error_not_a_crash(root):
    # measured T x 0 for a model without sensors, no state fitted: a SIGSEGV before (-11)
    code = """
try:
    mjsysid.fit(XML, [{"name": "damping", "kind": "joint_damping", "object": "hinge",
                      "initial": 0.2}],
                [{"ctrl": np.zeros((T, 1)), "measured": np.zeros((T, 0)), "qpos": [0.3]}])
except ValueError as e:
    print("ValueError:", e)
"""
    rc, out = in_subprocess(root, code)
    assert rc == 0, (rc, out)
    expect(out, "ValueError: sequence 'seq0': nothing to fit", "measured is 200 x 0",
           "model 'model' has 0 sensors", "no logged state fitted")
    # no_sensors without fitted states: the same crash before
    rc, out = in_subprocess(root, code.replace("XML", repr(str(root / "models/pendulum.xml")))
                            .replace('"measured": np.zeros((T, 0))',
                                     '"measured": np.zeros((T, 2)), "no_sensors": True'))
    assert rc == 0, (rc, out)
    expect(out, "ValueError: sequence 'seq0': nothing to fit", "no_sensors is set")


def test_the_sensorless_model_with_its_logged_states_still_fits(root, seq):
    # the control case: the same sensorless model fits its logged qpos (sigma 0.01 rad)
    qpos = seq["measured"][:, :1]
    r = mjsysid.fit(sensorless(root), DAMPING,
                    [{"ctrl": seq["ctrl"], "measured": np.zeros((T, 0)), "qpos": qpos,
                      "time": seq["time"]}],
                    options={"states": {"qpos": {"sigma": 0.01}}, "max_iterations": 3})
    assert r.sequences[0].state_names == ["qpos:hinge"]


def test_nothing_to_estimate_and_no_sequence(model, seq):
    # no parameter: it "converged" (no measurement term: model_mismatch) estimating nothing before
    expect(fit_error(model, seq, parameters=[]), "nothing to estimate: no parameter")
    with pytest.raises(ValueError, match="no sequence"):
        mjsysid.fit(model, DAMPING, [])


@pytest.mark.parametrize("change, parts", [
    # measured: no column, no row, one sensor's columns only
    ({"measured": np.zeros((T, 0))},
     ["measured must be T x nsensordata = T x 2 with T >= 1", "got 200 x 0"]),
    ({"measured": np.zeros((0, 2)), "ctrl": np.zeros((0, 1)), "time": np.zeros(0)},
     ["measured must be T x nsensordata = T x 2", "got 0 x 2"]),
    ({"measured": np.zeros((T, 1))}, ["got 200 x 1"]),
    ({"measured": np.zeros((T, 2, 1))},
     ["'measured' must be a 1-D or 2-D array, got shape (200, 2, 1)"]),
    ({"measured": [["a", "b"]] * T}, ["sequences[0]: 'measured' is not an array of numbers"]),
    # ctrl: columns and rows against the model and measured
    ({"ctrl": np.zeros((T, 2))}, ["ctrl must be 200 x 1", "nu = 1", "got 200 x 2"]),
    ({"ctrl": np.zeros((T - 3, 1))}, ["ctrl must be 200 x 1 (one row per row of measured",
                                      "got 197 x 1"]),
    ({"ctrl": None}, ["'ctrl' must be a 1-D or 2-D array, got shape () (NoneType)"]),
    ({"ctrl_hold": ["zoh", "zoh"]},
     ["ctrl_hold must be empty or have one entry per actuator (1), got 2"]),
    ({"ctrl_delay": [0.01, 0.02]},
     ["ctrl_delay must be empty or have one entry per actuator (1), got 2"]),
    # the initial state (1-D) and the logged states (2-D)
    ({"qpos": np.zeros(T)}, ["the initial qpos has 200 entries, expected nq = 1"]),
    ({"qvel": [0.0, 0.0]}, ["the initial qvel has 2 entries, expected nv = 1"]),
    ({"act": [0.0]}, ["the initial act has 1 entries, expected na = 0"]),
    ({"qpos": np.zeros((T, 3))}, ["logged qpos must be T x nq = 200 x 1", "got 200 x 3"]),
    ({"qpos": np.zeros((T - 5, 1))}, ["logged qpos must be T x nq = 200 x 1", "got 195 x 1"]),
    # times
    ({"time": np.zeros(T)}, ["sample times must be finite and strictly increasing (row 1: 0 "
                             "after 0)"]),
    ({"time": -np.arange(T) * 0.002}, ["strictly increasing (row 1: -0.002 after 0)"]),
    ({"time": np.arange(T - 1) * 0.002},
     ["time must be empty or have 200 entries (one per row of measured), got 199"]),
    ({"time": np.zeros((T, 2))}, ["'time' must be a 1-D array, got shape (200, 2)"]),
    # NaN everywhere
    ({"time": np.full(T, np.nan)}, ["strictly increasing (row 0: nan)"]),
    ({"measured": np.full((T, 2), np.nan)},
     ["measured sensor 'angle' has no measured sample (all 200 are NaN): nothing to fit"]),
    ({"ctrl": np.full((T, 1), np.nan)}, ["ctrl of actuator 0 is NaN from row 0 to the end"]),
    ({"qpos": [np.nan]}, ["the initial qpos is not finite at entry 0 (nan;"]),
    ({"qpos": np.full((T, 1), np.nan)}, ["the initial qpos is not finite at entry 0 (nan;",
                                         "with logged states, their first row"]),
])
def test_shapes_and_values_are_value_errors_with_sizes(model, seq, change, parts):
    message = fit_error(model, dict(seq, **change))
    expect(message, *parts)
    assert "sequence" in message  # which sequence: sequences[0] or its name 'seq0'


@pytest.mark.parametrize("options, message", [
    # max_iterations -5: status solver_failed before
    ({"max_iterations": -5}, "options: max_iterations must be >= 0, got -5"),
    ({"function_tolerance": -1e-6}, "options: function_tolerance must be >= 0, got -1e-06"),
    ({"threads": 10000},
     "options['threads']: expected 0 (all cores) or a whole number from 1 to 256"),
])
def test_options_out_of_range_are_value_errors(model, seq, options, message):
    expect(fit_error(model, seq, options=options), message)


def test_times_in_ns_are_a_value_error_not_an_allocation(model, seq):
    # stamps 1e6 "s" apart (ns read as seconds): 9.8e10 steps of 2 ms; std::bad_alloc
    # (MemoryError) before, after an int overflow
    expect(fit_error(model, dict(seq, time=np.arange(T) * 1e6)),
           "the sample times span 1.99e+08 s, 9.95e+10 steps of the model's timestep 0.002 s",
           "more than the 1e+08 a fit simulates")
