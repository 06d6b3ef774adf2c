"""vtkPreciseMarchingCubes from Python: wrapping, equality with
vtkMarchingCubes, geometry handling, attributes, pipeline and errors."""

import math

import numpy as np
import pytest
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkCommand
from vtkmodules.vtkCommonDataModel import vtkPolyData
from vtkmodules.vtkCommonMath import vtkMatrix3x3
from vtkmodules.vtkFiltersCore import vtkMarchingCubes, vtkProbeFilter

from conftest import (ErrorObserver, canonical, image_from_array, match_points, points,
                      triangles, trilinear, wavelet)

from precisemc import vtkPreciseMarchingCubes


def precise(image, values, **props):
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    for i, v in enumerate(values):
        f.SetValue(i, v)
    f.SetOutputPointsPrecision(1)  # double
    for name, value in props.items():
        getattr(f, "Set" + name)(value)
    f.Update()
    return f


def observed_run(image, precision=None):
    """The filter run at 150.0 on `image` (output points of `precision`, if
    given) and the ErrorObserver that watched it."""
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 150.0)
    if precision is not None:
        f.SetOutputPointsPrecision(precision)
    errors = ErrorObserver(f)
    f.Update()
    return f, errors


def marching_cubes(image, values):
    mc = vtkMarchingCubes()
    mc.SetInputData(image)
    for i, v in enumerate(values):
        mc.SetValue(i, v)
    mc.ComputeNormalsOn()
    mc.Update()
    return mc.GetOutput()


def assert_same_surface(ours, ref, tol=1e-5, normals=True):
    assert ours.GetNumberOfPoints() == ref.GetNumberOfPoints()
    assert ours.GetNumberOfPolys() == ref.GetNumberOfPolys()
    ids = match_points(ours, ref, tol)
    assert (ids >= 0).all()
    assert len(np.unique(ids)) == len(ids)
    assert np.array_equal(canonical(ids[triangles(ours)]), canonical(triangles(ref)))
    if normals:
        na = vtk_to_numpy(ours.GetPointData().GetNormals())
        nb = vtk_to_numpy(ref.GetPointData().GetNormals())[ids]
        assert np.abs(na - nb).max() < 2e-5
    return ids


def test_defaults_and_wrapping():
    f = vtkPreciseMarchingCubes()
    assert f.GetClassName() == "vtkPreciseMarchingCubes"
    assert f.GetEpsilon() == 0.01
    assert f.GetMaxLevel() == 5
    assert f.GetRule() == vtkPreciseMarchingCubes.RULE_A1
    assert f.GetTopology() == vtkPreciseMarchingCubes.TOPOLOGY_TRILINEAR
    assert f.GetNormalMode() == vtkPreciseMarchingCubes.NORMALS_GRADIENT
    assert f.GetComputeNormals() == 1 and f.GetComputeScalars() == 1
    assert f.GetInterpolateAttributes() == 0 and f.GetComputeLevels() == 0
    assert f.GetMaxTriangles() == 0 and f.GetNumberOfThreads() == 0
    assert f.GetNumberOfContours() == 1 and f.GetValue(0) == 0.0
    f.SetMaxLevel(99)
    assert f.GetMaxLevel() == 10
    f.GenerateValues(3, 0.0, 2.0)
    assert [f.GetValue(i) for i in range(f.GetNumberOfContours())] == [0.0, 1.0, 2.0]
    assert "Epsilon" in str(f)


@pytest.mark.parametrize("dtype", [np.int8, np.uint8, np.int16, np.uint16, np.int32, np.uint32,
                                   np.int64, np.uint64, np.float32, np.float64])
def test_classic_equals_marching_cubes_every_type(dtype, rng):
    if np.issubdtype(dtype, np.integer):
        info = np.iinfo(dtype)
        lo, hi = max(info.min, -100), min(info.max, 100)
        values = rng.integers(lo, hi, size=(11, 12, 13), endpoint=True).astype(dtype)
        iso = (lo + hi) / 2 + 0.5
    else:
        values = rng.random((11, 12, 13)).astype(dtype)
        iso = 0.4
    image = image_from_array(values)
    f = precise(image, [iso], Topology=1, Epsilon=0.0, NormalMode=2)
    ref = marching_cubes(image, [iso])
    assert ref.GetNumberOfPolys() > 100
    assert_same_surface(f.GetOutput(), ref)
    scalars = f.GetOutput().GetPointData().GetScalars()
    assert scalars.GetName() == "values"
    assert scalars.GetDataType() == image.GetPointData().GetScalars().GetDataType()
    assert np.all(vtk_to_numpy(scalars) == np.array(iso).astype(dtype))


def test_classic_equals_marching_cubes_wavelet_several_values():
    image = wavelet(12)
    values = [90.0, 150.0, 210.0]
    f = precise(image, values, Topology=1, Epsilon=0.0, NormalMode=2)
    ref = marching_cubes(image, values)
    ids = assert_same_surface(f.GetOutput(), ref)
    ours = vtk_to_numpy(f.GetOutput().GetPointData().GetScalars())
    theirs = vtk_to_numpy(ref.GetPointData().GetScalars())[ids]
    assert np.array_equal(ours.astype(np.float32), theirs)


def test_multiple_values_are_appended():
    image = wavelet(10)
    values = [100.0, 160.0, 230.0]
    both = precise(image, values)
    singles = [precise(image, [v]) for v in values]
    assert both.GetOutput().GetNumberOfPoints() == sum(s.GetOutput().GetNumberOfPoints() for s in singles)
    assert both.GetOutput().GetNumberOfPolys() == sum(s.GetOutput().GetNumberOfPolys() for s in singles)
    assert both.GetNumberOfRefinedTriangles() == sum(s.GetNumberOfRefinedTriangles() for s in singles)
    assert both.GetNumberOfMCTriangles() == sum(s.GetNumberOfMCTriangles() for s in singles)
    assert both.GetMaxLevelReached() == max(s.GetMaxLevelReached() for s in singles)
    expected = np.concatenate([points(s.GetOutput()) for s in singles])
    assert np.array_equal(points(both.GetOutput()), expected)
    scalars = vtk_to_numpy(both.GetOutput().GetPointData().GetScalars())
    counts = [s.GetOutput().GetNumberOfPoints() for s in singles]
    assert np.array_equal(scalars, np.repeat(values, counts).astype(np.float32))


def test_extent_not_at_zero(rng):
    values = rng.random((9, 10, 11))
    spacing = (0.5, 0.75, 1.25)
    origin = (1.0, -2.0, 3.0)
    start = (4, -6, 100)
    at_zero = precise(image_from_array(values, spacing, origin), [0.5])
    moved = precise(image_from_array(values, spacing, origin, start), [0.5])
    p0, p1 = points(at_zero.GetOutput()), points(moved.GetOutput())
    assert len(p0) > 100 and p0.shape == p1.shape
    assert np.array_equal(triangles(at_zero.GetOutput()), triangles(moved.GetOutput()))
    # The same data at extent start `start` is shifted by start * spacing.
    assert np.abs(p1 - (p0 + np.array(start) * spacing)).max() < 1e-9
    n0 = vtk_to_numpy(at_zero.GetOutput().GetPointData().GetNormals())
    n1 = vtk_to_numpy(moved.GetOutput().GetPointData().GetNormals())
    # Normals are evaluated at the global index point, whose last bits
    # depend on the extent start (100 + t keeps fewer bits of t than t
    # alone): a component can round to the neighbouring float32.
    assert np.abs(n0 - n1).max() <= 4 * np.finfo(np.float32).eps
    assert np.mean(n0 == n1) > 0.99


def rotation(axis, angle):
    axis = np.asarray(axis, dtype=float)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


@pytest.mark.parametrize("mirror", [False, True])
def test_direction_matrix(rng, mirror):
    values = rng.random((10, 9, 8))
    spacing = (0.5, 1.0, 2.0)
    origin = (3.0, -1.0, 2.0)
    plain = precise(image_from_array(values, spacing, origin), [0.5])
    image = image_from_array(values, spacing, origin)
    d = rotation((1, 2, 3), 0.7)
    if mirror:
        d = d @ np.diag([1.0, -1.0, 1.0])
    m = vtkMatrix3x3()
    for r in range(3):
        for c in range(3):
            m.SetElement(r, c, d[r, c])
    image.SetDirectionMatrix(m)
    rotated = precise(image, [0.5])
    p0, p1 = points(plain.GetOutput()), points(rotated.GetOutput())
    assert p0.shape == p1.shape and len(p0) > 100
    expected = np.array(origin) + (p0 - np.array(origin)) @ d.T
    assert np.abs(p1 - expected).max() < 1e-9
    n0 = vtk_to_numpy(plain.GetOutput().GetPointData().GetNormals()).astype(float)
    n1 = vtk_to_numpy(rotated.GetOutput().GetPointData().GetNormals()).astype(float)
    assert np.abs(n1 - n0 @ d.T).max() < 1e-5
    t0, t1 = triangles(plain.GetOutput()), triangles(rotated.GetOutput())
    if mirror:
        t0 = t0[:, [0, 2, 1]]
    assert np.array_equal(t0, t1)
    # Triangle winding agrees with the point normals (towards lower values)
    # as much after the transform as before (random data: not everywhere).
    fractions = []
    for pts, tris, nrm in ((p0, triangles(plain.GetOutput()), n0), (p1, t1, n1)):
        a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
        face = np.cross(b - a, c - a)
        fractions.append((np.einsum("ij,ij->i", face, nrm[tris].mean(axis=1)) > 0).mean())
    assert fractions[0] > 0.85
    assert abs(fractions[0] - fractions[1]) < 0.005


def test_interpolate_attributes_matches_probe_filter():
    image = wavelet(8)
    pd = image.GetPointData()
    n = image.GetNumberOfPoints()
    coords = np.array([image.GetPoint(i) for i in range(n)])
    from vtkmodules.util.numpy_support import numpy_to_vtk

    vec = numpy_to_vtk(np.sin(coords * 0.3).astype(np.float64), deep=1)
    vec.SetName("vectors")
    pd.AddArray(vec)
    other = numpy_to_vtk((coords[:, 0] ** 2 + coords[:, 1] * coords[:, 2]).astype(np.float32), deep=1)
    other.SetName("other")
    pd.AddArray(other)

    f = precise(image, [150.0], InterpolateAttributes=True)
    out = f.GetOutput()
    assert f.GetNumberOfSplitPoints() > 0  # refined points are interpolated too
    probe = vtkProbeFilter()
    probe.SetInputData(out)
    probe.SetSourceData(image)
    probe.Update()
    probed = probe.GetOutput().GetPointData()
    assert vtk_to_numpy(probe.GetOutput().GetPointData().GetArray("vtkValidPointMask")).all()
    for name in ("vectors", "other"):
        ours = vtk_to_numpy(out.GetPointData().GetArray(name)).astype(float)
        ref = vtk_to_numpy(probed.GetArray(name)).astype(float)
        assert ours.shape == ref.shape
        assert np.abs(ours - ref).max() <= 1e-5 * max(1.0, np.abs(ref).max())
    # The contoured array is replaced by the contour value.
    scalars = out.GetPointData().GetScalars()
    assert scalars.GetName() == "RTData"
    assert np.all(vtk_to_numpy(scalars) == 150.0)


@pytest.mark.parametrize("normals", [True, False])
def test_interpolated_input_normals_are_kept_beside_the_computed_ones(normals):
    # The input's active normals are interpolated like any other array;
    # the filter's own normals, when computed, become the active ones
    # without dropping them (SetNormals did), as vtkFlyingEdges3D does.
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

    image = wavelet(6)
    n = image.GetNumberOfPoints()
    input_normals = numpy_to_vtk(np.tile([0.0, 0.0, 1.0], (n, 1)), deep=1)
    input_normals.SetName("inNormals")
    image.GetPointData().SetNormals(input_normals)
    out = precise(image, [150.0], InterpolateAttributes=True, ComputeNormals=normals).GetOutput()
    pd = out.GetPointData()
    names = {pd.GetArrayName(a) for a in range(pd.GetNumberOfArrays())}
    assert "inNormals" in names
    assert np.allclose(vtk_to_numpy(pd.GetArray("inNormals")), [0.0, 0.0, 1.0])
    fe = vtkFlyingEdges3D()
    fe.SetInputData(image)
    fe.SetValue(0, 150.0)
    fe.SetComputeNormals(normals)
    fe.SetInterpolateAttributes(True)
    fe.Update()
    fe_pd = fe.GetOutput().GetPointData()
    assert names == {fe_pd.GetArrayName(a) for a in range(fe_pd.GetNumberOfArrays())}
    if normals:
        assert pd.GetNormals().GetName() == "Normals"
        assert out.GetPointData().GetNormals().GetNumberOfTuples() == out.GetNumberOfPoints()


