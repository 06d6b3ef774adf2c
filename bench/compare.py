#!/usr/bin/python3
"""PreciseMC against vtkMarchingCubes, vtkFlyingEdges3D and "upsample then
contour": time, triangles, peak memory and the measured distance to the
trilinear isosurface S_K of the ORIGINAL volume (pmc_measure_distance).

Run through bench/run.sh (it builds the project and fetches the real volume
from PyPI). Every configuration runs in its own subprocess (`--worker`), so
that its peak memory (VmHWM) is its own: the figure reported is the peak
minus the worker's peak after it has loaded the volume. The small volumes'
speed rows are run once more with the filters interleaved in one process
(`interleaved`), where their 0.1-2 ms calls compare more steadily.

    bench/run.sh [--quick] [--out DIR] [--only VOL[,VOL...]] [--interleaved-only]

Needs Debian's /usr/bin/python3 (python3-vtk9, numpy, matplotlib) and
PYTHONPATH with the PreciseMC module (build/vtk/precisemc_pythonpath.txt).
"""
import argparse
import ctypes
import gzip
import json
import math
import os
import platform
import random
import resource
import statistics
import struct
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CACHE = os.environ.get("PMC_BENCH_CACHE", os.path.join(ROOT, "bench", ".cache"))

# --- Volumes --------------------------------------------------------------------


def smooth(n):
    """The wavy sphere of src/samples.rs (samples::smooth), values in [0, 1]."""
    s = n - 1.0
    ax = np.arange(n, dtype=np.float64) / s - 0.5
    w = ax[:, None, None]
    v = ax[None, :, None]
    u = ax[None, None, :]
    r = np.sqrt(u * u + v * v + w * w)
    wave = 0.04 * (np.sin(7.0 * u) + np.sin(9.0 * v) * np.cos(5.0 * w))
    return np.clip(1.0 - 1.6 * r + wave, 0.0, 1.0)  # shape (z, y, x)


def read_vti(path):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader
    r = vtkXMLImageDataReader()
    r.SetFileName(path)
    r.Update()
    img = r.GetOutput()
    nx, ny, nz = img.GetDimensions()
    a = vtk_to_numpy(img.GetPointData().GetScalars())
    return a.reshape(nz, ny, nx).copy()


def read_nifti_frame0(path):
    """Frame 0 of a little- or big-endian NIfTI-1 file (int16/uint8/float32)."""
    raw = open(path, "rb").read()
    if path.endswith(".gz"):
        raw = gzip.decompress(raw)
    for endian in "<>":
        if struct.unpack(endian + "i", raw[:4])[0] == 348:
            break
    dim = struct.unpack(endian + "8h", raw[40:56])
    datatype = struct.unpack(endian + "h", raw[70:72])[0]
    offset = int(struct.unpack(endian + "f", raw[108:112])[0])
    dtype = {2: "u1", 4: "i2", 16: "f4", 512: "u2"}[datatype]
    nx, ny, nz = dim[1:4]
    a = np.frombuffer(raw, dtype=endian + dtype, count=nx * ny * nz, offset=offset)
    return a.reshape(nz, ny, nx).astype(dtype).copy()


def prepare_volumes(quick, tool):
    """Writes CACHE/<name>.npy and returns {name: meta}."""
    os.makedirs(CACHE, exist_ok=True)
    vols = {}

    def put(name, data, iso, desc, group):
        path = os.path.join(CACHE, name + ".npy")
        if not os.path.exists(path):
            np.save(path, np.ascontiguousarray(data))
        vols[name] = dict(path=path, iso=float(iso), desc=desc, group=group,
                          dims=[int(data.shape[2]), int(data.shape[1]), int(data.shape[0])],
                          dtype=str(data.dtype))

    sizes = [64, 128] if quick else [64, 128, 256, 512]
    main_n = 64 if quick else 256
    for n in sizes:
        if os.path.exists(os.path.join(CACHE, f"smooth{n}_f32.npy")):
            f = None
        else:
            f = smooth(n)
        put(f"smooth{n}_f32", f.astype(np.float32) if f is not None else np.load(
            os.path.join(CACHE, f"smooth{n}_f32.npy"), mmap_mode="r"), 0.5,
            f"wavy sphere {n}^3 float32", "main" if n == main_n else "scaling")
        if n == main_n and not quick:
            f = smooth(n) if f is None else f
            put(f"smooth{n}_u8", np.round(255.0 * f).astype(np.uint8), 127.5,
                f"wavy sphere {n}^3 uint8", "main")
            put(f"smooth{n}_i16", np.round(32000.0 * f).astype(np.int16), 16000.5,
                f"wavy sphere {n}^3 int16", "main")
        if n == 512:
            # The large integer volumes: the speed rows and two epsilons
            # (group "large"); float32 at 512^3 is in the scaling rows.
            for tag, scale, dtype, iso in (("u8", 255.0, np.uint8, 127.5),
                                           ("i16", 32000.0, np.int16, 16000.5)):
                if os.path.exists(os.path.join(CACHE, f"smooth{n}_{tag}.npy")):
                    a = np.load(os.path.join(CACHE, f"smooth{n}_{tag}.npy"), mmap_mode="r")
                else:
                    f = smooth(n) if f is None else f
                    a = np.round(scale * f).astype(dtype)
                put(f"smooth{n}_{tag}", a, iso,
                    f"wavy sphere {n}^3 {np.dtype(dtype).name}", "large")

    # The tool's built-in samples, written by the tool itself.
    out = os.path.join(CACHE, "sample.vti")
    if not all(os.path.exists(os.path.join(CACHE, f"sample-{s}.vti")) for s in ("tube", "atoms", "ml")):
        subprocess.run([tool, "--sample", "all", "--epsilon", "0", "-q", "--write-volume", out],
                       check=True)
    for s, iso, desc in (("tube", 50.5, "trefoil tube 48x48x20 uint8 (precisemc --sample tube)"),
                         ("atoms", 50.5, "Gaussian atom chain 40^3 float32 (--sample atoms)"),
                         ("ml", 0.5, "Marschner-Lobb 41^3 float32 (--sample ml)")):
        put(s, read_vti(os.path.join(CACHE, f"sample-{s}.vti")), iso, desc, "small")

    nii = os.path.join(CACHE, "example4d.nii.gz")
    if os.path.exists(nii):
        a = read_nifti_frame0(nii)
        # Brain/background threshold: half way between the background and
        # the mean of the bright (tissue) voxels.
        iso = 0.5 * float(a[a > a.mean()].mean()) + 0.5
        put("brain_epi", a, iso, "fMRI EPI 128x96x24 int16, frame 0 of nibabel's "
            "tests/data/example4d.nii.gz", "small")
    return vols


# --- The C API, through ctypes ---------------------------------------------------

SCALAR = {"int8": 0, "uint8": 1, "int16": 2, "uint16": 3, "int32": 4, "uint32": 5,
          "int64": 6, "uint64": 7, "float32": 8, "float64": 9}


