"""Memory running out never aborts the host: under an address-space limit
the filter either contours, or reports the library's out-of-memory error,
or, when the library's mesh fitted but the output's VTK arrays do not,
reports that with an empty output. (VTK's arrays throw std::bad_alloc
there, which used to end the process: the ParaView session with it.)"""

import os
import pathlib
import resource
import subprocess
import sys

import precisemc

# Two contour values (the connectivity is copied, not adopted) refined
# deep on a smooth source: about 3.8 M triangles in a second or two.
CHILD = r"""
import sys
from vtkmodules.vtkImagingCore import vtkRTAnalyticSource
import precisemc
src = vtkRTAnalyticSource()
src.SetWholeExtent(-30, 30, -30, 30, -30, 30)
src.Update()
f = precisemc.vtkPreciseMarchingCubes()
f.SetInputData(src.GetOutput())
f.SetValue(0, 150.0)
f.SetValue(1, 151.0)
f.SetEpsilon(0.00003)
f.SetMaxLevel(8)
f.SetNumberOfThreads(1)
f.SetComputeLevels(1)
f.Update()
print("cells", f.GetOutput().GetNumberOfCells(), flush=True)
"""

OUTPUT_MESSAGE = "Out of memory while building the output"


def run_limited(limit_bytes):
    """The child under an address-space limit: (exit status, cells or
    None, stderr)."""
    env = dict(os.environ)
    package_root = str(pathlib.Path(precisemc.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([package_root] + sys.path)

    def limit():
        # The soft limit only: the hard one may already be finite.
        if limit_bytes != resource.RLIM_INFINITY:
            hard = resource.getrlimit(resource.RLIMIT_AS)[1]
            soft = limit_bytes if hard == resource.RLIM_INFINITY else min(limit_bytes, hard)
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))

    r = subprocess.run([sys.executable, "-c", CHILD], env=env, preexec_fn=limit,
                       capture_output=True, text=True, timeout=300)
    cells = None
    for line in r.stdout.splitlines():
        if line.startswith("cells "):
            cells = int(line.split()[1])
    return r.returncode, cells, r.stderr


def test_output_arrays_running_out_of_memory_is_an_error_not_an_abort():
    # Unlimited first: the size of the job.
    status, full, err = run_limited(resource.RLIM_INFINITY)
    assert status == 0 and full and full > 1_000_000, (status, full, err[-500:])
    # Bisect the limit between a run that fails early and one that
    # succeeds, until one fails on the output's arrays; every run must
    # end normally, with one of the three outcomes.
    lo, hi = 64 << 20, 8 << 30
    seen = []
    for _ in range(14):
        mid = (lo + hi) // 2
        status, cells, err = run_limited(mid)
        seen.append((mid >> 20, status, cells))
        # Exit status 0, or 1 with a Python traceback where Python or VTK
        # could not even load under the limit; never a signal (an abort).
        assert status == 0 or (status == 1 and cells is None and "Traceback" in err), \
            f"limit {mid >> 20} MiB: status {status}, stderr {err[-800:]!r}"
        if cells == full:
            hi = mid
            continue
        if OUTPUT_MESSAGE in err:
            assert cells == 0, f"limit {mid >> 20} MiB: {cells} cells after {err[-400:]!r}"
            return
        # The library ran out first, or Python and VTK did not even load.
        assert cells in (None, 0), f"limit {mid >> 20} MiB: {cells} of {full} cells"
        lo = mid
    raise AssertionError(f"no limit made the output's arrays run out: {seen}")
