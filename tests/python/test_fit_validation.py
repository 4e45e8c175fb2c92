"""Held-out sequences in the library API: fit(..., validation=[...]) as the experiment's `validation:`.

Data: the pendulum experiment's simulated log, 3 x 2000 steps (truth damping 0.08, frictionloss
0.03, bob_mass 1.2; sensor noise sigma 0.001 rad (angle) and 0.01 rad/s (rate); start 0.2, 0.01,
0.8): seq0 and seq1 fitted, seq2 held out.
"""

import numpy as np
import pytest

import mjsysid

PARAMETERS = [
    {"name": "damping", "target": "joint_damping", "object": "hinge", "initial": 0.2,
     "bounds": [1e-4, 5.0], "transform": "log"},
    {"name": "frictionloss", "target": "joint_frictionloss", "object": "hinge", "initial": 0.01,
     "bounds": [1e-4, 2.0], "transform": "log"},
    {"name": "bob_mass", "target": "body_mass", "object": "bob", "initial": 0.8,
     "bounds": [0.05, 10.0], "transform": "log"},
]
OPTIONS = {"sensor_sigmas": {"angle": 0.001, "rate": 0.01}, "max_iterations": 50}


def sequences(pendulum):
    log = mjsysid.simulate(str(pendulum), write=False)
    return [{"name": s.name, "time": s.time, "ctrl": s.ctrl, "measured": s.sensordata,
             "qpos": s.qpos[0], "qvel": s.qvel[0]} for s in log.sequences]


def test_held_out_sequences_are_simulated_at_the_start_and_at_the_estimate(root, pendulum):
    seqs = sequences(pendulum)
    model = str(root / "models/pendulum.xml")
    held = mjsysid.fit(model, PARAMETERS, seqs[:2], OPTIONS, validation=[seqs[2]])
    plain = mjsysid.fit(model, PARAMETERS, seqs[:2], OPTIONS)
    assert held.status == "converged"
    # never fitted: the estimates are those without it, bit for bit
    assert [p.value for p in held.parameters] == [p.value for p in plain.parameters]
    assert plain.validation == []
    [v] = held.validation
    assert v.name == "seq2" and [f.channel for f in v.channel_fits] == ["angle", "rate"]
    for f in v.channel_fits:
        # the estimate explains the held-out sequence to its noise; the start does not
        assert f.fit_final > 95, (f.channel, f.fit_final)
        assert f.fit_initial < f.fit_final - 10, (f.channel, f.fit_initial)
    assert v.simulated_initial.shape == v.simulated_final.shape == v.measured.shape == (2000, 2)
    # what the experiment's `validation: [seq2]` gives for the same fit (the runner's path)
    exp = pendulum.read_text().replace("sensor_time: pre",
                                       "sensor_time: pre\nsequences: [seq0, seq1]\n"
                                       "validation: [seq2]")
    pendulum.write_text(exp)
    mjsysid.simulate(str(pendulum))
    runner = mjsysid.fit_experiment(str(pendulum), out=str(pendulum.parent / "out"))
    [r] = runner.validation
    for f, g in zip(v.channel_fits, r.channel_fits):
        assert f.channel == g.channel
        assert f.fit_initial == pytest.approx(g.fit_initial, rel=1e-9)
        assert f.fit_final == pytest.approx(g.fit_final, abs=0.01)


def test_a_bad_held_out_sequence_is_a_value_error_before_the_fit(root, pendulum):
    seqs = sequences(pendulum)
    bad = dict(seqs[2], name="short", measured=seqs[2]["measured"][:, :1])
    with pytest.raises(ValueError, match=r"validation\[0\].*measured"):
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, seqs[:1], OPTIONS,
                    validation=[bad])
    bad = dict(seqs[2], name="inf", ctrl=np.where(np.arange(2000)[:, None] == 7, np.inf,
                                                  seqs[2]["ctrl"]))
    with pytest.raises(ValueError, match=r"validation\[0\] \('inf'\): ctrl of actuator 0 is "
                                         r"infinite at row 7"):
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, seqs[:1], OPTIONS,
                    validation=[bad])
    with pytest.raises(ValueError, match=r"validation\[0\]: .*'bogus'"):
        mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, seqs[:1], OPTIONS,
                    validation=[dict(seqs[2], bogus=1)])
