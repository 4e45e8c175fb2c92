"""mjsysid.design: the excitation design from Python gives what `sysid design` gives (the same
controls bit for bit and the same predicted standard errors for the same seed), writes the same
files, and refuses bad arguments with ValueError.

Pendulum experiment (damping, friction loss, bob mass; torque amplitude 2, 4 s), criterion
worst_relative_std, 40 candidates, seed 3, 2 threads."""

import csv
import subprocess

import numpy as np
import pytest

import mjsysid


def read_controls(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in row] for row in rows[1:]])


def test_design_equals_the_command_line(root, sysid, tmp_path):
    exp = root / "experiments" / "pendulum.yaml"
    d = mjsysid.design(exp, out=tmp_path / "py", criterion="worst_relative_std", evaluations=40,
                       seed=3, threads=2)
    run = subprocess.run([sysid, "design", str(exp), "--out", str(tmp_path / "cli"),
                          "--criterion", "worst_relative_std", "--evaluations", "40",
                          "--seed", "3", "--threads", "2"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    header, cli = read_controls(tmp_path / "cli" / "controls.csv")
    assert header == ["time", "torque"]
    assert d["actuators"] == ["torque"]
    assert d["parameters"] == ["damping", "frictionloss", "bob_mass"]
    u = d["design"]["controls"]
    assert u.shape == (2000, 1)
    assert np.array_equal(cli[:, 1:], u)
    assert np.array_equal(cli[:, 0], d["time"])
    assert (tmp_path / "py" / "controls.csv").read_bytes() == \
        (tmp_path / "cli" / "controls.csv").read_bytes()
    # the design is within the amplitude limit, starts and ends at rest, and is no worse than the
    # shipped sines on the criterion it was searched for
    assert np.abs(u).max() <= 2.0 + 1e-12
    assert u[0, 0] == 0.0 and u[-1, 0] == 0.0
    assert d["design"]["meets_constraints"]
    assert d["evaluations"] == 40
    worst = d["design"]["criteria"]["worst_relative_std"]
    assert worst == max(d["design"]["relative_std"].values())
    assert worst < d["current"]["criteria"]["worst_relative_std"]
    for name, std in d["design"]["predicted_std"].items():
        assert std == pytest.approx(d["design"]["relative_std"][name] * d["values"][name],
                                    rel=1e-12)
    assert d["files"]["design"].endswith("design.yaml")
    assert d["files"]["page"].endswith("design.html")
    assert "Predicted standard errors" in (tmp_path / "py" / "design.html").read_text()
    assert d["time_limited"] is False


def test_bad_arguments_raise_value_error(root, tmp_path):
    exp = root / "experiments" / "pendulum.yaml"
    with pytest.raises(ValueError, match="criterion"):
        mjsysid.design(exp, criterion="a_optimal")
    with pytest.raises(ValueError, match="range-margin"):
        mjsysid.design(exp, range_margin=0.7)
    with pytest.raises(ValueError, match="threads"):
        mjsysid.design(exp, threads=-3)
    with pytest.raises(ValueError, match="max_joint_speed"):
        mjsysid.design(exp, max_joint_speed=0.0)
    with pytest.raises(ValueError, match="no candidate met the constraints"):
        mjsysid.design(root / "experiments" / "box_floor.yaml", contacts=False, evaluations=2)