@pytest.mark.parametrize("side", ["max", "min"])
def test_extents_at_the_ends_of_int(side):
    # An extent reaching INT_MAX (or INT_MIN): the ghost samples asked for
    # around it were computed in int and overflowed, and the default run
    # (normals on) failed with a misleading error about the scalars.
    values = np.fromfunction(lambda k, j, i: np.sqrt((i - 5.5) ** 2 + (j - 5.5) ** 2 +
                                                     (k - 5.5) ** 2), (12, 12, 12))
    start = 2**31 - 12 if side == "max" else -(2**31)
    image = image_from_array(values, extent_start=(start, 0, 0))
    reference = precise(image_from_array(values), [4.0]).GetOutput()
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 4.0)
    errors = ErrorObserver(f)
    f.Update()
    assert not errors.errors and not errors.warnings, (errors.errors, errors.warnings)
    out = f.GetOutput()
    assert out.GetNumberOfCells() == reference.GetNumberOfCells() > 0
    assert out.GetPointData().GetNormals().GetNumberOfTuples() == out.GetNumberOfPoints()


@pytest.mark.parametrize("epsilon", [0.0, 0.01])
def test_interpolated_attributes_take_only_the_corners_that_count(epsilon):
    # f = x on a 6 x 7 x 5 grid, contoured at 2.5: every point lies on an x
    # edge, halfway. The other array is NaN on the sample plane y = 4 and
    # 10 + y elsewhere: a point on the plane y = 3 (or 5) takes nothing from
    # it, so only points strictly between y = 3 and y = 5 may be NaN.
    k, j, i = np.meshgrid(np.arange(5.0), np.arange(7.0), np.arange(6.0), indexing="ij")
    image = image_from_array(i)
    from vtkmodules.util.numpy_support import numpy_to_vtk

    aux = np.where(j == 4.0, np.nan, 10.0 + j)
    array = numpy_to_vtk(aux.ravel(), deep=1)
    array.SetName("aux")
    image.GetPointData().AddArray(array)
    out = precise(image, [2.5], Epsilon=epsilon, InterpolateAttributes=True).GetOutput()
    assert out.GetNumberOfPoints() > 0
    y = points(out)[:, 1]
    values = vtk_to_numpy(out.GetPointData().GetArray("aux"))
    away = (y <= 3.0) | (y >= 5.0)
    assert np.isfinite(values[away]).all()
    assert np.allclose(values[away], 10.0 + y[away], rtol=0, atol=1e-12)
    assert np.isnan(values[~away]).all()


def test_refined_vertices_on_trilinear_surface(rng):
    values = rng.random((10, 11, 12))
    f = precise(image_from_array(values), [0.5], ComputeLevels=True)
    plain = precise(image_from_array(values), [0.5], Epsilon=0.0)
    out = f.GetOutput()
    levels = vtk_to_numpy(out.GetCellData().GetArray("RefinementLevel"))
    assert levels.max() == f.GetMaxLevelReached() > 0
    assert abs(levels.mean() - f.GetMeanLevel()) < 1e-9
    ids = match_points(out, plain.GetOutput(), 1e-12)
    refined = points(out)[ids < 0]
    assert len(refined) > 1000
    assert np.abs(trilinear(values, refined) - 0.5).max() < 1e-9


def test_threads_do_not_change_the_output():
    image = wavelet(10)
    one = precise(image, [160.0], NumberOfThreads=1, Epsilon=0.001)
    two = precise(image, [160.0], NumberOfThreads=2, Epsilon=0.001)
    assert np.array_equal(points(one.GetOutput()), points(two.GetOutput()))
    assert np.array_equal(triangles(one.GetOutput()), triangles(two.GetOutput()))


@pytest.mark.parametrize("precision", [0, 1])
def test_parallel_copy_into_polydata_matches_one_thread(precision):
    # Outputs of 65 536 points and more are copied into vtkPolyData through
    # vtkSMPTools (STDThread here) unless NumberOfThreads is 1: the copy must
    # not change a bit, in float and double points, with the refinement
    # levels and normals.
    from vtkmodules.vtkCommonCore import vtkSMPTools
    previous = vtkSMPTools.GetBackend()
    vtkSMPTools.SetBackend("STDThread")
    try:
        image = wavelet(32)
        runs = [precise(image, [160.0], NumberOfThreads=t, Epsilon=0.0005, ComputeLevels=True,
                        OutputPointsPrecision=precision).GetOutput() for t in (1, 0)]
        one, many = runs
        assert one.GetNumberOfPoints() >= 65536
        assert np.array_equal(points(one), points(many))
        assert np.array_equal(triangles(one), triangles(many))
        for name in ("RefinementLevel",):
            a = vtk_to_numpy(one.GetCellData().GetArray(name))
            b = vtk_to_numpy(many.GetCellData().GetArray(name))
            assert np.array_equal(a, b)
        assert np.array_equal(vtk_to_numpy(one.GetPointData().GetNormals()),
                              vtk_to_numpy(many.GetPointData().GetNormals()))
    finally:
        vtkSMPTools.SetBackend(previous)


def test_pipeline_reexecution():
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    f.Update()
    f.Update()
    assert f.GetNumberOfExecutions() == 1
    f.SetEpsilon(0.01)  # unchanged
    f.Update()
    assert f.GetNumberOfExecutions() == 1
    f.SetTopologyToClassic()
    f.Update()
    assert f.GetNumberOfExecutions() == 2
    f.GenerateValues(2, 100.0, 200.0)
    f.Update()
    assert f.GetNumberOfExecutions() == 3


def test_abort_from_progress_observer():
    image = wavelet(16)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 150.0)
    f.SetEpsilon(0.0005)
    errors = ErrorObserver(f)
    seen = []

    def on_progress(obj, event):
        seen.append(obj.GetProgress())
        if obj.GetProgress() > 0.0:
            obj.SetAbortExecute(1)

    tag = f.AddObserver(vtkCommand.ProgressEvent, on_progress)
    f.Update()
    assert seen
    assert f.GetOutput().GetNumberOfPoints() == 0 and f.GetOutput().GetNumberOfPolys() == 0
    assert not errors.errors
    f.RemoveObserver(tag)
    f.SetAbortExecute(0)
    f.Modified()
    f.Update()
    assert f.GetOutput().GetNumberOfPolys() > 0


@pytest.mark.parametrize("threads", [1, 2])
def test_progress_runs_from_0_to_1_over_every_contour_value(threads):
    """ProgressEvent values over three contour values: 0 first, 1 last,
    never decreasing, within [0, 1], and reported during each value's run
    (the aborts above stop at the first event and would pass with progress
    reported only at the end, or beyond 1)."""
    image = wavelet(16)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    for i, v in enumerate((120.0, 150.0, 200.0)):
        f.SetValue(i, v)
    f.SetEpsilon(0.0005)
    f.SetNumberOfThreads(threads)
    seen = []
    f.AddObserver(vtkCommand.ProgressEvent, lambda obj, event: seen.append(obj.GetProgress()))
    f.Update()
    assert f.GetOutput().GetNumberOfPolys() > 0
    assert seen[0] == 0.0 and seen[-1] == 1.0, seen
    assert all(0.0 <= p <= 1.0 for p in seen), seen
    assert all(a <= b for a, b in zip(seen, seen[1:])), seen
    # Reported inside each third of the run, not only at its ends.
    for third in range(3):
        assert any(third / 3 < p < (third + 1) / 3 for p in seen), (third, seen)


def test_abort_with_smp_tools_on_the_stdthread_backend():
    # STDThread runs none of a For's range on the calling thread, where
    # the library reports progress: the filter's executor makes the caller
    # take tasks too, so progress events come during the run and an abort
    # at the first one (not at 1.0, the end) leaves the output empty.
    from vtkmodules.vtkCommonCore import vtkSMPTools
    previous = vtkSMPTools.GetBackend()
    vtkSMPTools.SetBackend("STDThread")
    vtkSMPTools.Initialize(2)
    try:
        image = wavelet(24)
        f = vtkPreciseMarchingCubes()
        f.SetInputData(image)
        f.SetValue(0, 150.0)
        f.SetEpsilon(0.0005)
        f.SetUseSMPTools(True)
        errors = ErrorObserver(f)
        seen = []

        def on_progress(obj, event):
            seen.append(obj.GetProgress())
            if 0.0 < obj.GetProgress() < 1.0:
                obj.SetAbortExecute(1)

        tag = f.AddObserver(vtkCommand.ProgressEvent, on_progress)
        f.Update()
        # The slabs' step ends at 0.9 of the progress (then the assembly):
        # the first event comes before, from a task of the calling thread.
        first = [p for p in seen if 0.0 < p < 1.0]
        assert first and first[0] < 0.9, seen
        assert f.GetOutput().GetNumberOfPolys() == 0
        assert not errors.errors
        assert f.GetNumberOfRefinedTriangles() == 0
        # Without the abort, the same run on the same backend is whole and
        # equal to the library's own threads'.
        f.RemoveObserver(tag)
        f.SetAbortExecute(0)
        f.Modified()
        f.Update()
        own = precise(image, [150.0], Epsilon=0.0005)
        f.SetOutputPointsPrecision(1)
        f.Update()
        assert f.GetOutput().GetNumberOfPolys() > 1000
        assert np.array_equal(points(f.GetOutput()), points(own.GetOutput()))
        assert np.array_equal(triangles(f.GetOutput()), triangles(own.GetOutput()))
    finally:
        vtkSMPTools.SetBackend(previous)


def refused(image, value, fragment):
    """A filter run on `image` that must end in an error naming `fragment`
    and an empty output; returns the filter."""
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, value)
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and fragment in errors.errors[-1], errors.errors
    assert f.GetOutput().GetNumberOfPoints() == 0 and f.GetOutput().GetNumberOfPolys() == 0
    return f


def test_singular_direction_is_refused_before_any_work():
    image = wavelet(8)
    image.SetDirectionMatrix(1, 0, 0, 1, 0, 0, 0, 0, 1)
    f = refused(image, 150.0, "singular")
    assert f.GetNumberOfExecutions() == 0
    assert f.GetNumberOfMCTriangles() == 0 and f.GetNumberOfRefinedTriangles() == 0
    # A NaN or infinite entry is named as such (it was called singular).
    for bad in (math.nan, math.inf):
        image = wavelet(8)
        image.SetDirectionMatrix(1, 0, 0, 0, 1, bad, 0, 0, 1)
        f = refused(image, 150.0, "NaN or infinite entry")
        assert f.GetNumberOfExecutions() == 0
    # A scaled matrix is invertible, but its determinant under- or
    # overflows: said so (it was called singular, nothing more).
    for scale in (1e-300, 1e300):
        image = wavelet(8)
        image.SetDirectionMatrix(scale, 0, 0, 0, scale, 0, 0, 0, scale)
        refused(image, 150.0, "determinant under- or overflows")


@pytest.mark.parametrize("direction, spacing", [
    ((1, 0, 0, 0, 1, 0, 0, 0, 1), (1e307, 1e307, 1e307)),
    ((0, 1, 0, 1, 0, 0, 0, 0, 1), (1e307, 1e307, 1e307)),
    ((1, 0, 0, 0, 1, 0, 0, 0, 1), (1e307, 1e307, -1e307)),
])
def test_world_coordinates_that_overflow_are_refused(direction, spacing):
    # Axis-aligned, the library refuses the grid; with a direction matrix
    # or a negative spacing the filter maps the points itself, and used to
    # output points at infinity without a word.
    image = wavelet(8)  # extent -8..8
    image.SetOrigin(1.75e308, 0.0, 0.0)
    image.SetSpacing(*spacing)
    image.SetDirectionMatrix(*direction)
    f = refused(image, 150.0, "not finite")
    assert f.GetNumberOfMCTriangles() == 0
    # The same geometry one step back from overflowing is contoured, finite.
    image.SetOrigin(1e308, 0.0, 0.0)
    image.SetSpacing(*(s / 1e3 for s in spacing))
    g = vtkPreciseMarchingCubes()
    g.SetInputData(image)
    g.SetValue(0, 150.0)
    g.SetOutputPointsPrecision(1)
    g.Update()
    assert g.GetOutput().GetNumberOfPolys() > 100
    assert np.isfinite(points(g.GetOutput())).all()


