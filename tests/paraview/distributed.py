"""Distributed runs of the Precise Contour filter (pvbatch, with or without MPI).

    pvbatch distributed.py PLUGIN OUT.npz [REFERENCE.npz]
    mpiexec -n 3 pvbatch distributed.py PLUGIN OUT.npz REFERENCE.npz

ParaView splits a Wavelet source into one piece per rank; every rank
contours its piece and the pieces are gathered on rank 0 (Fetch). The
triangles of each configuration, as coordinate triples in a canonical form
(each triangle rotated to start at its smallest vertex, which keeps its
orientation; the list sorted), are saved to OUT.npz. With REFERENCE.npz (the
serial run's file) they must be exactly equal: same triangles, same
orientation, bit-identical vertices on piece boundaries, nothing missing or
doubled. The point data the filter writes goes with each vertex (normals,
scalars, the interpolated attributes) and must be equal too, and so must
the names of the point arrays (a distributed input's ghost flags must not
leak into the output). Besides the Wavelet, which splits as the filter asks,
an image source that splits the volume its own way (as Resample To Image
does) must give the serial surface too. Prints "ok ..." or "FAIL ..." per
configuration (pvbatch's exit status does not tell: a script ending early
under MPI aborts the other ranks, so the script always runs to its end).
"""
import os
import sys

import numpy as np
from paraview import servermanager
import paraview.simple as pvs
from vtkmodules.util.numpy_support import vtk_to_numpy

# The configurations compared: plain Marching Cubes and refined surfaces.
# "ghosts": a filter downstream asks for a ghost level, which must not make
# the pieces overlap (the filter asks its input for the ghost layers it
# needs, not those asked for downstream, and outputs only its cells).
# "same_as": the serial configuration whose triangles it must equal.
# "input": "wavelet" (the default), "attributes" (the Wavelet with a second
# point array, "aux"), "own-split" (OWN_SPLIT_SOURCE below: no ghost
# levels, so only runs that need none, without normals) or "group" (the
# Wavelet as the block of a multiblock, Group Datasets: contoured block by
# block, each with the ghost layer the run asks the composite input for, or
# that the shared Wavelet holds already) or "legacy" (the Wavelet saved as
# a legacy .vtk file by the serial run: ParaView's legacy reader gives the
# whole volume to the first rank and nothing to the others, so the first
# rank must contour all of it, "one_rank").
CONFIGS = {
    "mc": dict(Epsilon=0.0, MaxLevel=0),
    # Normals read the samples beyond the piece's faces (one ghost level);
    # without them one is asked for too (flat triangles on a cut cancel
    # against the cells across it), which the Wavelet does not need.
    "mc-no-normals": dict(Epsilon=0.0, MaxLevel=0, ComputeNormals=0),
    "mc-central-differences": dict(Epsilon=0.0, MaxLevel=0, NormalMode="Central Difference"),
    "mc-attributes": dict(Epsilon=0.0, MaxLevel=0, InterpolateAttributes=1, input="attributes"),
    "refined-attributes": dict(Epsilon=0.01, MaxLevel=5, InterpolateAttributes=1,
                               input="attributes"),
    "own-split-mc": dict(Epsilon=0.0, MaxLevel=0, ComputeNormals=0, input="own-split"),
    "own-split-refined": dict(Epsilon=0.01, MaxLevel=2, ComputeNormals=0, input="own-split"),
    "refined": dict(Epsilon=0.01, MaxLevel=5, Rule="A1"),
    # After "refined", which asks for a ghost level (a cell may be meshed
    # again on sub-cells): the shared Wavelet still holds that layer, which
    # this one must not contour (it keeps its own cells' triangles).
    "refined-classic-B": dict(Epsilon=0.002, MaxLevel=3, Rule="B", Topology="Classic"),
    # The same through Group Datasets: each rank's block is its piece with
    # that ghost layer, whose cells (marked as duplicates) must not be
    # contoured twice (until the thirty-third session they were).
    "group-mc": dict(Epsilon=0.0, MaxLevel=0, ComputeNormals=0, input="group",
                     same_as="mc-no-normals"),
    # Runs that need a ghost layer, asked of the composite input (until the
    # fifty-second session it was not, and their surfaces next to the cuts
    # differed), one after the other on the same Group Datasets: each asks
    # for another layer (a cubic run after a trilinear one lost half its
    # triangles when each block's run left its own request on the composite
    # input, which the next update cut the Wavelet's piece from again).
    "group-mc-normals": dict(Epsilon=0.0, MaxLevel=0, input="group", same_as="mc"),
    "group-refined": dict(Epsilon=0.01, MaxLevel=5, Rule="A1", input="group",
                          same_as="refined"),
    "group-cubic-catmull-rom": dict(Epsilon=0.02, MaxLevel=3, ReconstructionFilter="Catmull-Rom",
                                    input="group", same_as="cubic-catmull-rom"),
    "group-refined-again": dict(Epsilon=0.01, MaxLevel=5, Rule="A1", input="group",
                                same_as="refined"),
    "legacy-mc": dict(Epsilon=0.0, MaxLevel=0, input="legacy", one_rank=True),
    "legacy-refined": dict(Epsilon=0.01, MaxLevel=5, input="legacy", one_rank=True),
    "refined-ghosts": dict(Epsilon=0.01, MaxLevel=5, ghosts=True),
    # On vtkSMPTools tasks: the serial run of "refined", bit for bit.
    "refined-smp": dict(Epsilon=0.01, MaxLevel=5, Rule="A1", UseSMPTools=1, same_as="refined"),
    # The cubic filters read a ghost layer of samples (the whole volume for
    # the prefiltered B-spline) and must still give exactly the serial run.
    "cubic-catmull-rom": dict(Epsilon=0.02, MaxLevel=3, ReconstructionFilter="Catmull-Rom"),
    "cubic-bspline-ghosts": dict(Epsilon=0.02, MaxLevel=3, ReconstructionFilter="B-Spline",
                                 ghosts=True),
    "cubic-bspline-interpolating": dict(Epsilon=0.05, MaxLevel=2,
                                        ReconstructionFilter="B-Spline Interpolating"),
}
ASK_FOR_GHOSTS = """
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as sddp
info = self.GetExecutive().GetInputInformation(0, 0)
info.Set(sddp.UPDATE_NUMBER_OF_GHOST_LEVELS(), 1)
"""
ISOVALUES = [130.0, 190.0]
EXTENT = [-16, 16, -16, 16, -16, 16]
# A second point array for InterpolateAttributes, with NaN on one plane of
# samples: a point on a face or an edge of a cell takes nothing from the
# corners off it, so only the points next to that plane may be NaN.
AUX = "aux"
AUX_EXPRESSION = "RTData * 0.5 + coordsX - 2 * coordsZ + if(coordsY == 3, sqrt(-1), 0)"