class PmcVolume(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint64), ("data", ctypes.c_void_p),
                ("len", ctypes.c_uint64),
                ("scalar_type", ctypes.c_uint32), ("dims", ctypes.c_uint64 * 3),
                ("strides", ctypes.c_int64 * 3), ("origin", ctypes.c_double * 3),
                ("spacing", ctypes.c_double * 3)]


class PmcDistance(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint64), ("max", ctypes.c_double),
                ("mean", ctypes.c_double), ("rms", ctypes.c_double),
                ("samples", ctypes.c_uint64), ("unresolved", ctypes.c_uint64)]


def library():
    for p in (os.environ.get("PMC_LIBRARY", ""),
              os.path.join(ROOT, "build/core/cargo-target/release/libprecisemc.so")):
        if p and os.path.exists(p):
            lib = ctypes.CDLL(p)
            lib.pmc_measure_distance.restype = ctypes.c_uint32
            lib.pmc_measure_distance.argtypes = [
                ctypes.POINTER(PmcVolume), ctypes.c_double, ctypes.c_void_p, ctypes.c_uint64,
                ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint32, ctypes.POINTER(PmcDistance)]
            return lib
    raise SystemExit("libprecisemc.so not found: build first (bench/run.sh does)")


def measure(volume, iso, points, tris, cap, density):
    """Distance to S_K of the volume (index frame = world, spacing 1): every
    k-th triangle so that at most `cap` are measured."""
    lib = library()
    ntri = len(tris)
    stride = max(1, math.ceil(ntri / cap)) if ntri else 1
    sub = np.ascontiguousarray(tris[::stride], dtype=np.int64)
    pts = np.ascontiguousarray(points, dtype=np.float64)
    v = PmcVolume()  # zeroed
    v.struct_size = ctypes.sizeof(PmcVolume)
    v.data = volume.ctypes.data
    v.len = volume.size
    v.scalar_type = SCALAR[str(volume.dtype)]
    v.dims[:] = [volume.shape[2], volume.shape[1], volume.shape[0]]
    v.strides[:] = [0, 0, 0]
    v.origin[:] = [0.0, 0.0, 0.0]
    v.spacing[:] = [1.0, 1.0, 1.0]
    out = PmcDistance()
    out.struct_size = ctypes.sizeof(PmcDistance)
    status = lib.pmc_measure_distance(ctypes.byref(v), iso, pts.ctypes.data, len(pts),
                                      sub.ctypes.data, len(sub), density, ctypes.byref(out))
    if status != 0:
        raise RuntimeError(f"pmc_measure_distance: status {status}")
    if out.unresolved:
        # Left out of max and mean: a figure over the rest would understate
        # the distance (a surface exists here, so none should be).
        raise RuntimeError(f"pmc_measure_distance: {out.unresolved} of "
                           f"{out.unresolved + out.samples} samples found no point of S_K")
    return dict(max=out.max, mean=out.mean, samples=out.samples, measured_tris=len(sub),
                stride=stride)


# --- Worker: one configuration ----------------------------------------------------


def vm_hwm_kib():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    return 0


def to_image(a):
    from vtkmodules.util.numpy_support import numpy_to_vtk
    from vtkmodules.vtkCommonDataModel import vtkImageData
    img = vtkImageData()
    img.SetDimensions(a.shape[2], a.shape[1], a.shape[0])
    arr = numpy_to_vtk(a.ravel(), deep=False)
    arr.SetName("s")
    img.GetPointData().SetScalars(arr)
    img._keep = a  # numpy_to_vtk(deep=False) does not own the memory
    return img


def build(cfg, img, iso):
    """A fresh pipeline for the configuration; returns its last filter."""
    kind = cfg["kind"]
    if kind == "mc":
        from vtkmodules.vtkFiltersCore import vtkMarchingCubes
        f = vtkMarchingCubes()
        f.ComputeNormalsOff()
        f.ComputeGradientsOff()
        f.ComputeScalarsOff()
        f.SetInputData(img)
    elif kind in ("fe", "upsample"):
        from vtkmodules.vtkFiltersCore import vtkFlyingEdges3D
        f = vtkFlyingEdges3D()
        f.ComputeNormalsOff()
        f.ComputeGradientsOff()
        f.ComputeScalarsOff()
        if kind == "upsample":
            from vtkmodules.vtkCommonCore import VTK_FLOAT
            from vtkmodules.vtkImagingCore import vtkImageResample
            r = vtkImageResample()
            r.SetInputData(img)
            for axis in range(3):
                r.SetAxisMagnificationFactor(axis, cfg["factor"])
            r.SetInterpolationModeToLinear()
            # Integer inputs are resampled to float: rounding the upsampled
            # values back to integers would move the surface.
            r.SetOutputScalarType(VTK_FLOAT)
            r.SetNumberOfThreads(cfg["threads"])
            f.SetInputConnection(r.GetOutputPort())
        else:
            f.SetInputData(img)
    elif kind == "pmc":
        from precisemc import vtkPreciseMarchingCubes
        f = vtkPreciseMarchingCubes()
        f.SetEpsilon(cfg.get("eps", 0.0))
        f.SetMaxLevel(cfg.get("level", 5))
        f.SetRule({"A": 0, "A1": 1, "A2": 2, "B": 3}[cfg.get("rule", "A1")])
        f.SetTopology({"trilinear": 0, "classic": 1}[cfg.get("topology", "trilinear")])
        f.SetComputeNormals(False)
        f.SetComputeScalars(False)
        f.SetNumberOfThreads(cfg["threads"])
        # On vtkSMPTools (the worker's backend and thread count) instead of
        # threads of the library's own.
        f.SetUseSMPTools(cfg.get("smp_tools", False))
        f.SetInputData(img)
    else:
        raise ValueError(kind)
    f.SetValue(0, iso)
    return f


def triangles_of(poly):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    polys = poly.GetPolys()
    n = polys.GetNumberOfCells()
    if n == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    offsets = vtk_to_numpy(polys.GetOffsetsArray())
    conn = vtk_to_numpy(polys.GetConnectivityArray()).astype(np.int64)
    assert np.all(np.diff(offsets) == 3), "triangles expected"
    pts = vtk_to_numpy(poly.GetPoints().GetData()).astype(np.float64)
    return pts, conn.reshape(-1, 3)


INTERLEAVED = (("FE", dict(kind="fe")),
               ("classic", dict(kind="pmc", topology="classic", eps=0.0)),
               ("trilinear", dict(kind="pmc", topology="trilinear", eps=0.0)),
               ("classic SMP", dict(kind="pmc", topology="classic", eps=0.0, smp_tools=True)),
               ("trilinear SMP", dict(kind="pmc", topology="trilinear", eps=0.0,
                                      smp_tools=True)))


