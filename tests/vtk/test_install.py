"""The module installs with `cmake --install` and imports from the install
tree without the build tree (the Rust core is linked into the module)."""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT


def _build_dir():
    build = pathlib.Path(os.environ.get("PRECISEMC_VTK_BUILD", ROOT / "build" / "vtk"))
    return build if (build / "CMakeCache.txt").exists() else None


@pytest.mark.skipif(_build_dir() is None or shutil.which("cmake") is None,
                    reason="no configured build/vtk")
def test_install_and_import(tmp_path):
    build = _build_dir()
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(build), "--prefix", str(prefix)], check=True,
                   stdout=subprocess.DEVNULL)
    hint = (build / "precisemc_pythonpath.txt").read_text().strip()
    relative = pathlib.Path(hint).relative_to(build)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LD_LIBRARY_PATH")}
    env["PYTHONPATH"] = str(prefix / relative)
    code = ("import precisemc, sys\n"
            "from precisemc import vtkPreciseMarchingCubes\n"
            "from vtkmodules.vtkImagingCore import vtkRTAnalyticSource\n"
            "s = vtkRTAnalyticSource()\n"
            "f = vtkPreciseMarchingCubes(); f.SetInputConnection(s.GetOutputPort())\n"
            "f.SetValue(0, 150.0); f.Update()\n"
            "assert f.GetOutput().GetNumberOfPolys() > 0\n"
            "print(precisemc.__file__)\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(tmp_path), check=True,
                         capture_output=True, text=True).stdout
    assert str(prefix) in out
    assert (prefix / "lib" / "cmake" / "PreciseMCVTK" / "PreciseMCVTKConfig.cmake").exists() or \
        list(prefix.glob("lib*/cmake/PreciseMCVTK/PreciseMCVTKConfig.cmake"))
    # Both licence texts, as the files of the source tree.
    for name in ("LICENSE-MIT", "LICENSE-APACHE"):
        installed = prefix / "share" / "licenses" / "PreciseMCVTK" / name
        assert installed.read_bytes() == (ROOT / name).read_bytes(), name