# An image source that cuts the volume along x its own way (not as
# vtkExtentTranslator does, and with no ghost levels, as Resample To Image
# does), with values that do not depend on the cut.
OWN_SPLIT_INFORMATION = """
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as sddp
self.GetOutputInformation(0).Set(sddp.WHOLE_EXTENT(), 0, 30, 0, 26, 0, 22)
"""
OWN_SPLIT_SOURCE = """
# (min and max are ParaView's array functions in this script's namespace.)
from builtins import max, min
import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as sddp
info = self.GetOutputInformation(0)
piece = info.Get(sddp.UPDATE_PIECE_NUMBER()) if info.Has(sddp.UPDATE_PIECE_NUMBER()) else 0
pieces = info.Get(sddp.UPDATE_NUMBER_OF_PIECES()) if info.Has(sddp.UPDATE_NUMBER_OF_PIECES()) else 1
cuts = [0] + [min(30, (30 * k + pieces // 2 + 1) // pieces + 1) for k in range(1, pieces)] + [30]
x0, x1 = cuts[piece], max(cuts[piece], cuts[piece + 1])
out = self.GetOutput()
out.SetExtent(x0, x1, 0, 26, 0, 22)
k, j, i = np.meshgrid(np.arange(23.0), np.arange(27.0), np.arange(x0, x1 + 1.0), indexing="ij")
f = np.sin(0.35 * i) * np.cos(0.3 * j) + np.sin(0.25 * k + 0.1 * i) + 0.02 * (i - 15) ** 2
a = numpy_to_vtk(np.ascontiguousarray(f.ravel()), deep=1)
a.SetName("RTData")
out.GetPointData().SetScalars(a)
"""
OWN_SPLIT_ISOVALUES = [0.4, 1.3]


