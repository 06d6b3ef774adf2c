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
doubled. Prints "ok ..." or "FAIL ..." per configuration (pvbatch's exit
status does not tell: a script ending early under MPI aborts the other
ranks, so the script always runs to its end).
"""
import sys

import numpy as np
from paraview import servermanager
import paraview.simple as pvs
from vtkmodules.util.numpy_support import vtk_to_numpy

# The configurations compared: plain Marching Cubes and refined surfaces.
# "ghosts": a filter downstream asks for a ghost level, which must not make
# the pieces overlap (the filter asks its input for none, or for the ghost
# layers that refinement on sub-cells or a cubic filter needs, and outputs
# only its cells).
# "same_as": the serial configuration whose triangles it must equal.
CONFIGS = {
    "mc": dict(Epsilon=0.0, MaxLevel=0),
    "refined": dict(Epsilon=0.01, MaxLevel=5, Rule="A1"),
    # After "refined", which asks for a ghost level (a cell may be meshed
    # again on sub-cells): the shared Wavelet still holds that layer, which
    # this one (no ghost level: classic topology) must not contour.
    "refined-classic-B": dict(Epsilon=0.002, MaxLevel=3, Rule="B", Topology="Classic"),
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


def canonical(poly):
    """Triangles of a vtkPolyData as a sorted (n, 9) float64 array."""
    n = poly.GetNumberOfCells()
    if n == 0:
        return np.zeros((0, 9)), np.zeros(0, dtype=np.int64)
    points = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    polys = poly.GetPolys()
    assert polys.GetNumberOfCells() == n, "only triangles expected"
    offsets = vtk_to_numpy(polys.GetOffsetsArray())
    conn = vtk_to_numpy(polys.GetConnectivityArray())
    assert np.all(np.diff(offsets) == 3), "only triangles expected"
    tris = conn.reshape(-1, 3)
    xyz = points[tris]  # (n, 3 vertices, 3 coordinates)
    # Rotate each triangle so that its lexicographically smallest vertex
    # comes first (a rotation keeps the orientation).
    first = np.zeros(n, dtype=np.int64)
    for k in (1, 2):
        a, b = xyz[np.arange(n), k], xyz[np.arange(n), first]
        smaller = (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & (
            (a[:, 1] < b[:, 1]) | ((a[:, 1] == b[:, 1]) & (a[:, 2] < b[:, 2]))))
        first[smaller] = k
    order = (first[:, None] + np.arange(3)[None, :]) % 3
    rotated = xyz[np.arange(n)[:, None], order].reshape(n, 9)
    ranks = np.zeros(n, dtype=np.int64)
    pid = poly.GetPointData().GetArray("ProcessId")
    if pid is not None:
        ranks = vtk_to_numpy(pid).astype(np.int64)[tris[:, 0]]
    keys = np.lexsort(rotated.T[::-1])
    return rotated[keys], ranks[keys]


def main():
    plugin, out = sys.argv[1], sys.argv[2]
    reference = np.load(sys.argv[3]) if len(sys.argv) > 3 else None
    pvs.LoadPlugin(plugin, remote=False, ns=pvs.__dict__)
    ranks = servermanager.vtkProcessModule.GetProcessModule().GetNumberOfLocalPartitions()
    print(f"ranks: {ranks}")

    wavelet = pvs.Wavelet(WholeExtent=EXTENT)
    results = {}
    failed = 0
    for name, props in CONFIGS.items():
        props = dict(props)
        ghosts = props.pop("ghosts", False)
        same_as = props.pop("same_as", name)
        contour = pvs.PreciseContour(
            Input=wavelet,
            ContourBy=["POINTS", "RTData"],
            Isosurfaces=ISOVALUES,
            OutputPointsPrecision="Double",
            NumberOfThreads=1,
            **props,
        )
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
        counts = np.bincount(owner, minlength=ranks)
        line = f"{name}: {len(tris)} triangles, per rank {counts.tolist()}"
        if reference is None:
            print(line)
            continue
        ref = reference[same_as]
        problems = []
        if ranks > 1 and np.any(counts == 0):
            problems.append("a rank produced no triangles (volume not split?)")
        if tris.shape != ref.shape:
            problems.append(f"{len(tris)} triangles, serial run {len(ref)}")
        elif not np.array_equal(tris, ref):
            differ = np.any(tris != ref, axis=1)
            problems.append(f"{int(differ.sum())} triangles differ from the serial run")
        # Vertices on piece boundaries: the same coordinates used by the
        # triangles of several ranks.
        vertices = tris.reshape(-1, 3)
        vertex_ranks = np.repeat(owner, 3)
        unique, inverse = np.unique(vertices, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        lo = np.full(len(unique), ranks, dtype=np.int64)
        hi = np.full(len(unique), -1, dtype=np.int64)
        np.minimum.at(lo, inverse, vertex_ranks)
        np.maximum.at(hi, inverse, vertex_ranks)
        shared = int(np.sum(lo != hi))
        ref_unique = len(np.unique(ref.reshape(-1, 3), axis=0))
        if len(unique) != ref_unique:
            problems.append(f"{len(unique)} distinct vertices, serial run {ref_unique}")
        if ranks > 1 and shared == 0:
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
