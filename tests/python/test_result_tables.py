"""to_dict() and to_pandas() of the results: result.yaml's keys in plain Python objects, the
parameters and the sequences as pandas tables.

Data: the pendulum experiment's simulated log (truth damping 0.08, frictionloss 0.03, bob_mass
1.2; noise sigma 0.001 rad and 0.01 rad/s; start 0.2, 0.01, 0.8), sigmas stated.
"""

import json
import math
import sys

import numpy as np
import pandas as pd
import pytest
import yaml

import mjsysid
from test_fit_api import PARAMETERS, SIGMAS, TRUTH, frames, sequences_of  # noqa: F401


class Loader(yaml.SafeLoader):
    """PyYAML's safe loader with timestamps left as text (result.yaml's `created`, as written)"""


Loader.yaml_implicit_resolvers = {
    k: [(tag, regexp) for tag, regexp in v if tag != "tag:yaml.org,2002:timestamp"]
    for k, v in yaml.SafeLoader.yaml_implicit_resolvers.items()}


def same(a, b, where="dict"):
    """a and b equal, recursively; floats to the bit, NaN = NaN (YAML's .nan read by PyYAML)."""
    if isinstance(a, str) and not isinstance(b, str):
        # result.yaml's `solver` settings are text written plainly: PyYAML reads "1" as 1
        assert where.startswith("dict['solver']") and yaml.safe_load(a) == b, (where, a, b)
    elif isinstance(a, float) or isinstance(b, float):
        assert (a == b) or (math.isnan(a) and math.isnan(b)), (where, a, b)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), (where, sorted(a.keys() ^ b.keys()))
        for k in a:
            same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{where}[{i}]")
    else:
        assert a == b, (where, a, b)


def test_fit_to_dict_has_result_yamls_names(root, frames):  # noqa: F811
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                         options={"sensor_sigmas": SIGMAS})
    d = result.to_dict()
    json.dumps(d)  # plain Python objects only
    assert d["status"] == result.status == "converged"
    assert d["intervals_valid"] is True and d["iterations"] == result.iterations
    assert d["final_cost"] == result.final_cost and d["wall_time_s"] == result.seconds
    assert [p["name"] for p in d["parameters"]] == list(TRUTH)
    for p, e in zip(d["parameters"], result.parameters):
        assert (p["value"], p["initial"], p["std"]) == (e.value, e.initial, e.std_error)
        assert p["ci95"] == list(e.ci95) and p["flags"] == []
    # % fit per channel, as the sequences' channel_fits
    (metrics,) = d["fit_metrics"]
    assert metrics["sequence"] == "run0" and metrics["role"] == "fit"
    for c, f in zip(metrics["channels"], result.sequences[0].channel_fits):
        assert (c["channel"], c["fit_final"], c["nrmse_initial"]) == (
            f.channel, f.fit_final, f.nrmse_initial)
    assert [r["channel"] for r in d["residuals"]] == ["angle", "rate"]
    assert d["warnings"] == list(result.warnings)
    # no file: the run's own keys are empty
    assert d["experiment"] == "" and d["identified_models"] == {}


def test_experiment_fit_to_dict_is_result_yaml(pendulum, tmp_path):
    # every key and value of result.yaml (read by PyYAML), the warnings ungrouped
    mjsysid.simulate(str(pendulum))
    out = tmp_path / "out"
    fit = mjsysid.fit_experiment(str(pendulum), out=str(out))
    from_yaml = yaml.load((out / "result.yaml").read_text(), Loader=Loader)
    for key in ["format", "format_version"]:
        del from_yaml[key]
    d = fit.to_dict()
    assert d.pop("out_dir") == str(out) and d.pop("exit_code") == 0
    assert d["warnings"] == list(fit.warnings)
    d["warnings"] = from_yaml["warnings"]  # (result.yaml groups those that recur per sequence)
    same(d, from_yaml)
    json.dumps(d)
    # the file read back gives the same dict
    d = fit.to_dict()
    del d["out_dir"], d["exit_code"]
    same(mjsysid.read_result(str(out)).to_dict(), d)


