"""vtkPreciseMarchingCubes from Python: wrapping, equality with
vtkMarchingCubes, geometry handling, attributes, pipeline and errors."""

import math

import numpy as np
import pytest
from vtkmodules.util.numpy_support import vtk_to_numpy
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
    assert np.array_equal(n0, n1)


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
