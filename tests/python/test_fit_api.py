"""The library API on numpy arrays: fit(model, parameters, sequences, options, callback).

Data: the pendulum experiment's simulated log (truth damping 0.08, frictionloss 0.03, bob_mass
1.2; sensor noise sigma 0.001 rad (angle) and 0.01 rad/s (rate); start 0.2, 0.01, 0.8).
"""

import copy
import math
import pickle
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


def test_channel_fits_give_each_channels_percent_fit(root, frames):
    # % fit = 100 (1 - NRMSE), NRMSE = RMS(simulated - measured) / std(measured), per channel, as
    # the runner and result.yaml give it; recomputed here from the result's own arrays (1e-9)
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames),
                         options={"sensor_sigmas": SIGMAS, "max_iterations": 50})
    for seq in result.sequences:
        assert [f.channel for f in seq.channel_fits] == ["angle", "rate"]
        one_piece = seq.simulated_one_piece.size > 0  # a fit in segments
        final = seq.simulated_one_piece if one_piece else seq.simulated_final
        for j, f in enumerate(seq.channel_fits):
            y = seq.measured[:, j]
            for simulated, nrmse, fit in [(seq.simulated_initial, f.nrmse_initial, f.fit_initial),
                                          (final, f.nrmse_final, f.fit_final)]:
                expected = np.sqrt(np.mean((simulated[:, j] - y) ** 2)) / np.std(y)
                assert nrmse == pytest.approx(expected, rel=1e-9), f
                assert fit == pytest.approx(100 * (1 - expected), rel=1e-9), f
            assert np.isnan(f.fit_segments) != one_piece and np.isnan(f.nrmse_segments) != one_piece
            # at the estimate the misfit is the noise: NRMSE = sigma / std(y) within 10 % (sigma
            # 0.001 rad, 0.01 rad/s; measured 0.98 to 1.03 of it: % fit 99.45 to 99.63 for the
            # angle, 98.74 to 99.08 for the rate); the start (damping 0.2, friction 0.01, mass 0.8
            # for 0.08, 0.03, 1.2) is far worse (measured 50.7 to 74.3 %)
            floor = SIGMAS[f.channel] / np.std(y)
            assert 0.9 * floor < f.nrmse_final < 1.1 * floor, (f, floor)
            assert f.fit_initial < 80, f
        assert "% fit angle" in repr(seq)


def named_sequences(frames, measured, ctrl=lambda df: df[["torque"]]):
    """The sequences with measured and ctrl given as DataFrames or dicts made by the functions."""
    return [{"name": f"run{i}", "time": df["time"], "ctrl": ctrl(df), "measured": measured(df),
             "qpos": qpos, "qvel": qvel} for i, (df, qpos, qvel) in enumerate(frames)]


def test_dataframe_columns_are_matched_to_the_sensors_by_name(root, frames):
    # the columns swapped (rate, angle): placed by name, the fit recovers the truth (within 4
    # standard errors; noise 0.001 rad, 0.01 rad/s; start 0.2, 0.01, 0.8). Taken in model order,
    # as before, the same frames ended model_mismatch with every parameter on a bound
    model = str(root / "models/pendulum.xml")
    options = {"sensor_sigmas": SIGMAS, "max_iterations": 50}
    swapped = mjsysid.fit(model, PARAMETERS,
                          named_sequences(frames, lambda df: df[["rate", "angle"]]),
                          options=options)
    assert swapped.status == "converged" and swapped.intervals_valid
    for p in swapped.parameters:
        assert abs(p.value - TRUTH[p.name]) < 4 * p.std_error, p
    assert swapped.sequences[0].sensor_names == ["angle", "rate"]
    # a dict of named columns places them as the DataFrame does: the same estimates to the bit
    first = frames[:1]
    a = mjsysid.fit(model, PARAMETERS, named_sequences(first, lambda df: df[["rate", "angle"]]),
                    options=options)
    b = mjsysid.fit(model, PARAMETERS,
                    named_sequences(first, lambda df: {"rate": df["rate"].to_numpy(),
                                                       "angle": list(df["angle"])},
                                    ctrl=lambda df: {"torque": df["torque"]}),
                    options=options)
    c = mjsysid.fit(model, PARAMETERS, sequences_of(first), options=options)  # arrays, model order
    assert a.estimates == b.estimates == c.estimates