def point_arrays(poly):
    """The point arrays a run compares: all but ParaView's ProcessId."""
    pd = poly.GetPointData()
    names = [pd.GetArrayName(a) for a in range(pd.GetNumberOfArrays())]
    return sorted(n for n in names if n and n != "ProcessId")


def column_of(poly, name):
    """The column of a vertex's row in canonical() holding array `name`."""
    pd = poly.GetPointData()
    column = 3
    for a in point_arrays(poly):
        if a == name:
            return column
        column += pd.GetArray(a).GetNumberOfComponents()
    raise KeyError(name)


def canonical(poly):
    """Triangles of a vtkPolyData as a sorted (n, 9 + 3 k) float64 array:
    each vertex's coordinates, then its values of the point arrays
    (point_arrays(), k components in all)."""
    n = poly.GetNumberOfCells()
    names = point_arrays(poly)
    pd = poly.GetPointData()
    width = 3
    for a in names:
        width += pd.GetArray(a).GetNumberOfComponents()
    if n == 0:
        return np.zeros((0, 3 * width)), np.zeros(0, dtype=np.int64)
    points = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    values = [points] + [vtk_to_numpy(pd.GetArray(a)).astype(np.float64).reshape(len(points), -1)
                         for a in names]
    per_point = np.concatenate(values, axis=1)
    polys = poly.GetPolys()
    assert polys.GetNumberOfCells() == n, "only triangles expected"
    offsets = vtk_to_numpy(polys.GetOffsetsArray())
    conn = vtk_to_numpy(polys.GetConnectivityArray())
    assert np.all(np.diff(offsets) == 3), "only triangles expected"
    tris = conn.reshape(-1, 3)
    xyz = points[tris]  # (n, 3 vertices, 3 coordinates)
    rows = per_point[tris]  # (n, 3 vertices, width)
    # Rotate each triangle so that its lexicographically smallest vertex
    # comes first (a rotation keeps the orientation).
    first = np.zeros(n, dtype=np.int64)
    for k in (1, 2):
        a, b = xyz[np.arange(n), k], xyz[np.arange(n), first]
        smaller = (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & (
            (a[:, 1] < b[:, 1]) | ((a[:, 1] == b[:, 1]) & (a[:, 2] < b[:, 2]))))
        first[smaller] = k
    order = (first[:, None] + np.arange(3)[None, :]) % 3
    rotated = rows[np.arange(n)[:, None], order].reshape(n, 3 * width)
    ranks = np.zeros(n, dtype=np.int64)
    pid = poly.GetPointData().GetArray("ProcessId")
    if pid is not None:
        ranks = vtk_to_numpy(pid).astype(np.int64)[tris[:, 0]]
    # NaN values (of an interpolated attribute) sort and compare as one
    # value: replaced by the largest number.
    rotated = np.where(np.isnan(rotated), np.finfo(np.float64).max, rotated)
    keys = np.lexsort(rotated.T[::-1])
    return rotated[keys], ranks[keys]


