"""vtkPreciseMarchingCubes' ComputeGradients: off by default, the same
"Gradients" as vtkFlyingEdges3D (central differences: the same values at
the same points; exact gradients: the same directions), in world units
and axes for any spacing and direction matrix, each normal the negated,
normalised gradient, and pieces of a volume equal to the serial run."""

import numpy as np
import pytest
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonMath import vtkMatrix3x3
from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D

from conftest import image_from_array, match_points, points

from precisemc import vtkPreciseMarchingCubes

SPACING = (0.25, 0.625, 0.4)
CENTRE = (24.4, 21.8, 19.4)  # the field's centre, in samples
ORIGIN = (-3.0, 1.0, 2.0)


def ellipsoid_image(direction=None):
    """A smooth field of ellipsoidal level sets, sampled with non-unit
    spacing; `direction`, if given, the image's direction matrix."""
    n = (49, 45, 41)  # x, y, z samples
    z, y, x = np.meshgrid(*(np.arange(m, dtype=float) for m in n[::-1]), indexing="ij")
    x, y, z = ((x - CENTRE[0]) * SPACING[0], (y - CENTRE[1]) * SPACING[1],
               (z - CENTRE[2]) * SPACING[2])
    values = x * x + 0.8 * y * y + 1.3 * z * z + 0.3 * x * y + 0.5 * np.sin(x + 0.5 * z)
    image = image_from_array(values, SPACING, ORIGIN)
    if direction is not None:
        set_direction(image, direction)
    return image


def set_direction(image, direction):
    """Gives `image` the 3x3 direction matrix `direction` (a numpy array)."""
    m = vtkMatrix3x3()
    for r in range(3):
        for c in range(3):
            m.SetElement(r, c, direction[r, c])
    image.SetDirectionMatrix(m)


def precise(image, value, **props):
    f = vtkPreciseMarchingCubes()
    f.SetInputData(image)
    f.SetValue(0, value)
    f.SetOutputPointsPrecision(1)  # double
    for name, v in props.items():
        getattr(f, "Set" + name)(v)
    f.Update()
    return f.GetOutput()


def flying_edges(image, value):
    fe = vtkFlyingEdges3D()
    fe.SetInputData(image)
    fe.SetValue(0, value)
    fe.ComputeGradientsOn()
    fe.ComputeNormalsOn()
    fe.Update()
    return fe.GetOutput()


def array(poly, name):
    return vtk_to_numpy(poly.GetPointData().GetArray(name)).astype(float)


def rotation(axis, angle):
    axis = np.asarray(axis, dtype=float)
    axis /= np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_off_by_default_and_the_array_comes_on_request():
    f = vtkPreciseMarchingCubes()
    assert f.GetComputeGradients() == 0
    f.ComputeGradientsOn()
    assert f.GetComputeGradients() == 1
    f.ComputeGradientsOff()
    assert "Compute Gradients: Off" in str(f)
    image = ellipsoid_image()
    out = precise(image, 20.0)
    assert out.GetNumberOfPoints() > 500
    assert out.GetPointData().GetArray("Gradients") is None
    out = precise(image, 20.0, ComputeGradients=True)
    g = out.GetPointData().GetArray("Gradients")
    assert g is not None and g.GetNumberOfComponents() == 3
    assert g.GetNumberOfTuples() == out.GetNumberOfPoints() and g.GetDataType() == 10  # float
    # The active vectors and beside the normals, as vtkFlyingEdges3D's.
    assert out.GetPointData().GetVectors().GetName() == "Gradients"
    assert out.GetPointData().GetNormals().GetName() == "Normals"


@pytest.mark.parametrize("direction", [None, "rotation"])
def test_central_differences_equal_flying_edges(direction):
    d = rotation((1, -2, 3), 0.9) if direction else None
    image = ellipsoid_image(d)
    ref = flying_edges(image, 20.0)
    ours = precise(image, 20.0, Epsilon=0.0, Topology=vtkPreciseMarchingCubes.TOPOLOGY_CLASSIC,
                   NormalMode=vtkPreciseMarchingCubes.NORMALS_CENTRAL_DIFFERENCE,
                   ComputeGradients=True)
    assert ours.GetNumberOfPoints() == ref.GetNumberOfPoints() > 500
    ids = match_points(ours, ref, 1e-5)
    assert (ids >= 0).all()
    ga, gb = array(ours, "Gradients"), array(ref, "Gradients")[ids]
    # Towards higher values, as vtkFlyingEdges3D's: away from the centre.
    centre = np.array(ORIGIN) + (d if d is not None else np.eye(3)) @ (
        np.array(CENTRE) * SPACING)
    assert (np.einsum("ij,ij->i", ga, points(ours) - centre) > 0).all()
    scale = np.linalg.norm(gb, axis=1)
    assert (np.linalg.norm(ga - gb, axis=1) <= 1e-4 * scale).all()
    # Each normal the negated, normalised gradient.
    na = array(ours, "Normals")
    assert np.abs(na + ga / np.linalg.norm(ga, axis=1)[:, None]).max() < 1e-5