def test_coordinates_beyond_float_give_double_points_or_an_error():
    # Float points would be infinite at 1e39: the default precision gives
    # double points there, single precision is refused, as asked.
    image = wavelet(8)
    image.SetOrigin(1e39, 0.0, 0.0)
    for direction in ((1, 0, 0, 0, 1, 0, 0, 0, 1), (0, 1, 0, 1, 0, 0, 0, 0, 1)):
        image.SetDirectionMatrix(*direction)
        g = precise(image, [150.0], OutputPointsPrecision=2)  # DEFAULT_PRECISION
        out = g.GetOutput()
        assert out.GetNumberOfPolys() > 100
        assert out.GetPoints().GetDataType() == 11  # VTK_DOUBLE
        assert np.isfinite(points(out)).all()
        f, errors = observed_run(image, 0)  # SINGLE_PRECISION
        assert errors.errors and "single precision" in errors.errors[-1], errors.errors
        assert f.GetOutput().GetNumberOfPoints() == 0
    # Within float's range, with cells float can tell apart, the default
    # stays float.
    image.SetOrigin(1e30, 0.0, 0.0)
    image.SetSpacing(1e25, 1e25, 1e25)
    default = precise(image, [150.0], OutputPointsPrecision=2).GetOutput()
    assert default.GetPoints().GetDataType() == 10  # VTK_FLOAT


def test_cells_float_cannot_tell_apart_give_double_points_or_a_warning():
    # A cell side below float's least normal number (all points were one
    # float, (0, 0, 0)), or too few float steps across a cell at the
    # largest coordinate for refinement's finest level (origin 1e7, unit
    # spacing: 1 float step is 1, a level-5 point 1/32 cell apart): the
    # default gives double points, the same surface as at a plain scale;
    # single precision warns and gives float.
    reference = precise(wavelet(10), [150.0]).GetOutput()
    want = points(reference)
    assert reference.GetNumberOfPolys() > 100
    for origin, spacing in (((0.0, 0.0, 0.0), 1e-200), ((1e7, -3e6, 0.0), 1.0)):
        image = wavelet(10)
        image.SetOrigin(*origin)
        image.SetSpacing(spacing, spacing, spacing)
        for direction in ((1, 0, 0, 0, 1, 0, 0, 0, 1), (0, 1, 0, 1, 0, 0, 0, 0, 1)):
            image.SetDirectionMatrix(*direction)
            g = precise(image, [150.0], OutputPointsPrecision=2)  # DEFAULT_PRECISION
            out = g.GetOutput()
            assert out.GetPoints().GetDataType() == 11, (origin, spacing)  # VTK_DOUBLE
            got = (points(out) - np.array(origin)) / spacing
            got = got[:, [1, 0, 2]] if direction[1] else got
            assert out.GetNumberOfPolys() == reference.GetNumberOfPolys()
            # Each output point at its place in the plain-scale surface.
            assert np.allclose(np.sort(got, axis=0), np.sort(want, axis=0), atol=1e-6)
            f, errors = observed_run(image, 0)  # SINGLE_PRECISION
            assert not errors.errors, errors.errors
            assert errors.warnings and "cannot tell" in errors.warnings[-1], errors.warnings
            assert f.GetOutput().GetPoints().GetDataType() == 10  # VTK_FLOAT
    # An everyday volume: float, no warning.
    image = wavelet(10)
    image.SetOrigin(-120.0, 35.5, 1000.0)
    image.SetSpacing(0.3, 0.3, 1.25)
    f, errors = observed_run(image)
    assert not errors.errors and not errors.warnings
    assert f.GetOutput().GetPoints().GetDataType() == 10  # VTK_FLOAT


def test_coordinates_too_large_for_double_points_are_warned_about():
    # An origin of 1e17 with unit spacing: a double's step there is 16
    # cells, so the surface's points fell onto a few x values, without a
    # word (the command-line tool refuses such a volume as it reads it).
    # Now a warning, whatever the points' precision and the frame.
    for direction in ((1, 0, 0, 0, 1, 0, 0, 0, 1), (0, 1, 0, 1, 0, 0, 0, 0, 1)):
        for precision in (0, 1, 2):
            image = wavelet(8)
            image.SetOrigin(1e17, 0.0, 0.0)
            image.SetDirectionMatrix(*direction)
            f, errors = observed_run(image, precision)
            assert not errors.errors, errors.errors
            assert f.GetOutput().GetNumberOfPolys() > 100
            assert errors.warnings, (direction, precision)
            assert "too large for its spacing" in errors.warnings[-1], errors.warnings
    # Large coordinates with a spacing to match, and large coordinates on
    # another axis than the fine one, are not warned about.
    for origin, spacing in (((1e17, 0.0, 0.0), (1e6, 1e6, 1e6)),
                            ((1e12, 0.0, 0.0), (1.0, 1.0, 1.0)),
                            ((1e17, 0.0, 0.0), (1e6, 1.0, 1.0))):
        image = wavelet(8)
        image.SetOrigin(*origin)
        image.SetSpacing(*spacing)
        f, errors = observed_run(image, 1)
        assert not errors.errors and not errors.warnings, (origin, spacing, errors.warnings)
        assert f.GetOutput().GetNumberOfPolys() > 100


def test_thread_count_is_clamped_to_the_library_limit():
    f = vtkPreciseMarchingCubes()
    warned = ErrorObserver(f)
    f.SetNumberOfThreads(100000)
    assert f.GetNumberOfThreads() == 4096
    assert said(warned.warnings) == ["NumberOfThreads 100000 is outside 0..4096: using 4096"]
    f.SetInputData(wavelet(8))
    f.SetValue(0, 150.0)
    errors = ErrorObserver(f)
    f.Update()
    assert not errors.errors, errors.errors
    assert f.GetOutput().GetNumberOfPolys() > 100


def said(messages):
    """The text of VTK messages, without "Warning: In file, line n" and the object."""
    return [m.split("): ", 1)[1].strip() for m in messages]


# Each setting with a range: (name, lowest, highest, default).
RANGED_SETTINGS = [
    ("MaxLevel", 0, 10, 5),
    ("Rule", 0, 3, 1),
    ("ReconstructionFilter", 0, 3, 0),
    ("Topology", 0, 1, 0),
    ("NormalMode", 1, 2, 1),
    ("NumberOfThreads", 0, 4096, 0),
    ("OutputPointsPrecision", 0, 2, 2),
]


@pytest.mark.parametrize("name,lo,hi,default", RANGED_SETTINGS)
def test_a_setting_out_of_its_range_is_clamped_with_a_warning(name, lo, hi, default):
    # The C API and the command-line tool refuse such values; the filter
    # clamps them as vtkSetClampMacro does, but says so (it was silent: a
    # MaxLevel of 11 ran at 10, and ParaView's property kept showing 11).
    f = vtkPreciseMarchingCubes()
    warned = ErrorObserver(f)
    get, set_ = getattr(f, "Get" + name), getattr(f, "Set" + name)
    assert get() == default
    assert (getattr(f, f"Get{name}MinValue")(), getattr(f, f"Get{name}MaxValue")()) == (lo, hi)
    for value in range(lo, hi + 1) if hi - lo < 20 else (lo, lo + 1, hi - 1, hi):
        set_(value)
        assert get() == value
    assert not warned.warnings and not warned.errors
    mtime = f.GetMTime()
    set_(hi + 1)
    assert get() == hi and f.GetMTime() == mtime  # unchanged: not modified
    set_(lo)
    set_(lo - 5)
    assert get() == lo
    set_(2**31 - 1)
    assert get() == hi and f.GetMTime() > mtime
    assert said(warned.warnings) == [
        f"{name} {hi + 1} is outside {lo}..{hi}: using {hi}",
        f"{name} {lo - 5} is outside {lo}..{hi}: using {lo}",
        f"{name} {2**31 - 1} is outside {lo}..{hi}: using {hi}",
    ]
    assert not warned.errors


def test_max_triangles_on_a_piece_warns_of_cracks():
    # Each piece meets the cap on its own: one stopping at a lower level
    # than its neighbour does not meet it along the cut, which the filter
    # says. The whole volume in one piece under the same cap does not warn.
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 16)
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 130.0)
    f.SetEpsilon(0.001)
    f.SetMaxTriangles(8000)
    errors = ErrorObserver(f)
    f.UpdatePiece(0, 1, 0)
    assert f.GetBudgetReached() and not errors.warnings
    warned = []
    for piece in range(2):
        f.UpdatePiece(piece, 2, 0)
        if f.GetBudgetReached():
            warned.append(piece)
    assert warned, "no piece reached the cap"
    assert len(errors.warnings) == len(warned)
    assert "may not meet along their cuts" in errors.warnings[-1]
    assert not errors.errors


def _blanked_wavelet(rng):
    from vtkmodules.vtkCommonDataModel import vtkDataSetAttributes, vtkUniformGrid

    grid = vtkUniformGrid()
    grid.DeepCopy(wavelet(8))
    blocks = rng.random((4, 4, 4)) < 0.5  # hidden 4x4x4 blocks of cells
    hide = np.kron(blocks, np.ones((4, 4, 4), dtype=bool)).ravel()
    flags = np.where(hide, vtkDataSetAttributes.HIDDENCELL, 0).astype(np.uint8)
    ghosts = numpy_to_vtk(flags, deep=1, array_type=3)  # VTK_UNSIGNED_CHAR
    ghosts.SetName("vtkGhostType")
    grid.GetCellData().AddArray(ghosts)
    return grid


@pytest.mark.parametrize("case", ["hidden cells", "pieces"])
def test_max_triangles_counts_the_triangles_kept(case, rng):
    """MaxTriangles caps the output: the triangles of hidden cells and of a
    piece's ghost layer, contoured and dropped, do not count. A cap equal
    to the output at some level gives exactly that level's output (before,
    a cap the uncapped output fitted lowered a blanked grid to plain
    Marching Cubes, and pieces by one or two levels), never more triangles
    than the cap, and BudgetReached only when the level was lowered."""
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    if case == "hidden cells":
        grid = _blanked_wavelet(rng)
        runs = [(None, grid)]
    else:
        source = vtkRTAnalyticSource()
        source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
        runs = [(piece, source) for piece in range(4)]
    for piece, data in runs:
        def run(**settings):
            f = vtkPreciseMarchingCubes()
            if piece is None:
                f.SetInputData(data)
            else:
                f.SetInputConnection(data.GetOutputPort())
            f.SetValue(0, 150.0)
            f.SetEpsilon(0.002)
            for name, value in settings.items():
                getattr(f, "Set" + name)(value)
            errors = ErrorObserver(f)
            if piece is None:
                f.Update()
            else:
                f.UpdatePiece(piece, 4, 0)
            assert not errors.errors
            return f, coordinate_triangles(f.GetOutput())

        at_level = [run(MaxLevel=level) for level in range(6)]
        counts = [len(tris) for _, tris in at_level]
        assert counts[0] < counts[-1], counts
        tried = 0
        for level in range(6):
            for cap in (counts[level], counts[level] + 1):
                f, tris = run(MaxLevel=5, MaxTriangles=cap)
                fits = max(l for l in range(6) if counts[l] <= cap)
                assert len(tris) <= cap
                assert np.array_equal(tris, at_level[fits][1]), (piece, level, cap, fits)
                assert f.GetBudgetReached() == (counts[fits] < counts[-1])
                tried += counts[fits] < counts[-1]
        assert tried > 0


def test_error_no_scalars():
    from vtkmodules.vtkCommonDataModel import vtkImageData

    image = vtkImageData()
    image.SetDimensions(4, 4, 4)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and "No scalars" in errors.errors[-1]
    assert f.GetOutput().GetNumberOfPoints() == 0


def test_error_names_a_missing_chosen_array(rng):
    # An array chosen by a name the input lacks (ParaView's Contour By of
    # another dataset): the message names it and the arrays there are.
    image = image_from_array(rng.random((5, 6, 7)))
    image.GetPointData().GetScalars().SetName("RTData")
    # A point ghost array (a piece's) is the pipeline's: not listed.
    ghosts = numpy_to_vtk(np.zeros(5 * 6 * 7, dtype=np.uint8), deep=1, array_type=3)
    ghosts.SetName("vtkGhostType")
    image.GetPointData().AddArray(ghosts)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 0.5)
    f.SetInputArrayToProcess(0, 0, 0, 0, "pressure")  # points, by name
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and (
        "No point array named 'pressure' to contour (the input's point arrays: RTData)"
        in errors.errors[-1]
    )
    assert f.GetOutput().GetNumberOfPoints() == 0