def interleaved(cfg):
    """The small volumes' speed comparison in one process: vtkFlyingEdges3D
    (TBB) and PreciseMC with refinement off, each one pipeline kept for
    all calls (as an application that contours again and again), called
    in turn round after round, so that a neighbour's burst on the shared
    machine slows every filter of a round alike. Each round's order is
    shuffled (fixed seed): a call's time depends on the call before it
    (the library's helper threads still watching for work, caches), and
    a rotating order kept the same neighbours in every round (Marschner-Lobb
    classic on 2 threads ran at 1.72x FlyingEdges after it, 1.27-1.34x
    after trilinear).
    Returns each filter's median time and the median over rounds of its
    time over FlyingEdges' in the same round. Runs in `worker`, on the TBB
    backend it sets up with the configuration's threads."""
    img = to_image(np.load(cfg["path"]))
    filters = [(label, build(dict(cfg, **extra), img, cfg["iso"])) for label, extra in INTERLEAVED]
    times = {label: [] for label, _ in filters}
    faults = {label: 0 for label, _ in filters}
    warmup = INTERLEAVED_WARMUP
    order = random.Random(7)
    for k in range(warmup + cfg["rounds"]):
        turn = list(filters)
        order.shuffle(turn)
        for label, f in turn:
            f.Modified()
            before = minor_faults()
            t0 = time.perf_counter()
            f.Update()
            t1 = time.perf_counter()
            if k >= warmup:
                times[label].append(t1 - t0)
                faults[label] += minor_faults() - before
    fe = times["FE"]
    return dict(cfg, malloc=os.environ.get("GLIBC_TUNABLES", ""), filters={
        label: dict(time=statistics.median(ts),
                    ratio=statistics.median(t / e for t, e in zip(ts, fe)),
                    faults=faults[label] / max(1, cfg["rounds"]),
                    tris=int(f.GetOutput().GetNumberOfCells()))
        for (label, f), ts in zip(filters, times.values())})


def minor_faults():
    """Minor page faults of this process so far (all its threads)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def worker(cfg):
    from vtkmodules.vtkCommonCore import vtkSMPTools
    threads = cfg["threads"]
    # Every filter's vtkSMPTools work (VTK's filters, and the copies into
    # vtkPolyData of PreciseMC's) on the configuration's backend: TBB,
    # Debian's default, unless it says otherwise.
    if not vtkSMPTools.SetBackend(cfg.get("smp", "TBB")):
        raise RuntimeError(f"SMP backend {cfg.get('smp', 'TBB')} not available")
    vtkSMPTools.Initialize(threads)
    if cfg["kind"] == "interleaved":
        return interleaved(cfg)
    a = np.load(cfg["path"])
    img = to_image(a)
    # Import everything the run needs before the baseline.
    build(cfg, img, cfg["iso"])
    base = vm_hwm_kib()
    times = []
    cold = []
    poly = None
    extra = {}
    # PreciseMC keeps its working buffers between calls (at most 64 MiB):
    # its calls alternate between cold ones, the buffers released first as
    # for a program that contours once, and warm ones, which reuse those of
    # the call before. The other filters keep nothing: every call is cold.
    pmc = cfg["kind"] == "pmc"
    for i in range(2 * cfg["reps"] if pmc else cfg["reps"]):
        poly = None
        f = build(cfg, img, cfg["iso"])
        fresh = pmc and i % 2 == 0
        if fresh:
            f.ReleaseRetainedMemory()
        t0 = time.perf_counter()
        f.Update()
        (cold if fresh else times).append(time.perf_counter() - t0)
        poly = f.GetOutput()
        if cfg["kind"] == "pmc":
            extra = dict(mc_tris=int(f.GetNumberOfMCTriangles()),
                         above=int(f.GetNumberOfFacesAboveEpsilon()),
                         proj_failures=int(f.GetNumberOfProjectionFailures()))
    peak = vm_hwm_kib()
    pts, tris = triangles_of(poly)
    result = dict(cfg, time=statistics.median(times), time_min=min(times), times=times,
                  tris=int(len(tris)),
                  **(dict(time_cold=statistics.median(cold), times_cold=cold) if cold else {}),
                  mem_mib=(peak - base) / 1024.0, smp=vtkSMPTools.GetBackend(), **extra)
    if cfg.get("measure_cap", 0) > 0 and len(tris):
        t0 = time.perf_counter()
        result["dist"] = measure(a, cfg["iso"], pts, tris, cfg["measure_cap"], cfg["density"])
        result["measure_s"] = time.perf_counter() - t0
    return result


# Keys a worker adds to its configuration.
RESULT_KEYS = ("time", "time_min", "times", "time_cold", "times_cold", "tris", "mem_mib", "smp", "mc_tris", "above",
               "proj_failures", "dist", "measure_s", "dist_all", "error")


# glibc's malloc settings for the interleaved measure (see `run_worker`).
STEADY_MALLOC = "glibc.malloc.trim_threshold=134217728:glibc.malloc.mmap_threshold=33554432"


def run_worker(cfg, env):
    if cfg["kind"] == "interleaved":
        # Fixed trim and mmap thresholds: with glibc's defaults, whether a
        # filter's freed output stays mapped for its next call depends on
        # what else the process allocated and freed before (the thresholds
        # adapt to it), and in some processes every vtkFlyingEdges3D call
        # faulted its output in afresh (about 300 page faults a call on the
        # EPI scan, 200 on Marschner-Lobb: 30-70 % more time), while
        # PreciseMC, which keeps its buffers, did not. Fixed, no filter's
        # call pays for another's frees.
        env = dict(env, GLIBC_TUNABLES=":".join(
            t for t in (env.get("GLIBC_TUNABLES", ""), STEADY_MALLOC) if t))
    try:
        r = subprocess.run([sys.executable, os.path.abspath(__file__), "--worker", json.dumps(cfg)],
                           capture_output=True, text=True, env=env, timeout=900)
    except subprocess.TimeoutExpired:
        # One configuration's row, not the whole run.
        return dict(cfg, error="timed out after 900 s")
    if r.returncode != 0:
        return dict(cfg, error=(r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1])
    return json.loads(r.stdout.strip().splitlines()[-1])


# --- The plan -----------------------------------------------------------------------

EPSILONS = [0.1, 0.03, 0.01, 0.003, 0.001]
SPEED_ROUNDS = 3  # rounds of the FlyingEdges and PreciseMC-off rows
INTERLEAVED_ROUNDS = 300  # rounds of the small volumes' interleaved calls
INTERLEAVED_WARMUP = 5  # unmeasured rounds before them
UPSAMPLE_CAP = 160e6  # largest upsampled volume (samples); 4 bytes each + FE's work
MEASURE_CAP = 25000  # triangles measured per surface (every k-th); 5000 in the quick mode
ALL_TRIANGLES = 10 ** 12  # a cap that measures every triangle


def plan(vols, quick):
    cfgs = []
    # Enough runs for a steady median: the first runs of a process pay for
    # fresh memory and thread start-up, in every filter.
    reps_for = lambda v: 3 if quick else (7 if v["dims"][0] >= 256 else 11)
    # The rows the speed target compares (FlyingEdges, PreciseMC off) run
    # again in later rounds, interleaved with each other, and their time is
    # the median over all rounds' calls: on a shared machine a neighbour's
    # burst then moves both sides of a ratio instead of one.
    rounds = 1 if quick else SPEED_ROUNDS
    for name, v in vols.items():
        if v["group"] == "scaling":
            continue
        reps = 3 if v["dims"][0] >= 512 else reps_for(v)
        base = dict(vol=name, path=v["path"], iso=v["iso"], reps=reps,
                    measure_cap=5000 if quick else MEASURE_CAP, density=3)
        cfgs.append(dict(base, kind="mc", label="vtkMarchingCubes", threads=1))
        for t in (1, 2):
            # The issue asked for STDThread; Debian's default backend, TBB,
            # runs FlyingEdges 1.5-2.5 times faster: both are timed, and
            # ratios are to the faster one.
            for smp in ("TBB", "STDThread"):
                cfgs.append(dict(base, kind="fe", label=f"vtkFlyingEdges3D {t}T {smp}",
                                 threads=t, smp=smp, rounds=rounds))
        for topo in ("classic", "trilinear"):
            for t in ((2,) if quick else (1, 2)):
                cfgs.append(dict(base, kind="pmc", label=f"PreciseMC off {topo} {t}T",
                                 topology=topo, eps=0.0, threads=t, rounds=rounds))
                cfgs.append(dict(base, kind="pmc", label=f"PreciseMC off {topo} {t}T SMP",
                                 topology=topo, eps=0.0, threads=t, rounds=rounds,
                                 smp_tools=True))
        eps_list = [0.03, 0.003] if quick else list(EPSILONS)
        if v["group"] == "large":
            eps_list = [0.01, 0.001]
        if v["group"] == "main" and v["dtype"] != "uint8" and not quick:
            # Smooth data: Marching Cubes is already within ~0.003 cells.
            eps_list += [0.0003, 0.0001]
        for eps in eps_list:
            cfgs.append(dict(base, kind="pmc", label=f"PreciseMC A1 eps {eps} 2T", rule="A1",
                             eps=eps, threads=2))
        if v["group"] == "small" and not quick:
            cfgs.append(dict(base, kind="pmc", label="PreciseMC A1 eps 0.001 L8 2T", rule="A1",
                             eps=0.001, level=8, threads=2))
        if v["group"] == "small" and not quick:
            for rule in ("A", "A2", "B"):
                for eps in (0.01, 0.001):
                    cfgs.append(dict(base, kind="pmc", label=f"PreciseMC {rule} eps {eps} 2T",
                                     rule=rule, eps=eps, threads=2))
        for factor in ((2, 4) if quick else (2, 4, 8)):
            n = v["dims"][0] * v["dims"][1] * v["dims"][2] * factor ** 3
            if n > UPSAMPLE_CAP:
                continue
            # Measured over all their triangles (outside the quick mode):
            # their max is what PreciseMC must reach, and a subset's max is
            # a lower bound (16-19 % low on the atoms' x4 and x8).
            cfgs.append(dict(base, kind="upsample", label=f"upsample x{factor} + FE 2T",
                             factor=factor, threads=2,
                             measure_cap=base["measure_cap"] if quick else ALL_TRIANGLES))
    # Scaling: time and memory against the size, and against epsilon.
    scal = [n for n in vols if n.startswith("smooth") and n.endswith("_f32")]
    for name in scal:
        v = vols[name]
        # As many calls as the speed rows, and the FlyingEdges and
        # PreciseMC-off rows in interleaved rounds too: at 64^3-128^3 a
        # call takes 1-5 ms, and one round of seven calls, the first ones
        # paying for fresh memory, left ratios swinging up to 1.8x.
        reps = 3 if v["dims"][0] >= 512 else reps_for(v)
        base = dict(vol=name, path=v["path"], iso=v["iso"], reps=reps,
                    measure_cap=0, density=3, scaling=True)
        cfgs.append(dict(base, kind="fe", label="vtkFlyingEdges3D 2T TBB", threads=2,
                         rounds=rounds))
        cfgs.append(dict(base, kind="pmc", label="PreciseMC off trilinear 2T", eps=0.0, threads=2,
                         rounds=rounds))
        cfgs.append(dict(base, kind="pmc", label="PreciseMC off trilinear 2T SMP", eps=0.0,
                         threads=2, smp_tools=True, rounds=rounds))
        if not quick:
            cfgs.append(dict(base, kind="mc", label="vtkMarchingCubes", threads=1))
            cfgs.append(dict(base, kind="pmc", label="PreciseMC A1 eps 0.01 2T", rule="A1",
                             eps=0.01, threads=2))
        if v["group"] == "scaling" and v["dims"][0] * 2 <= 256 and not quick:
            cfgs.append(dict(base, kind="upsample", label="upsample x2 + FE 2T", factor=2,
                             threads=2))
    return cfgs


def more_rounds(cfgs, results, env):
    """Runs the configurations with `rounds` > 1 again, round after round
    in plan order (without measuring distances again), and pools their
    calls' times: `time` becomes the median of all of them."""
    for k in range(1, max((c.get("rounds", 1) for c in cfgs), default=1)):
        for cfg, r in zip(cfgs, results):
            if cfg.get("rounds", 1) <= k or "error" in r:
                continue
            again = run_worker(dict(cfg, measure_cap=0), env)
            if "error" in again:
                r["error"] = again["error"]
                continue
            r["times"] += again["times"]
            r["time"] = statistics.median(r["times"])
            r["time_min"] = min(r["times"])
            if "times_cold" in r:
                r["times_cold"] += again["times_cold"]
                r["time_cold"] = statistics.median(r["times_cold"])
            print(f"[round {k + 1}] {r['vol']:>14} {r['label']:<34} "
                  f"{again['time'] * 1000:9.1f} ms (all rounds: {r['time'] * 1000:.1f} ms)",
                  flush=True)