@pytest.mark.parametrize("direction", [None, "rotation"])
def test_exact_gradients_point_as_flying_edges(direction):
    image = ellipsoid_image(rotation((2, 1, -1), -0.6) if direction else None)
    ref = flying_edges(image, 20.0)
    ours = precise(image, 20.0, Epsilon=0.0, Topology=vtkPreciseMarchingCubes.TOPOLOGY_CLASSIC,
                   ComputeGradients=True)
    ids = match_points(ours, ref, 1e-5)
    assert (ids >= 0).all()
    ga, gb = array(ours, "Gradients"), array(ref, "Gradients")[ids]
    cos = np.einsum("ij,ij->i", ga, gb) / (np.linalg.norm(ga, axis=1) * np.linalg.norm(gb, axis=1))
    # Across its edge the interpolant's gradient at a vertex is a one-sided
    # difference (of the cell on the upper side), half a cell from the
    # central one: a few degrees on a surface 8 to 18 cells in radius
    # (measured: 3.4 on average, 5.8 at most).
    angle = np.degrees(np.arccos(np.clip(cos, -1, 1)))
    assert angle.mean() < 4.5 and angle.max() < 8.0, (angle.mean(), angle.max())
    # Of similar size too (the field is smooth on the cell scale).
    ratio = np.linalg.norm(ga, axis=1) / np.linalg.norm(gb, axis=1)
    assert 0.8 < ratio.min() and ratio.max() < 1.25
    # Refined, the gradients stay those of the trilinear interpolant:
    # still close to the smooth field's.
    refined = precise(image, 20.0, ComputeGradients=True, ComputeNormals=False)
    assert refined.GetPointData().GetNormals() is None
    assert refined.GetNumberOfPoints() > ours.GetNumberOfPoints()
    assert np.isfinite(array(refined, "Gradients")).all()


@pytest.mark.parametrize("mode", ["Gradient", "CentralDifference"])
def test_gradients_do_not_depend_on_normals_being_on(mode):
    image = ellipsoid_image()
    props = dict(NormalMode=getattr(vtkPreciseMarchingCubes, "NORMALS_" + {
        "Gradient": "GRADIENT", "CentralDifference": "CENTRAL_DIFFERENCE"}[mode]),
        ComputeGradients=True, Epsilon=0.005)
    with_normals = precise(image, 20.0, **props)
    without = precise(image, 20.0, ComputeNormals=False, **props)
    assert without.GetPointData().GetNormals() is None
    assert np.array_equal(array(with_normals, "Gradients"), array(without, "Gradients"))


def test_linear_field_with_a_sheared_mirroring_direction_is_exact():
    # F = c . ijk in index space; x = origin + D S ijk, so grad_x F =
    # D^-T S^-1 c, whatever D (here neither orthogonal nor a rotation) and
    # the signs of S.
    c = np.array([0.7, -1.1, 1.9])
    n = 9
    k, j, i = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    values = c[0] * i + c[1] * j + c[2] * k
    spacing = (0.5, -1.5, 2.0)
    d = np.array([[1.0, 0.3, 0.0], [0.0, 1.0, -0.4], [0.2, 0.0, -1.0]])
    for direction in (None, d):
        image = image_from_array(values, spacing, (1.0, 2.0, 3.0))
        expected = c / np.array(spacing)
        if direction is not None:
            set_direction(image, direction)
            expected = np.linalg.inv(direction).T @ expected
        for mode in (vtkPreciseMarchingCubes.NORMALS_GRADIENT,
                     vtkPreciseMarchingCubes.NORMALS_CENTRAL_DIFFERENCE):
            out = precise(image, float(values.mean()) + 0.1, NormalMode=mode,
                          ComputeGradients=True)
            g = array(out, "Gradients")
            assert len(g) > 50
            assert np.abs(g - expected).max() < 1e-5 * np.abs(expected).max()
            nrm = array(out, "Normals")
            assert np.abs(nrm + expected / np.linalg.norm(expected)).max() < 1e-5


@pytest.mark.parametrize("mode", ["GRADIENT", "CENTRAL_DIFFERENCE"])
def test_pieces_have_the_serial_gradients(mode):
    # Plain Marching Cubes without normals reads no sample beyond a piece;
    # gradients at a point on its face do (as normals): one ghost layer.
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource

    source = vtkRTAnalyticSource()
    source.SetWholeExtent(-8, 8, -8, 8, -8, 8)
    f = vtkPreciseMarchingCubes()
    f.SetInputConnection(source.GetOutputPort())
    f.SetValue(0, 150.0)
    f.SetEpsilon(0.0)
    f.SetOutputPointsPrecision(1)
    f.ComputeNormalsOff()
    f.ComputeGradientsOn()
    f.SetNormalMode(getattr(vtkPreciseMarchingCubes, "NORMALS_" + mode))
    f.UpdatePiece(0, 1, 0)
    serial = {tuple(p): g for p, g in zip(points(f.GetOutput()), array(f.GetOutput(), "Gradients"))}
    assert len(serial) > 1000
    for pieces in (2, 3):
        seen = 0
        for piece in range(pieces):
            f.UpdatePiece(piece, pieces, 0)
            out = f.GetOutput()
            for p, g in zip(points(out), array(out, "Gradients")):
                assert np.array_equal(serial[tuple(p)], g), (pieces, piece, p)
                seen += 1
        assert seen >= len(serial)
