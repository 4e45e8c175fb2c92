"""docs/python.md "Gradients through physics" runs as it stands: each ```python block of the
section, in order, in a fresh namespace, with the repository root as the working directory (the
examples open models/pendulum.xml); the two examples must also reach what their text says."""

import re

import pytest

from conftest import ROOT


def blocks():
    doc = (ROOT / "docs/python.md").read_text()
    section = re.search(r"^## Gradients through physics\n(.*?)(?=^## |\Z)", doc, re.S | re.M)
    assert section, "docs/python.md has no section 'Gradients through physics'"
    return re.findall(r"^```python\n(.*?)^```$", section.group(1), flags=re.S | re.M)


def test_the_section_has_its_examples():
    assert len(blocks()) == 3  # the API tour, the control sequence, the damping fit


@pytest.mark.parametrize("index", range(3))
def test_block_runs(index, monkeypatch):
    code = blocks()[index]
    for module in sorted(set(re.findall(r"^import (torch|jax)\b", code, re.M))):
        pytest.importorskip(module)
    monkeypatch.chdir(ROOT)
    namespace = {"__name__": f"docs_gradients_{index}"}
    exec(compile(code, f"docs/python.md (Gradients through physics, block {index})", "exec"),
         namespace)
    if "Adam" in code:
        # "from rest to 1 rad in 0.5 s and stopped there": within 0.01 rad and 0.05 rad/s (it
        # ends 1e-3 rad and 1e-3 rad/s away)
        angle, rate = namespace["states"][-1].tolist()
        assert abs(angle - 1.0) < 0.01 and abs(rate) < 0.05, (angle, rate)
    if "LBFGS" in code:
        # 2000 samples of 1 mrad noise pin the damping to ~1e-4 relative; 1 % is a sure margin
        assert namespace["module"].params.item() == pytest.approx(0.08, rel=1e-2)