# --- PreciseMC asked for each upsampled surface's accuracy ---------------------------

ASKED = (1.0, 0.8)  # epsilons tried per upsampled surface, as fractions of its max


def asked_configs(cfgs, results):
    """PreciseMC A1 runs (2 threads) whose epsilon is each upsampled
    surface's measured max distance (and a little less, ASKED): what a user
    who wants that accuracy would ask for. Refinement keeps the max close to
    epsilon (since the cubic along interior edges is checked), so these find
    the fewest triangles for the equal-accuracy tables that the fixed
    epsilons above straddle. Epsilons (two significant digits) already run
    for the volume are skipped."""
    out = []
    done = {(c["vol"], c["eps"]) for c in cfgs
            if c["kind"] == "pmc" and c.get("rule") == "A1" and c.get("level", 5) == 5
            and c.get("threads") == 2}
    for cfg, r in zip(cfgs, results):
        if cfg["kind"] != "upsample" or cfg.get("scaling") or "dist" not in r:
            continue
        for k in ASKED:
            eps = float(f"{r['dist']['max'] * k:.2g}")
            if eps <= 0 or (cfg["vol"], eps) in done:
                continue
            done.add((cfg["vol"], eps))
            base = {key: cfg[key] for key in ("vol", "path", "iso", "reps", "density")}
            out.append(dict(base, measure_cap=min(cfg["measure_cap"], MEASURE_CAP), kind="pmc", label=f"PreciseMC A1 eps {eps:g} 2T", rule="A1",
                            eps=eps, threads=2, asked=cfg["factor"]))
    return out


# --- Full maxima of the equal-accuracy candidates ------------------------------------

