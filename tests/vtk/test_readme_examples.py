"""The Python examples of the READMEs run as written: each ```python block
that uses the VTK module (not ParaView's, which tests/paraview covers) runs
in a fresh interpreter and must exit 0 and print something. (cpp/README's
example once made its source inline, `vtkRTAnalyticSource().GetOutputPort()`:
the source is freed before Update, which crashed.)"""

import os
import re
import subprocess
import sys

import pytest

from conftest import ROOT

import precisemc


def _blocks():
    found = []
    for name in ("README.md", "cpp/README.md"):
        text = (ROOT / name).read_text()
        for m in re.finditer(r"^```python\n(.*?)^```", text, re.S | re.M):
            code = m.group(1)
            if "paraview" in code:
                continue
            line = text.count("\n", 0, m.start()) + 1
            found.append(pytest.param(code, id=f"{name}:{line}"))
    return found


BLOCKS = _blocks()


def test_there_are_examples_in_both_readmes():
    ids = [b.id for b in BLOCKS]
    assert any(i.startswith("README.md:") for i in ids), ids
    assert any(i.startswith("cpp/README.md:") for i in ids), ids


@pytest.mark.parametrize("code", BLOCKS)
def test_readme_example_runs(code, tmp_path):
    env = dict(os.environ)
    package = os.path.dirname(os.path.dirname(precisemc.__file__))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package, env.get("PYTHONPATH")) if p)
    r = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(tmp_path),
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"exit {r.returncode}\n{r.stdout}\n{r.stderr}"
    assert r.stdout.strip(), "printed nothing"