def test_named_columns_that_do_not_match_are_value_errors(root, frames):
    model = str(root / "models/pendulum.xml")
    lists = "(the columns given: time, angle, rate; the sensors of model 'model': angle, rate)"
    with pytest.raises(ValueError) as e:  # a column that is not a sensor
        mjsysid.fit(model, PARAMETERS, named_sequences(frames[:1], lambda df: df[["time", "angle",
                                                                                  "rate"]]))
    assert "sequences[0]: 'measured': column 'time' is not a sensor " + lists in str(e.value)
    with pytest.raises(ValueError, match=r"'measured': no column for sensor rate \(the columns "
                                         r"given: angle; the sensors of model 'model': angle, "
                                         r"rate\)"):
        mjsysid.fit(model, PARAMETERS, named_sequences(frames[:1], lambda df: df[["angle"]]))
    with pytest.raises(ValueError, match=r"'ctrl': column 'motor' is not an actuator \(the columns "
                                         r"given: motor; the actuators of model 'model': torque\)"):
        mjsysid.fit(model, PARAMETERS, named_sequences(
            frames[:1], lambda df: df[["angle", "rate"]],
            ctrl=lambda df: df[["torque"]].rename(columns={"torque": "motor"})))
    with pytest.raises(ValueError, match=r"column 'angle' has 10 rows, the columns before it 2000"):
        mjsysid.fit(model, PARAMETERS, named_sequences(
            frames[:1], lambda df: {"rate": df["rate"], "angle": df["angle"][:10]}))
    # the fitted sensors only (`sensors`): the others may be absent (not measured)
    seqs = named_sequences(frames[:1], lambda df: df[["angle"]])
    result = mjsysid.fit(model, PARAMETERS, [dict(seqs[0], sensors=["angle"])],
                         options={"max_iterations": 2})
    assert result.sequences[0].sensor_names == ["angle"]
    # a DataFrame without names (pandas' default 0, 1 labels) is an array: model order, as before
    unnamed = named_sequences(frames[:1], lambda df: pd.DataFrame(df[["angle", "rate"]].to_numpy()))
    a = mjsysid.fit(model, PARAMETERS, unnamed, options={"max_iterations": 2})
    b = mjsysid.fit(model, PARAMETERS, sequences_of(frames[:1]), options={"max_iterations": 2})
    assert a.estimates == b.estimates


def test_mujoco_model_and_spec_give_the_fit_of_the_path(root, frames):
    mujoco = pytest.importorskip("mujoco")
    path = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    options = {"sensor_sigmas": SIGMAS}
    by_path = mjsysid.fit(path, PARAMETERS, seqs, options=options)
    by_model = mjsysid.fit(mujoco.MjModel.from_xml_path(path), PARAMETERS, seqs, options=options)
    by_spec = mjsysid.fit(mujoco.MjSpec.from_file(path), PARAMETERS, seqs, options=options)
    several = mjsysid.fit({"p": mujoco.MjModel.from_xml_path(path)}, PARAMETERS,
                          [dict(seqs[0], model="p")], options=options)
    assert by_path.estimates == by_model.estimates == by_spec.estimates == several.estimates
    with pytest.raises(ValueError, match="model: expected a path, MJCF text, a mujoco.MjModel or "
                                         "a mujoco.MjSpec, got int"):
        mjsysid.fit(42, PARAMETERS, seqs)


def test_results_have_a_useful_repr(root, frames):
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                         options={"sensor_sigmas": SIGMAS})
    text = repr(result)
    assert text.startswith(f"FitResult({result.status}, {result.iterations} iterations, cost ")
    assert "damping = " in text and "bob_mass = " in text and "1 sequence" in text
    p = result.parameters[0]
    assert repr(p).startswith(f"ParameterEstimate(damping = {p.value:.6g} +- {p.std_error:.2g}, "
                              "initial 0.2")
    f = result.sequences[0].channel_fits[0]
    assert repr(f).startswith("ChannelFit(angle, fit ")


def assert_same(a, b, where="result"):
    """a and b equal in every public attribute, recursively (arrays to the bit, NaN = NaN)."""
    assert type(a) is type(b), where
    if isinstance(a, np.ndarray):
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True), where
    elif isinstance(a, float):
        assert a == b or (math.isnan(a) and math.isnan(b)), (where, a, b)
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif type(a).__module__.startswith("mjsysid"):
        names = [n for n in dir(a) if not n.startswith("_") and not callable(getattr(a, n))]
        assert names, where
        for n in names:
            assert_same(getattr(a, n), getattr(b, n), f"{where}.{n}")
    else:
        assert a == b, (where, a, b)