VERIFY_TRIES = 4  # candidates re-measured per upsampling factor and distance


def full_max(r):
    """The run's max distance over ALL its triangles, when known: measured
    on all of them in the run, or re-measured by `verify_maxima`."""
    if "dist_all" in r:
        return r["dist_all"]["max"]
    d = r.get("dist")
    return d["max"] if d and d.get("stride", 1) == 1 else None


def max_candidates(pm, u):
    """PreciseMC runs whose subset max is within the upsampled surface's
    (a subset max is a lower bound), fewest triangles first."""
    return sorted((r for r in pm if r["dist"]["max"] <= u["dist"]["max"]),
                  key=lambda r: r["tris"])


def holds(r, u):
    """Whether run r's max over all triangles is known and within u's."""
    m = full_max(r)
    return m is not None and m <= u["dist"]["max"]


def reaching_max(pm, u):
    """The run with the fewest triangles whose max over all triangles is
    within the upsampled surface's, among the candidates verified."""
    return next((r for r in max_candidates(pm, u)[:VERIFY_TRIES] if holds(r, u)), None)


def verify_maxima(results, env):
    """Re-measures, over all their triangles, the PreciseMC runs that the
    equal-accuracy tables would take as reaching an upsampled surface's max
    distance on a subset only: a far triangle the subset missed would make
    the claim false. Stops at the first that holds (per factor), or after
    VERIFY_TRIES candidates."""
    by_vol = {}
    for r in results:
        if not r.get("scaling") and "error" not in r:
            by_vol.setdefault(r["vol"], []).append(r)
    for name, rs in by_vol.items():
        pm = [r for r in rs if r["kind"] == "pmc" and "dist" in r]
        for u in (r for r in rs if r["kind"] == "upsample" and "dist" in r):
            for r in max_candidates(pm, u)[:VERIFY_TRIES]:
                if full_max(r) is None:
                    cfg = {k: r[k] for k in r if k not in RESULT_KEYS}
                    v = run_worker(dict(cfg, reps=1, measure_cap=ALL_TRIANGLES), env)
                    if "dist" in v:
                        r["dist_all"] = v["dist"]
                    print(f"[verify] {name:>14} {r['label']:<34} max over all "
                          f"{r['tris']:,} triangles: "
                          + (f"{v['dist']['max']:.4f}" if "dist" in v else
                             f"error: {v.get('error')}"), flush=True)
                if holds(r, u):
                    break


# --- Report --------------------------------------------------------------------------


def fmt_t(s):
    # Milliseconds; three decimals below 10 ms (a small volume's call is
    # 0.1-2 ms: one decimal hid the differences the ratios show).
    ms = s * 1000
    return f"{ms:.3f}" if ms < 10 else (f"{ms:.1f}" if s < 10 else f"{ms:.0f}")


def machine():
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2 ** 30
    import vtkmodules
    return (f"{cpu}, {os.cpu_count()} cores, {mem:.0f} GiB, {platform.system()} "
            f"{platform.release()}, VTK {vtkmodules.__version__}, Python {platform.python_version()}")


def fastest_fe(rs):
    """{threads: the faster vtkFlyingEdges3D run (of the SMP backends timed)}."""
    fe = {}
    for r in rs:
        if r["kind"] == "fe" and "error" not in r:
            t = r["threads"]
            if t not in fe or r["time"] < fe[t]["time"]:
                fe[t] = r
    return fe


