"""Shared fixtures of the Python tests (tools/run_tests.sh runs them after the C++ tests).

The tests import the installed `mjsysid` package (pip install . into the project .venv) and run
the command line `sysid` of the C++ build (MJSYSID_SYSID, default build/default/bin/sysid) where
they compare the two. Every test writes into its own temporary folder.
"""

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root():
    return ROOT


@pytest.fixture(scope="session")
def sysid():
    """The command line of the C++ build; a missing one fails the tests that need it."""
    path = pathlib.Path(os.environ.get("MJSYSID_SYSID", ROOT / "build/default/bin/sysid"))
    if not path.is_file():
        pytest.fail(f"{path}: no sysid binary (build it: cmake --build --preset default "
                    "--target sysid, or set MJSYSID_SYSID)")
    return str(path)


def copy_experiment(name, tmp_path, data_name=None):
    """experiments/NAME.yaml copied into tmp_path with its model path made absolute and its
    `data:` log (and so its outputs) in tmp_path; the rest of the file unchanged."""
    text = (ROOT / "experiments" / f"{name}.yaml").read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith("model: "):
            model = (ROOT / "experiments" / line.split(": ", 1)[1]).resolve()
            line = f"model: {model}"
        elif line.startswith("data: "):
            line = f"data: {tmp_path / (data_name or name + '.h5')}"
        lines.append(line)
    path = tmp_path / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def pendulum(tmp_path):
    """experiments/pendulum.yaml in tmp_path (its log at tmp_path/pendulum.h5, not written)."""
    return copy_experiment("pendulum", tmp_path)
