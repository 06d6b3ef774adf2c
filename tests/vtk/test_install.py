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


def _build_consumer(tmp_path, name, package_args):
    """Configures, builds and runs tests/vtk_consumer; returns its output."""
    binary = tmp_path / name
    subprocess.run(["cmake", "-S", str(ROOT / "tests" / "vtk_consumer"), "-B", str(binary)]
                   + package_args, check=True, capture_output=True, text=True)
    subprocess.run(["cmake", "--build", str(binary)], check=True, capture_output=True,
                   text=True)
    run = subprocess.run([str(binary / "vtk_consumer")], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    return run.stdout


@pytest.mark.skipif(_build_dir() is None or shutil.which("cmake") is None,
                    reason="no configured build/vtk")
def test_cpp_consumers_find_the_package_installed_and_in_the_build_tree(tmp_path):
    """find_package(PreciseMCVTK 0.2) and PreciseMC::FiltersPrecise work from
    an install prefix and from the build tree (whose package file once
    looked for the module's targets beside itself, where they were not)."""
    build = _build_dir()
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", str(build), "--prefix", str(prefix)], check=True,
                   stdout=subprocess.DEVNULL)
    installed = _build_consumer(tmp_path, "installed", [f"-DCMAKE_PREFIX_PATH={prefix}"])
    packages = list(build.glob("lib*/cmake/PreciseMCVTK"))
    assert len(packages) == 1, packages
    in_tree = _build_consumer(tmp_path, "tree", [f"-DPreciseMCVTK_DIR={packages[0]}"])
    assert installed == in_tree and "triangles" in installed
