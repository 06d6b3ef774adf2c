"""Shared fixtures of the vtkPreciseMarchingCubes tests.

Run with Debian's Python (the one VTK 9.1 is built for):

    PYTHONPATH=build/vtk/lib/python3/dist-packages /usr/bin/python3 -m pytest tests/vtk -q

or through tests/vtk/run.sh, which builds everything first. Without
PYTHONPATH the package is looked up in build/vtk (or $PRECISEMC_VTK_BUILD).
"""

import os
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _add_build_tree():
    try:
        import precisemc  # noqa: F401

        return
    except ImportError:
        pass
    build = pathlib.Path(os.environ.get("PRECISEMC_VTK_BUILD", ROOT / "build" / "vtk"))
    hint = build / "precisemc_pythonpath.txt"
    candidates = []
    if hint.exists():
        candidates.append(pathlib.Path(hint.read_text().strip()))
    candidates += sorted(build.glob("lib*/python3*/*-packages"))
    for path in candidates:
        if (path / "precisemc").is_dir():
            sys.path.insert(0, str(path))
            return


_add_build_tree()

import numpy as np  # noqa: E402
from vtkmodules.util.misc import calldata_type  # noqa: E402
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy  # noqa: E402
from vtkmodules.util.vtkConstants import VTK_STRING  # noqa: E402
from vtkmodules.vtkCommonCore import vtkCommand  # noqa: E402
from vtkmodules.vtkCommonDataModel import vtkImageData  # noqa: E402
from vtkmodules.vtkImagingCore import vtkRTAnalyticSource  # noqa: E402


class ErrorObserver:
    """Counts (and silences) ErrorEvents and WarningEvents of an object."""

    def __init__(self, obj):
        self.errors = []
        self.warnings = []
        obj.AddObserver(vtkCommand.ErrorEvent, self._error)
        obj.AddObserver(vtkCommand.WarningEvent, self._warning)

    @calldata_type(VTK_STRING)
    def _error(self, obj, event, message=None):
        self.errors.append(message)

    @calldata_type(VTK_STRING)
    def _warning(self, obj, event, message=None):
        self.warnings.append(message)


def image_from_array(values, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), extent_start=(0, 0, 0),
                     name="values"):
    """A vtkImageData holding `values` (indexed [k, j, i] or [k, j, i, c])."""
    values = np.ascontiguousarray(values)
    nz, ny, nx = values.shape[:3]
    comps = values.shape[3] if values.ndim == 4 else 1
    image = vtkImageData()
    e = extent_start
    image.SetExtent(e[0], e[0] + nx - 1, e[1], e[1] + ny - 1, e[2], e[2] + nz - 1)
    image.SetSpacing(*spacing)
    image.SetOrigin(*origin)
    array = numpy_to_vtk(values.reshape(-1, comps) if comps > 1 else values.ravel(), deep=1)
    array.SetName(name)
    image.GetPointData().SetScalars(array)
    return image


def wavelet(extent=10):
    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-extent, extent, -extent, extent, -extent, extent)
    source.Update()
    return source.GetOutput()


def points(polydata):
    if polydata.GetNumberOfPoints() == 0:
        return np.zeros((0, 3))
    return vtk_to_numpy(polydata.GetPoints().GetData()).astype(np.float64)


def triangles(polydata):
    if polydata.GetNumberOfPolys() == 0:
        return np.zeros((0, 3), dtype=np.int64)
    return vtk_to_numpy(polydata.GetPolys().GetConnectivityArray()).reshape(-1, 3).astype(np.int64)


def canonical(tris):
    """Rotate every triangle so its smallest id is first (winding kept), sorted."""
    tris = np.asarray(tris)
    if len(tris) == 0:
        return tris
    shift = np.argmin(tris, axis=1)
    rows = np.arange(len(tris))[:, None]
    rotated = tris[rows, (shift[:, None] + np.arange(3)[None, :]) % 3]
    order = np.lexsort(rotated.T[::-1])
    return rotated[order]


def match_points(ours, ref, tol):
    """Index in `ref` of each point of `ours` (same position within tol), or -1."""
    from vtkmodules.vtkCommonDataModel import vtkStaticPointLocator

    locator = vtkStaticPointLocator()
    locator.SetDataSet(ref)
    locator.BuildLocator()
    p = points(ours)
    q = points(ref)
    ids = np.full(len(p), -1, dtype=np.int64)
    for i, x in enumerate(p):
        j = locator.FindClosestPoint(x)
        if j >= 0 and np.linalg.norm(q[j] - x) <= tol:
            ids[i] = j
    return ids


def trilinear(values, index_points):
    """Trilinear interpolation of values[k, j, i] at continuous (i, j, k)."""
    nz, ny, nx = values.shape
    p = np.asarray(index_points, dtype=np.float64)
    c = np.clip(np.floor(p).astype(np.int64), 0, [nx - 2, ny - 2, nz - 2])
    r = p - c
    out = np.zeros(len(p))
    for corner in range(8):
        d = [(corner >> a) & 1 for a in range(3)]
        w = np.ones(len(p))
        for a in range(3):
            w *= r[:, a] if d[a] else 1.0 - r[:, a]
        out += w * values[c[:, 2] + d[2], c[:, 1] + d[1], c[:, 0] + d[0]]
    return out


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