def report(vols, results, out, quick, elapsed, mach=None, load=None, date=None, reruns=(),
           interleaved=()):
    lines = []
    add = lines.append
    add("# PreciseMC against VTK\n")
    load = os.getloadavg()[0] if load is None else load
    add(f"Machine: {mach or machine()}. Load average at the start: {load:.2f} "
        "(the machine is shared: compare the ratios, measured side by side).  ")
    add(f"Mode: {'quick' if quick else 'full'}; total run {elapsed:.0f} s; "
        f"{date or time.strftime('%Y-%m-%d')}.\n")
    for rr in reruns:
        on = f", on {rr['machine']}" if rr.get("machine") and rr["machine"] != mach else ""
        add(f"Re-run alone with `--only` ({rr['date']}{on}, load {rr['load']:.2f}, "
            f"{rr['seconds']:.0f} s): "
            f"{', '.join(rr['volumes'])}; their rows (speed, accuracy and their ratios) come "
            "from that run, the other volumes' from the run above.\n")
    add("Times are the median of 7 runs of `Update()` (11 on the volumes under 256^3; "
        "3 in the quick mode and at 512^3; "
        f"the FlyingEdges and PreciseMC-off rows: {SPEED_ROUNDS} rounds of them, interleaved, "
        "median over all rounds' calls, outside the quick mode), "
        "no normals, gradients or scalars in any filter. PreciseMC keeps its working buffers "
        "between calls (at most 64 MiB): its calls alternate between cold ones, those buffers "
        "released first (`ReleaseRetainedMemory()`), as for a program that contours once, and "
        "warm ones, which reuse the buffers of the call before; `time` is the warm median, "
        "`cold` the cold one. The other filters keep nothing, so each of their calls is cold. "
        "Memory: peak RSS (VmHWM) of the "
        "worker process minus its peak after loading the volume. Distances are measured by "
        "`pmc_measure_distance` against S_K of the ORIGINAL volume, in cells, at density 3 "
        "(10 points per triangle), on every k-th triangle when there are more than "
        f"{5000 if quick else MEASURE_CAP} (column `measured`): the max over a subset is a lower "
        "bound of the true max, and so is the max over the 10 points of each triangle (at density "
        "8 a review measured maxima 4-17 % higher, means 20-27 % higher: three of the 10 points "
        "are vertices, on S_K for every filter). "
        "The upsampled surfaces are measured over all their triangles (outside the quick mode). "
        "Upsampling: `vtkImageResample` (linear, float output) by the factor on each axis, "
        "then `vtkFlyingEdges3D`, both with 2 threads; time includes the resampling. "
        "PreciseMC max level 5 (default). SMP backend of VTK's filters (and of PreciseMC's "
        "copies into `vtkPolyData`): TBB, Debian's default; `vtkFlyingEdges3D` also on "
        "STDThread, which the issue named. \"× FE same T\": time over the FASTER "
        "`vtkFlyingEdges3D` run with the same thread count.\n")
    by_vol = {}
    for r in results:
        if r.get("scaling"):
            continue
        by_vol.setdefault(r["vol"], []).append(r)
    for name, rs in by_vol.items():
        v = vols[name]
        add(f"## {name}: {v['desc']}, isovalue {v['iso']:g}\n")
        fe = fastest_fe(rs)
        add("| configuration | time (ms) | × FE same T | cold (ms) | cold × FE | triangles | "
            "Mtris/s | mem (MiB) | max dist | mean dist | measured |")
        add("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rs:
            if "error" in r:
                add(f"| {r['label']} | error: {r['error'][:80]} | | | | | | | | | |")
                continue
            ref = fe.get(min(r["threads"], 2))
            ratio = f"{r['time'] / ref['time']:.2f}" if ref else ""
            cold, cold_ratio = "", ""
            if "time_cold" in r:
                cold = fmt_t(r["time_cold"])
                cold_ratio = f"{r['time_cold'] / ref['time']:.2f}" if ref else ""
            d = r.get("dist", {})
            meas = (f"{d['measured_tris']}" + (f" (1/{d['stride']})" if d.get("stride", 1) > 1
                                                 else "")) if d else ""
            add(f"| {r['label']} | {fmt_t(r['time'])} | {ratio} | {cold} | {cold_ratio} | "
                f"{r['tris']:,} | "
                f"{r['tris'] / r['time'] / 1e6:.2f} | {r['mem_mib']:.0f} | "
                f"{d.get('max', float('nan')):.4f} | {d.get('mean', float('nan')):.5f} | {meas} |")
        add("")
        # Equal accuracy: the cheapest PreciseMC run reaching each upsampling
        # factor's measured max (and mean) distance.
        ups = [r for r in rs if r["kind"] == "upsample" and "dist" in r]
        pm = [r for r in rs if r["kind"] == "pmc" and "dist" in r]
        if ups and pm:
            add("Equal accuracy (PreciseMC runs with the fewest triangles whose measured "
                "distance is at most the upsampled surface's; for the max, measured over ALL "
                "the run's triangles: a run measured on a subset is re-measured whole, "
                "\"all: ...\", before it counts, and at most "
                f"{VERIFY_TRIES} candidates are tried; time ratios of warm PreciseMC calls, "
                "in brackets of cold ones):\n")
            add("| upsampling | its max / mean | its tris | its ms | PreciseMC for ≤ max | tris ratio "
                "| time ratio | PreciseMC for ≤ mean | tris ratio | time ratio |")
            add("|---|---|---:|---:|---|---:|---:|---|---:|---:|")
            for u in ups:
                row = [f"x{u['factor']}", f"{u['dist']['max']:.4f} / {u['dist']['mean']:.5f}",
                       f"{u['tris']:,}", fmt_t(u["time"])]
                for key in ("max", "mean"):
                    if key == "max":
                        best = reaching_max(pm, u)
                    else:
                        ok = [r for r in pm if r["dist"][key] <= u["dist"][key]]
                        best = min(ok, key=lambda r: r["tris"]) if ok else None
                    if best:
                        note = (f" (all: {best['dist_all']['max']:.4f})"
                                if key == "max" and "dist_all" in best else "")
                        ratio = f"{best['time'] / u['time']:.2f}"
                        if "time_cold" in best:
                            ratio += f" ({best['time_cold'] / u['time']:.2f})"
                        row += [best["label"].replace("PreciseMC ", "") + note,
                                f"{best['tris'] / u['tris']:.2f}", ratio]
                    else:
                        row += ["not reached", "", ""]
                add("| " + " | ".join(row) + " |")
            add("")
    add("## Targets\n")
    add("Refinement off against vtkFlyingEdges3D at the same thread count (time ratio, "
        "< 1 is faster), on every volume (the small samples too, where a call takes under "
        "2 ms); each cell: the library's own threads / its tasks on vtkSMPTools "
        "(UseSMPTools):\n")
    add("| volume | calls | classic 1T | classic 2T | trilinear 1T | trilinear 2T |")
    add("|---|---|---:|---:|---:|---:|")
    for name, rs in by_vol.items():
        fe = fastest_fe(rs)
        for key, calls in (("time", "warm"), ("time_cold", "cold")):
            cells = []
            for topo in ("classic", "trilinear"):
                for t in (1, 2):
                    pair = []
                    for suffix in ("", " SMP"):
                        m = [r for r in rs
                             if r.get("label") == f"PreciseMC off {topo} {t}T{suffix}"
                             and key in r]
                        pair.append(f"{m[0][key] / fe[t]['time']:.2f}" if m and t in fe else "-")
                    cells.append(" / ".join(pair))
            add(f"| {name} | {calls} | " + " | ".join(cells) + " |")
    if interleaved:
        rounds = max((r.get("rounds", 0) for r in interleaved), default=0)
        ran = [STEADY_MALLOC in r.get("malloc", "") for r in interleaved if "error" not in r]
        fixed = (f"glibc's malloc thresholds fixed (`GLIBC_TUNABLES={STEADY_MALLOC}`); with "
                 "its defaults, in some processes every FlyingEdges call faulted its output in "
                 "afresh")
        if all(ran):
            malloc_note = f" The processes ran with {fixed}."
        elif any(ran):
            malloc_note = (f" Rows with a fault count ran with {fixed}; the others (`-`, "
                           "measured before the count) with the defaults.")
        else:
            malloc_note = (" These rows ran with glibc's default malloc thresholds, with which "
                           "in some processes every FlyingEdges call faulted its output in "
                           "afresh (the measure fixes them, and counts the faults, since "
                           "2026-12-01; `-`: not counted).")
        # Rows re-run alone (`--interleaved-only`) carry when and where.
        runs = {}
        for r in interleaved:
            if "when" in r:
                w = r["when"]
                on = f", on {w['machine']}" if w.get("machine") and w["machine"] != mach else ""
                runs.setdefault(f"{w['date']}{on}, load {w['load']:.2f}", []).append(r["vol"])
        again = "".join(f" (re-run alone with `--interleaved-only`, {k}: "
                        f"{', '.join(dict.fromkeys(v))})" for k, v in runs.items())
        add("\nThe small volumes again, the filters interleaved in one process"
            f"{again}: vtkFlyingEdges3D (TBB) and PreciseMC with refinement off, one pipeline "
            f"each for all calls, called in turn for {rounds} rounds (after "
            f"{INTERLEAVED_WARMUP} unmeasured), each round's order shuffled (fixed seed); "
            "median time in ms, and in brackets the median over rounds of the call's time "
            "over FlyingEdges' call of the same round (own threads; SMP: tasks on "
            "vtkSMPTools); last column: the minor page faults a call of FlyingEdges and "
            "the most of any PreciseMC row (means over the rounds)."
            + malloc_note + "\n")
        labels = [label for label, _ in INTERLEAVED]
        add("| volume | threads | " + " | ".join(labels) + " | faults a call |")
        add("|---|---:|" + "---:|" * len(labels) + "---:|")
        for r in interleaved:
            if "error" in r:
                add(f"| {r['vol']} | {r['threads']} | error: {r['error'][:80]} |")
                continue
            fs = r["filters"]
            faults = "-"
            if all("faults" in x for x in fs.values()):
                most = max(x["faults"] for l, x in fs.items() if l != "FE")
                faults = f"{fs['FE']['faults']:.0f} / {most:.0f}"
            add(f"| {r['vol']} | {r['threads']} | " + " | ".join(
                f"{fs[l]['time'] * 1000:.3f}" + ("" if l == "FE" else f" ({fs[l]['ratio']:.2f})")
                for l in labels) + f" | {faults} |")
    refined = [r for r in results if r.get("kind") == "pmc" and r.get("eps", 0) > 0
               and "error" not in r and r["threads"] == 2 and r["tris"] >= 1e6]
    if refined:
        def rates(key):
            return [r["tris"] / r[key] / 1e6 for r in refined if key in r]
        best = max(refined, key=lambda r: r["tris"] / r["time"])
        cold = rates("time_cold")
        add(f"\nRefined output on 2 threads (runs with at least 1 M triangles): best "
            f"{max(rates('time')):.2f} M triangles/s warm ({best['vol']}, {best['label']}), "
            f"median {statistics.median(rates('time')):.2f} M/s warm over {len(refined)} runs"
            + (f"; cold: best {max(cold):.2f}, median {statistics.median(cold):.2f} M/s"
               if cold else "") + " (target: 10 M/s).")
    add("\nEqual measured max distance: see the \"Equal accuracy\" tables (target: at most "
        "1/4 of the triangles of upsample-then-contour, and less time).\n")
    sc = [r for r in results if r.get("scaling") and "error" not in r]
    if sc:
        add("## Scaling (wavy sphere float32)\n")
        add("| volume | configuration | time (ms) | cold (ms) | triangles | Mcells/s | "
            "mem (MiB) |")
        add("|---|---|---:|---:|---:|---:|---:|")
        for r in sc:
            n = vols[r["vol"]]["dims"]
            cells = (n[0] - 1) * (n[1] - 1) * (n[2] - 1)
            cold = fmt_t(r["time_cold"]) if "time_cold" in r else ""
            add(f"| {r['vol']} | {r['label']} | {fmt_t(r['time'])} | {cold} | {r['tris']:,} | "
                f"{cells / r['time'] / 1e6:.1f} | {r['mem_mib']:.0f} |")
        add("")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(out, "results.md"), "w") as f:
        f.write(text)
    return text