def test_error_says_a_selection_of_cell_or_field_data_is_not_contoured(rng):
    # A selection among the cells' (or the field's) arrays that finds none
    # there: the message says only point data is contoured, not that a
    # point array it lists is missing.
    from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkDataSetAttributes

    image = image_from_array(rng.random((5, 6, 7)))
    image.GetPointData().GetScalars().SetName("RTData")
    for association, what in (
        (vtkDataObject.FIELD_ASSOCIATION_CELLS, "RTData"),
        (vtkDataObject.FIELD_ASSOCIATION_NONE, "RTData"),
        (vtkDataObject.FIELD_ASSOCIATION_CELLS, vtkDataSetAttributes.SCALARS),
    ):
        f = vtkPreciseMarchingCubes()
        f.SetInputData(image)
        f.SetValue(0, 0.5)
        f.SetInputArrayToProcess(0, 0, 0, association, what)
        errors = ErrorObserver(f)
        f.Update()
        assert errors.errors, (association, what)
        assert "only point data can be contoured" in errors.errors[-1], errors.errors[-1]
        assert "No point array named" not in errors.errors[-1]
        assert f.GetOutput().GetNumberOfPoints() == 0
    # Selected among the points, the same array contours.
    f.SetInputArrayToProcess(0, 0, 0, vtkDataObject.FIELD_ASSOCIATION_POINTS, "RTData")
    errors = ErrorObserver(f)
    f.Update()
    assert not errors.errors and f.GetOutput().GetNumberOfPoints() > 0


def test_error_extent_whose_point_count_overflows():
    # Extents of more points than vtkIdType counts (read as negative) or
    # one axis longer than an int (read as 0 points): an error, not an
    # empty output with nothing said.
    from vtkmodules.vtkCommonDataModel import vtkImageData

    for extent in ((0, 2097152, 0, 2097152, 0, 2097152), (-2**31, 2**31 - 1, 0, 3, 0, 3)):
        image = vtkImageData()
        image.SetExtent(*extent)
        a = numpy_to_vtk(np.linspace(0.0, 1.0, 8), deep=1)
        a.SetName("s")
        image.GetPointData().SetScalars(a)
        f = vtkPreciseMarchingCubes()
        f.SetInputData(image)
        f.SetValue(0, 0.5)
        errors = ErrorObserver(f)
        f.Update()
        assert errors.errors and "more than vtkImageData can count" in errors.errors[-1], extent
        assert f.GetOutput().GetNumberOfPoints() == 0


def test_error_bad_array_component(rng):
    image = image_from_array(rng.random((5, 6, 7, 2)))
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 0.5)
    f.SetArrayComponent(2)
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and "ArrayComponent" in errors.errors[-1]
    assert f.GetOutput().GetNumberOfPoints() == 0
    # Component 1 of 2 is read in place and equals the extracted component.
    f.SetArrayComponent(1)
    f.Update()
    single = precise(image_from_array(np.ascontiguousarray(
        vtk_to_numpy(image.GetPointData().GetScalars())[:, 1].reshape(5, 6, 7))), [0.5],
        OutputPointsPrecision=0)
    assert np.array_equal(points(f.GetOutput()), points(single.GetOutput()))


def test_error_nan_epsilon():
    f = vtkPreciseMarchingCubes()
    f.SetInputData(wavelet(5))
    f.SetValue(0, 150.0)
    f.SetEpsilon(float("nan"))
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and "psilon" in errors.errors[-1]
    assert f.GetOutput().GetNumberOfPoints() == 0


def test_wrong_input_type():
    f = vtkPreciseMarchingCubes()
    f.SetInputData(vtkPolyData())
    errors = ErrorObserver(f)
    executive_errors = ErrorObserver(f.GetExecutive())
    f.Update()
    assert errors.errors or executive_errors.errors


def test_points_precision():
    image = wavelet(6)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 150.0)
    f.Update()
    assert f.GetOutput().GetPoints().GetDataType() == 10  # VTK_FLOAT
    f.SetOutputPointsPrecision(1)
    f.Update()
    assert f.GetOutput().GetPoints().GetDataType() == 11  # VTK_DOUBLE


def test_negative_spacing_matches_marching_cubes_with_consistent_winding(rng):
    # VTK allows negative spacing (a mirrored grid). The points and normals
    # equal vtkMarchingCubes's; the winding is reversed on purpose so that
    # (p1 - p0) x (p2 - p0) still points towards lower values, whereas
    # vtkMarchingCubes mirrors the points without re-orienting triangles.
    values = rng.random((9, 10, 11))
    image = image_from_array(values, spacing=(1.0, -1.0, 1.0), origin=(0.5, 2.0, -1.0))
    f = precise(image, [0.5], Topology=1, Epsilon=0.0, NormalMode=2)
    ref = marching_cubes(image, [0.5])
    ours = f.GetOutput()
    ids = match_points(ours, ref, 1e-5)
    assert (ids >= 0).all() and len(np.unique(ids)) == len(ids)
    flipped = ids[triangles(ours)][:, [0, 2, 1]]
    assert np.array_equal(canonical(flipped), canonical(triangles(ref)))
    na = vtk_to_numpy(ours.GetPointData().GetNormals())
    nb = vtk_to_numpy(ref.GetPointData().GetNormals())[ids]
    assert np.abs(na - nb).max() < 2e-5


def test_runs_again_after_abort_without_manual_reset():
    image = wavelet(12)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 150.0)

    def on_progress(obj, event):
        if obj.GetProgress() > 0.0:
            obj.SetAbortExecute(1)

    tag = f.AddObserver(vtkCommand.ProgressEvent, on_progress)
    f.Update()
    assert f.GetOutput().GetNumberOfPolys() == 0
    f.RemoveObserver(tag)
    f.Modified()
    f.Update()
    assert f.GetOutput().GetNumberOfPolys() > 0


# --- Reconstruction filters ------------------------------------------------

RECONSTRUCTIONS = {
    "Trilinear": vtkPreciseMarchingCubes.RECONSTRUCTION_TRILINEAR,
    "CatmullRom": vtkPreciseMarchingCubes.RECONSTRUCTION_CATMULL_ROM,
    "BSpline": vtkPreciseMarchingCubes.RECONSTRUCTION_BSPLINE,
    "BSplineInterpolating": vtkPreciseMarchingCubes.RECONSTRUCTION_BSPLINE_INTERPOLATING,
}
CUBIC = ["CatmullRom", "BSpline", "BSplineInterpolating"]


def test_reconstruction_filter_property():
    f = vtkPreciseMarchingCubes()
    assert f.GetReconstructionFilter() == vtkPreciseMarchingCubes.RECONSTRUCTION_TRILINEAR == 0
    assert f.GetReconstructionFilterAsString() == "Trilinear"
    assert sorted(RECONSTRUCTIONS.values()) == [0, 1, 2, 3]
    for name, value in RECONSTRUCTIONS.items():
        f.SetReconstructionFilterToTrilinear()
        getattr(f, "SetReconstructionFilterTo" + name)()
        assert f.GetReconstructionFilter() == value
        assert f.GetReconstructionFilterAsString() == name
        assert f"ReconstructionFilter: {name}" in str(f)
        f.SetReconstructionFilter(0)
        f.SetReconstructionFilter(value)
        assert f.GetReconstructionFilterAsString() == name
    # Out of range values are clamped, with a warning, and a set marks the
    # filter modified.
    warned = ErrorObserver(f)
    f.SetReconstructionFilter(-7)
    assert f.GetReconstructionFilter() == 0
    assert said(warned.warnings) == ["ReconstructionFilter -7 is outside 0..3: using 0"]
    mtime = f.GetMTime()
    f.SetReconstructionFilter(99)
    assert f.GetReconstructionFilter() == 3
    assert f.GetMTime() > mtime


# Independent evaluation of the reconstruction filters (public formulas):
# tensor products of 1-D cubic kernels over the 4x4x4 samples around a
# cell, the border sample repeated at the volume's border.
def catmull_rom_weights(t):
    return np.stack([0.5 * (-t + 2 * t**2 - t**3), 0.5 * (2 - 5 * t**2 + 3 * t**3),
                     0.5 * (t + 4 * t**2 - 3 * t**3), 0.5 * (t**3 - t**2)], axis=-1)


def bspline_weights(t):
    return np.stack([(1 - t)**3 / 6, (4 - 6 * t**2 + 3 * t**3) / 6,
                     (1 + 3 * t + 3 * t**2 - 3 * t**3) / 6, t**3 / 6], axis=-1)


def tricubic(coefficients, index_points, weights):
    """sum_abc w(x)_a w(y)_b w(z)_c c[k+c-1, j+b-1, i+a-1] at continuous (i, j, k)."""
    nz, ny, nx = coefficients.shape
    p = np.asarray(index_points, dtype=np.float64)
    n = np.array([nx, ny, nz])
    cell = np.clip(np.floor(p).astype(np.int64), 0, n - 2)
    w = [weights(p[:, a] - cell[:, a]) for a in range(3)]
    out = np.zeros(len(p))
    for dz in range(4):
        z = np.clip(cell[:, 2] + dz - 1, 0, nz - 1)
        for dy in range(4):
            y = np.clip(cell[:, 1] + dy - 1, 0, ny - 1)
            for dx in range(4):
                x = np.clip(cell[:, 0] + dx - 1, 0, nx - 1)
                out += w[0][:, dx] * w[1][:, dy] * w[2][:, dz] * coefficients[z, y, x]
    return out


def bspline_coefficients(values):
    """Coefficients whose cubic B-spline passes through the samples: along each
    axis, (c[k-1] + 4 c[k] + c[k+1]) / 6 = s[k] with c[-1] = c[0], c[n] = c[n-1]
    (the repeated border), solved densely."""
    c = np.asarray(values, dtype=np.float64)
    for axis in range(3):
        n = c.shape[axis]
        m = np.zeros((n, n))
        for k in range(n):
            m[k, k] += 4.0
            m[k, max(k - 1, 0)] += 1.0
            m[k, min(k + 1, n - 1)] += 1.0
        m /= 6.0
        moved = np.moveaxis(c, axis, 0)
        c = np.moveaxis(np.linalg.solve(m, moved.reshape(n, -1)).reshape(moved.shape), 0, axis)
    return c


def reconstruct(name, values, index_points):
    if name == "Trilinear":
        return trilinear(values, index_points)
    if name == "CatmullRom":
        return tricubic(values, index_points, catmull_rom_weights)
    if name == "BSpline":
        return tricubic(values, index_points, bspline_weights)
    return tricubic(bspline_coefficients(values), index_points, bspline_weights)


def test_reference_filters_interpolate():
    # The evaluator above: Catmull-Rom and the prefiltered B-spline pass
    # through the samples, the plain B-spline does not.
    values = np.random.default_rng(3).random((6, 7, 8))
    grid = np.stack(np.meshgrid(np.arange(8), np.arange(7), np.arange(6), indexing="ij"), -1)
    grid = grid.reshape(-1, 3).astype(np.float64)
    samples = values[grid[:, 2].astype(int), grid[:, 1].astype(int), grid[:, 0].astype(int)]
    for name in ["Trilinear", "CatmullRom", "BSplineInterpolating"]:
        assert np.abs(reconstruct(name, values, grid) - samples).max() < 1e-12, name
    assert np.abs(reconstruct("BSpline", values, grid) - samples).max() > 0.05


def blobs(n=18, seed=7):
    """Overlapping Gaussian blobs inside a zero border: a closed isosurface at
    0.5 whose cubic and trilinear reconstructions differ."""
    rng = np.random.default_rng(seed)
    k, j, i = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    values = np.zeros((n, n, n))
    for _ in range(6):
        c = rng.uniform(5, n - 6, 3)
        r = rng.uniform(1.5, 2.5)
        values += np.exp(-((i - c[0])**2 + (j - c[1])**2 + (k - c[2])**2) / (2 * r * r))
    values[:2] = values[-2:] = 0
    values[:, :2] = values[:, -2:] = 0
    values[:, :, :2] = values[:, :, -2:] = 0
    return values


def assert_watertight(poly):
    """Every directed edge is used once and its reverse once."""
    tris = triangles(poly)
    assert len(tris) > 0
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    assert len(np.unique(edges, axis=0)) == len(edges), "an edge is used twice in one direction"
    forward = {tuple(e) for e in edges}
    assert all((b, a) in forward for a, b in edges), "an edge has no opposite triangle"