def main():
    plugin, out = sys.argv[1], sys.argv[2]
    reference = np.load(sys.argv[3]) if len(sys.argv) > 3 else None
    pvs.LoadPlugin(plugin, remote=False, ns=pvs.__dict__)
    ranks = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
    print(f"ranks: {ranks}")

    wavelet = pvs.Wavelet(WholeExtent=EXTENT)
    legacy = os.path.join(os.path.dirname(os.path.abspath(out)), "wavelet-legacy.vtk")
    if reference is None:
        pvs.SaveData(legacy, proxy=wavelet)
    inputs = {
        "wavelet": (wavelet, ISOVALUES),
        "attributes": (pvs.Calculator(Input=wavelet, ResultArrayName=AUX,
                                      Function=AUX_EXPRESSION, ReplaceInvalidResults=0),
                       ISOVALUES),
        "own-split": (pvs.ProgrammableSource(OutputDataSetType="vtkImageData",
                                             Script=OWN_SPLIT_SOURCE,
                                             ScriptRequestInformation=OWN_SPLIT_INFORMATION),
                      OWN_SPLIT_ISOVALUES),
        "group": (pvs.GroupDatasets(Input=[wavelet]), ISOVALUES),
        "legacy": (pvs.LegacyVTKReader(FileNames=[legacy]), ISOVALUES),
    }
    results = {}
    failed = 0
    for name, props in CONFIGS.items():
        props = dict(props)
        ghosts = props.pop("ghosts", False)
        same_as = props.pop("same_as", name)
        one_rank = props.pop("one_rank", False)
        input_name = props.pop("input", "wavelet")
        source, isovalues = inputs[input_name]
        contour = pvs.PreciseContour(
            Input=source,
            ContourBy=["POINTS", "RTData"],
            Isosurfaces=isovalues,
            OutputPointsPrecision="Double",
            NumberOfThreads=1,
            **props,
        )
        if input_name == "group":
            # The blocks' triangles as one polydata per rank.
            contour = pvs.ExtractSurface(Input=pvs.MergeBlocks(Input=contour))
        if ghosts:
            contour = pvs.ProgrammableFilter(
                Input=contour,
                OutputDataSetType="vtkPolyData",
                Script="self.GetOutput().ShallowCopy(self.GetInput())",
                RequestUpdateExtentScript=ASK_FOR_GHOSTS,
            )
        tagged = pvs.ProcessIdScalars(Input=contour)
        poly = servermanager.Fetch(tagged)
        tris, owner = canonical(poly)
        results[name] = tris
        results[name + "-ranks"] = owner
        results[name + "-arrays"] = np.array(point_arrays(poly))
        counts = np.bincount(owner, minlength=ranks)
        line = f"{name}: {len(tris)} triangles, per rank {counts.tolist()}"
        if input_name == "attributes" and len(tris):
            # NaN only next to the plane y = 3 (see AUX_EXPRESSION).
            rows = tris.reshape(-1, tris.shape[1] // 3)
            nan = rows[:, column_of(poly, AUX)] == np.finfo(np.float64).max
            stray = nan & ((rows[:, 1] <= 2.0) | (rows[:, 1] >= 4.0))
            if not nan.any() or stray.any():
                failed += 1
                print(f"FAIL {name}: {int(nan.sum())} vertices with a NaN {AUX}, "
                      f"{int(stray.sum())} of them away from the plane of NaN samples")
                continue
        if reference is None:
            print(line)
            continue
        ref = reference[same_as]
        problems = []
        if one_rank:
            if ranks > 1 and np.count_nonzero(counts) != 1:
                problems.append(f"triangles from {np.count_nonzero(counts)} ranks, not one")
        elif ranks > 1 and np.any(counts == 0):
            problems.append("a rank produced no triangles (volume not split?)")
        arrays = point_arrays(poly)
        ref_arrays = reference[same_as + "-arrays"].tolist()
        if arrays != ref_arrays:
            problems.append(f"point arrays {arrays}, serial run {ref_arrays}")
        elif tris.shape != ref.shape:
            problems.append(f"{len(tris)} triangles, serial run {len(ref)}")
        elif not np.array_equal(tris, ref):
            differ = np.any(tris != ref, axis=1)
            problems.append(f"{int(differ.sum())} triangles (with their point data) "
                            "differ from the serial run")
        # Vertices on piece boundaries: the same coordinates used by the
        # triangles of several ranks.
        width = tris.shape[1] // 3
        vertices = tris.reshape(-1, width)[:, :3]
        vertex_ranks = np.repeat(owner, 3)
        unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        lo = np.full(len(unique), ranks, dtype=np.int64)
        hi = np.full(len(unique), -1, dtype=np.int64)
        np.minimum.at(lo, inverse, vertex_ranks)
        np.maximum.at(hi, inverse, vertex_ranks)
        shared = int(np.sum(lo != hi))
        ref_unique = len(np.unique(ref.reshape(-1, ref.shape[1] // 3)[:, :3], axis=0))
        if len(unique) != ref_unique:
            problems.append(f"{len(unique)} distinct vertices, serial run {ref_unique}")
        if ranks > 1 and shared == 0 and not one_rank:
            problems.append("no vertex shared between ranks")
        line += f", {shared} vertices shared between ranks"
        if problems:
            failed += 1
            print(f"FAIL {line}: " + "; ".join(problems))
        else:
            print(f"ok {line}: identical to the serial run")
    np.savez(out, **results)
    print(f"distributed: {len(CONFIGS) - failed if reference is not None else 0} passed, {failed} failed")
    sys.stdout.flush()


main()
