"""mjsysid.fit with the experiment file's names: a parameter's `target`, `bounds`, `transform`,
`prior: {mean, sigma}` beside today's `kind`, `lower`/`upper`, `log`, `prior: [mean, sigma]`;
`initial: "auto"` (the equation-error start) and the options `starts` and `seed` (multi-start),
each computed by the code the experiment runner uses.

Data: the pendulum experiment's simulated log (truth damping 0.08, frictionloss 0.03, bob_mass
1.2; noise sigma 0.001 rad and 0.01 rad/s; start 0.2, 0.01, 0.8).
"""

import math

import numpy as np
import pytest

import mjsysid
from conftest import copy_experiment
from test_fit_api import PARAMETERS, SIGMAS, TRUTH, frames, sequences_of  # noqa: F401

# PARAMETERS as the experiment file writes them (experiments/pendulum.yaml)
YAML_PARAMETERS = [
    {"name": "damping", "target": "joint_damping", "object": "hinge", "initial": 0.2,
     "bounds": [1e-4, 5.0], "transform": "log"},
    {"name": "frictionloss", "target": "joint_frictionloss", "object": "hinge", "initial": 0.01,
     "bounds": [1e-4, 2.0], "transform": "log"},
    {"name": "bob_mass", "target": "body_mass", "object": "bob", "initial": 0.8,
     "bounds": [0.05, 10.0], "transform": "log"},
]


def test_the_experiment_files_names_give_the_same_fit(root, frames):  # noqa: F811
    model = str(root / "models/pendulum.xml")
    seqs = sequences_of(frames)[:1]
    options = {"sensor_sigmas": SIGMAS, "max_iterations": 20}
    ours = mjsysid.fit(model, PARAMETERS, seqs, options=options)
    yamls = mjsysid.fit(model, YAML_PARAMETERS, seqs, options=options)
    assert ours.status == "converged"
    assert [p.value for p in yamls.parameters] == [p.value for p in ours.parameters]
    assert [p.std_error for p in yamls.parameters] == [p.std_error for p in ours.parameters]
    # a prior as the file writes it ({mean, sigma}) is the list [mean, sigma]; transform: scale
    # with its scale is today's scale alone
    a = [dict(PARAMETERS[0], prior=[0.1, 0.05])] + [
        {k: v for k, v in p.items() if k != "log"} | {"scale": 0.5} for p in PARAMETERS[1:]]
    b = [dict(YAML_PARAMETERS[0], prior={"mean": 0.1, "sigma": 0.05})] + [
        dict(p, transform="scale", scale=0.5) for p in YAML_PARAMETERS[1:]]
    fa = mjsysid.fit(model, a, seqs, options=options)
    fb = mjsysid.fit(model, b, seqs, options=options)
    assert [p.value for p in fa.parameters] == [p.value for p in fb.parameters]
    # transform: none is no transform (log and scale change the iterates)
    c = [dict(p, transform="none") for p in YAML_PARAMETERS]
    d = [{k: v for k, v in p.items() if k != "log"} for p in PARAMETERS]
    fc = mjsysid.fit(model, c, seqs, options=options)
    fd = mjsysid.fit(model, d, seqs, options=options)
    assert [p.value for p in fc.parameters] == [p.value for p in fd.parameters]


@pytest.mark.parametrize("ours,yaml_key,value", [
    ("kind", "target", "joint_damping"),
    ("lower", "bounds", [1e-4, 5.0]),
    ("upper", "bounds", [1e-4, 5.0]),
    ("log", "transform", "log"),
])
def test_both_spellings_of_one_thing_are_a_value_error(root, frames,  # noqa: F811
                                                       ours, yaml_key, value):
    p = dict(PARAMETERS[0])
    p[yaml_key] = value
    if ours not in p:
        p[ours] = 1.0
    with pytest.raises(ValueError, match=rf"parameters\[0\]: '(kind|lower|upper|log)' and "
                                         rf"'{yaml_key}' are two spellings of one thing"):
        mjsysid.fit(str(root / "models/pendulum.xml"), [p], sequences_of(frames)[:1])


