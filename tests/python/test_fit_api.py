"""The library API on numpy arrays: fit(model, parameters, sequences, options, callback).

Data: the pendulum experiment's simulated log (truth damping 0.08, frictionloss 0.03, bob_mass
1.2; sensor noise sigma 0.001 rad (angle) and 0.01 rad/s (rate); start 0.2, 0.01, 0.8).
"""

import threading

import numpy as np
import pandas as pd
import pytest

import mjsysid

TRUTH = {"damping": 0.08, "frictionloss": 0.03, "bob_mass": 1.2}
PARAMETERS = [
    {"name": "damping", "kind": "joint_damping", "object": "hinge", "initial": 0.2,
     "lower": 1e-4, "upper": 5.0, "log": True},
    {"name": "frictionloss", "kind": "joint_frictionloss", "object": "hinge", "initial": 0.01,
     "lower": 1e-4, "upper": 2.0, "log": True},
    {"name": "bob_mass", "kind": "body_mass", "object": "bob", "initial": 0.8,
     "lower": 0.05, "upper": 10.0, "log": True},
]
SIGMAS = {"angle": 0.001, "rate": 0.01}


@pytest.fixture
def frames(pendulum):
    """The simulated log as one pandas DataFrame per sequence: time, torque, angle, rate."""
    log = mjsysid.simulate(str(pendulum), write=False)
    out = []
    for s in log.sequences:
        df = pd.DataFrame({"time": s.time})
        df[s.actuator_names] = s.ctrl
        df[s.sensor_names] = s.sensordata  # both sensors are 1-D
        out.append((df, s.qpos[0], s.qvel[0]))
    return out


def sequences_of(frames):
    return [{"name": f"run{i}", "time": df["time"], "ctrl": df[["torque"]].to_numpy(),
             "measured": df[["angle", "rate"]].to_numpy(), "qpos": qpos, "qvel": qvel}
            for i, (df, qpos, qvel) in enumerate(frames)]


def test_fit_from_dataframes_recovers_truth(root, frames):
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames),
                         options={"sensor_sigmas": SIGMAS, "max_iterations": 50})
    assert result.status == "converged" and result.intervals_valid
    for p in result.parameters:
        # within 4 standard errors of the truth, and the error bars are tight (< 5 %)
        assert abs(p.value - TRUTH[p.name]) < 4 * p.std_error, p
        assert 0 < p.std_error < 0.05 * TRUTH[p.name], p
    assert result.estimates == {p.name: p.value for p in result.parameters}
    assert result.covariance.shape == (3, 3)
    seq = result.sequences[0]
    assert seq.sensor_names == ["angle", "rate"]
    assert seq.measured.shape == seq.simulated_final.shape == (2000, 2)


def test_sigma_auto_estimates_the_logs_noise(root, frames):
    # the shipped pendulum log (noise 0.001 rad, 0.01 rad/s): "auto" estimates each sensor's noise
    # from the log (within 10 %), the fit then judges the model as with stated sigmas
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames),
                         options={"sensor_sigmas": {"angle": "auto", "rate": "auto"},
                                  "max_iterations": 50})
    assert result.status == "converged" and result.intervals_valid
    assert set(result.sigma_from_log) == {"angle", "rate"}
    for sensor, sigma in result.sigma_from_log.items():
        assert abs(sigma / SIGMAS[sensor] - 1) < 0.1, (sensor, sigma)
    assert all(d.sigma_from_log for d in result.residuals)
    assert abs(result.chi2_ratio - 1) < 0.15
    for p in result.parameters:
        assert abs(p.value - TRUTH[p.name]) < 4 * p.std_error, p
    with pytest.raises(ValueError, match=r"sensor_sigmas\['angle'\] must be a number > 0 or 'auto'"):
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                    options={"sensor_sigmas": {"angle": "atuo"}})


def test_model_as_xml_text_gives_the_same_fit(root, frames):
    xml = (root / "models/pendulum.xml").read_text()
    seqs = sequences_of(frames)[:1]
    a = mjsysid.fit(xml, PARAMETERS, seqs, options={"sensor_sigmas": SIGMAS})
    b = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, seqs,
                    options={"sensor_sigmas": SIGMAS})
    assert [p.value for p in a.parameters] == [p.value for p in b.parameters]


def test_callback_sees_every_iteration(root, frames):
    seen = []
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                         callback=seen.append)
    assert [it.iteration for it in seen] == [it.iteration for it in result.trace]
    assert [it.cost for it in seen] == [it.cost for it in result.trace]
    assert len(seen) >= 3 and seen[-1].parameters.shape == (3,)


def test_callback_exception_stops_the_fit_and_is_raised(root, frames):
    def stop(it):
        if it.iteration == 1:
            raise ZeroDivisionError("from the callback")

    with pytest.raises(ZeroDivisionError, match="from the callback"):
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                    callback=stop)


def test_gil_released_during_the_fit(root, frames):
    # a fit in a thread; this thread keeps running meanwhile (it could not hold the GIL)
    seqs = sequences_of(frames)
    done = threading.Event()
    ticks = 0

    def work():
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, seqs,
                    options={"threads": 1, "max_iterations": 5})
        done.set()

    t = threading.Thread(target=work)
    t.start()
    while not done.wait(0.001):
        ticks += 1
    t.join()
    assert ticks >= 20


def test_bad_input_raises_value_error(root, frames):
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    with pytest.raises(ValueError, match="parameters\\[0\\]: unknown key 'lowr'"):
        mjsysid.fit(model, [dict(PARAMETERS[0], lowr=0)], seqs)
    with pytest.raises(ValueError, match="hnige"):
        mjsysid.fit(model, [dict(PARAMETERS[0], object="hnige")], seqs)
    with pytest.raises(ValueError, match="'measured' is required"):
        mjsysid.fit(model, PARAMETERS, [{"ctrl": seqs[0]["ctrl"]}])
    with pytest.raises(ValueError):  # 1 column where the model has 2 sensors
        mjsysid.fit(model, PARAMETERS, [dict(seqs[0], measured=seqs[0]["measured"][:, :1])])
    with pytest.raises(ValueError, match="loss 'l1'"):
        mjsysid.fit(model, PARAMETERS, seqs, options={"loss": "l1"})
    with pytest.raises(ValueError):
        mjsysid.fit("<mujoco><worldbody><body>", PARAMETERS, seqs)