def test_to_pandas_parameters_and_sequences(root, frames):  # noqa: F811
    # bob_mass with an upper bound below its truth 1.2: it stops there (flag at_upper_bound)
    params = [dict(p) for p in PARAMETERS]
    params[2]["upper"] = 1.0
    params[2]["initial"] = 0.9
    result = mjsysid.fit(str(root / "models/pendulum.xml"), params, sequences_of(frames)[:1],
                         options={"sensor_sigmas": SIGMAS})
    df = result.to_pandas()
    assert isinstance(df, pd.DataFrame) and list(df.index) == list(TRUTH)
    assert df.index.name == "name"
    # (the fit ends model_mismatch: the timestep check runs and gives each a timestep_bias)
    assert all(p.timestep_bias is not None for p in result.parameters), result.status
    assert list(df.columns) == ["value", "initial", "std", "ci95_low", "ci95_high",
                                "at_lower_bound", "at_upper_bound", "unidentifiable",
                                "timestep_bias"]
    for e in result.parameters:
        row = df.loc[e.name]
        assert (row["value"], row["initial"], row["std"]) == (e.value, e.initial, e.std_error)
        assert (row["ci95_low"], row["ci95_high"]) == e.ci95
        assert (row["at_lower_bound"], row["at_upper_bound"], row["unidentifiable"]) == (
            e.at_lower, e.at_upper, not e.identifiable)
        assert row["timestep_bias"] == e.timestep_bias
    assert bool(df.loc["bob_mass", "at_upper_bound"]) and df.loc["bob_mass", "value"] == 1.0

    seq = result.sequences[0]
    t = seq.to_pandas()
    assert list(t.columns) == ["time", "measured:angle", "simulated_initial:angle",
                               "simulated_final:angle", "measured:rate",
                               "simulated_initial:rate", "simulated_final:rate"]
    assert len(t) == 2000
    assert np.array_equal(t["time"].to_numpy(), seq.time)
    assert np.array_equal(t["simulated_final:rate"].to_numpy(), seq.simulated_final[:, 1])
    assert np.array_equal(t["measured:angle"].to_numpy(), seq.measured[:, 0])


def test_to_pandas_truth_column_from_an_experiment(pendulum, tmp_path):
    # simulated data: truth known, a column of its own (result.yaml's `truth`)
    mjsysid.simulate(str(pendulum))
    fit = mjsysid.fit_experiment(str(pendulum), out=str(tmp_path / "out"))
    df = fit.to_pandas()
    assert df["truth"].to_dict() == TRUTH
    assert mjsysid.read_result(str(tmp_path / "out")).to_pandas().equals(df)


def test_to_pandas_without_pandas_is_an_import_error(root, frames, monkeypatch):  # noqa: F811
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames)[:1],
                         options={"max_iterations": 0})
    monkeypatch.setitem(sys.modules, "pandas", None)  # `import pandas` raises ImportError
    with pytest.raises(ImportError, match="to_pandas\\(\\) needs pandas.*pip install pandas"):
        result.to_pandas()
    with pytest.raises(ImportError, match="pip install pandas"):
        result.sequences[0].to_pandas()
    assert result.to_dict()["status"] == result.status  # to_dict needs nothing more


def test_docstrings_of_the_tables():
    for cls in [mjsysid.FitResult, mjsysid.ResultFile, mjsysid.ExperimentFit]:
        assert "result.yaml" in cls.to_dict.__doc__
        assert "pandas" in cls.to_pandas.__doc__
    assert "measured:CHANNEL" in mjsysid.SequenceResult.to_pandas.__doc__


def test_validation_starts_and_spread_are_attributes(pendulum, tmp_path):
    # the pendulum experiment fitted on seq0 and seq1 with seq2 held out, from 2 starts (seed 0)
    text = pendulum.read_text().replace("max_iterations: 50", "max_iterations: 50\n  starts: 2")
    pendulum.write_text(text + "sequences: [seq0, seq1]\nvalidation: [seq2]\n")
    mjsysid.simulate(str(pendulum))
    fit = mjsysid.fit_experiment(str(pendulum), out=str(tmp_path / "out"))
    d = fit.to_dict()
    assert [s.name for s in fit.sequences] == ["seq0", "seq1"]
    (held_out,) = fit.validation
    assert held_out.name == "seq2" and held_out.measured.shape == (2000, 2)
    (metrics,) = [m for m in d["fit_metrics"] if m["role"] == "validation"]
    assert metrics["sequence"] == "seq2"
    assert [c["fit_final"] for c in metrics["channels"]] == [
        f.fit_final for f in held_out.channel_fits]
    rate = held_out.to_pandas()["measured:rate"].to_numpy()
    assert rate.tolist() == held_out.measured[:, 1].tolist()
    # the starts as typed attributes, the same as result.yaml's `starts`
    assert len(fit.starts) == 2 and fit.best_start == d["starts"]["best"]
    for s, run in zip(fit.starts, d["starts"]["runs"]):
        assert s.start.tolist() == run["start"] and s.estimate.tolist() == run["estimate"]
        assert (s.status, s.iterations, s.final_cost) == (run["status"], run["iterations"],
                                                          run["final_cost"])
    assert [(p.name, p.min, p.max, p.relative) for p in fit.start_spread] == [
        (p["name"], p["min"], p["max"], p["relative"]) for p in d["starts"]["spread"]]
    assert fit.derived == [] and "derived" not in d
    back = mjsysid.read_result(str(tmp_path / "out"))
    assert [s.start.tolist() for s in back.starts] == [s.start.tolist() for s in fit.starts]
    assert back.validation[0].name == "seq2"
