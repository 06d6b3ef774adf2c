"""vtkPreciseMarchingCubes in processes forked by Python's multiprocessing
(its default start method on Linux), while a thread of the parent keeps
contouring: each child must contour like the parent, not hang on a lock
or on helper threads that it does not have."""

import multiprocessing
import threading

import numpy as np

from conftest import points, triangles, wavelet

from precisemc import vtkPreciseMarchingCubes


def contour(threads, epsilon):
    f = vtkPreciseMarchingCubes()
    f.SetInputData(wavelet(12))
    f.SetValue(0, 160.0)
    f.SetOutputPointsPrecision(1)
    f.SetNumberOfThreads(threads)
    f.SetEpsilon(epsilon)
    f.Update()
    return f.GetOutput()


def child_counts(k):
    out = contour(2, 0.01 if k % 2 else 0.0)
    return k, out.GetNumberOfPoints(), out.GetNumberOfCells()


def test_forked_children_contour_while_the_parent_does():
    expected = {}
    for k in range(2):
        out = contour(2, 0.01 if k % 2 else 0.0)
        expected[k] = (out.GetNumberOfPoints(), out.GetNumberOfCells())
    stop = threading.Event()
    busy_runs = []

    def busy():
        while not stop.is_set():
            contour(2, 0.01)
            busy_runs.append(1)

    t = threading.Thread(target=busy)
    t.start()
    try:
        ctx = multiprocessing.get_context("fork")
        for _ in range(5):
            with ctx.Pool(2) as pool:
                result = pool.map_async(child_counts, range(8))
                got = result.get(timeout=120)
            for k, n_points, n_cells in got:
                assert (n_points, n_cells) == expected[k % 2]
    finally:
        stop.set()
        t.join()
    assert busy_runs


def test_a_forked_child_gives_the_same_surface():
    parent = contour(2, 0.001)
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()

    def run():
        out = contour(2, 0.001)
        queue.put((points(out).tobytes(), triangles(out).tobytes()))

    p = ctx.Process(target=run)
    p.start()
    pts, tris = queue.get(timeout=120)
    p.join(timeout=60)
    assert p.exitcode == 0
    assert pts == points(parent).tobytes()
    assert tris == triangles(parent).tobytes()
    assert np.frombuffer(tris, dtype=triangles(parent).dtype).size > 0