@pytest.mark.parametrize("name", CUBIC)
def test_cubic_filter_refines_onto_its_isosurface(name):
    values = blobs()
    image = image_from_array(values)
    iso = 0.5
    f = precise(image, [iso], ReconstructionFilter=RECONSTRUCTIONS[name], Epsilon=0.002,
                ComputeLevels=True)
    out = f.GetOutput()
    assert f.GetReconstructionFilterAsString() == name
    assert_watertight(out)
    assert f.GetMaxLevelReached() > 0 and f.GetNumberOfSplitPoints() > 0

    # With refinement off the surface is plain Marching Cubes whatever the
    # filter (the trilinear decision).
    plain = precise(image, [iso], Epsilon=0.0)
    cubic_plain = precise(image, [iso], Epsilon=0.0, ReconstructionFilter=RECONSTRUCTIONS[name])
    assert np.array_equal(points(plain.GetOutput()), points(cubic_plain.GetOutput()))
    assert np.array_equal(triangles(plain.GetOutput()), triangles(cubic_plain.GetOutput()))

    # Refining, each Marching Cubes vertex first moves along its grid edge
    # onto the filter's isosurface (always found by the interpolating
    # filters; the smoothing B-spline may not bracket one on the edge).
    pts = points(out)
    on_line = (pts == np.round(pts)).sum(axis=1) >= 2
    assert on_line.sum() == len(points(plain.GetOutput()))
    edge_error = np.abs(reconstruct(name, values, pts[on_line]) - iso)
    if name != "BSpline":
        assert edge_error.max() < 1e-6
    assert (edge_error < 1e-6).mean() > 0.5

    # The split points lie on the chosen filter's isosurface, not on the
    # trilinear one (index coordinates = world coordinates here).
    refined = pts[~on_line]
    assert len(refined) > 100
    assert np.abs(reconstruct(name, values, refined) - iso).max() < 1e-6
    assert np.abs(trilinear(values, refined) - iso).max() > 1e-3
    others = [n for n in CUBIC if n != name]
    for other in others:
        assert np.abs(reconstruct(other, values, refined) - iso).max() > 1e-3, other

    # Different from the trilinear refinement.
    tri = precise(image, [iso], Epsilon=0.002)
    assert not np.array_equal(points(tri.GetOutput()), points(out))


def test_trilinear_is_the_default_and_unchanged():
    image = wavelet(10)
    default = precise(image, [160.0], Epsilon=0.005)
    explicit = precise(image, [160.0], Epsilon=0.005,
                       ReconstructionFilter=vtkPreciseMarchingCubes.RECONSTRUCTION_TRILINEAR)
    assert np.array_equal(points(default.GetOutput()), points(explicit.GetOutput()))
    assert np.array_equal(triangles(default.GetOutput()), triangles(explicit.GetOutput()))
    values = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(21, 21, 21)
    ids = match_points(default.GetOutput(), precise(image, [160.0], Epsilon=0.0).GetOutput(), 1e-12)
    refined = points(default.GetOutput())[ids < 0] + 10.0  # extent starts at -10
    assert len(refined) > 100
    assert np.abs(trilinear(values, refined) - 160.0).max() < 1e-9


def coordinate_triangles(poly):
    """Triangles as sorted rows of 9 coordinates, each rotated to start at its
    lexicographically smallest vertex (orientation kept)."""
    if poly.GetNumberOfPolys() == 0:
        return np.zeros((0, 9))
    return coordinate_rows(points(poly)[triangles(poly)])


def coordinate_rows(xyz):
    """coordinate_triangles() of triangles given by their corners (n, 3, 3)."""
    rows = []
    for tri in xyz:
        first = min(range(3), key=lambda v: tuple(tri[v]))
        rows.append(np.roll(tri, -first, axis=0).ravel())
    rows = np.array(rows)
    return rows[np.lexsort(rows.T[::-1])]


@pytest.mark.parametrize("name", list(RECONSTRUCTIONS))
def test_pieces_equal_the_serial_surface(name):
    from vtkmodules.vtkCommonExecutionModel import vtkExtentTranslator
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    f.SetValue(1, 200.0)
    f.SetEpsilon(0.01)
    f.SetOutputPointsPrecision(1)
    f.SetReconstructionFilter(RECONSTRUCTIONS[name])
    f.UpdatePiece(0, 1, 0)
    serial = coordinate_triangles(f.GetOutput())
    assert len(serial) > 1000
    for pieces in (2, 3):
        parts = []
        for piece in range(pieces):
            f.UpdatePiece(piece, pieces, 0)
            parts.append(coordinate_triangles(f.GetOutput()))
            assert len(parts[-1]) > 0
            # What the filter asked its input for: one ghost sample more
            # (trilinear, refined: a cell may be meshed again on sub-cells),
            # two (cubic), or the whole volume.
            ghosts = {"Trilinear": 1, "CatmullRom": 2, "BSpline": 2}.get(name)
            expected = [-8, 8, -8, 8, -8, 8]
            if ghosts is not None:
                vtkExtentTranslator().PieceToExtentThreadSafe(
                    piece, pieces, ghosts, [-8, 8, -8, 8, -8, 8], expected,
                    vtkExtentTranslator.BLOCK_MODE, 0)
            assert list(source.GetOutput().GetExtent()) == expected
        union = np.concatenate(parts)
        union = union[np.lexsort(union.T[::-1])]
        assert union.shape == serial.shape, f"{pieces} pieces"
        assert np.array_equal(union, serial), f"{pieces} pieces"


@pytest.mark.parametrize("stage", ["change-information", "translate-extent"])
@pytest.mark.parametrize("props", [{"Epsilon": 0.0}, {"Epsilon": 0.01, "MaxLevel": 5}])
def test_pieces_through_filters_that_pass_point_ghosts_only_equal_the_serial_surface(
        stage, props):
    """vtkImageChangeInformation and vtkImageTranslateExtent pass a piece on
    grown by the ghost levels asked for, with its point ghost array but not
    its cell ghost array. The filter took such a piece for a volume split
    its own way and contoured its ghost layer too (2 pieces: 200 of 1422
    triangles twice, without a warning); the point flags tell the piece's
    own cells."""
    from vtkmodules.vtkImagingCore import (vtkImageChangeInformation, vtkImageTranslateExtent,
                                           vtkRTAnalyticSource)

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
    if stage == "change-information":
        between = vtkImageChangeInformation()
        between.SetOriginTranslation(2.5, -1.0, 0.5)
    else:
        between = vtkImageTranslateExtent()
        between.SetTranslation(3, -2, 5)
    between.SetInputConnection(source.GetOutputPort())
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(between.GetOutputPort())
    f.SetValue(0, 150.0)
    f.SetValue(1, 200.0)
    f.SetOutputPointsPrecision(1)
    for name, value in props.items():
        getattr(f, "Set" + name)(value)
    observer = ErrorObserver(f)
    f.UpdatePiece(0, 1, 0)
    serial = coordinate_triangles(f.GetOutput())
    assert len(serial) > 1000
    for pieces in (2, 3, 4):
        parts = []
        for piece in range(pieces):
            f.UpdatePiece(piece, pieces, 0)
            parts.append(coordinate_triangles(f.GetOutput()))
            assert len(parts[-1]) > 0
            # The case covered: a piece grown by its ghost layer, with no
            # cell ghost array.
            data = between.GetOutput()
            assert data.GetCellData().GetArray("vtkGhostType") is None
            assert data.GetPointData().GetArray("vtkGhostType") is not None
            assert data.GetNumberOfPoints() > 17 * 17 * 17 / pieces
        union = np.concatenate(parts)
        union = union[np.lexsort(union.T[::-1])]
        assert union.shape == serial.shape, f"{pieces} pieces"
        assert np.array_equal(union, serial), f"{pieces} pieces"
    assert not observer.errors and not observer.warnings, observer.warnings


def rows_with_normals(poly):
    """coordinate_triangles() with each vertex's normal after its position."""
    if poly is None or poly.GetNumberOfPolys() == 0:
        return np.zeros((0, 18))
    normals = vtk_to_numpy(poly.GetPointData().GetNormals()).astype(np.float64)
    ids = triangles(poly)
    return coordinate_rows(np.concatenate([points(poly)[ids], normals[ids]], axis=2))


def grouped_wavelet():
    """A Wavelet source (17^3 samples) through a group filter (a composite
    input, as ParaView's Group Datasets makes) into the filter, contour
    value 150: the source and the filter."""
    from vtkmodules.vtkFiltersGeneral import vtkMultiBlockDataGroupFilter
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
    group = vtkMultiBlockDataGroupFilter()
    group.AddInputConnection(source.GetOutputPort())
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(group.GetOutputPort())
    f.SetValue(0, 150.0)
    return source, f


# Run in this order on the same pipelines: each asks the grouped source for
# a different ghost layer (a cubic run after a trilinear one lost half its
# triangles under MPI when the blocks' runs left their own request on the
# composite input, which the next update cut the source's piece from).
COMPOSITE_RUNS = [
    {"Epsilon": 0.0},
    {"Epsilon": 0.01, "MaxLevel": 5},
    {"Epsilon": 0.02, "MaxLevel": 3, "ReconstructionFilter": RECONSTRUCTIONS["CatmullRom"]},
    {"Epsilon": 0.01, "MaxLevel": 5,
     "NormalMode": vtkPreciseMarchingCubes.NORMALS_CENTRAL_DIFFERENCE},
    {"Epsilon": 0.02, "MaxLevel": 3, "ReconstructionFilter": RECONSTRUCTIONS["BSpline"]},
    {"Epsilon": 0.0, "ComputeNormals": 0},
]


@pytest.mark.parametrize("pieces", [2, 3])
def test_blocks_of_a_composite_input_in_pieces_equal_the_serial_surface(pieces):
    """A composite input (the Wavelet through a group filter, as ParaView's
    Group Datasets) asked for in pieces: each piece's block is its piece of
    the volume, which must come with the ghost layer the run needs (normals
    and gradients, refinement, the cubic filters), and its own cells only
    contoured. Until the fifty-second session no ghost level was asked for
    and the surfaces next to the cuts differed (Catmull-Rom on 2 pieces:
    49924 triangles where the serial run has 50824). Each piece has a
    pipeline of its own, as a process of a distributed run has, and the
    runs follow each other on it, changing the ghost layer asked for."""
    def pipeline():
        source, f = grouped_wavelet()
        f.SetValue(1, 200.0)
        f.SetOutputPointsPrecision(1)
        return source, f, ErrorObserver(f)

    serial = pipeline()
    ranks = [pipeline() for _ in range(pieces)]
    for props in COMPOSITE_RUNS:
        for _, f, _ in [serial] + ranks:
            f.SetComputeNormals(1)
            for name, value in props.items():
                getattr(f, "Set" + name)(value)
        rows = rows_with_normals if props.get("ComputeNormals", 1) else (
            lambda poly: coordinate_triangles(poly) if poly is not None else np.zeros((0, 9)))
        serial[1].UpdatePiece(0, 1, 0)
        expected = rows(serial[1].GetOutputDataObject(0).GetBlock(0))
        assert len(expected) > 4000, props
        parts = []
        for piece, (source, f, _) in enumerate(ranks):
            f.UpdatePiece(piece, pieces, 0)
            parts.append(rows(f.GetOutputDataObject(0).GetBlock(0)))
            assert 0 < len(parts[-1]) < len(expected), props
        union = np.concatenate(parts)
        union = union[np.lexsort(union.T[::-1])]
        assert union.shape == expected.shape, props
        assert np.array_equal(union, expected), props
        # Each block came with a ghost layer, marked.
        for source, _, _ in ranks:
            assert source.GetOutput().GetCellData().GetArray("vtkGhostType") is not None, props
    for _, _, observer in [serial] + ranks:
        assert not observer.errors and not observer.warnings, observer.warnings


def test_b_spline_interpolating_on_blocks_of_a_composite_input_in_pieces_warns():
    """Its prefilter couples whole lines of samples: a block that is a piece
    of the volume gives a surface that differs from the serial one, which a
    composite request cannot avoid (it cannot name the whole volume): said."""
    _, f = grouped_wavelet()
    f.SetReconstructionFilter(RECONSTRUCTIONS["BSplineInterpolating"])
    observer = ErrorObserver(f)
    f.UpdatePiece(0, 1, 0)
    assert not observer.warnings
    f.UpdatePiece(1, 2, 0)
    assert f.GetOutputDataObject(0).GetBlock(0).GetNumberOfPolys() > 0
    assert any("B-Spline Interpolating" in w and "2 pieces" in w for w in observer.warnings), \
        observer.warnings
    assert not observer.errors