def plots(vols, results, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ok = [r for r in results if "error" not in r]

    # Error against triangles, one panel per volume with measured runs.
    names = [n for n in vols if any(r["vol"] == n and "dist" in r and not r.get("scaling")
                                    for r in ok)]
    cols = min(4, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.8 * rows), squeeze=False)
    for ax, name in zip(axes.flat, names):
        rs = [r for r in ok if r["vol"] == name and "dist" in r and not r.get("scaling")]
        groups = [("PreciseMC A1", lambda r: r["kind"] == "pmc" and r.get("rule") == "A1"
                   and r.get("eps", 0) > 0, "o", "-", "C0"),
                  ("PreciseMC off", lambda r: r["kind"] == "pmc" and r.get("eps", 0) == 0, "s",
                   "", "C1"),
                  ("upsample+FE", lambda r: r["kind"] == "upsample", "^", "-", "C2"),
                  ("vtkMarchingCubes", lambda r: r["kind"] == "mc", "x", "", "C3"),
                  ("PreciseMC A/A2/B", lambda r: r["kind"] == "pmc" and r.get("rule") in
                   ("A", "A2", "B") and r.get("eps", 0) > 0, ".", "", "C4")]
        for label, pred, marker, line, color in groups:
            g = sorted((r for r in rs if pred(r)), key=lambda r: r["tris"])
            if g:
                # The max over all triangles where it was measured (the
                # upsampled surfaces, the verified PreciseMC runs).
                ax.loglog([r["tris"] for r in g],
                          [max(full_max(r) or r["dist"]["max"], 1e-6) for r in g],
                          marker=marker, ls=line or "none", color=color, label=label, ms=4)
                ax.loglog([r["tris"] for r in g], [max(r["dist"]["mean"], 1e-7) for r in g],
                          marker=marker, ls="--" if line else "none", color=color, alpha=0.45,
                          ms=3)
        ax.set_title(name, fontsize=8)
        # Minor ticks get labels on an axis spanning under a decade: small
        # and slanted, or they run into each other.
        ax.tick_params(labelsize=7)
        ax.tick_params(axis="x", which="minor", labelsize=5, labelrotation=30)
        ax.set_xlabel("triangles", fontsize=7)
        ax.set_ylabel("distance to S_K (cells)", fontsize=7)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=6)
    fig.suptitle("max (solid; over all triangles where measured so, else over a subset: a "
                 "lower bound) and mean (faded) distance to S_K vs triangles", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "error_vs_triangles.png"), dpi=80)
    plt.close(fig)

    # Time and memory against size.
    sc = [r for r in ok if r.get("scaling")]
    if sc:
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(8, 3))
        for label in sorted({r["label"] for r in sc}):
            g = sorted((r for r in sc if r["label"] == label), key=lambda r: vols[r["vol"]]["dims"][0])
            xs = [vols[r["vol"]]["dims"][0] ** 3 for r in g]
            a1.loglog(xs, [r["time"] for r in g], "o-", label=label, ms=3)
            a2.loglog(xs, [max(r["mem_mib"], 0.1) for r in g], "o-", label=label, ms=3)
        a1.set_xlabel("samples (64^3 .. 512^3)", fontsize=7)
        a1.set_ylabel("time (s)", fontsize=7)
        a2.set_xlabel("samples", fontsize=7)
        a2.set_ylabel("peak extra memory (MiB)", fontsize=7)
        for a in (a1, a2):
            a.tick_params(labelsize=7)
        a1.legend(fontsize=6)
        fig.tight_layout()
        fig.savefig(os.path.join(out, "time_vs_size.png"), dpi=80)
        plt.close(fig)

    # Time and memory against epsilon (PreciseMC A1, max level 5), each
    # main/small volume.
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(8, 3))
    for name in vols:
        g = sorted((r for r in ok if r["vol"] == name and r["kind"] == "pmc" and
                    r.get("rule") == "A1" and r.get("eps", 0) > 0 and r.get("level", 5) == 5
                    and not r.get("scaling")), key=lambda r: r["eps"])
        if g:
            ax.loglog([r["eps"] for r in g], [r["time"] for r in g], "o-", label=name, ms=3)
            bx.loglog([r["eps"] for r in g], [max(r["mem_mib"], 0.1) for r in g], "o-",
                      label=name, ms=3)
    ax.set_ylabel("time (s), rule A1, 2 threads", fontsize=7)
    bx.set_ylabel("peak extra memory (MiB)", fontsize=7)
    for a in (ax, bx):
        a.set_xlabel("epsilon (cells)", fontsize=7)
        a.tick_params(labelsize=7)
        a.invert_xaxis()
    ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "time_vs_epsilon.png"), dpi=80)
    plt.close(fig)


def run_interleaved(vols, names, quick, env):
    """The interleaved measure of the small volumes (those in `names`
    unless it is None), on 1 and 2 threads; one result a run."""
    inter = []
    for name, v in vols.items():
        if v["group"] != "small" or (names is not None and name not in names):
            continue
        for t in (1, 2):
            r = run_worker(dict(kind="interleaved", vol=name, path=v["path"], iso=v["iso"],
                                threads=t, rounds=50 if quick else INTERLEAVED_ROUNDS), env)
            inter.append(r)
            print(f"[interleaved] {name:>14} {t}T " + (
                f"error: {r['error']}" if "error" in r else "  ".join(
                    f"{label} {x['time'] * 1000:.3f} ms ({x['ratio']:.2f})"
                    for label, x in r["filters"].items())), flush=True)
    return inter