def test_results_pickle_and_deepcopy_exactly(root, frames, pendulum, tmp_path):
    # every public attribute of the copy equals the original's, arrays to the bit (a fit of the
    # first sequence; then a fit_experiment's ExperimentFit and the ResultFile read back)
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                         options={"sensor_sigmas": SIGMAS})
    for twin in [pickle.loads(pickle.dumps(result)), copy.deepcopy(result)]:
        assert_same(result, twin)
        assert repr(twin) == repr(result)
    mjsysid.simulate(str(pendulum))
    exp_fit = mjsysid.fit_experiment(str(pendulum), out=str(tmp_path / "out"))
    from_file = mjsysid.read_result(str(tmp_path / "out"))
    for r in [exp_fit, from_file]:
        assert_same(r, pickle.loads(pickle.dumps(r)))
    assert pickle.loads(pickle.dumps(exp_fit)).out_dir == exp_fit.out_dir
    # bytes that are not a pickled result are refused, not misread
    blank = mjsysid.FitResult.__new__(mjsysid.FitResult)
    with pytest.raises(ValueError, match="not a pickled mjsysid result"):
        blank.__setstate__(b"not a result")
    state = result.__getstate__()
    with pytest.raises(ValueError, match="truncated|corrupt"):
        mjsysid.FitResult.__new__(mjsysid.FitResult).__setstate__(state[:len(state) // 2])


def test_wide_sensors_and_several_actuators_by_name(root):
    # the spherical pendulum (models/ball_pendulum.xml: sensors quat 4, angvel 3, bob_pos 3
    # columns; motors tx, ty), 300 steps from a 0.4 rad tilt under uniform random torques in
    # [-0.5, 0.5] (seed 0), rolled out by mujoco, noise-free; damping (truth 0.05) from 0.1, 3
    # iterations. Named columns in reverse order (a DataFrame of NAME[i], a dict of NAME as
    # T x dim) place the data as the array in model order does: the same measured and estimate
    # to the bit
    mujoco = pytest.importorskip("mujoco")
    path = str(root / "models/ball_pendulum.xml")
    m = mujoco.MjModel.from_xml_path(path)
    d = mujoco.MjData(m)
    steps = 300
    ctrl = np.random.default_rng(0).uniform(-0.5, 0.5, (steps, 2))
    d.qpos[:] = [np.cos(0.2), np.sin(0.2), 0.0, 0.0]
    qpos0 = d.qpos.copy()
    y = np.empty((steps, m.nsensordata))
    for k in range(steps):
        d.ctrl[:] = ctrl[k]
        mujoco.mj_forward(m, d)
        y[k] = d.sensordata
        mujoco.mj_step(m, d)
    adr = {"quat": (0, 4), "angvel": (4, 3), "bob_pos": (7, 3)}
    frame = pd.DataFrame({f"{n}[{i}]": y[:, a + i] for n, (a, w) in reversed(adr.items())
                          for i in reversed(range(w))})
    columns = {n: y[:, a:a + w] for n, (a, w) in reversed(adr.items())}
    damping = [{"name": "damping", "kind": "joint_damping", "object": "ball", "initial": 0.1,
                "lower": 1e-4, "upper": 5.0, "log": True}]

    def fit(measured, ctrl_given):
        return mjsysid.fit(path, damping, [{"ctrl": ctrl_given, "measured": measured,
                                            "qpos": qpos0}], options={"max_iterations": 3})

    by_array = fit(y, ctrl)
    by_frame = fit(frame, pd.DataFrame({"ty": ctrl[:, 1], "tx": ctrl[:, 0]}))
    by_dict = fit(columns, {"ty": ctrl[:, 1], "tx": ctrl[:, 0]})
    assert by_array.estimates == by_frame.estimates == by_dict.estimates
    for r in [by_frame, by_dict]:
        assert np.array_equal(r.sequences[0].measured, by_array.sequences[0].measured)
    assert np.array_equal(by_array.sequences[0].measured, y)
    with pytest.raises(ValueError, match=r"column 'bob_pos' must have 3 column\(s\), got 2 "
                                         r"\(give T x 3, or 'bob_pos\[0\]' ... 'bob_pos\[2\]' "
                                         r"one by one\)"):
        fit(dict(columns, bob_pos=y[:, 7:9]), ctrl)
    with pytest.raises(ValueError, match=r"column 'bob_pos\[3\]': sensor 'bob_pos' has 3 column"):
        fit(dict(columns, **{"bob_pos[3]": y[:, 9]}), ctrl)
    with pytest.raises(ValueError, match=r"column 'quat\[0\]' gives a column of sensor 'quat' "
                                         r"twice"):
        fit(dict(columns, **{"quat[0]": y[:, 0]}), ctrl)
    with pytest.raises(ValueError, match=r"no column for sensor angvel\[2\] \(the columns given"):
        fit(frame.drop(columns=["angvel[2]"]), ctrl)