@pytest.mark.parametrize("where", ["cell", "point"])
def test_ghost_arrays_that_do_not_fit_the_image_are_ignored_with_a_warning(where):
    """A ghost array whose length is not the number of cells (or points),
    as VTK 9.1's Extract Subset with a sample rate delivers under MPI, was
    ignored without a word (pieces lost triangles). It is still ignored,
    the surface is the one without it, and the filter says so."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkDataSetAttributes, vtkImageData

    image = wavelet(6)
    plain = coordinate_triangles(precise(image, [150.0], OutputPointsPrecision=1).GetOutput())
    flagged = vtkImageData()
    flagged.DeepCopy(image)
    flags = np.full(64, vtkDataSetAttributes.DUPLICATECELL | vtkDataSetAttributes.HIDDENCELL,
                    dtype=np.uint8)
    ghosts = numpy_to_vtk(flags, deep=1, array_type=3)  # VTK_UNSIGNED_CHAR
    ghosts.SetName("vtkGhostType")
    data = flagged.GetCellData() if where == "cell" else flagged.GetPointData()
    data.AddArray(ghosts)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(flagged)
    f.SetValue(0, 150.0)
    f.SetOutputPointsPrecision(1)
    observer = ErrorObserver(f)
    f.Update()
    assert not observer.errors
    assert len(observer.warnings) == 1, observer.warnings
    assert f"{where} ghost array holds 64 tuples" in observer.warnings[0]
    assert np.array_equal(coordinate_triangles(f.GetOutput()), plain)


@pytest.mark.parametrize("props", [
    {"Epsilon": 0.0, "Topology": 1},
    {"Epsilon": 0.0},
    {"Epsilon": 0.002, "MaxLevel": 5},
])
def test_hidden_cells_make_no_triangles(props, rng):
    """Cells the ghost array flags HIDDENCELL (AMR blanking: a finer block
    covers them) make no triangles, as vtkContourFilter skips them in a
    vtkUniformGrid, where the filter contoured them (overlapping surfaces
    in AMR data). The rest of the surface is unchanged: their samples still
    shape it. Duplicate-cell flags alone hide nothing."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkDataSetAttributes, vtkUniformGrid
    from vtkmodules.vtkFiltersCore import vtkContourFilter

    image = wavelet(8)
    full = precise(image, [150.0], **props)
    shape = (16, 16, 16)  # cells, [k, j, i]
    blocks = rng.random((4, 4, 4)) < 0.4  # hidden 4x4x4 blocks of cells
    hide = np.kron(blocks, np.ones((4, 4, 4), dtype=bool)).reshape(shape)
    for flag, dropped in ((vtkDataSetAttributes.HIDDENCELL, True),
                          (vtkDataSetAttributes.DUPLICATECELL, False)):
        grid = vtkUniformGrid()
        grid.DeepCopy(image)
        flags = np.where(hide, flag, 0).astype(np.uint8).ravel()
        ghosts = numpy_to_vtk(flags, deep=1, array_type=3)  # VTK_UNSIGNED_CHAR
        ghosts.SetName("vtkGhostType")
        grid.GetCellData().AddArray(ghosts)
        out = precise(grid, [150.0], **props).GetOutput()
        # The full surface's triangles whose cell (the floor of their
        # lowest vertex coordinates, index space) is not hidden.
        xyz = points(full.GetOutput())[triangles(full.GetOutput())]
        cell = np.minimum(np.floor(xyz.min(axis=1) + 8.0).astype(int), 15)  # extent from -8
        hidden = hide[cell[:, 2], cell[:, 1], cell[:, 0]]
        assert 0 < hidden.sum() < len(hidden)
        keep = ~hidden if dropped else np.ones(len(hidden), dtype=bool)
        assert np.array_equal(coordinate_triangles(out), coordinate_rows(xyz[keep]))
        if props.get("Topology") == 1 and dropped:
            contour = vtkContourFilter()
            contour.SetInputData(grid)
            contour.SetValue(0, 150.0)
            contour.Update()
            assert out.GetNumberOfPolys() == contour.GetOutput().GetNumberOfPolys()


@pytest.mark.parametrize("props", [
    {"Epsilon": 0.0, "Topology": 1},
    {"Epsilon": 0.0},
    {"Epsilon": 0.002, "MaxLevel": 5},
])
def test_hidden_points_hide_their_cells(props, rng):
    """A vtkUniformGrid blanked by points (HIDDENPOINT in the point ghost
    array) hides every cell with a hidden corner, as
    vtkUniformGrid::IsCellVisible() and vtkContourFilter have it; the filter
    read only the cell flags and contoured the whole blanked region. Cell
    flags still count beside the point flags."""
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkDataSetAttributes, vtkUniformGrid
    from vtkmodules.vtkFiltersCore import vtkContourFilter

    image = wavelet(8)
    full = precise(image, [150.0], **props)
    off = rng.random((17, 17, 17)) < 0.01  # hidden points, [k, j, i]
    off[:, :, 12:] = True  # and a slab of them
    cell_hidden = np.zeros((16, 16, 16), dtype=bool)
    for dk in (0, 1):
        for dj in (0, 1):
            for di in (0, 1):
                cell_hidden |= off[dk:dk + 16, dj:dj + 16, di:di + 16]
    by_cell = np.zeros((16, 16, 16), dtype=bool)
    by_cell[2:4, :, :] = True  # hidden by the cell flags
    grid = vtkUniformGrid()
    grid.DeepCopy(image)
    for data, hidden_flags, flag in ((grid.GetPointData(), off, vtkDataSetAttributes.HIDDENPOINT),
                                     (grid.GetCellData(), by_cell, vtkDataSetAttributes.HIDDENCELL)):
        ghosts = numpy_to_vtk(np.where(hidden_flags, flag, 0).astype(np.uint8).ravel(), deep=1,
                              array_type=3)  # VTK_UNSIGNED_CHAR
        ghosts.SetName("vtkGhostType")
        data.AddArray(ghosts)
    out = precise(grid, [150.0], **props).GetOutput()
    xyz = points(full.GetOutput())[triangles(full.GetOutput())]
    cell = np.minimum(np.floor(xyz.min(axis=1) + 8.0).astype(int), 15)  # extent from -8
    hide = (cell_hidden | by_cell)[cell[:, 2], cell[:, 1], cell[:, 0]]
    assert 0 < hide.sum() < len(hide)
    assert np.array_equal(coordinate_triangles(out), coordinate_rows(xyz[~hide]))
    if props.get("Topology") == 1:
        contour = vtkContourFilter()
        contour.SetInputData(grid)
        contour.SetValue(0, 150.0)
        contour.Update()
        assert out.GetNumberOfPolys() == contour.GetOutput().GetNumberOfPolys()


def test_pieces_choose_the_serial_points_precision():
    """With the default precision, points are double where float could not
    tell the refined points apart (far from the origin). The choice is the
    whole volume's on every piece: a piece nearer the origin took float
    points and no longer met its neighbour (a crack along the cut)."""
    from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
    from vtkmodules.vtkCommonDataModel import vtkDataObject, vtkImageData
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    class Moved(VTKPythonAlgorithmBase):
        """The input at another origin, its pieces' ghost cells kept marked
        (vtkImageChangeInformation passes on the point data only)."""

        def __init__(self, origin):
            super().__init__(nInputPorts=1, inputType="vtkImageData", nOutputPorts=1,
                             outputType="vtkImageData")
            self.origin = origin

        def RequestInformation(self, request, inInfo, outInfo):
            outInfo.GetInformationObject(0).Set(vtkDataObject.ORIGIN(), *self.origin)
            return 1

        def RequestData(self, request, inInfo, outInfo):
            out = vtkImageData.GetData(outInfo)
            out.ShallowCopy(vtkImageData.GetData(inInfo[0]))
            out.SetOrigin(*self.origin)
            return 1

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-16, 16, -4, 4, -4, 4)
    # x from 262124 to 262156: float steps are 2^-5 from 2^18 = 262144 on,
    # as fine as refinement at MaxLevel 5 splits a cell.
    moved = Moved((262140.0, 0.0, 0.0))
    moved.SetInputConnection(source.GetOutputPort())
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(moved.GetOutputPort())
    f.SetValue(0, 150.0)
    f.SetEpsilon(0.001)
    f.SetMaxLevel(5)
    assert f.GetOutputPointsPrecision() == 2  # DEFAULT_PRECISION
    f.UpdatePiece(0, 1, 0)
    assert f.GetOutput().GetPoints().GetPoint(0)[0] > 262000
    assert f.GetOutput().GetPoints().GetDataType() == 11  # VTK_DOUBLE
    serial = coordinate_triangles(f.GetOutput())
    assert len(serial) > 500
    parts = []
    for piece in range(2):
        f.UpdatePiece(piece, 2, 0)
        out = f.GetOutput()
        assert out.GetNumberOfPolys() > 0
        assert out.GetPoints().GetDataType() == 11, f"piece {piece}"  # VTK_DOUBLE
        parts.append(coordinate_triangles(out))
    union = np.concatenate(parts)
    union = union[np.lexsort(union.T[::-1])]
    assert np.array_equal(union, serial)


@pytest.mark.parametrize("props", [
    {"Epsilon": 0.0},
    {"Epsilon": 0.01, "Topology": 1},
    {"Epsilon": 0.01, "MaxLevel": 2},
])
def test_pieces_cut_through_samples_at_the_isovalue(props, rng):
    # Where a plane of samples equals the isovalue, the cells on both sides
    # of it emit the same flat triangles with opposite orientations, which
    # cancel: a volume whose inside is that plane alone has no surface. A
    # piece holding the cells on one side only keeps its copy unless it sees
    # the cells across the cut: without normals (which ask for a ghost level
    # anyway), two pieces cut along the plane gave a double-sided sheet that
    # the serial run has not.
    from vtkmodules.vtkCommonExecutionModel import vtkExtentTranslator
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    flat = np.zeros((3, 3, 5))
    flat[:, :, 2] = 1.0
    # Integer data where ties are everywhere, cut into 2 to 5 pieces.
    ties = rng.integers(0, 4, size=(7, 8, 9)).astype(np.float64)
    rt = vtkRTAnalyticSource()
    rt.SetWholeExtent(-6, 6, -6, 6, -6, 6)
    rt.Update()
    wavelet_ties = vtk_to_numpy(rt.GetOutput().GetPointData().GetScalars()).reshape(13, 13, 13)
    wavelet_ties = np.round(wavelet_ties / 20.0)
    cases = [(flat, 1.0, (2,)), (ties, 2.0, (2, 3, 4, 5)), (wavelet_ties, 8.0, (2, 3, 4))]
    for values, iso, counts in cases:
        image = image_from_array(values)
        assert (values == iso).any()

        def run(piece, pieces):
            f = vtkPreciseMarchingCubes()
            f.SetInputData(image)
            f.SetValue(0, iso)
            f.SetComputeNormals(0)
            f.SetOutputPointsPrecision(1)
            for name, v in props.items():
                getattr(f, "Set" + name)(v)
            observer = ErrorObserver(f)
            f.UpdatePiece(piece, pieces, 0)
            assert not observer.errors and not observer.warnings
            return coordinate_triangles(f.GetOutput())

        serial = run(0, 1)
        if values is flat:
            assert len(serial) == 0
            extent = [0] * 6
            vtkExtentTranslator().PieceToExtentThreadSafe(
                0, 2, 0, [0, 4, 0, 2, 0, 2], extent, vtkExtentTranslator.BLOCK_MODE, 0)
            assert extent[1] == 2  # the cut is the plane at the isovalue
        for pieces in counts:
            union = np.concatenate([run(piece, pieces) for piece in range(pieces)])
            union = union[np.lexsort(union.T[::-1])]
            assert union.shape == serial.shape and np.array_equal(union, serial), \
                f"{values.shape}, {pieces} pieces: {len(union)} triangles, serial {len(serial)}"