def interleaved_only(args, vols, out, load):
    """`--interleaved-only`: the interleaved measure again, its rows
    replaced in OUT/results.json (each marked with when and where it ran),
    every other row kept; the report and plots rewritten."""
    path = os.path.join(out, "results.json")
    if not os.path.exists(path):
        print(f"bench: --interleaved-only needs an earlier run's {path}", file=sys.stderr)
        return 2
    with open(path) as f:
        saved = json.load(f)
    if saved["quick"] != args.quick:
        print("bench: --interleaved-only must match the earlier run's mode (--quick or not)",
              file=sys.stderr)
        return 2
    names = set(args.only.split(",")) if args.only else None
    small = {n for n, v in vols.items() if v["group"] == "small"}
    if names is not None and not names <= small:
        print(f"bench: not small volumes: {', '.join(sorted(names - small))}; "
              f"small: {', '.join(sorted(small))}", file=sys.stderr)
        return 2
    when = dict(date=time.strftime("%Y-%m-%d"), load=load, machine=machine())
    inter = [dict(r, when=when) for r in run_interleaved(vols, names, args.quick, dict(os.environ))]
    fresh = {(r["vol"], r["threads"]) for r in inter}
    inter += [r for r in saved.get("interleaved", []) if (r["vol"], r["threads"]) not in fresh]
    order = {name: i for i, name in enumerate(vols)}
    inter.sort(key=lambda r: (order.get(r["vol"], len(order)), r["threads"]))
    saved["interleaved"] = inter
    with open(path, "w") as f:
        json.dump(saved, f, indent=1)
    report(saved["volumes"], saved["results"], out, saved["quick"], saved["seconds"],
           saved.get("machine"), saved.get("load"), saved.get("date"),
           saved.get("reruns", ()), inter)
    plots(saved["volumes"], saved["results"], out)
    print(f"bench: interleaved measure, {len(fresh)} runs; results in {out}")
    return 1 if any("error" in r for r in inter) else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small volumes, a minute or so")
    ap.add_argument("--out", default=None, help="results folder (default bench/results, "
                    "bench/results-quick with --quick)")
    ap.add_argument("--tool", default=os.path.join(ROOT, "build/vtk/bin/precisemc"))
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--report-only", action="store_true",
                    help="rebuild results.md and the plots from OUT/results.json")
    ap.add_argument("--only", default=None, metavar="VOL[,VOL...]",
                    help="run only these volumes' configurations (names as in results.md, "
                    "e.g. ml,brain_epi) and replace their rows in OUT/results.json, "
                    "keeping the other volumes' rows of the earlier run")
    ap.add_argument("--interleaved-only", action="store_true",
                    help="run only the small volumes' interleaved measure (those of --only, "
                    "if given) and replace its rows in OUT/results.json, keeping every "
                    "other row of the earlier run")
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return 0
    out = args.out or os.path.join(ROOT, "bench", "results-quick" if args.quick else "results")
    os.makedirs(out, exist_ok=True)
    if args.report_only:
        with open(os.path.join(out, "results.json")) as f:
            saved = json.load(f)
        report(saved["volumes"], saved["results"], out, saved["quick"], saved["seconds"],
               saved.get("machine"), saved.get("load"), saved.get("date"),
               saved.get("reruns", ()), saved.get("interleaved", ()))
        plots(saved["volumes"], saved["results"], out)
        return 0
    start = time.perf_counter()
    load = os.getloadavg()[0]
    vols = prepare_volumes(args.quick, args.tool)
    if args.interleaved_only:
        return interleaved_only(args, vols, out, load)
    cfgs = plan(vols, args.quick)
    kept = []
    if args.only:
        only = set(args.only.split(","))
        unknown = only - set(vols)
        if unknown:
            print(f"bench: unknown volume(s) {', '.join(sorted(unknown))}; "
                  f"known: {', '.join(vols)}", file=sys.stderr)
            return 2
        with open(os.path.join(out, "results.json")) as f:
            saved = json.load(f)
        if saved["quick"] != args.quick:
            print("bench: --only must match the earlier run's mode (--quick or not)",
                  file=sys.stderr)
            return 2
        kept = [r for r in saved["results"] if r["vol"] not in only]
        cfgs = [c for c in cfgs if c["vol"] in only]
    env = dict(os.environ)
    results = []

    def run_all(batch):
        for cfg in batch:
            r = run_worker(cfg, env)
            results.append(r)
            d = r.get("dist")
            print(f"[{len(results)}/{len(cfgs)}] {r['vol']:>14} {r['label']:<34} "
                  + (f"error: {r['error']}" if "error" in r else
                     f"{r['time'] * 1000:9.1f} ms {r['tris']:>10,} tris {r['mem_mib']:7.0f} MiB"
                     + (f"  max {d['max']:.4f} mean {d['mean']:.5f}" if d else "")), flush=True)

    run_all(cfgs)
    # Then PreciseMC asked for each upsampled surface's measured accuracy.
    asked = asked_configs(cfgs, results)
    cfgs = cfgs + asked
    run_all(asked)
    more_rounds(cfgs, results, env)
    verify_maxima(results, env)
    # The small volumes' speed rows again, the filters interleaved in one
    # process (their calls take 0.1-2 ms, where a fresh pipeline a call
    # and a neighbour's burst move the ratios above by a third).
    inter = run_interleaved(vols, only if args.only else None, args.quick, env)
    if args.only:
        inter = [r for r in saved.get("interleaved", []) if r["vol"] not in only] + inter
    # The rows of the volumes not re-run, in plan order around the new ones.
    order = {name: i for i, name in enumerate(vols)}
    inter.sort(key=lambda r: (order[r["vol"]], r["threads"]))
    results = sorted(kept + results, key=lambda r: (r.get("scaling", False), order[r["vol"]]))
    elapsed = time.perf_counter() - start
    run = dict(seconds=elapsed, load=load, date=time.strftime("%Y-%m-%d"))
    mach = machine()
    reruns = []
    if args.only:
        # The header keeps the full run's figures and machine; this run is
        # listed apart, with its own (it may be another machine).
        # An earlier re-run keeps only the volumes this one leaves alone
        # (listed with none, it is dropped: its rows are all replaced).
        earlier = [dict(rr, volumes=[v for v in rr["volumes"] if v not in only])
                   for rr in saved.get("reruns", [])]
        reruns = [rr for rr in earlier if rr["volumes"]]
        reruns.append(dict(run, volumes=sorted(only), machine=mach))
        run = dict(seconds=saved["seconds"], load=saved["load"], date=saved["date"])
        mach = saved.get("machine") or mach
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(dict(volumes=vols, results=results, machine=mach, quick=args.quick,
                       reruns=reruns, interleaved=inter, **run), f, indent=1)
    report(vols, results, out, args.quick, run["seconds"], mach=mach, load=run["load"],
           date=run["date"], reruns=reruns, interleaved=inter)
    plots(vols, results, out)
    print(f"bench: {len(results)} configurations in {elapsed:.0f} s; results in {out}")
    failed = [r for r in results + inter if "error" in r]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