def test_bad_yaml_spellings_are_value_errors(root, frames):  # noqa: F811
    model, seqs = str(root / "models/pendulum.xml"), sequences_of(frames)[:1]
    cases = [
        (dict(YAML_PARAMETERS[0], transform="exp"), r"transform 'exp': expected none, log, scale"),
        (dict(YAML_PARAMETERS[0], bounds=[1.0]), r"'bounds' is \[lower, upper\]"),
        (dict(YAML_PARAMETERS[0], prior={"mean": 1.0}), r"'prior' is \[mean, sigma\]"),
        (dict(YAML_PARAMETERS[0], prior={"mean": 1.0, "sd": 1}), r"prior: unknown key 'sd'"),
        (dict(YAML_PARAMETERS[0], initial="automatic"), r"'initial' is a number or 'auto'"),
        ({k: v for k, v in YAML_PARAMETERS[0].items() if k != "target"},
         r"'target' \(or 'kind'\) is required"),
    ]
    for p, message in cases:
        with pytest.raises(ValueError, match=message):
            mjsysid.fit(model, [p], seqs)


def auto_experiment(tmp_path, starts=None):
    """experiments/pendulum.yaml with every initial `auto` (or with solver.starts and seed, few
    iterations), its log simulated into tmp_path; returns the path and its sequences as dicts"""
    path = copy_experiment("pendulum", tmp_path)
    text = path.read_text()
    if starts:
        text = text.replace("max_iterations: 50", f"max_iterations: 3\n  starts: {starts}\n"
                                                  "  seed: 7")
    else:
        for start in ["0.2", "0.01", "0.8"]:
            text = text.replace(f"initial: {start}\n", "initial: auto\n")
    path.write_text(text)
    log = mjsysid.simulate(str(path))
    seqs = [{"name": s.name, "time": s.time, "ctrl": s.ctrl, "measured": s.sensordata,
             "qpos": s.qpos, "qvel": s.qvel} for s in log.sequences]
    return path, seqs


def test_initial_auto_is_the_experiment_runners_start(root, tmp_path):
    path, seqs = auto_experiment(tmp_path)
    assert path.read_text().count("initial: auto") == 3
    params = [dict(p, initial="auto") for p in YAML_PARAMETERS]
    result = mjsysid.fit(str(root / "models/pendulum.xml"), params, seqs,
                         options={"sensor_sigmas": SIGMAS, "max_iterations": 50})
    # the equation-error start: near the truth (noise 0.01 rad/s on the differenced rate), not the
    # model's values (0.05, 0.01, 1.0)
    starts = {p.name: p.initial for p in result.parameters}
    for name, truth in TRUTH.items():
        assert abs(starts[name] / truth - 1) < 0.2, (name, starts[name])
    assert any(w.startswith("initial: auto (model 'model'): equation-error start")
               for w in result.warnings)
    assert result.status == "converged"
    for p in result.parameters:
        assert abs(p.value - TRUTH[p.name]) < 4 * p.std_error, p
    # the experiment runner's start from the same log is the same start
    fit = mjsysid.fit_experiment(str(path), out=str(tmp_path / "out"))
    for a, b in zip(fit.parameters, result.parameters):
        assert math.isclose(a.initial, b.initial, rel_tol=1e-12), (a, b)


def test_starts_and_seed_are_the_experiment_runners(root, tmp_path):
    path, seqs = auto_experiment(tmp_path, starts=3)
    options = {"sensor_sigmas": SIGMAS, "max_iterations": 3, "starts": 3, "seed": 7}
    result = mjsysid.fit(str(root / "models/pendulum.xml"), YAML_PARAMETERS, seqs,
                         options=options)
    runs = result.to_dict()["starts"]["runs"]
    assert len(runs) == 3
    assert runs[0]["start"] == [p["initial"] for p in YAML_PARAMETERS]
    for run in runs[1:]:
        for x, p in zip(run["start"], YAML_PARAMETERS):
            assert p["bounds"][0] <= x <= p["bounds"][1]
    assert runs[1]["start"] != runs[2]["start"]
    spread = result.to_dict()["starts"]["spread"]
    assert [s["name"] for s in spread] == list(TRUTH)
    # the runner's starts for solver.starts 3, seed 7 are these
    fit = mjsysid.fit_experiment(str(path), out=str(tmp_path / "out"))
    assert [r["start"] for r in fit.to_dict()["starts"]["runs"]] == [r["start"] for r in runs]
    # another seed, other starts
    other = mjsysid.fit(str(root / "models/pendulum.xml"), YAML_PARAMETERS, seqs[:1],
                        options=dict(options, seed=8))
    assert other.to_dict()["starts"]["runs"][1]["start"] != runs[1]["start"]
    for bad, message in [({"starts": 0}, "starts must be 1..10000"),
                         ({"seed": -1}, "seed must be >= 0")]:
        with pytest.raises(ValueError, match=message):
            mjsysid.fit(str(root / "models/pendulum.xml"), YAML_PARAMETERS, seqs[:1],
                        options=bad)
    assert np.isfinite(result.final_cost)