@pytest.mark.parametrize("source", ["SetInputData", "vtkRTAnalyticSource"])
@pytest.mark.parametrize("props", [{}, {"Epsilon": 0.0, "ComputeNormals": 0}])
def test_pieces_without_cells_are_empty_without_an_error(source, props, rng):
    # vtkExtentTranslator cuts a volume two cells wide along every axis into
    # 3 (5, 9) pieces of which some are a single layer of samples: valid
    # pieces of a 3D volume that hold no cell. Such a piece has no surface;
    # it is not a 2D input, so no error, and the pieces still make up the
    # serial surface.
    from vtkmodules.vtkCommonExecutionModel import vtkExtentTranslator
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    whole = [0, 2, -1, 1, 4, 6]
    if source == "SetInputData":
        image = image_from_array(rng.random((3, 3, 3)), extent_start=(0, -1, 4))
        value = 0.5

        def connect(f):
            f.SetInputData(image)
    else:
        rt = vtkRTAnalyticSource()
        rt.SetWholeExtent(*whole)
        rt.Update()
        value = float(np.mean(rt.GetOutput().GetPointData().GetScalars().GetRange()))

        def connect(f):
            f.SetInputConnection(rt.GetOutputPort())

    def run(piece, pieces):
        f = vtkPreciseMarchingCubes()
        connect(f)
        f.SetValue(0, value)
        f.SetOutputPointsPrecision(1)
        for name, v in props.items():
            getattr(f, "Set" + name)(v)
        observer = ErrorObserver(f)
        f.UpdatePiece(piece, pieces, 0)
        return f.GetOutput(), observer

    serial, observer = run(0, 1)
    assert serial.GetNumberOfPolys() > 0 and not observer.errors
    serial = coordinate_triangles(serial)
    for pieces in (3, 5, 9):
        flat = 0
        parts = []
        for piece in range(pieces):
            extent = [0] * 6
            if vtkExtentTranslator().PieceToExtentThreadSafe(
                    piece, pieces, 0, whole, extent, vtkExtentTranslator.BLOCK_MODE, 0):
                flat += any(extent[2 * a] == extent[2 * a + 1] for a in range(3))
            out, observer = run(piece, pieces)
            assert not observer.errors, f"piece {piece} of {pieces}: {observer.errors}"
            parts.append(coordinate_triangles(out))
        assert flat > 0, "the translator no longer makes pieces without cells here"
        union = np.concatenate(parts)
        union = union[np.lexsort(union.T[::-1])]
        assert union.shape == serial.shape and np.array_equal(union, serial), f"{pieces} pieces"


def no_information_source(image):
    """An algorithm that delivers `image` (a copy) but sets no WHOLE_EXTENT
    in RequestInformation, as ParaView's Programmable Source without its
    information script: the pipeline reports the empty whole extent
    (0, -1, 0, -1, 0, -1)."""
    from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
    from vtkmodules.vtkCommonDataModel import vtkImageData

    class NoInformation(VTKPythonAlgorithmBase):
        def __init__(self):
            super().__init__(nInputPorts=0, nOutputPorts=1, outputType="vtkImageData")

        def RequestData(self, request, inInfo, outInfo):
            vtkImageData.GetData(outInfo).DeepCopy(image)
            return 1

    return NoInformation()


@pytest.mark.parametrize("props", [{"Topology": 1, "Epsilon": 0.0, "NormalMode": 2},
                                   {"Epsilon": 0.01}])
def test_a_source_without_a_whole_extent_is_contoured(props):
    # The filter took the empty whole extent for the piece to contour and
    # gave an empty surface without a word (vtkMarchingCubes and
    # vtkFlyingEdges3D contour the same volume given with SetInputData).
    # The volume delivered is contoured; asked for in pieces, each cuts its
    # own from it, so that the pieces make up the serial surface once.
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline
    from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

    image = wavelet(8)
    source = no_information_source(image)
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    f.SetOutputPointsPrecision(1)
    for name, value in props.items():
        getattr(f, "Set" + name)(value)
    observer = ErrorObserver(f)
    f.Update()
    whole = source.GetOutputInformation(0).Get(vtkStreamingDemandDrivenPipeline.WHOLE_EXTENT())
    assert tuple(whole) == (0, -1, 0, -1, 0, -1)
    assert not observer.errors and not observer.warnings
    direct = precise(image, [150.0], **props)
    assert direct.GetOutput().GetNumberOfPolys() > 500
    assert_same_surface(f.GetOutput(), direct.GetOutput(), tol=0.0, normals=False)
    if props.get("Epsilon") == 0.0:
        assert_same_surface(f.GetOutput(), marching_cubes(image, [150.0]))
        fe = vtkFlyingEdges3D()
        fe.SetInputData(image)
        fe.SetValue(0, 150.0)
        fe.Update()
        assert f.GetOutput().GetNumberOfPolys() == fe.GetOutput().GetNumberOfPolys()
    serial = coordinate_triangles(f.GetOutput())
    for pieces in (2, 3):
        union = np.concatenate([coordinate_triangles(f.GetOutput())
                                for piece in range(pieces) if f.UpdatePiece(piece, pieces, 0)])
        union = union[np.lexsort(union.T[::-1])]
        assert union.shape == serial.shape and np.array_equal(union, serial), f"{pieces} pieces"
    # Each piece says what it did (test_pieces_without_a_whole_extent_warn).
    assert not observer.errors and len(observer.warnings) == 5
    assert all("reports no whole extent" in w for w in observer.warnings)


def piece_asked(info, image):
    """The extent of the piece an output information asks for, without ghost
    levels, as vtkExtentTranslator cuts `image` in block mode."""
    from vtkmodules.vtkCommonExecutionModel import (vtkExtentTranslator,
                                                    vtkStreamingDemandDrivenPipeline as sddp)

    extent = [0] * 6
    vtkExtentTranslator().PieceToExtentThreadSafe(
        info.Get(sddp.UPDATE_PIECE_NUMBER()), info.Get(sddp.UPDATE_NUMBER_OF_PIECES()), 0,
        image.GetExtent(), extent, vtkExtentTranslator.BLOCK_MODE, 0)
    return extent


def crop(image, extent):
    """`image` cut to `extent`."""
    from vtkmodules.vtkImagingCore import vtkExtractVOI

    voi = vtkExtractVOI()
    voi.SetInputData(image)
    voi.SetVOI(extent)
    voi.Update()
    return voi.GetOutput()


def piece_source(image):
    """A source with `image`'s whole extent that delivers each piece as
    vtkExtentTranslator cuts it, without a ghost layer, or (its `ghosts`
    set) the update extent asked for, ghost layer included. Keep a
    reference: the pipeline holds none on the Python object."""
    from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as sddp

    class Pieces(VTKPythonAlgorithmBase):
        def __init__(self):
            super().__init__(nInputPorts=0, nOutputPorts=1, outputType="vtkImageData")
            self.ghosts = False

        def RequestInformation(self, request, inInfo, outInfo):
            info = outInfo.GetInformationObject(0)
            info.Set(sddp.WHOLE_EXTENT(), *image.GetExtent())
            info.Set(VTKPythonAlgorithmBase.CAN_PRODUCE_SUB_EXTENT(), 1)
            return 1

        def RequestData(self, request, inInfo, outInfo):
            info = outInfo.GetInformationObject(0)
            extent = info.Get(sddp.UPDATE_EXTENT()) if self.ghosts else piece_asked(info, image)
            vtkImageData.GetData(outInfo).ShallowCopy(crop(image, extent))
            return 1

    return Pieces()


def test_pieces_without_the_ghost_layer_asked_for_warn():
    # A source with a whole extent that delivers each piece as asked but
    # without the ghost layer asked with it (and no ghost array): the
    # surface next to the cuts may differ from the serial one, which the
    # filter said only for inputs split otherwise than asked. It says it
    # here too, and not when no ghost layer is needed or the source gives
    # it.
    source = piece_source(wavelet(8))
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    observer = ErrorObserver(f)
    # Plain Marching Cubes without normals needs no ghost layer; refinement
    # that may mesh a cell again on sub-cells needs one.
    f.SetComputeNormals(0)
    for props, ghosts, warns in (({"Epsilon": 0.0}, False, False),
                                 ({"Epsilon": 0.001, "MaxLevel": 5}, False, True),
                                 ({"Epsilon": 0.001, "MaxLevel": 5}, True, False)):
        for name, value in props.items():
            getattr(f, "Set" + name)(value)
        source.ghosts = ghosts
        source.Modified()
        observer.warnings.clear()
        for piece in range(2):
            f.UpdatePiece(piece, 2, 0)
            assert f.GetOutput().GetNumberOfPolys() > 0
        assert not observer.errors
        assert len(observer.warnings) == (2 if warns else 0), (props, ghosts, observer.warnings)
        for piece, warning in enumerate(observer.warnings):
            assert "without the samples around it" in warning
            assert "surface may differ from a serial run's" in warning
            assert "for the piece (" in warning


def test_pieces_of_a_2d_volume_get_the_dimension_error_alone():
    # A 2D volume contoured in pieces (as under MPI) has no cells to lack
    # a ghost layer around: the dimension error, without the warning about
    # missing samples that came before it (the pieces' extents are thin
    # along the flat axis, which looked like a layer short).
    from vtkmodules.vtkCommonDataModel import vtkImageData
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    wave = vtkRTAnalyticSource()
    for flat in range(3):
        extent = [-8, 8] * 3
        extent[2 * flat:2 * flat + 2] = [0, 0]
        wave.SetWholeExtent(*extent)
        wave.Update()
        image = vtkImageData()
        image.DeepCopy(wave.GetOutput())
        source = piece_source(image)
        f = vtkPreciseMarchingCubes()
        f.SetInputConnection(source.GetOutputPort())
        f.SetValue(0, 150.0)
        # Refinement, which needs a ghost layer: the warning's condition.
        f.SetEpsilon(0.001)
        f.SetMaxLevel(5)
        observer = ErrorObserver(f)
        for piece in range(2):
            f.UpdatePiece(piece, 2, 0)
            assert f.GetOutput().GetNumberOfPolys() == 0
        assert not observer.warnings, (flat, observer.warnings)
        assert len(observer.errors) == 2, (flat, observer.errors)
        assert all("dimension != 3" in e for e in observer.errors), observer.errors


def test_pieces_without_a_whole_extent_warn():
    # A source that honours pieces but reports no whole extent delivers
    # only its own piece; each piece of the filter takes it for the whole
    # volume and cuts its piece from it again, so most of the surface is
    # lost. Nothing tells it from a source that delivers the whole volume
    # to every piece (the test above): the filter says what it did, where
    # it was silent.
    from vtkmodules.util.vtkAlgorithm import VTKPythonAlgorithmBase
    from vtkmodules.vtkCommonDataModel import vtkImageData

    image = wavelet(8)

    class OwnPieceOnly(VTKPythonAlgorithmBase):
        def __init__(self):
            super().__init__(nInputPorts=0, nOutputPorts=1, outputType="vtkImageData")

        def RequestData(self, request, inInfo, outInfo):
            info = outInfo.GetInformationObject(0)
            vtkImageData.GetData(outInfo).ShallowCopy(crop(image, piece_asked(info, image)))
            return 1

    source = OwnPieceOnly()  # kept: the pipeline holds no Python reference
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    observer = ErrorObserver(f)
    f.Update()
    assert not observer.errors and not observer.warnings
    for piece in range(2):
        f.UpdatePiece(piece, 2, 0)
    assert not observer.errors and len(observer.warnings) == 2
    for piece, warning in enumerate(observer.warnings):
        assert "reports no whole extent" in warning
        assert f"piece {piece} of 2 cut from it is contoured" in warning
        assert "loses the rest of the surface" in warning


def test_a_flat_image_is_still_an_error():
    # The other side of the test above: an input whose whole extent is a
    # single layer of samples is not 3D data.
    for shape in ((1, 4, 5), (4, 1, 5), (4, 5, 1)):
        f = vtkPreciseMarchingCubes()
        f.SetInputData(image_from_array(np.random.default_rng(1).random(shape)))
        f.SetValue(0, 0.5)
        observer = ErrorObserver(f)
        f.Update()
        assert observer.errors and "dimension" in observer.errors[0]
        assert f.GetOutput().GetNumberOfPoints() == 0
        # Asked for as pieces too.
        f.UpdatePiece(1, 2, 0)
        assert len(observer.errors) == 2


@pytest.mark.parametrize("kind", ["ghost-array", "blanked", "duplicate-corner"])
def test_pieces_of_a_whole_volume_with_ghost_flags_cover_it_once(kind):
    # An image that every piece receives whole (SetInputData) but that
    # carries a cell ghost array: all zeros, the HIDDENCELL flag of a
    # blanked cell of a vtkUniformGrid, or a corner cell marked as a
    # DUPLICATECELL (the mark that a block of a composite input, which also
    # arrives as a whole volume of its own, carries on its ghost layer).
    # The pieces must still split the volume as asked (each used to contour
    # all of it: the union held the surface once per piece).
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray
    from vtkmodules.vtkCommonDataModel import vtkUniformGrid
    from vtkmodules.util.numpy_support import numpy_to_vtk

    n = 16
    g = np.mgrid[0:n, 0:n, 0:n].astype(float)
    values = np.sqrt(((g - (n - 1) / 2) ** 2).sum(0)).ravel()
    image = vtkUniformGrid()
    image.SetDimensions(n, n, n)
    scalars = numpy_to_vtk(values, deep=1)
    scalars.SetName("s")
    image.GetPointData().SetScalars(scalars)
    if kind != "blanked":
        ghosts = vtkUnsignedCharArray()
        ghosts.SetName("vtkGhostType")
        ghosts.SetNumberOfTuples((n - 1) ** 3)
        ghosts.Fill(0)
        if kind == "duplicate-corner":
            ghosts.SetValue(0, 1)  # vtkDataSetAttributes.DUPLICATECELL
        image.GetCellData().AddArray(ghosts)
    else:
        image.BlankCell(0)  # a corner cell, far from the surface
    assert image.GetCellGhostArray() is not None
    for eps in (0.0, 0.01):
        f = vtkPreciseMarchingCubes()
        f.SetInputData(image)
        f.SetValue(0, 5.0)
        f.SetEpsilon(eps)
        f.SetOutputPointsPrecision(1)
        f.UpdatePiece(0, 1, 0)
        serial = coordinate_triangles(f.GetOutput())
        assert len(serial) > 500
        for pieces in (2, 4):
            parts = []
            for piece in range(pieces):
                f.UpdatePiece(piece, pieces, 0)
                parts.append(coordinate_triangles(f.GetOutput()))
                assert 0 < len(parts[-1]) < len(serial), f"{kind} eps {eps} {piece}/{pieces}"
            union = np.concatenate(parts)
            union = union[np.lexsort(union.T[::-1])]
            assert np.array_equal(union, serial), f"{kind} eps {eps}, {pieces} pieces"


# A cell of the EPI scan of the benchmark (values less the isovalue, x
# fastest) where S_K narrows to a neck: refinement stalls there and the
# cell is meshed again on sub-cells.
FOLD = [-7.102, 20.898, -106.102, -87.102, 33.898, -77.102, -49.102, 161.898]


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_pieces_cut_between_two_cells_meshed_again(axis):
    # The fold cell and its mirror image across its high face on `axis`,
    # walled in by outside samples: both are meshed again on sub-cells,
    # and in the serial run their strips in the shared face cancel. Two
    # pieces cut along that face: each is contoured with the cells across
    # the cut (one ghost sample) and must give exactly its part of the
    # serial surface.
    dims = [4, 4, 4]
    dims[axis] = 5
    values = np.full(dims[::-1], -300.0)
    for z in range(1, dims[2] - 1):
        for y in range(1, dims[1] - 1):
            for x in range(1, dims[0] - 1):
                c = [x - 1, y - 1, z - 1]
                if c[axis] == 2:
                    c[axis] = 0
                values[z, y, x] = FOLD[c[0] + 2 * c[1] + 4 * c[2]]
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image_from_array(values))
    f.SetValue(0, 0.0)
    f.SetEpsilon(0.01)
    f.SetMaxLevel(5)
    f.SetOutputPointsPrecision(1)
    f.UpdatePiece(0, 1, 0)
    assert f.GetNumberOfCellsOnSubcells() == 2
    serial = coordinate_triangles(f.GetOutput())
    # No strip left in the shared face (coordinate 2 on `axis`).
    assert not np.any(np.all(serial.reshape(-1, 3, 3)[:, :, axis] == 2.0, axis=1))
    parts = []
    for piece in range(2):
        f.UpdatePiece(piece, 2, 0)
        part = coordinate_triangles(f.GetOutput())
        assert len(part) > 0
        parts.append(part)
    # The cut is the shared face: each piece holds one of the two cells.
    spans = sorted((p.reshape(-1, 3, 3)[:, :, axis].min(), p.reshape(-1, 3, 3)[:, :, axis].max())
                   for p in parts)
    assert spans[0][1] <= 2.0 <= spans[1][0]
    union = np.concatenate(parts)
    union = union[np.lexsort(union.T[::-1])]
    assert union.shape == serial.shape
    assert np.array_equal(union, serial)
    # Control: the two halves contoured alone (no cells across the cut)
    # each keep their strips in the cut, which the serial run has not.
    from vtkmodules.vtkImagingCore import vtkExtractVOI
    alone = []
    for lo, hi in ((0, 2), (2, 4)):
        voi = vtkExtractVOI()
        voi.SetInputData(image_from_array(values))
        bounds = [0, dims[0] - 1, 0, dims[1] - 1, 0, dims[2] - 1]
        bounds[2 * axis], bounds[2 * axis + 1] = lo, hi
        voi.SetVOI(*bounds)
        voi.Update()
        half = precise(voi.GetOutput(), [0.0], Epsilon=0.01, MaxLevel=5).GetOutput()
        alone.append(coordinate_triangles(half))
    xyz = np.concatenate(alone).reshape(-1, 3, 3)
    others = [a for a in range(3) if a != axis]
    in_face = np.all(xyz[:, :, axis] == 2.0, axis=1) & np.all(
        (xyz[:, :, others] >= 1.0) & (xyz[:, :, others] <= 2.0), axis=(1, 2))
    assert in_face.sum() > 0


@pytest.mark.parametrize("name", ["CatmullRom", "BSpline"])
def test_cubic_pieces_need_the_ghost_layer(name):
    # Control for the test above: contouring the pieces' extents without
    # the ghost layer gives another surface near the piece boundary.
    from vtkmodules.vtkImagingCore import vtkExtractVOI, vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
    source.Update()
    whole = precise(source.GetOutput(), [150.0], ReconstructionFilter=RECONSTRUCTIONS[name])
    parts = []
    for lo, hi in ((-8, 0), (0, 8)):
        voi = vtkExtractVOI()
        voi.SetInputData(source.GetOutput())
        voi.SetVOI(-8, 8, -8, 8, lo, hi)
        voi.Update()
        parts.append(coordinate_triangles(
            precise(voi.GetOutput(), [150.0], ReconstructionFilter=RECONSTRUCTIONS[name])
            .GetOutput()))
    union = np.concatenate(parts)
    serial = coordinate_triangles(whole.GetOutput())
    assert union.shape != serial.shape or not np.array_equal(
        union[np.lexsort(union.T[::-1])], serial)


def test_cells_refined_on_faces_only_are_counted():
    # A cell where two split points meet on the surface (straight gradient
    # lines cross there): the library refines it again on its faces only,
    # and the filter reports the count; a smooth sphere needs none.
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    values = np.full((4, 4, 4), -1.0)
    for (i, j, k), v in zip(corners, [-1, -3, -1, 1, 5, 3, -3, -1]):
        values[k + 1, j + 1, i + 1] = v
    f = precise(image_from_array(values), [1e-9], Epsilon=0.01, MaxLevel=3, Rule=3)
    assert f.GetNumberOfCellsRefinedOnFacesOnly() > 0
    assert f.GetOutput().GetNumberOfCells() > 0
    n = 12
    g = np.mgrid[0:n, 0:n, 0:n].astype(float)
    sphere = np.sqrt(((g - (n - 1) / 2) ** 2).sum(axis=0))
    s = precise(image_from_array(sphere), [4.0], Epsilon=0.01, MaxLevel=3, Rule=3)
    assert s.GetNumberOfRefinedTriangles() > s.GetNumberOfMCTriangles()
    assert s.GetNumberOfCellsRefinedOnFacesOnly() == 0


def test_recut_polygons_are_counted():
    # A cell of the "atoms" sample where the surface hugs the top face: the
    # case table's diagonal crosses the part of the cell the surface never
    # enters, so the library re-cuts the polygon before refining and the
    # filter reports it; plain Marching Cubes keeps the table's cut.
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    f = [113.68658, 99.584435, 71.3651, 118.850815, 49.37087, 48.697723, 40.276493, 68.39907]
    values = np.empty((3, 3, 3))
    for k in range(3):
        for j in range(3):
            for i in range(3):
                values[k, j, i] = f[corners.index((int(i > 0), int(j > 0), int(k > 0)))]
    r = precise(image_from_array(values), [50.5], Epsilon=0.001)
    assert r.GetNumberOfRecutPolygons() > 0
    m = precise(image_from_array(values), [50.5], Epsilon=0.0)
    assert m.GetNumberOfRecutPolygons() == 0


def test_library_scalar_type_and_unsupported_arrays():
    from vtkmodules import vtkCommonCore as core
    from vtkmodules.vtkCommonDataModel import vtkImageData

    # The codes of precisemc.h's PMC_SCALAR_TYPE_*, for every numeric VTK type.
    expected = {core.VTK_SIGNED_CHAR: 0, core.VTK_UNSIGNED_CHAR: 1, core.VTK_SHORT: 2,
                core.VTK_UNSIGNED_SHORT: 3, core.VTK_INT: 4, core.VTK_UNSIGNED_INT: 5,
                core.VTK_LONG_LONG: 6, core.VTK_UNSIGNED_LONG_LONG: 7, core.VTK_FLOAT: 8,
                core.VTK_DOUBLE: 9, core.VTK_ID_TYPE: 6, core.VTK_LONG: 6,
                core.VTK_UNSIGNED_LONG: 7, core.VTK_CHAR: 0}
    for vtk_type, code in expected.items():
        assert vtkPreciseMarchingCubes.LibraryScalarType(vtk_type) == code, vtk_type
    for vtk_type in (core.VTK_BIT, core.VTK_STRING, core.VTK_VARIANT, core.VTK_VOID):
        assert vtkPreciseMarchingCubes.LibraryScalarType(vtk_type) == -1
    # A bit array is refused with an error naming its type, and no output.
    image = vtkImageData()
    image.SetDimensions(3, 3, 3)
    bits = core.vtkBitArray()
    bits.SetNumberOfTuples(27)
    for i in range(27):
        bits.SetValue(i, i % 2)
    image.GetPointData().SetScalars(bits)
    refused(image, 0.5, "Unsupported scalar type bit")
    # A string array selected by name is named too (it is no data array:
    # the error said there were no scalars).
    words = core.vtkStringArray()
    words.SetName("labels")
    words.SetNumberOfValues(27)
    for i in range(27):
        words.SetValue(i, str(i))
    image.GetPointData().AddArray(words)
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, 0.5)
    f.SetInputArrayToProcess(0, 0, 0, 0, "labels")
    errors = ErrorObserver(f)
    f.Update()
    assert errors.errors and "Unsupported scalar type string of array labels" in errors.errors[-1]
    assert f.GetOutput().GetNumberOfPoints() == 0


def test_release_retained_memory_frees_the_bins_and_keeps_the_output():
    # Executions leave their buffers in the library's bins for the next
    # one; releasing them returns their size once, and the executions
    # after it (on fresh memory) give the same surface bit for bit.
    image = wavelet(16)
    runs = []
    for release in (False, True, False):
        if release:
            freed = vtkPreciseMarchingCubes.ReleaseRetainedMemory()
            assert freed > 0
            assert vtkPreciseMarchingCubes.ReleaseRetainedMemory() == 0
        f = precise(image, [150.0], Epsilon=0.01, NumberOfThreads=2)
        out = f.GetOutput()
        assert out.GetNumberOfCells() > 0
        runs.append((points(out).tobytes(), triangles(out).tobytes()))
    assert runs[1] == runs[0] and runs[2] == runs[0]
    assert vtkPreciseMarchingCubes.ReleaseRetainedMemory() > 0


def test_cells_on_subcells_are_counted():
    # A cell of the EPI scan of the benchmark (values less the isovalue, x
    # fastest) where the surface folds through a neck: refinement stalls
    # and the cell is meshed again on sub-cells.
    f = np.array([-7.102, 20.898, -106.102, -87.102, 33.898, -77.102, -49.102, 161.898])
    values = f.reshape(2, 2, 2)  # (z, y, x)
    r = precise(image_from_array(values), [0.0], Epsilon=0.01, MaxLevel=5)
    assert r.GetNumberOfCellsOnSubcells() == 1
    assert r.GetOutput().GetNumberOfPolys() > 0
    m = precise(image_from_array(values), [0.0], Epsilon=0.0)
    assert m.GetNumberOfCellsOnSubcells() == 0


def test_contour_values_read_back_as_a_tuple():
    # GetValues() gives the values in Python (it gave a pointer's name).
    f = vtkPreciseMarchingCubes()
    f.SetValue(0, 1.5)
    f.SetValue(1, 2.5)
    f.GenerateValues(3, 10.0, 30.0)
    assert tuple(f.GetValues()) == (10.0, 20.0, 30.0)
