#!/usr/bin/python3
"""Tests of the precisemc command-line tool, run by tests/cli/run.sh.

A plain script (not pytest) so that it can count its checks and print the
closing line "cli: N passed, M failed". It needs Debian's /usr/bin/python3
(VTK's Python bindings) to write the input volumes and read the outputs
back. Environment: PRECISEMC (the tool), CLI_TMP (scratch directory).
"""
import math
import os
import re
import shutil
import signal
import stat
import struct
import subprocess
import sys
import tempfile
import time
import tomllib
import traceback

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkStringArray
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkIOGeometry import vtkOBJReader, vtkSTLReader
from vtkmodules.vtkIOImage import vtkMetaImageWriter, vtkNIFTIImageWriter, vtkPNGReader
from vtkmodules.vtkIOLegacy import vtkStructuredPointsWriter
from vtkmodules.vtkIOPLY import vtkPLYReader
from vtkmodules.vtkIOXML import vtkXMLImageDataWriter, vtkXMLPolyDataReader

TOOL = os.environ.get("PRECISEMC", "build/vtk/bin/precisemc")
SCRATCH = os.environ.get("CLI_TMP") or tempfile.mkdtemp(prefix="precisemc-cli-")
TIMEOUT = 300

CHECKS = []


def check(fn):
    CHECKS.append(fn)
    return fn


class Failure(Exception):
    pass


class Skipped(Exception):
    """A check that cannot run here: reported and counted, not a pass."""


def expect(condition, message):
    if not condition:
        raise Failure(message)


def run(*args, env=None, cwd=None):
    environment = dict(os.environ)
    # Exercise the tool's own display handling (a private Xvfb).
    environment.pop("DISPLAY", None)
    if env:
        environment.update(env)
    return subprocess.run([TOOL, *map(str, args)], capture_output=True, text=True, env=environment,
                          cwd=cwd, timeout=TIMEOUT)


DICOM_FRAME_WARNING = "the series' patient position and orientation are not applied"


def ok(*args, warns=None, **kw):
    """A successful run: status 0 and nothing on stderr, or with `warns` one
    line 'precisemc: warning: ...' holding it."""
    r = run(*args, **kw)
    expect(r.returncode == 0, f"exit status {r.returncode}, stderr: {r.stderr.strip()!r}")
    if warns is None:
        expect(r.stderr == "", f"unexpected stderr on success: {r.stderr!r}")
    else:
        lines = r.stderr.splitlines()
        expect(len(lines) == 1 and lines[0].startswith("precisemc: warning: ") and
               warns in lines[0], f"want one warning with {warns!r}, stderr: {r.stderr!r}")
    return r


def fresh_dir(name):
    d = os.path.join(SCRATCH, name)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    return d


def table_value(stdout, key):
    """The integer of row `key` of the first table ('output triangles 7 030 (x...)')."""
    m = re.search(r"^  " + re.escape(key) + r"\s+([0-9 ]+[0-9])", stdout, re.M)
    expect(m, f"no row {key!r} in the table:\n{stdout}")
    return int(m.group(1).replace(" ", ""))


def table_values(stdout, key):
    return [int(v.replace(" ", "")) for v in
            re.findall(r"^  " + re.escape(key) + r"\s+([0-9 ]+[0-9])", stdout, re.M)]


def expect_error(args, fragment=None, outputs=(), status=None, env=None, cwd=None):
    """A failing run: non-zero status, exactly one stderr line 'precisemc:
    error: ...', nothing on stdout, none of `outputs` (nor temporary files
    next to them) left behind."""
    r = run(*args, env=env, cwd=cwd)
    expect(r.returncode != 0, f"exit status 0 for {args}")
    if status is not None:
        expect(r.returncode == status, f"exit status {r.returncode}, expected {status}")
    lines = r.stderr.splitlines()
    expect(len(lines) == 1, f"expected one stderr line, got {len(lines)}: {r.stderr!r}")
    expect(lines[0].startswith("precisemc: error: "), f"stderr: {lines[0]!r}")
    if fragment:
        expect(fragment.lower() in lines[0].lower(), f"{fragment!r} not in {lines[0]!r}")
    expect(r.stdout == "", f"stdout not empty: {r.stdout!r}")
    for path in outputs:
        expect(not os.path.exists(path), f"{path} was written")
        d = os.path.dirname(path) or "."
        if os.path.isdir(d):
            leftovers = [f for f in os.listdir(d) if ".tmp" in f]
            expect(not leftovers, f"temporary files left: {leftovers}")
    return lines[0]


# --- Reading outputs back -----------------------------------------------------

def read_surface(path):
    ext = os.path.splitext(path)[1].lower()
    reader = {".vtp": vtkXMLPolyDataReader, ".ply": vtkPLYReader, ".stl": vtkSTLReader,
              ".obj": vtkOBJReader}[ext]()
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


def png_size(path):
    expect(os.path.isfile(path) and os.path.getsize(path) > 1000, f"{path} missing or tiny")
    with open(path, "rb") as f:
        head = f.read(24)
    expect(head[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG")
    reader = vtkPNGReader()
    reader.SetFileName(path)
    reader.Update()
    dims = reader.GetOutput().GetDimensions()
    # Not a blank picture: some variation in the pixels.
    scalars = reader.GetOutput().GetPointData().GetScalars()
    lo, hi = scalars.GetRange(0)
    expect(hi - lo > 50, f"{path} looks blank (red channel range {lo}..{hi})")
    return dims[0], dims[1]


# --- Input volumes --------------------------------------------------------------

def blob_volume():
    """Two Gaussian blobs on a 24x20x18 grid, float32, anisotropic spacing;
    scalar range about [0, 100]."""
    nx, ny, nz = 24, 20, 18
    z, y, x = np.mgrid[0:nz, 0:ny, 0:nx].astype(np.float64)
    v = 100.0 * np.exp(-((x - 8.3) ** 2 + (y - 9.6) ** 2 + (z - 8.1) ** 2) / 18.0)
    v += 80.0 * np.exp(-((x - 15.7) ** 2 + (y - 10.2) ** 2 + (z - 9.4) ** 2) / 12.0)
    return (nx, ny, nz), (0.8, 0.9, 1.1), (1.0, -2.0, 0.5), v.astype(np.float32)


def density_image(values, dims, spacing, origin):
    """`values` (z, y, x order) as image data with scalars "density"."""
    image = vtkImageData()
    image.SetDimensions(*dims)
    image.SetSpacing(*spacing)
    image.SetOrigin(*origin)
    arr = numpy_to_vtk(np.ascontiguousarray(values).ravel(), deep=True)
    arr.SetName("density")
    image.GetPointData().SetScalars(arr)
    return image


def blob_image():
    dims, spacing, origin, v = blob_volume()
    return density_image(v, dims, spacing, origin)


def write_inputs(d):
    """The blob volume in every readable format; returns {label: path}."""
    image = blob_image()
    paths = {}

    w = vtkXMLImageDataWriter()
    paths["vti"] = os.path.join(d, "blob.vti")
    w.SetFileName(paths["vti"])
    w.SetInputData(image)
    w.Write()

    w = vtkStructuredPointsWriter()
    paths["vtk"] = os.path.join(d, "blob.vtk")
    w.SetFileName(paths["vtk"])
    w.SetInputData(image)
    w.SetFileTypeToBinary()
    w.Write()

    for ext in ("mha", "mhd"):
        w = vtkMetaImageWriter()
        paths[ext] = os.path.join(d, "blob." + ext)
        w.SetFileName(paths[ext])
        if ext == "mhd":
            w.SetRAWFileName(os.path.join(d, "blob.raw"))
        w.SetCompression(False)
        w.SetInputData(image)
        w.Write()

    for ext in ("nii", "nii.gz"):
        w = vtkNIFTIImageWriter()
        paths[ext] = os.path.join(d, "blob." + ext)
        w.SetFileName(paths[ext])
        w.SetInputData(image)
        w.Write()

    # VTK has no NRRD writer: the format is a text header and raw data.
    dims, spacing, _, v = blob_volume()
    header = ("NRRD0004\ntype: float\ndimension: 3\nsizes: %d %d %d\nspacings: %g %g %g\n"
              "endian: little\nencoding: raw\n" % (*dims, *spacing))
    paths["nrrd"] = os.path.join(d, "blob.nrrd")
    with open(paths["nrrd"], "wb") as f:
        f.write(header.encode() + b"\n" + v.astype("<f4").tobytes())
    paths["nhdr"] = os.path.join(d, "blob.nhdr")
    with open(os.path.join(d, "blob-nrrd.raw"), "wb") as f:
        f.write(v.astype("<f4").tobytes())
    with open(paths["nhdr"], "w") as f:
        f.write(header + "data file: blob-nrrd.raw\n\n")
    return paths


# --- Checks ---------------------------------------------------------------------

@check
def help_and_version():
    r = ok("--help")
    expect(r.stdout.startswith("usage: precisemc"), "help text")
    for option in ("--value", "--array", "--epsilon", "--max-level", "--rule", "--topology", "--filter",
                   "catmull-rom", "bspline-interpolating", "--normals", "--gradients",
                   "--max-triangles", "--threads", "--smp", "--output", "--compare", "--distance",
                   "--quiet", "--sample", "--version"):
        expect(option in r.stdout, f"{option} not in --help")
    r = ok("--version")
    # The crate's version: the tool's build reads it from Cargo.toml.
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "Cargo.toml"),
              "rb") as f:
        version = tomllib.load(f)["package"]["version"]
    expect(r.stdout.startswith(f"precisemc {version} (VTK 9."), f"{r.stdout!r}, crate {version}")


def sample_check(name):
    def fn():
        d = fresh_dir("sample-" + name)
        out = os.path.join(d, name + ".vtp")
        r = ok("--sample", name, "-o", out)
        expect(r.stdout.startswith(name + ": "), f"table header: {r.stdout[:80]!r}")
        mc = table_value(r.stdout, "MC triangles")
        refined = table_value(r.stdout, "output triangles")
        expect(0 < mc < refined, f"MC {mc}, output {refined}: refinement added nothing")
        for key in ("cells", "maxL / meanL", "time", "isovalue"):
            expect(re.search(r"^  " + re.escape(key), r.stdout, re.M), f"no row {key}")
        pd = read_surface(out)
        expect(pd.GetNumberOfPolys() == refined,
               f"{out}: {pd.GetNumberOfPolys()} triangles, table says {refined}")
        expect(pd.GetPointData().GetNormals() is not None, "no normals in the .vtp")
        expect(pd.GetCellData().GetArray("RefinementLevel") is not None, "no RefinementLevel")
    fn.__name__ = "sample_" + name
    return fn


for _name in ("tube", "atoms", "ml"):
    check(sample_check(_name))


@check
def sample_all_writes_one_file_per_sample():
    d = fresh_dir("sample-all")
    r = ok("--sample", "all", "-o", os.path.join(d, "s.vtp"))
    refined = table_values(r.stdout, "output triangles")
    expect(len(refined) == 3, f"{len(refined)} tables")
    for name, count in zip(("tube", "atoms", "ml"), refined):
        pd = read_surface(os.path.join(d, f"s-{name}.vtp"))
        expect(pd.GetNumberOfPolys() == count, f"s-{name}.vtp: {pd.GetNumberOfPolys()} != {count}")
    expect(sorted(os.listdir(d)) == ["s-atoms.vtp", "s-ml.vtp", "s-tube.vtp"], os.listdir(d))
    # No input and no --sample: the same three samples.
    r2 = ok("-q")
    expect(r2.stdout == "", "-q printed something")
    r3 = ok()
    expect(table_values(r3.stdout, "output triangles") == refined, "default run differs")


def format_check(ext):
    def fn():
        d = fresh_dir("format-" + ext)
        out = os.path.join(d, "atoms." + ext)
        r = ok("--sample", "atoms", "-o", out)
        refined = table_value(r.stdout, "output triangles")
        pd = read_surface(out)
        expect(pd.GetNumberOfPolys() == refined,
               f"{out}: {pd.GetNumberOfPolys()} triangles read back, table says {refined}")
        expect(pd.GetNumberOfPoints() >= 3, "no points")
        expect(os.listdir(d) == ["atoms." + ext], f"extra files: {os.listdir(d)}")
    fn.__name__ = "output_" + ext
    return fn


for _ext in ("vtp", "ply", "stl", "obj"):
    check(format_check(_ext))


@check
def input_formats():
    d = fresh_dir("inputs")
    paths = write_inputs(d)
    counts = {}
    for label, path in paths.items():
        out = os.path.join(d, f"out-{label.replace('.', '-')}.vtp")
        r = run(path, "-o", out)
        expect(r.returncode == 0, f"{label}: {r.stderr.strip()}")
        expect(re.search(r"^isovalue [0-9.]+: the middle of the scalar range", r.stdout, re.M),
               f"{label}: default isovalue not announced:\n{r.stdout}")
        counts[label] = table_value(r.stdout, "output triangles")
        expect(read_surface(out).GetNumberOfPolys() == counts[label], f"{label}: read back")
    # The same samples in every format: the same surface.
    expect(len(set(counts.values())) == 1, f"triangle counts differ between formats: {counts}")
    expect(set(paths) == {"vti", "vtk", "mha", "mhd", "nii", "nii.gz", "nrrd", "nhdr"}, paths)


@check
def input_dicom_series():
    from dicom import write_series
    d = fresh_dir("dicom")
    _, spacing, _, v = blob_volume()
    series = os.path.join(d, "series")
    write_series(series, np.round(v * 10.0).astype(np.int16), spacing)
    out = os.path.join(d, "dicom.vtp")
    r = ok(series, "-o", out, warns=DICOM_FRAME_WARNING)
    ok(series, "-q", "-o", out)  # not with -q
    expect("series: 24x20x18, short" in r.stdout, f"table header:\n{r.stdout}")
    expect(re.search(r"^isovalue 495\.5: the middle", r.stdout, re.M), r.stdout)
    refined = table_value(r.stdout, "output triangles")
    expect(refined > 0 and read_surface(out).GetNumberOfPolys() == refined, "read back")


def damaged_series(series, samples, spacing, damage):
    """Writes a DICOM series into `series` whose slice007.dcm is then
    replaced by `damage` of its bytes; returns `series`."""
    from dicom import write_series
    write_series(series, samples, spacing)
    victim = os.path.join(series, "slice007.dcm")
    with open(victim, "rb") as f:
        data = f.read()
    with open(victim, "wb") as f:
        f.write(damage(data))
    return series


@check
def dicom_slice_that_cannot_be_read_is_refused():
    """VTK's DICOM reader leaves out a file of the series it cannot parse:
    with one slice file empty, or cut short after its header, a 24x20x18
    series was read as 24x20x17, exit status 0 (the slices around the gap
    closed up). Such a series is refused, naming the file; files named
    otherwise than the slices (a README, a DICOMDIR, a report) or hidden
    ones are not an error (a second series is: see
    dicom_directory_with_two_series_is_refused)."""
    from dicom import write_series
    d = fresh_dir("dicom-bad-slice")
    _, spacing, _, v = blob_volume()
    samples = np.round(v * 10.0).astype(np.int16)
    out = os.path.join(d, "o.vtp")
    for label, damage in (("empty", lambda b: b""), ("cut short", lambda b: b[:300]),
                          ("not DICOM", lambda b: b"hello\n")):
        series = damaged_series(os.path.join(d, label.replace(" ", "-")), samples, spacing,
                                damage)
        try:
            expect_error([series, "-o", out], "slice007.dcm", outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{label}: {e}")
    # A slice file missing altogether: the reader closed the gap up
    # (24x20x17 at the same spacing). Seen in the slice positions.
    gap = os.path.join(d, "gap")
    write_series(gap, samples, spacing)
    os.remove(os.path.join(gap, "slice006.dcm"))
    expect_error([gap, "-o", out], "its slice positions jump by 2.2 between 'slice005.dcm' and "
                 "'slice007.dcm', where the other slices are 1.1 apart: a slice is missing",
                 outputs=[out], status=1)
    # A slice there twice (a copy named otherwise): the reader took both,
    # and the volume grew by a slice (a third review under AddressSanitizer,
    # fifty-second session).
    twice = os.path.join(d, "twice")
    write_series(twice, samples, spacing)
    shutil.copy(os.path.join(twice, "slice006.dcm"), os.path.join(twice, "copy of slice006.dcm"))
    expect_error([twice, "-o", out], "a slice is there twice", outputs=[out], status=1)
    # Slice files without an extension: the same.
    bare = os.path.join(d, "bare")
    write_series(bare, samples, spacing, prefix="IM", suffix="")
    with open(os.path.join(bare, "IM007"), "wb") as f:
        f.write(b"")
    expect_error([bare, "-o", out], "IM007", outputs=[out], status=1)
    # Not errors: files that are not slices of the series (named
    # otherwise, or hidden, as a copy from a Mac leaves them).
    both = os.path.join(d, "other-files")
    write_series(both, samples, spacing)
    for name in ("README", "DICOMDIR", "report.dcm", "._slice001.dcm", "notes.txt"):
        with open(os.path.join(both, name), "wb") as f:
            f.write(b"not a slice\n")
    ok(both, "-q", "-o", os.path.join(d, "both.vtp"))
    plain = os.path.join(d, "bare-readme")
    write_series(plain, samples, spacing, prefix="IM", suffix="")
    for name in ("README", "DICOMDIR", "._IM001"):
        with open(os.path.join(plain, name), "wb") as f:
            f.write(b"not a slice\n")
    ok(plain, "-q", "-o", os.path.join(d, "bare.vtp"))


@check
def dicom_slice_cut_short_in_its_pixel_data_is_refused():
    """VTK's DICOM reader copies a slice's pixels from its pixel data
    element without looking at how many bytes the file held: a slice file
    cut short within its pixel data (by a byte, by half, all of it, or the
    whole element gone) or declaring fewer bytes than its rows x columns
    need read as 24x20x18 with zeros or garbage in the gap, exit status 0.
    So did compressed (RLE) slices, which it does not decode. Such series
    are refused, naming the file; uncompressed series in implicit VR, or of
    8-bit samples on an odd number of pixels, still read."""
    from dicom import IMPLICIT, RLE, write_series
    d = fresh_dir("dicom-short-pixels")
    _, spacing, _, v = blob_volume()
    samples = np.round(v * 10.0).astype(np.int16)
    pixel_bytes = samples.shape[1] * samples.shape[2] * 2
    out = os.path.join(d, "o.vtp")

    def shorter(data):
        # The same file with a pixel data length 100 bytes short.
        at = len(data) - pixel_bytes - 4
        expect(struct.unpack("<I", data[at:at + 4])[0] == pixel_bytes, "pixel data length")
        return data[:at] + struct.pack("<I", pixel_bytes - 100) + data[at + 4:-100]

    for label, damage, fragment in (
            ("a byte", lambda b: b[:-1], "cut short"),
            ("half", lambda b: b[:-pixel_bytes // 2], "cut short"),
            ("all pixels", lambda b: b[:-pixel_bytes], "cut short"),
            ("no element", lambda b: b[:-pixel_bytes - 12], "no pixel data"),
            ("declared short", shorter, "fewer than")):
        series = damaged_series(os.path.join(d, label.replace(" ", "-")), samples, spacing,
                                damage)
        try:
            line = expect_error([series, "-o", out], "slice007.dcm", outputs=[out], status=1)
            expect(fragment in line, f"{fragment!r} not in {line!r}")
        except Failure as e:
            raise Failure(f"{label}: {e}")
    rle = os.path.join(d, "rle")
    write_series(rle, samples, spacing, syntax=RLE)
    expect_error([rle, "-o", out], "compressed", outputs=[out], status=1)
    # Valid series: the same surface in implicit VR as in explicit VR.
    explicit = os.path.join(d, "explicit")
    implicit = os.path.join(d, "implicit")
    write_series(explicit, samples, spacing)
    write_series(implicit, samples, spacing, syntax=IMPLICIT)
    a = ok(explicit, "-v", "400", "-o", os.path.join(d, "explicit.vtp"),
           warns=DICOM_FRAME_WARNING)
    b = ok(implicit, "-v", "400", "-o", os.path.join(d, "implicit.vtp"),
           warns=DICOM_FRAME_WARNING)
    expect(table_value(a.stdout, "output triangles") == table_value(b.stdout, "output triangles"),
           f"implicit VR read differently:\n{a.stdout}\n{b.stdout}")
    odd = os.path.join(d, "odd-8-bit")
    write_series(odd, (samples[:, :19, :23] // 4).astype(np.uint8), spacing)
    r = ok(odd, "-v", "100", "-o", os.path.join(d, "odd.vtp"), warns=DICOM_FRAME_WARNING)
    expect("odd-8-bit: 23x19x18, unsigned char" in r.stdout, f"table header:\n{r.stdout}")


@check
def dicom_slice_laid_out_otherwise_is_refused():
    """VTK's DICOM reader sizes the volume by its first slice and copies
    each slice's pixels as that slice's own header lays them out: one 4x4
    slice among 16x16 ones, or a 3-slice 4x4 localizer series mixed into
    the directory, crashed the tool or was read as garbage. A slice whose
    rows, columns, bits allocated or samples per pixel differ from the
    other slices' is refused, naming the file and the field, and so are
    slices laid out otherwise than the volume the reader makes of them."""
    from dicom import write_series
    d = fresh_dir("dicom-layout")
    z, y, x = np.mgrid[0:12, 0:16, 0:16]
    samples = (np.sqrt((x - 7.5) ** 2 + (y - 7.5) ** 2 + (z - 5.5) ** 2) * 100).astype(np.int16)
    out = os.path.join(d, "o.vtp")
    small = os.path.join(d, "small")
    write_series(small, samples, (1, 1, 2))
    write_series(os.path.join(d, "tmp"), np.ones((12, 4, 4), np.int16), (1, 1, 2))
    shutil.copy(os.path.join(d, "tmp", "slice007.dcm"), os.path.join(small, "slice007.dcm"))
    expect_error([small, "-o", out], "'slice007.dcm' has rows 4 where", outputs=[out], status=1)
    # 8-bit pixels of the same size.
    bits = os.path.join(d, "bits")
    write_series(bits, samples, (1, 1, 2))
    write_series(os.path.join(d, "tmp8"), np.ones((12, 16, 16), np.uint8), (1, 1, 2))
    shutil.copy(os.path.join(d, "tmp8", "slice007.dcm"), os.path.join(bits, "slice007.dcm"))
    expect_error([bits, "-o", out], "'slice007.dcm' has bits allocated 8", outputs=[out],
                 status=1)
    # A localizer series sorting first, named like the slices.
    localizer = os.path.join(d, "localizer")
    write_series(localizer, samples, (1, 1, 2))
    write_series(os.path.join(d, "loc"), (np.arange(48).reshape(3, 4, 4) * 10).astype(np.int16),
                 (1, 1, 2), series="1.2.826.0.1.3680043.9.7777.0", prefix="loc")
    for i in (1, 2, 3):
        shutil.copy(os.path.join(d, "loc", f"loc{i:03d}.dcm"),
                    os.path.join(localizer, f"slice90{i}.dcm"))
    # The reader takes the series sorting first (the localizer) but lays
    # the volume out by the last file it parsed, in directory order: a
    # 16x16 slice of the other series (refused as such), or a localizer
    # slice (its 4x4x3 volume was read as it is; refused since as two
    # series in one directory).
    line = expect_error([localizer, "-o", out], outputs=[out], status=1)
    expect("have rows 4 where VTK's reader lays the volume out with 16" in line or
           "its files belong to 2 DICOM series" in line, f"stderr: {line!r}")


@check
def dicom_directory_with_two_series_is_refused():
    """VTK's DICOM reader reads the first series of a directory by Series
    Instance UID and leaves the others out without a word: a directory
    holding a second series (of the same layout, or of another spacing and
    slice positions: no slice of one clashes with the other's) was read as
    one of them, exit status 0. Refused, naming both series' UIDs and a
    file of each; each series in a directory of its own reads."""
    from dicom import write_series
    d = fresh_dir("dicom-two-series")
    _, spacing, _, v = blob_volume()
    samples = np.round(v * 10.0).astype(np.int16)
    out = os.path.join(d, "o.vtp")
    first, second = "1.2.826.0.1.3680043.9.7777.1", "1.2.826.0.1.3680043.9.7777.2"
    for label, other_spacing in (("same-layout", spacing), ("other-geometry", (2.0, 2.0, 3.0))):
        both = os.path.join(d, label)
        write_series(both, samples, spacing, series=first)
        write_series(both, samples[:5], other_spacing, series=second, prefix="other")
        try:
            line = expect_error([both, "-o", out], "its files belong to 2 DICOM series",
                                outputs=[out], status=1)
            for fragment in (f"{first} ('slice001.dcm' and 17 more files)",
                             f"{second} ('other001.dcm' and 4 more files)",
                             "put each series in a directory of its own"):
                expect(fragment in line, f"{fragment!r} not in {line!r}")
        except Failure as e:
            raise Failure(f"{label}: {e}")
    # Apart, each reads.
    a = os.path.join(d, "first")
    b = os.path.join(d, "second")
    write_series(a, samples, spacing, series=first)
    write_series(b, samples[:5], (2.0, 2.0, 3.0), series=second, prefix="other")
    ok(a, "-q", "-o", os.path.join(d, "a.vtp"))
    ok(b, "-q", "-o", os.path.join(d, "b.vtp"))


@check
def explicit_values_and_filter_options():
    d = fresh_dir("options")
    paths = write_inputs(d)
    r1 = ok(paths["vti"], "-v", "30")
    r2 = ok(paths["vti"], "-v", "30", "--value", "60")
    expect("isovalues" in r2.stdout and "30, 60" in r2.stdout, r2.stdout)
    # The cells row counts each isovalue's cells, and says so.
    expect(re.search(r"^  cells .*; summed over the 2 isovalues\)$", r2.stdout, re.M), r2.stdout)
    expect("summed" not in r1.stdout, r1.stdout)
    expect(table_value(r2.stdout, "output triangles") > table_value(r1.stdout, "output triangles"),
           "two isovalues give no more triangles than one")
    # --epsilon 0 / --max-level 0: plain Marching Cubes.
    for args in (("--epsilon", "0"), ("--max-level", "0")):
        r = ok(paths["vti"], "-v", "30", *args)
        expect(table_value(r.stdout, "output triangles") == table_value(r.stdout, "MC triangles"),
               f"{args}: refinement happened")
    # The other options are accepted, with both spellings.
    r = ok("--sample=tube", "--rule", "B", "--topology=classic", "--normals", "central",
           "--threads", "1", "--max-level=3", "--epsilon", "0.05")
    expect(table_value(r.stdout, "maxL / meanL") <= 3, "max level not applied")
    # --smp: the same surface, bit for bit, as the library's own threads.
    surfaces = []
    for extra in ((), ("--smp",), ("--smp", "--threads", "2")):
        out = os.path.join(d, f"smp{len(extra)}.vtp")
        ok("--sample", "atoms", "--epsilon", "0.003", "-q", "-o", out, *extra)
        s = read_surface(out)
        surfaces.append((vtk_to_numpy(s.GetPoints().GetData()).tobytes(),
                         vtk_to_numpy(s.GetPolys().GetConnectivityArray()).tobytes()))
    expect(surfaces[0] == surfaces[1] == surfaces[2] and len(surfaces[0][1]) > 0,
           "--smp changed the surface")
    out = os.path.join(d, "nonormals.vtp")
    ok("--sample", "tube", "--normals", "none", "-o", out)
    expect(read_surface(out).GetPointData().GetNormals() is None, "normals written with none")
    expect(read_surface(out).GetPointData().GetArray("Gradients") is None,
           "gradients written without --gradients")
    ok("--sample", "tube", "--normals", "central", "--gradients", "-o", out)
    pd = read_surface(out).GetPointData()
    g, n = (vtk_to_numpy(pd.GetArray(a)).astype(float) for a in ("Gradients", "Normals"))
    expect(len(g) > 0 and np.abs(n + g / np.linalg.norm(g, axis=1)[:, None]).max() < 1e-5,
           "--gradients: the normals are not the negated, normalised gradients")
    # Only .vtp holds the array: the other formats say that it is left out
    # (it was dropped without a word), -q does not.
    for ext in ("ply", "stl", "obj"):
        ok("--sample", "tube", "--gradients", "-o", os.path.join(d, "g." + ext),
           warns=f'{ext} holds no "Gradients" array')
        ok("--sample", "tube", "--gradients", "-q", "-o", os.path.join(d, "q." + ext))
    # Without -o nothing would hold the array: said (it was computed and
    # dropped without a word), not with -q.
    ok("--sample", "tube", "--gradients", warns="--gradients without -o")
    ok("--sample", "tube", "--gradients", "-q")
    for rule in ("A", "a1", "A2", "b"):
        ok("--sample", "tube", "--rule", rule, "-q")
    r = ok("--sample", "atoms", "--max-triangles", "4000")
    mc = table_value(r.stdout, "MC triangles")
    out_tris = table_value(r.stdout, "output triangles")
    expect(out_tris <= max(4000, mc), f"--max-triangles 4000 gave {out_tris}")
    expect("capped by --max-triangles" in r.stdout, "cap not reported")


@check
def compare_and_distance_pictures():
    d = fresh_dir("pictures")
    c, dist = os.path.join(d, "c.png"), os.path.join(d, "d.png")
    r = ok("--sample", "tube", "--compare", c, "--distance", dist)
    expect(png_size(c) == (1600, 800), f"compare size {png_size(c)}")
    expect(png_size(dist) == (1000, 860), f"distance size {png_size(dist)}")
    expect(re.search(r"MC to refined\s+max [0-9.]+, mean", r.stdout), "no distance row")
    c3, d3 = os.path.join(d, "c3.png"), os.path.join(d, "d3.png")
    ok("--sample", "all", "--compare", c3, "--distance", d3)
    expect(png_size(c3) == (1600, 1680), f"compare size {png_size(c3)}")
    expect(png_size(d3) == (1800, 760), f"distance size {png_size(d3)}")
    expect(sorted(os.listdir(d)) == ["c.png", "c3.png", "d.png", "d3.png"], os.listdir(d))


@check
def pictures_of_a_file():
    d = fresh_dir("pictures-file")
    paths = write_inputs(d)
    c = os.path.join(d, "c.png")
    ok(paths["nii.gz"], "-v", "40", "--compare", c)
    expect(png_size(c) == (1600, 800), "size")


@check
def pictures_with_only_xvfb_on_path():
    xvfb = shutil.which("Xvfb")
    expect(xvfb, "Xvfb is not installed")
    d = fresh_dir("xvfb-only")
    bindir = os.path.join(d, "bin")
    os.makedirs(bindir)
    os.symlink(xvfb, os.path.join(bindir, "Xvfb"))
    c = os.path.join(d, "c.png")
    # The tool starts Xvfb itself (-displayfd) and stops it on exit.
    ok("--sample", "atoms", "--compare", c, env={"PATH": bindir})
    expect(png_size(c) == (1600, 800), "size")


@check
def pictures_without_any_x_server():
    d = fresh_dir("no-x")
    c = os.path.join(d, "c.png")
    # No Xvfb on PATH (the tool is called by full path).
    expect_error(["--sample", "tube", "--compare", c], "xvfb", outputs=[c],
                 env={"PATH": "/nonexistent"})


# --- Bad input ------------------------------------------------------------------

@check
def error_missing_input():
    d = fresh_dir("err-missing")
    out = os.path.join(d, "o.vtp")
    expect_error([os.path.join(d, "nope.vti"), "-o", out], "no such file", outputs=[out])


@check
def error_unknown_input_extension():
    d = fresh_dir("err-ext")
    path = os.path.join(d, "volume.xyz")
    with open(path, "w") as f:
        f.write("hello\n")
    out = os.path.join(d, "o.vtp")
    expect_error([path, "-o", out], "unknown input format", outputs=[out])


@check
def error_corrupt_inputs():
    d = fresh_dir("err-corrupt")
    good = write_inputs(fresh_dir("err-corrupt-src"))
    cases = {}
    for ext in ("vti", "vtk", "mha", "nii", "nii.gz", "nrrd"):
        path = os.path.join(d, "garbage." + ext)
        with open(path, "wb") as f:
            f.write(b"this is not a volume\n" * 20)
        cases["garbage." + ext] = path
    # Truncated files: a valid header without all the data.
    for ext in ("vti", "vtk", "mha", "nrrd", "nii"):
        with open(good[ext], "rb") as f:
            data = f.read()
        path = os.path.join(d, "truncated." + ext)
        with open(path, "wb") as f:
            f.write(data[: len(data) // 3])
        cases["truncated." + ext] = path
    # Uncompressed raw appended data cut short (by 10 %, or just before
    # the last data byte): VTK's reader fills the rest with zeros and says
    # nothing.
    dims, _, _, v = blob_volume()
    for header in ("UInt32", "UInt64"):
        w = vtkXMLImageDataWriter()
        raw = os.path.join(d, f"raw-{header}.vti")
        w.SetFileName(raw)
        w.SetInputData(density_image(v, dims, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)))
        w.SetDataModeToAppended()
        w.EncodeAppendedDataOff()
        w.SetCompressorTypeToNone()
        if header == "UInt64":
            w.SetHeaderTypeToUInt64()
        w.Write()
        ok(raw, "-v", "40", "-q")  # whole, it reads
        with open(raw, "rb") as f:
            data = f.read()
        # The last data byte: before the blanks ahead of </AppendedData>.
        last = len(data[: data.rindex(b"</AppendedData>")].rstrip()) - 1
        for label, cut in (("10%", data[: len(data) * 9 // 10]),
                           ("a byte", data[:last])):
            path = os.path.join(d, f"raw-{header}-short-{label.replace('%', '')}.vti")
            with open(path, "wb") as f:
                f.write(cut)
            cases[f"raw {header} short by {label}"] = path
    # A legacy header declaring 1000^3 samples in a file of a few KB: the
    # reader allocated 4 GB and read for 18 s before failing. Refused at
    # once, with the byte counts.
    with open(good["vtk"], "rb") as f:
        data = f.read()
    head = data[: data.index(b"LOOKUP_TABLE default\n") + 21]
    head = re.sub(rb"DIMENSIONS \d+ \d+ \d+", b"DIMENSIONS 1000 1000 1000", head)
    head = re.sub(rb"POINT_DATA \d+", b"POINT_DATA 1000000000", head)
    # So is any attribute: vectors (11.7 GB and 40 s), a type in capitals
    # (which the reader takes), a FIELD array, one after a real attribute
    # (4.4 GB), a FIELD of 2e9 arrays (16 GB, over a minute) and a lookup
    # table of 2e9 entries were not sized until the fifty-second session.
    attribute = re.search(rb"SCALARS \S+ float( 1)?\nLOOKUP_TABLE default\n", head)
    expect(attribute is not None, "the legacy writer's SCALARS line")
    for label, line, fragment in (
            ("scalars", attribute.group(0),
             "fewer than the 4000000000 that the 1000000000 float values of its attribute "
             "SCALARS"),
            ("capitals", b"SCALARS s FLOAT\nLOOKUP_TABLE default\n",
             "1000000000 FLOAT values of its attribute SCALARS 's'"),
            ("vectors", b"VECTORS v float\n",
             "fewer than the 12000000000 that the 3000000000 float values of its attribute "
             "VECTORS 'v' need"),
            ("field", b"FIELD f 1\nv 1 1000000000 float\n",
             "1000000000 float values of its attribute FIELD"),
            ("field-count", b"FIELD f 2000000000\nv 1 1 float\n",
             "declares 2000000000 arrays, more than its"),
            ("second", b"FIELD f 1\nv 1 1 float\n\0\0\0\0\nVECTORS w float\n",
             "values of its attribute VECTORS 'w'")):
        huge = os.path.join(d, f"huge-{label}.vtk")
        with open(huge, "wb") as f:
            f.write(head.replace(attribute.group(0), line) + b"\0" * 4000)
        started = time.monotonic()
        try:
            expect_error([huge, "-o", os.path.join(d, "o.vtp")], fragment, status=1)
        except Failure as e:
            raise Failure(f"{label}: {e}")
        expect(time.monotonic() - started < 60, f"{label}: read before it was refused")
    lookup = os.path.join(d, "huge-lookup.vtk")
    with open(lookup, "w") as f:
        f.write("# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\n"
                "DIMENSIONS 2 2 2\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 8\nSCALARS s float\n"
                "LOOKUP_TABLE t 2000000000\n0 1 2 3 4 5 6 7\n")
    expect_error([lookup, "-o", os.path.join(d, "o.vtp")],
                 "the 8000000000 ASCII float values of its attribute LOOKUP_TABLE 't' need",
                 status=1)
    # Empty file.
    path = os.path.join(d, "empty.vti")
    open(path, "w").close()
    cases["empty.vti"] = path
    out = os.path.join(d, "o.vtp")
    for label, path in cases.items():
        try:
            expect_error([path, "-o", out], outputs=[out])
        except Failure as e:
            raise Failure(f"{label}: {e}")


@check
def vti_base64_data_cut_short_is_refused():
    """Uncompressed base64 data cut short (appended: the file's first two
    thirds, or all but its last character; inline binary: a third of an
    array's text taken out, the element closed again) was read with zeros
    or garbage for the rest, exit status 0. Such files are refused, naming
    the array; the whole files read, with either header type. VTK encodes
    a block's header and data as one base64 stream."""
    d = fresh_dir("vti-base64")
    dims, _, _, v = blob_volume()
    out = os.path.join(d, "o.vtp")
    for header in ("UInt32", "UInt64"):
        for mode in ("appended", "binary"):
            w = vtkXMLImageDataWriter()
            path = os.path.join(d, f"{mode}-{header}.vti")
            w.SetFileName(path)
            w.SetInputData(density_image(v, dims, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)))
            w.SetCompressorTypeToNone()
            if mode == "appended":
                w.SetDataModeToAppended()
                w.EncodeAppendedDataOn()
            else:
                w.SetDataModeToBinary()
            if header == "UInt64":
                w.SetHeaderTypeToUInt64()
            w.Write()
            ok(path, "-v", "40", "-q", "-o", os.path.join(d, "whole.vtp"))
            with open(path, "rb") as f:
                data = f.read()
            if mode == "appended":
                last = len(data[: data.rindex(b"</AppendedData>")].rstrip()) - 1
                cuts = {"two thirds": data[: len(data) * 2 // 3], "a character": data[:last]}
            else:
                m = re.search(rb'format="binary"[^>]*>\s*([A-Za-z0-9+/=]+)\s*<', data)
                expect(m, "no inline base64 text in the written file")
                text = m.group(1)
                cuts = {"a third": data[: m.start(1)] + text[: len(text) * 2 // 3] +
                        data[m.end(1):],
                        "a character": data[: m.start(1)] + text[:-1] + data[m.end(1):]}
            for label, cut in cuts.items():
                bad = os.path.join(d, "cut.vti")
                with open(bad, "wb") as f:
                    f.write(cut)
                try:
                    expect_error([bad, "-v", "40", "-o", out], "array 'density'", outputs=[out],
                                 status=1)
                except Failure as e:
                    raise Failure(f"{mode} {header} short by {label}: {e}")


@check
def error_not_a_volume():
    d = fresh_dir("err-2d")
    image = vtkImageData()
    image.SetDimensions(8, 8, 1)
    arr = numpy_to_vtk(np.arange(64, dtype=np.float32), deep=True)
    arr.SetName("s")
    image.GetPointData().SetScalars(arr)
    path = os.path.join(d, "slice.vti")
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(image)
    w.Write()
    expect_error([path], "not a 3D volume")
    empty = os.path.join(d, "emptydir")
    os.makedirs(empty)
    expect_error([empty], "DICOM")


@check
def error_isovalue_outside_range():
    d = fresh_dir("err-iso")
    paths = write_inputs(d)
    out = os.path.join(d, "o.vtp")
    expect_error([paths["vti"], "-v", "1000", "-o", out], "outside the scalar range", outputs=[out])
    expect_error(["--sample", "tube", "-v", "-1", "-o", out], "outside the scalar range",
                 outputs=[out])
    # One bad value among good ones, and for one sample of "all": nothing written.
    expect_error(["--sample", "all", "-v", "50", "-o", out], "outside the scalar range",
                 outputs=[out] + [os.path.join(d, f"o-{n}.vtp") for n in ("tube", "atoms", "ml")])
    # The message tells the values apart: six digits printed 1000000.3
    # outside [1000000, 1000000.25] as "1e+06 ... [1e+06, 1e+06]". A float
    # array's range reads as the float it is (0.1, not 0.100000001490116).
    dims, spacing, origin, v = blob_volume()
    for values, iso, want in (
            (1e6 + 0.25 * v / v.max(), "1000000.3", "isovalue 1000000.3 is outside the scalar "
                                                    "range [1000000, 1000000.25]"),
            (0.1 + 0.0 * v, "0.5", "isovalue 0.5 is outside the scalar range [0.1, 0.1]")):
        path = os.path.join(d, "tight.vti")
        w = vtkXMLImageDataWriter()
        w.SetFileName(path)
        w.SetInputData(density_image(values.astype(np.float32), dims, spacing, origin))
        w.Write()
        expect_error([path, "-v", iso, "-o", out], want, outputs=[out])
    # At the range's minimum every sample is at or above the isovalue (a
    # sample at it counts as above): no surface, exit status 0 before. At
    # its maximum there is one (around the samples equal to it).
    mask = np.zeros(v.shape, np.float32)
    mask[6:12, 6:12, 6:12] = 1.0
    path = os.path.join(d, "mask.vti")
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(density_image(mask, dims, spacing, origin))
    w.Write()
    expect_error([path, "-v", "0", "-o", out], "isovalue 0 is the minimum of the scalar range "
                 "[0, 1] of mask.vti: every sample is at or above it", outputs=[out])
    r = ok(path, "-v", "1", "--epsilon", "0")
    expect(table_value(r.stdout, "MC triangles") > 0, r.stdout)
    # A constant volume: its default isovalue was that minimum.
    path = os.path.join(d, "constant.vti")
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(density_image(mask * 0.0 + 5.0, dims, spacing, origin))
    w.Write()
    expect_error([path, "-o", out], "the scalars of constant.vti are all 5 (the finite ones): "
                 "no isovalue gives a surface", outputs=[out])
    expect_error([path, "-v", "5", "-o", out], "isovalue 5 is the minimum", outputs=[out])
    # An empty file is called empty, whatever its extension.
    for ext in ("vti", "nrrd", "nii"):
        empty = os.path.join(d, "empty." + ext)
        open(empty, "w").close()
        expect_error([empty, "-o", out], "the file is empty", outputs=[out])


@check
def scalar_range_of_values_beyond_1e299():
    """VTK's GetFiniteRange starts its minimum at 1e+299 (and its maximum
    at -1e+299): a double volume with every value in [1.1e308, 1.7e308]
    had the range [1e+299, 1.7e+308], the default isovalue 8.5e+307 below
    every sample, an empty surface and exit status 0, and -v 1e308 passed
    the range check. The range is the data's, on either sign, and its
    middle does not overflow."""
    d = fresh_dir("huge-values")
    dims, spacing, origin, v = blob_volume()
    out = os.path.join(d, "o.vtp")
    v = v.astype(np.float64)
    shape = 1.1e308 + 0.6e308 * ((v - v.min()) / (v.max() - v.min()))
    for sign, lo, hi in ((1, "1.1e+308", "1.7e+308"), (-1, "-1.7e+308", "-1.1e+308")):
        path = write_vti(density_image(sign * shape, dims, spacing, origin),
                         os.path.join(d, f"huge{sign:+d}.vti"))
        r = ok(path, "--epsilon", "0")
        first = r.stdout.splitlines()[0]
        expect(f"scalar range [{lo}, {hi}]" in first, f"range line: {first!r}")
        expect(table_value(r.stdout, "MC triangles") > 0, r.stdout)
        expect_error([path, "-v", str(sign * 1e308), "-o", out],
                     f"is outside the scalar range [{lo}, {hi}]", outputs=[out], status=1)


@check
def default_isovalue_of_two_adjacent_values():
    """A double volume holding two adjacent doubles only (1 and 1 + 2^-52,
    0 and the least subnormal, the largest double and the one below it):
    the middle of its range rounds to the minimum, which the tool then
    refused as giving no surface. The maximum is taken instead, and cut."""
    d = fresh_dir("adjacent-values")
    dims, spacing, origin, v = blob_volume()
    out = os.path.join(d, "o.vtp")
    top = np.finfo(np.float64).max
    for lo, hi, text in ((1.0, np.nextafter(1.0, 2.0), "1.0000000000000002"),
                         (0.0, 5e-324, "4.94066e-324"),
                         (np.nextafter(top, 0.0), top, "1.7976931348623157e+308")):
        values = np.where(v > 50.0, hi, lo).astype(np.float64)
        path = write_vti(density_image(values, dims, spacing, origin),
                         os.path.join(d, f"adjacent-{text}.vti"))
        r = ok(path, "--epsilon", "0", "-o", out)
        first = r.stdout.splitlines()[0]
        expect(first.startswith(f"isovalue {text}: the maximum of the scalar range"),
               f"isovalue line: {first!r}")
        expect(table_value(r.stdout, "MC triangles") > 0, r.stdout)
        expect(read_surface(out).GetNumberOfPolys() > 0, "empty surface written")


@check
def reconstruction_filters():
    d = fresh_dir("filters")
    surfaces = {}
    for name in ("trilinear", "catmull-rom", "bspline", "bspline-interpolating"):
        out = os.path.join(d, name + ".vtp")
        # Case-insensitive, like the other enumerations.
        r = ok("--sample", "atoms", "--epsilon", "0.02", "--max-level", "3",
               "--filter", name.upper() if name == "bspline" else name, "-o", out)
        rows = re.findall(r"^  filter\s+(\S+)", r.stdout, re.M)
        if name == "trilinear":
            expect(rows == [], f"a filter row for the default: {rows}")
        else:
            expect(rows == [name], f"filter row {rows}, expected {name}")
        pd = read_surface(out)
        expect(pd.GetNumberOfPolys() == table_value(r.stdout, "output triangles"),
               f"{name}: file and table disagree")
        pts = vtk_to_numpy(pd.GetPoints().GetData()).astype(float)
        surfaces[name] = (table_value(r.stdout, "MC triangles"), pts)
    mc = {name: v[0] for name, v in surfaces.items()}
    expect(len(set(mc.values())) == 1, f"Marching Cubes differs between filters: {mc}")
    # The split points follow the filter: every cubic surface differs from the
    # trilinear one and from each other.
    names = list(surfaces)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            pa, pb = surfaces[a][1], surfaces[b][1]
            same = pa.shape == pb.shape and np.array_equal(np.sort(pa, axis=0), np.sort(pb, axis=0))
            expect(not same, f"--filter {a} and {b} give the same points")


@check
def error_bad_option_values():
    d = fresh_dir("err-options")
    out = os.path.join(d, "o.vtp")
    cases = [
        (["--epsilon", "-0.1"], "--epsilon"),
        # A repeated isovalue wrote its surface twice, coincident.
        (["-v", "50.5", "-v", "40", "--value", "50.5"], "isovalue 50.5 is given twice"),
        (["--epsilon", "abc"], "not a finite number"),
        (["--epsilon", "nan"], "not a finite number"),
        (["--rule", "C"], "unknown value"),
        (["--topology", "smooth"], "unknown value"),
        (["--filter", "cubic"], "--filter: unknown value 'cubic'"),
        (["--filter", ""], "--filter"),
        (["--filter"], "needs a value"),
        (["--normals", "flat"], "unknown value"),
        (["--max-level", "11"], "too large"),
        (["--max-level", "x"], "not a non-negative integer"),
        (["--threads", "-1"], "not a non-negative integer"),
        (["--max-triangles", "1e6"], "not a non-negative integer"),
        (["-v", "foo"], "not a finite number"),
        (["-v"], "needs a value"),
        (["--sample", "cube"], "unknown sample"),
        (["--frobnicate"], "unknown option"),
        (["a.vti", "b.vti"], "only one input"),
        (["a.vti", "--sample", "tube"], "not both"),
        (["--compare", os.path.join(d, "c.jpg")], "png"),
    ]
    for args, fragment in cases:
        try:
            expect_error(["--sample", "tube", "-o", out, *args]
                         if "--sample" not in args and "a.vti" not in args else
                         [*args, "-o", out], fragment, outputs=[out], status=2)
        except Failure as e:
            raise Failure(f"{args}: {e}")


@check
def repeated_options_are_refused():
    """An option given twice silently replaced the first: -o a -o b wrote
    b only, --sample tube --sample atoms ran atoms, --epsilon 0.1 --epsilon
    0 plain Marching Cubes. A command-line mistake (status 2), whatever
    the spelling, nothing written; -v/--value alone adds up."""
    d = fresh_dir("err-repeated")
    a = os.path.join(d, "a.vtp")
    b = os.path.join(d, "b.vtp")
    for args, fragment in (
            (["--sample", "tube", "-o", a, "-o", b], "-o/--output is given twice"),
            (["--sample", "tube", "-o", a, "--output=" + b], "-o/--output is given twice"),
            (["--sample", "tube", "--sample", "atoms", "-o", a], "--sample is given twice"),
            (["--sample", "tube", "--epsilon", "0.1", "--epsilon", "0", "-o", a],
             "--epsilon is given twice"),
            (["--sample", "tube", "--rule", "A", "--rule=B", "-o", a], "--rule is given twice"),
            (["--sample", "tube", "-q", "--quiet", "-o", a], "-q/--quiet is given twice"),
            (["--sample", "tube", "--compare", os.path.join(d, "a.png"), "--compare",
              os.path.join(d, "b.png"), "-o", a], "--compare is given twice")):
        try:
            expect_error(args, fragment, outputs=[a, b], status=2)
        except Failure as e:
            raise Failure(f"{args}: {e}")
    expect(os.listdir(d) == [], f"files written: {os.listdir(d)}")
    r = ok("--sample", "tube", "-v", "40", "--value", "60", "-o", a)
    expect(len(table_values(r.stdout, "output triangles")) == 1, r.stdout)


@check
def error_unwritable_outputs():
    d = fresh_dir("err-write")
    missing_dir = os.path.join(d, "no", "such", "dir", "o.vtp")
    expect_error(["--sample", "tube", "-o", missing_dir], "does not exist", outputs=[missing_dir])
    expect_error(["--sample", "tube", "-o", d], "", outputs=[])
    adir = os.path.join(d, "adir.vtp")
    os.makedirs(adir)
    expect_error(["--sample", "tube", "-o", adir], "is a directory")
    expect_error(["--sample", "tube", "-o", os.path.join(d, "o.xyz")], "unknown output format",
                 outputs=[os.path.join(d, "o.xyz")])
    png = os.path.join(d, "no", "c.png")
    expect_error(["--sample", "tube", "--compare", png], "does not exist", outputs=[png])
    # A bad picture path fails before the surface is written.
    out = os.path.join(d, "o.vtp")
    expect_error(["--sample", "tube", "-o", out, "--distance", png], "does not exist",
                 outputs=[out])
    expect(sorted(os.listdir(d)) == ["adir.vtp"], f"left behind: {os.listdir(d)}")


@check
def a_taken_temporary_name_is_not_an_unwritable_directory():
    """The output's directory is tried with a temporary file created there
    (and removed) before the work: when its name was taken (a stale one of
    a run whose process id came back) the directory was reported as one
    where "no file can be created". Another name is tried."""
    d = fresh_dir("taken-temporary")
    out = os.path.join(d, "o.vtp")
    # The names the tool's first temporaries take: .o.tmp<pid>-<n>.vtp.
    # The shell's process id is the tool's after exec.
    script = ('for n in 1 2 3 4 5; do : > "$1/.o.tmp$$-$n.vtp"; done; '
              'exec "$2" --sample tube -o "$1/o.vtp"')
    r = subprocess.run(["/bin/sh", "-c", script, "sh", d, TOOL], capture_output=True,
                       text=True, timeout=TIMEOUT)
    expect(r.returncode == 0, f"exit status {r.returncode}, stderr: {r.stderr.strip()!r}")
    expect(os.path.getsize(out) > 0, "no surface written")
    taken = sorted(f for f in os.listdir(d) if f != "o.vtp")
    expect(len(taken) == 5, f"the taken names were removed or others left: {taken}")


@check
def failures_after_the_default_isovalue_print_nothing_on_stdout():
    """The default isovalue's line went to stdout before the checks that
    came after it: a legacy .vtk with SPACING 0 1 1 (refused by the filter,
    after the read) or an output in a directory where no file can be
    created (/proc, which access() lets root write: the writer failed after
    the whole extraction) left it there on a failing run. A zero spacing
    is refused at read time, the output directory is tried before any work,
    and the line is printed once the checks have passed."""
    d = fresh_dir("late-stdout")
    dims, _, origin, v = blob_volume()
    legacy = os.path.join(d, "blob.vtk")
    w = vtkStructuredPointsWriter()
    w.SetFileName(legacy)
    w.SetInputData(density_image(v, dims, (1.0, 1.0, 1.0), origin))
    w.SetFileTypeToASCII()
    w.Write()
    with open(legacy) as f:
        text = f.read()
    expect("SPACING 1 1 1" in text, "no SPACING line in the legacy file")
    r = ok(legacy)
    expect(r.stdout.startswith("isovalue "), f"no default isovalue line: {r.stdout!r}")
    out = os.path.join(d, "o.vtp")
    zero = os.path.join(d, "zero.vtk")
    with open(zero, "w") as f:
        f.write(text.replace("SPACING 1 1 1", "SPACING 0 1 1"))
    expect_error([zero, "-o", out], "its spacing (0, 1, 1)", outputs=[out], status=1)
    vti = write_vti(density_image(v, dims, (1.0, 0.0, 1.0), origin), os.path.join(d, "zero.vti"))
    expect_error([vti, "-o", out], "its spacing (1, 0, 1)", outputs=[out], status=1)
    if os.path.isdir("/proc"):
        expect_error([legacy, "-o", "/proc/precisemc-test.vtp"], "cannot write surface",
                     status=1)
        expect_error(["--sample", "tube", "--compare", "/proc/precisemc-test.png"],
                     "cannot write picture", status=1)


@check
def geometry_the_filter_refuses_is_refused_at_read_time():
    """A singular direction matrix and world coordinates that overflow were
    refused by the filter, after the default isovalue's line had gone to
    stdout (exit status 1 with it there). They are the file's fault, said
    at read time for every format: the run prints nothing on stdout."""
    d = fresh_dir("late-geometry")
    v = np.arange(64, dtype=np.float64).reshape(4, 4, 4)
    out = os.path.join(d, "o.vtp")
    singular = density_image(v, (4, 4, 4), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    singular.SetDirectionMatrix(1, 0, 0, 1, 0, 0, 0, 0, 1)
    path = write_vti(singular, os.path.join(d, "singular.vti"))
    expect_error([path, "-o", out], "its direction matrix", outputs=[out], status=1)
    for name, spacing in (("huge", (1e308, 1.0, 1.0)), ("huge-negative", (-1e308, 1.0, 1.0))):
        path = write_vti(density_image(v, (4, 4, 4), spacing, (0.0, 0.0, 0.0)),
                         os.path.join(d, name + ".vti"))
        expect_error([path, "-o", out], "overflow", outputs=[out], status=1)
    # Rotated (not axis-aligned: the filter's own check) and legacy (axis-
    # aligned: the library's).
    rotated = density_image(v, (4, 4, 4), (1.0, 1e308, 1.0), (0.0, 0.0, 0.0))
    rotated.SetDirectionMatrix(0, 1, 0, 1, 0, 0, 0, 0, 1)
    path = write_vti(rotated, os.path.join(d, "rotated.vti"))
    expect_error([path, "-o", out], "overflow", outputs=[out], status=1)
    legacy = os.path.join(d, "huge.vtk")
    w = vtkStructuredPointsWriter()
    w.SetFileName(legacy)
    w.SetInputData(density_image(v, (4, 4, 4), (1.0, 1.0, 1e308), (0.0, 0.0, 0.0)))
    w.SetFileTypeToASCII()
    w.Write()
    expect_error([legacy, "-o", out], "overflow", outputs=[out], status=1)
    # At the edge: the last sample at 3 * 5e307, finite, is contoured.
    fine = write_vti(density_image(v, (4, 4, 4), (5e307, 1.0, 1.0), (0.0, 0.0, 0.0)),
                     os.path.join(d, "fine.vti"))
    r = ok(fine, "-o", out)
    expect(r.stdout.startswith("isovalue "), f"no default isovalue line: {r.stdout!r}")


# --- --measure ----------------------------------------------------------------

def measured(stdout, key):
    """[(max, mean, points)] of the rows `key` ('S_K distance MC' or
    'S_K distance out')."""
    rows = re.findall(r"^  " + re.escape(key) + r"\s+max ([0-9.]+), mean ([0-9.]+) cells "
                      r"\([^,]*, ([0-9 ]+[0-9]) points", stdout, re.M)
    expect(rows, f"no row {key!r} in the table:\n{stdout}")
    return [(float(a), float(b), int(c.replace(" ", ""))) for a, b, c in rows]


@check
def measure_refined_closer_than_mc():
    for sample, eps in (("atoms", "0.001"), ("tube", "0.01")):
        r = ok("--sample", sample, "--measure", "--measure-density", "2", "--epsilon", eps)
        (mc_max, mc_mean, mc_points), = measured(r.stdout, "S_K distance MC")
        (out_max, out_mean, out_points), = measured(r.stdout, "S_K distance out")
        # density 2: 6 points per triangle (vtkMarchingCubes's own triangles,
        # not the "MC triangles" of PreciseMC's trilinear topology).
        expect(mc_points > 0 and mc_points % 6 == 0, f"{sample}: MC points {mc_points}")
        expect(out_points == 6 * table_value(r.stdout, "output triangles"),
               f"{sample}: refined points")
        expect(mc_max > 0.1, f"{sample}: MC max distance {mc_max} implausibly small")
        expect(out_mean < 0.5 * mc_mean, f"{sample}: refined mean {out_mean} vs MC {mc_mean}")
        expect(out_max <= mc_max, f"{sample}: refined max {out_max} vs MC {mc_max}")
        expect(re.search(r"\| measure [0-9.]+ s", r.stdout), "no measure time")


@check
def measure_several_isovalues():
    r = ok("--sample", "atoms", "--measure", "--measure-density", "1", "-v", "30", "-v", "80")
    mc = measured(r.stdout, "S_K distance MC")
    out = measured(r.stdout, "S_K distance out")
    expect(len(mc) == 2 and len(out) == 2, "one row pair per isovalue expected")
    # density 1 measures the vertices only: both surfaces' vertices lie on S_K.
    for m in mc + out:
        expect(m[0] < 1e-3, f"vertex distance {m[0]} not ~0")
    expect(sum(p for _, _, p in out) == 3 * table_value(r.stdout, "output triangles"),
           "the refined triangles of both isovalues are measured once each")


@check
def measure_independent_of_extent_and_direction():
    """The same samples with an extent not starting at 0 and a rotated
    direction matrix measure the same distances (points are mapped back to
    the index frame)."""
    d = fresh_dir("measure-geometry")
    plain = blob_image()
    moved = vtkImageData()
    moved.DeepCopy(plain)
    moved.SetExtent(3, 26, -2, 17, 5, 22)
    c, s = math.cos(0.4), math.sin(0.4)
    moved.SetDirectionMatrix(c, -s, 0, s, c, 0, 0, 0, 1)
    results = []
    for name, image in (("plain.vti", plain), ("moved.vti", moved)):
        path = os.path.join(d, name)
        w = vtkXMLImageDataWriter()
        w.SetFileName(path)
        w.SetInputData(image)
        w.Write()
        r = ok(path, "-v", "40", "--measure")
        results.append((measured(r.stdout, "S_K distance MC"),
                        measured(r.stdout, "S_K distance out")))
    for a, b in zip(results[0], results[1]):
        (amax, amean, apts), = a
        (bmax, bmean, bpts), = b
        expect(apts == bpts, f"points {apts} vs {bpts}")
        expect(abs(amax - bmax) < 1e-4 and abs(amean - bmean) < 1e-4,
               f"distances differ: {a} vs {b}")


@check
def write_volume_round_trip():
    d = fresh_dir("write-volume")
    base = os.path.join(d, "s.vti")
    r = ok("--sample", "all", "--write-volume", base)
    for name in ("tube", "atoms", "ml"):
        path = os.path.join(d, f"s-{name}.vti")
        expect(os.path.isfile(path), f"{path} not written")
        # Contouring the written volume gives the sample's triangles.
        again = ok(path, "-v", {"tube": "50.5", "atoms": "50.5", "ml": "0.5"}[name])
        expect(table_value(again.stdout, "output triangles") ==
               table_values(r.stdout, "output triangles")[("tube", "atoms", "ml").index(name)],
               f"{name}: another surface from the written volume")
    expect_error(["--sample", "ml", "--write-volume", os.path.join(d, "v.png")], "does not end in .vti",
                 status=2)
    expect_error(["--sample", "ml", "--write-volume", os.path.join(d, "nodir", "v.vti")],
                 "does not exist")


@check
def error_measure_options():
    expect_error(["--sample", "ml", "--measure-density", "2"], "needs --measure", status=2)
    expect_error(["--sample", "ml", "--measure", "-q"], "--quiet", status=2)
    expect_error(["--sample", "ml", "--measure", "--measure-density", "0"], "between 1 and 64",
                 status=2)
    expect_error(["--sample", "ml", "--measure", "--measure-density", "65"], "too large",
                 status=2)
    expect_error(["--sample", "ml", "--measure=yes"], "takes no value", status=2)
    expect_error(["--sample", "ml", "--measure", "--measure-density", "x"],
                 "not a non-negative integer", status=2)


@check
def quiet_smp_threads_and_tiny_numbers():
    # More vtkSMPTools threads than cores: TBB's warning would break -q.
    ok("--sample", "ml", "--smp", "--threads", str(8 * (os.cpu_count() or 1)), "-q")
    # Underflow is a number (strtod flags it ERANGE like overflow).
    r = ok("--sample", "ml", "--epsilon", "1e-310", "--max-level", "1")
    expect(table_value(r.stdout, "output triangles") > 0, "no triangles")
    expect_error(["--sample", "ml", "--epsilon", "1e999"], "not a finite number", status=2)
    expect_error(["--sample", "ml", "-v", "-1e400"], "not a finite number", status=2)


@check
def late_failure_commits_nothing():
    """A picture failing after the surfaces and volumes are written (here a
    file size limit the picture exceeds) leaves none of them behind."""
    d = fresh_dir("late-failure")
    out, vti, c = (os.path.join(d, n) for n in ("t.vtp", "t.vti", "t.png"))
    # A limit of 100 kB: the surface (plain Marching Cubes, about 30 kB) and
    # the volume (3 kB) are written, the picture (about 150 kB) fails with
    # EFBIG (SIGXFSZ ignored).
    script = 'trap "" XFSZ; ulimit -f 100; exec "$0" "$@"'
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    r = subprocess.run(["/bin/sh", "-c", script, TOOL, "--sample", "tube", "--epsilon", "0",
                        "--normals", "none", "-o", out, "--write-volume", vti, "--compare", c],
                       capture_output=True, text=True, env=environment, timeout=TIMEOUT)
    expect(r.returncode == 1, f"exit status {r.returncode}, stderr {r.stderr!r}")
    lines = r.stderr.splitlines()
    expect(len(lines) == 1 and lines[0].startswith("precisemc: error: cannot write picture"),
           f"stderr: {r.stderr!r}")
    expect(os.listdir(d) == [], f"left behind: {os.listdir(d)}")


@check
def sample_all_checks_the_paths_written():
    d = fresh_dir("sample-all-paths")
    base = os.path.join(d, "s.vtp")
    # The base name is never written with several samples: it may be a
    # directory.
    os.makedirs(base)
    ok("--sample", "all", "-o", base, "--epsilon", "0")
    expect(sorted(os.listdir(d)) == ["s-atoms.vtp", "s-ml.vtp", "s-tube.vtp", "s.vtp"],
           os.listdir(d))
    for n in ("tube", "atoms", "ml"):
        os.remove(os.path.join(d, f"s-{n}.vtp"))
    # A per-sample path that cannot be written fails before any work, and
    # the samples before it leave nothing.
    os.makedirs(os.path.join(d, "s-ml.vtp"))
    expect_error(["--sample", "all", "-o", base], "s-ml.vtp': it is a directory",
                 outputs=[os.path.join(d, "s-tube.vtp"), os.path.join(d, "s-atoms.vtp")])
    vol = os.path.join(d, "v.vti")
    os.makedirs(os.path.join(d, "v-atoms.vti"))
    expect_error(["--sample", "all", "--write-volume", vol], "v-atoms.vti': it is a directory",
                 outputs=[os.path.join(d, "v-tube.vti")])
    expect(sorted(os.listdir(d)) == ["s-ml.vtp", "s.vtp", "v-atoms.vti"], os.listdir(d))


def unused_display():
    """A display number no X server listens on."""
    n = 987
    while os.path.exists(f"/tmp/.X11-unix/X{n}") or os.path.exists(f"/tmp/.X{n}-lock"):
        n += 1
    return f":{n}"


@check
def pictures_with_an_unusable_display():
    d = fresh_dir("bad-display")
    out, c = os.path.join(d, "x.vtp"), os.path.join(d, "x.png")
    bad = unused_display()
    # VTK abort()ed on it after the surface was written: now the tool sees
    # it cannot open it and renders on its private Xvfb instead.
    ok("--sample", "tube", "-o", out, "--compare", c, env={"DISPLAY": bad})
    expect(png_size(c) == (1600, 800), "size")
    expect(read_surface(out).GetNumberOfPolys() > 0, "no surface")
    for f in (out, c):
        os.remove(f)
    # Without Xvfb: one error line before any work.
    expect_error(["--sample", "tube", "-o", out, "--compare", c], f"cannot open the X display '{bad}'",
                 outputs=[out, c], status=1, env={"DISPLAY": bad, "PATH": "/nonexistent"})
    # A display without GLX (an Xvfb started with GLX disabled): refused too.
    xvfb = shutil.which("Xvfb")
    expect(xvfb, "Xvfb is not installed")
    bindir = os.path.join(d, "bin")
    os.makedirs(bindir)
    with open(os.path.join(bindir, "Xvfb"), "w") as f:
        f.write(f'#!/bin/sh\nexec {xvfb} "$@" -extension GLX\n')
    os.chmod(os.path.join(bindir, "Xvfb"), 0o755)
    expect_error(["--sample", "tube", "-o", out, "--compare", c], "has no GLX",
                 outputs=[out, c], status=1, env={"PATH": bindir})
    expect(sorted(os.listdir(d)) == ["bin"], f"left behind: {os.listdir(d)}")


def write_vti(image, path):
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(image)
    w.Write()
    return path


@check
def multi_component_input_has_a_baseline():
    """vtkMarchingCubes takes single-component scalars: it is given
    component 0, the one PreciseMC contours, so the baseline of a
    3-component volume is that of its component 0 alone."""
    d = fresh_dir("multi-component")
    plain = write_vti(blob_image(), os.path.join(d, "plain.vti"))
    image = blob_image()
    v = vtk_to_numpy(image.GetPointData().GetScalars())
    three = np.stack([v, np.full_like(v, 7.0), -v], axis=1)
    arr = numpy_to_vtk(three, deep=True)
    arr.SetName("vector")
    image.GetPointData().SetScalars(arr)
    vec = write_vti(image, os.path.join(d, "vec.vti"))
    results = []
    for path in (plain, vec):
        r = ok(path, "-v", "40", "--measure")
        results.append((measured(r.stdout, "S_K distance MC"),
                        measured(r.stdout, "S_K distance out")))
    expect("component 0 of 3" in r.stdout, "the table does not name the component")
    expect(results[0] == results[1], f"component 0 measures differently: {results}")
    expect(results[1][0][0][2] > 0, "no vtkMarchingCubes baseline measured")
    c = os.path.join(d, "c.png")
    r = ok(vec, "-v", "40", "--compare", c, "--distance", os.path.join(d, "d.png"))
    expect(png_size(c) == (1600, 800), "compare size")
    m = re.search(r"MC to refined\s+max ([0-9.]+), mean ([0-9.]+)", r.stdout)
    expect(m and float(m.group(1)) > 0, f"no distance of the baseline:\n{r.stdout}")


@check
def nan_samples_in_the_baseline():
    """vtkMarchingCubes gives NaN points next to NaN samples: its triangles
    using them are dropped (and counted) before measuring and the distance."""
    d = fresh_dir("nan")
    image = blob_image()
    v = vtk_to_numpy(image.GetPointData().GetScalars())
    v[::5] = np.nan
    image.GetPointData().GetScalars().Modified()
    path = write_vti(image, os.path.join(d, "nan.vti"))
    r = ok(path, "-v", "40", "--measure")
    for key in ("S_K distance MC", "S_K distance out"):
        (mx, mean, points), = measured(r.stdout, key)
        expect(points > 0 and math.isfinite(mx) and math.isfinite(mean), f"{key}: {r.stdout}")
    expect(re.search(r"^  MC non-finite\s+[0-9 ]+ vtkMarchingCubes triangles", r.stdout, re.M),
           f"the dropped triangles are not reported:\n{r.stdout}")
    r = ok(path, "-v", "40", "--distance", os.path.join(d, "d.png"))
    m = re.search(r"MC to refined\s+max ([0-9.]+), mean ([0-9.]+) cells", r.stdout)
    expect(m, f"no finite distance row:\n{r.stdout}")


@check
def measure_several_isovalues_on_integer_data():
    """On uint8 data the filter stores the isovalue 50.5 as the point scalar
    50 (the input's type, as VTK's contour filters do): each isovalue's
    surface is still measured, not an empty selection of it."""
    d = fresh_dir("measure-uint8")
    r = ok("--sample", "tube", "--measure", "--measure-density", "1", "-v", "50.5", "-v", "100.5")
    mc = measured(r.stdout, "S_K distance MC")
    out = measured(r.stdout, "S_K distance out")
    expect(len(mc) == 2 and len(out) == 2, "one row pair per isovalue expected")
    for m in mc + out:
        expect(m[2] > 0, f"a measurement of no points: {m}\n{r.stdout}")
        expect(m[0] < 1e-3, f"vertex distance {m[0]} not ~0")
    expect(sum(p for _, _, p in out) == 3 * table_value(r.stdout, "output triangles"),
           "the refined triangles of both isovalues are measured once each")
    # What the README says of the .vtp point scalars: the input's type.
    vtp = os.path.join(d, "tube.vtp")
    ok("--sample", "tube", "-v", "50.5", "-o", vtp)
    scalars = read_surface(vtp).GetPointData().GetScalars()
    expect(scalars is not None and scalars.GetDataTypeAsString() == "unsigned char",
           "the point scalars are not in the input's type")
    expect(scalars.GetRange() == (50.0, 50.0), f"point scalars {scalars.GetRange()}, expected 50")


@check
def memory_running_out_in_refinement_is_an_error():
    """Refinement that needs more memory than the process may have (here an
    address-space limit of 900 MB; epsilon 1e-6 at level 10 under rule B
    asks for billions of triangles) fails with an out-of-memory error,
    status 1 and no output: a refined cell's triangles and its edge
    decisions grew without a check past the cell's reservation, and the
    failed allocation aborted the process (the ParaView session with
    it). On one thread and on two (each worker refining its own cell)."""
    for threads in ("1", "2"):
        d = fresh_dir(f"out-of-memory-{threads}")
        out = os.path.join(d, "o.vtp")
        script = 'ulimit -v 900000; exec "$0" "$@"'
        environment = dict(os.environ)
        environment.pop("DISPLAY", None)
        r = subprocess.run(["/bin/sh", "-c", script, TOOL, "--sample", "atoms", "--epsilon",
                            "1e-6", "--max-level", "10", "--rule", "B", "--threads", threads,
                            "--normals", "none", "-q", "-o", out],
                           capture_output=True, text=True, env=environment, timeout=TIMEOUT)
        expect(r.returncode == 1,
               f"{threads} threads: exit status {r.returncode}, stderr {r.stderr[-400:]!r}")
        lines = r.stderr.splitlines()
        expect(len(lines) == 1 and lines[0].startswith("precisemc: error: atoms: ") and
               "out of memory" in lines[0], f"{threads} threads: stderr: {r.stderr[-400:]!r}")
        expect(os.listdir(d) == [], f"{threads} threads: left behind: {os.listdir(d)}")


def limited_run(limit_blocks, *args):
    """The tool under a file size limit (ulimit -f, SIGXFSZ ignored): a
    write past it fails with EFBIG, as a write to a full disk fails."""
    script = f'trap "" XFSZ; ulimit -f {limit_blocks}; exec "$0" "$@"'
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    return subprocess.run(["/bin/sh", "-c", script, TOOL, *map(str, args)], capture_output=True,
                          text=True, env=environment, timeout=TIMEOUT)


@check
def failed_writes_keep_the_old_files():
    """A surface or volume that cannot be written whole (the disk full: here
    a file size limit) fails the run and leaves the file there before
    untouched, for every format, including those whose VTK writer does not
    report the failure (PLY, OBJ, VTK XML image data)."""
    d = fresh_dir("failed-writes")
    for ext in ("vtp", "ply", "stl", "obj"):
        out = os.path.join(d, "t." + ext)
        with open(out, "w") as f:
            f.write("OLD\n")
        r = limited_run(8, "--sample", "tube", "--epsilon", "0", "--normals", "none", "-q",
                        "-o", out)
        expect(r.returncode == 1, f"{ext}: exit status {r.returncode}, stderr {r.stderr!r}")
        lines = r.stderr.splitlines()
        expect(len(lines) == 1 and lines[0].startswith(f"precisemc: error: cannot write '{out}'"),
               f"{ext}: stderr {r.stderr!r}")
        expect("request" not in lines[0], f"{ext}: a pipeline dump for a reason: {lines[0]!r}")
        with open(out) as f:
            expect(f.read() == "OLD\n", f"{ext}: the old file was changed")
        # The same run without the limit writes the whole surface.
        ok("--sample", "tube", "--epsilon", "0", "--normals", "none", "-q", "-o", out)
        expect(read_surface(out).GetNumberOfPolys() > 1000, f"{ext}: not written whole")
    vol = os.path.join(d, "v.vti")
    with open(vol, "w") as f:
        f.write("OLD\n")
    r = limited_run(16, "--sample", "ml", "-q", "--write-volume", vol)
    expect(r.returncode == 1 and "cannot write the volume" in r.stderr,
           f"volume: exit status {r.returncode}, stderr {r.stderr!r}")
    with open(vol) as f:
        expect(f.read() == "OLD\n", "the old volume was changed")
    leftovers = [f for f in os.listdir(d) if ".tmp" in f]
    expect(not leftovers, f"temporary files left: {leftovers}")


@check
def two_spellings_of_one_output():
    """Outputs are compared as files, not as strings: 'a.png' and './a.png'
    (or a path through a link to the directory) are refused up front."""
    d = fresh_dir("same-file")
    a = os.path.join(d, "a.png")
    with open(a, "w") as f:
        f.write("OLD\n")
    expect_error(["--sample", "tube", "--compare", "a.png", "--distance", "./a.png"],
                 "name the same file", status=2, cwd=d)
    os.symlink(d, os.path.join(d, "link"))
    expect_error(["--sample", "tube", "-o", os.path.join(d, "s.vtp"), "--write-volume",
                  os.path.join(d, "v.vti"), "--compare", a, "--distance",
                  os.path.join(d, "link", "a.png")], "name the same file", status=2)
    with open(a) as f:
        expect(f.read() == "OLD\n", "the picture was overwritten")
    expect_error(["--sample", "tube", "--compare", ""], "empty", status=2)
    expect_error(["--sample", "tube", "--distance="], "empty", status=2)
    # Nor may an output be the input (it rewrote the input in place), also
    # through a link to it.
    vol = os.path.join(d, "in.vti")
    ok("--sample", "tube", "-q", "--write-volume", vol)
    with open(vol, "rb") as f:
        before = f.read()
    os.symlink(vol, os.path.join(d, "in-link.vti"))
    for out in (vol, os.path.join(d, "in-link.vti"), os.path.join(d, "link", "in.vti")):
        expect_error([vol, "-q", "--write-volume", out], "names the input file", status=2)
    with open(vol, "rb") as f:
        expect(f.read() == before, "the input was rewritten")


@check
def outputs_are_written_through_symbolic_links():
    """An output path that is a symbolic link (relative or absolute, to an
    existing file or a missing one, through a chain of links) is written
    through: the link stays a link and its target gets the surface. A link
    and its target named as two outputs are one file; a loop of links is
    refused before any work."""
    d = fresh_dir("links")
    os.makedirs(os.path.join(d, "real"))
    target = os.path.join(d, "real", "s.vtp")
    with open(target, "w") as f:
        f.write("OLD\n")
    os.symlink(os.path.join("real", "s.vtp"), os.path.join(d, "rel.vtp"))
    os.symlink(os.path.join(d, "rel.vtp"), os.path.join(d, "chain.vtp"))
    for link in ("rel.vtp", "chain.vtp"):
        path = os.path.join(d, link)
        ok("--sample", "tube", "--epsilon", "0", "-q", "-o", path)
        expect(os.path.islink(path), f"{link} was replaced by a file")
        expect(read_surface(target).GetNumberOfPolys() > 1000, f"{link}: the target not written")
        expect(sorted(os.listdir(os.path.join(d, "real"))) == ["s.vtp"],
               f"left behind: {os.listdir(os.path.join(d, 'real'))}")
    # A file replaced keeps its permissions (through a link too), as with
    # '>'; they were the temporary's (0644 under umask 022).
    for mode in (0o600, 0o640, 0o755):
        os.chmod(target, mode)
        ok("--sample", "tube", "--epsilon", "0", "-q", "-o", os.path.join(d, "chain.vtp"))
        got = os.stat(target).st_mode & 0o7777
        expect(got == mode, f"permissions {oct(got)} after the write, want {oct(mode)}")
    # A dangling link: its target is created.
    os.remove(target)
    ok("--sample", "tube", "--epsilon", "0", "-q", "-o", os.path.join(d, "chain.vtp"))
    expect(os.path.isfile(target), "the missing target was not created")
    picture = os.path.join(d, "real", "p.png")
    os.symlink(picture, os.path.join(d, "abs.png"))
    expect_error(["--sample", "tube", "--compare", os.path.join(d, "abs.png"), "--distance",
                  picture], "name the same file", status=2)
    os.symlink("loop2.vtp", os.path.join(d, "loop1.vtp"))
    os.symlink("loop1.vtp", os.path.join(d, "loop2.vtp"))
    expect_error(["--sample", "tube", "-o", os.path.join(d, "loop1.vtp")],
                 "too many levels of symbolic links")
    os.symlink(os.path.join(d, "nowhere", "s.vtp"), os.path.join(d, "missing-dir.vtp"))
    expect_error(["--sample", "tube", "-o", os.path.join(d, "missing-dir.vtp")],
                 "a link to")


@check
def long_output_names_and_interrupts():
    """A file name that fits is written even when its temporary name, which
    adds a prefix and a tag, would not; an interrupted run (SIGTERM) leaves
    no temporary files behind."""
    d = fresh_dir("names")
    long_name = os.path.join(d, "x" * 250 + ".vtp")
    ok("--sample", "tube", "--epsilon", "0", "-q", "-o", long_name)
    expect(read_surface(long_name).GetNumberOfPolys() > 1000, "the long name was not written")
    # One of several outputs whose name is too long (S-atoms.vtp, 256
    # characters): refused before any work, nothing written (S-tube.vtp
    # was left behind, the run failing at the last rename).
    stem = os.path.join(d, "s" * 246)
    expect_error(["--sample", "all", "-q", "-o", stem + ".vtp"], "File name too long",
                 outputs=[stem + "-tube.vtp", stem + "-ml.vtp"])
    out = os.path.join(d, "run.vtp")
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    p = subprocess.Popen([TOOL, "--sample", "all", "--measure", "-o", out],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=environment)
    seen = []
    for _ in range(3000):
        seen = [f for f in os.listdir(d) if ".tmp" in f]
        if seen or p.poll() is not None:
            break
        time.sleep(0.01)
    expect(seen, "no temporary file seen while the run went on")
    p.terminate()
    p.wait(timeout=TIMEOUT)
    expect(p.returncode == -15, f"exit status {p.returncode} after SIGTERM")
    leftovers = [f for f in os.listdir(d) if ".tmp" in f or f.startswith("run")]
    expect(not leftovers, f"left behind after SIGTERM: {leftovers}")


@check
def infinite_samples_are_skipped():
    """An infinite sample is skipped like a NaN one (the cells touching it
    get no surface): the volume is read, the range is the finite one."""
    d = fresh_dir("inf")
    image = blob_image()
    v = vtk_to_numpy(image.GetPointData().GetScalars())
    v[100] = np.inf
    v[200] = -np.inf
    image.GetPointData().GetScalars().Modified()
    path = write_vti(image, os.path.join(d, "inf.vti"))
    out = os.path.join(d, "o.vtp")
    r = ok(path, "-o", out)
    m = re.search(r"the middle of the scalar range \[([-0-9.e+]+), ([-0-9.e+]+)\]", r.stdout)
    expect(m and all(math.isfinite(float(x)) for x in m.groups()), f"range: {r.stdout}")
    expect(read_surface(out).GetNumberOfPolys() > 100, "no surface")
    expect_error([path, "-v", "1e300"], "outside the scalar range")


@check
def nifti_scaling_is_applied():
    """NIfTI's scl_slope and scl_inter turn stored values into real ones (as
    DICOM's rescale does): the range and the isovalues are the real ones,
    and the surface at a real value is the stored volume's at the matching
    stored value."""
    d = fresh_dir("nifti-scaling")
    image = blob_image()
    plain = os.path.join(d, "plain.nii")
    scaled = os.path.join(d, "scaled.nii")
    for path, slope, intercept in ((plain, 0.0, 0.0), (scaled, 2.0, -100.0)):
        w = vtkNIFTIImageWriter()
        w.SetFileName(path)
        w.SetInputData(image)
        w.SetRescaleSlope(slope)
        w.SetRescaleIntercept(intercept)
        w.Write()
    r_plain = ok(plain, "-v", "40")
    r_scaled = ok(scaled, "-v", str(2.0 * 40 - 100.0))
    expect(table_value(r_plain.stdout, "output triangles") ==
           table_value(r_scaled.stdout, "output triangles"),
           f"different surfaces:\n{r_plain.stdout}\n{r_scaled.stdout}")
    r = ok(scaled)
    m = re.search(r"the middle of the scalar range \[([-0-9.e+]+), ([-0-9.e+]+)\]", r.stdout)
    lo, hi = (float(x) for x in m.groups())
    v = vtk_to_numpy(image.GetPointData().GetScalars())
    expect(abs(lo - (2 * float(v.min()) - 100)) < 1e-3 and abs(hi - (2 * float(v.max()) - 100)) < 1e-3,
           f"range [{lo}, {hi}] is not the scaled one")


def written_nifti(d):
    """The blob written by VTK's NIfTI writer to d/good.nii: its path and bytes."""
    good = os.path.join(d, "good.nii")
    w = vtkNIFTIImageWriter()
    w.SetFileName(good)
    w.SetInputData(blob_image())
    w.Write()
    with open(good, "rb") as f:
        return good, f.read()


@check
def nifti_datatype_vtk_cannot_read_is_refused():
    """A NIfTI header whose datatype code is none of the NIfTI-1 types VTK
    9.1's reader maps to a VTK type (5, 4096, 12345, 4097; binary 1) made
    the reader crash reading the data, or size it from garbage. Refused
    before the reader runs, naming the code, .nii and .nii.gz alike; the
    codes it reads still read."""
    import gzip
    d = fresh_dir("nifti-datatype")
    out = os.path.join(d, "o.vtp")
    good, data = written_nifti(d)
    expect(struct.unpack("<h", data[70:72])[0] == 16, "float32 datatype code at byte 70")
    for code in (5, 4096, 12345, 4097, 1):
        patched = data[:70] + struct.pack("<h", code) + data[72:]
        for ext in ("nii", "nii.gz"):
            path = os.path.join(d, f"code{code}.{ext}")
            with (gzip.open if ext == "nii.gz" else open)(path, "wb") as f:
                f.write(patched)
            try:
                expect_error([path, "-o", out], f"datatype code {code} is none", outputs=[out],
                             status=1)
            except Failure as e:
                raise Failure(f"{path}: {e}")
    ok(good, "-q", "-o", out)


@check
def nifti_scaling_beyond_float_leaves_no_finite_values():
    """double samples of 1e300 and more scaled by scl_slope 3e38 are all
    infinite:
    the check for finite values looked at the stored values, before the
    scaling, and the range computed after it, [inf, -inf], gave the default
    isovalue NaN, which passed the range checks. The range is computed once,
    on the scaled values, and the file is refused."""
    d = fresh_dir("nifti-overflow")
    dims, spacing, origin, v = blob_volume()
    stored = 1e300 * (1.0 + v.astype(np.float64))
    path = os.path.join(d, "overflow.nii")
    w = vtkNIFTIImageWriter()
    w.SetFileName(path)
    w.SetInputData(density_image(stored, dims, spacing, origin))
    w.SetRescaleSlope(3e38)
    w.SetRescaleIntercept(0.0)
    w.Write()
    out = os.path.join(d, "o.vtp")
    expect_error([path, "-o", out], "the scalars have no finite values", outputs=[out],
                 status=1)


@check
def array_option_chooses_the_point_array():
    """A file of several point arrays, none active: the first is contoured,
    and the table and a range error name it (the tool chose it without a
    word, and nothing else could be chosen); --array picks another, which
    gives the surface of a file holding that array alone; a missing name
    is an error listing the arrays; --array without an input file is a
    command-line mistake."""
    d = fresh_dir("array-option")
    dims, spacing, origin, v = blob_volume()
    image = vtkImageData()
    image.SetDimensions(*dims)
    image.SetSpacing(*spacing)
    image.SetOrigin(*origin)
    pd = image.GetPointData()
    for name, values in (("density", v), ("pressure", v * 100.0 + 1000.0)):
        array = numpy_to_vtk(np.ascontiguousarray(values).ravel(), deep=True)
        array.SetName(name)
        pd.AddArray(array)
    both = os.path.join(d, "both.vti")
    w = vtkXMLImageDataWriter()
    w.SetFileName(both)
    w.SetInputData(image)
    w.Write()
    expect(pd.GetNumberOfArrays() == 2 and pd.GetArrayName(0) == "density", "setup")
    alone = os.path.join(d, "alone.vti")
    w = vtkXMLImageDataWriter()
    w.SetFileName(alone)
    w.SetInputData(density_image(v * 100.0 + 1000.0, dims, spacing, origin))
    w.Write()
    r = ok(both, "-v", "40")
    expect(re.search(r"^both\.vti: 24x20x18, float, array 'density'$", r.stdout, re.M), r.stdout)
    expect_error([both, "-v", "5000"], "of both.vti (array 'density')")
    outs = {}
    for label, args in (("chosen", [both, "--array", "pressure"]), ("alone", [alone])):
        out = os.path.join(d, label + ".vtp")
        r = ok(*args, "-v", "5000", "-o", out)
        outs[label] = vtk_to_numpy(read_surface(out).GetPoints().GetData())
    expect(outs["chosen"].shape == outs["alone"].shape and
           np.array_equal(outs["chosen"], outs["alone"]), "--array pressure: another surface")
    out = os.path.join(d, "o.vtp")
    expect_error([both, "--array", "velocity", "-o", out],
                 "no point array of numbers named 'velocity' (its point arrays: 'density', "
                 "'pressure')", outputs=[out], status=1)
    expect_error(["--sample", "tube", "--array", "density"], "--array", status=2)


@check
def compressed_metaimage_shorter_than_its_header_is_refused():
    """A compressed MetaImage (.mha, or .mhd with its .zraw) whose DimSize
    declares more slices than its data holds: VTK's reader filled the
    missing slices with zeros, exit status 0. Refused with the byte
    counts; the file as written reads, and gives the uncompressed file's
    surface."""
    d = fresh_dir("mha-compressed")
    image = blob_image()
    dims = image.GetDimensions()
    surfaces = {}
    for ext in ("mha", "mhd"):
        for compressed in (False, True):
            path = os.path.join(d, f"blob-{int(compressed)}.{ext}")
            w = vtkMetaImageWriter()
            w.SetFileName(path)
            if ext == "mhd":
                w.SetRAWFileName(os.path.join(d, f"blob-{int(compressed)}.{'zraw' if compressed else 'raw'}"))
            w.SetCompression(compressed)
            w.SetInputData(image)
            w.Write()
            out = os.path.join(d, f"{ext}-{int(compressed)}.vtp")
            r = ok(path, "-v", "40", "-o", out)
            surfaces[(ext, compressed)] = table_value(r.stdout, "output triangles")
            if not compressed:
                continue
            with open(path, "rb") as f:
                data = f.read()
            declared = b"DimSize = %d %d %d" % dims
            expect(declared in data, data[:300])
            longer = os.path.join(d, f"longer.{ext}")
            with open(longer, "wb") as f:
                f.write(data.replace(declared, b"DimSize = %d %d %d" % (dims[0], dims[1], dims[2] + 7)))
            want = 4 * dims[0] * dims[1] * dims[2]
            refused = os.path.join(d, f"longer-{ext}.vtp")
            expect_error([longer, "-o", refused],
                         f"its compressed data holds {want} bytes where its DimSize declares "
                         f"{want // dims[2] * (dims[2] + 7)}", outputs=[refused], status=1)
    expect(len(set(surfaces.values())) == 1 and min(surfaces.values()) > 0, surfaces)


@check
def header_frames_are_applied():
    """The world frame a header gives (orientation, position, spacing) is the
    surface's, as a .vti with the same Direction, Origin and Spacing gives
    it: a NRRD's space directions and space origin, a MetaImage's
    TransformMatrix (each axis's direction in turn) and Offset, a NIfTI's
    sform (or qform). VTK 9.1's readers keep at most the spacing and the
    offset: a mirrored NRRD came out unmirrored, a NIfTI's offset was
    dropped, all with exit status 0. The frame here turns and mirrors
    (the axes' directions are not the identity's in any order); a 4D
    NIfTI is refused (its reader gives the first time point only)."""
    d = fresh_dir("header-frames")
    dims, _, _, v = blob_volume()
    spacing = (0.8, 0.9, 1.1)
    origin = (10.0, -20.0, 30.5)
    c, s = math.cos(0.5), math.sin(0.5)
    # Columns: each axis's direction in the world (a turn about z, then
    # the z axis mirrored).
    direction = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, -1.0]])
    reference = density_image(v, dims, spacing, origin)
    reference.SetDirectionMatrix(*direction.ravel())
    paths = {"vti": os.path.join(d, "frame.vti")}
    w = vtkXMLImageDataWriter()
    w.SetFileName(paths["vti"])
    w.SetInputData(reference)
    w.Write()
    steps = [direction[:, a] * spacing[a] for a in range(3)]
    vec = lambda x: "(%s)" % ",".join(repr(float(c)) for c in x)
    header = ("NRRD0004\ntype: float\ndimension: 3\nspace: left-posterior-superior\n"
              "sizes: %d %d %d\nspace directions: %s\nspace origin: %s\nendian: little\n"
              "encoding: raw\n\n" % (*dims, " ".join(vec(x) for x in steps), vec(origin)))
    paths["nrrd"] = os.path.join(d, "frame.nrrd")
    with open(paths["nrrd"], "wb") as f:
        f.write(header.encode() + v.astype("<f4").tobytes())
    # MetaImage: VTK's writer writes the Offset and an identity matrix.
    paths["mha"] = os.path.join(d, "frame.mha")
    w = vtkMetaImageWriter()
    w.SetFileName(paths["mha"])
    w.SetCompression(False)
    w.SetInputData(density_image(v, dims, spacing, origin))
    w.Write()
    with open(paths["mha"], "rb") as f:
        data = f.read()
    matrix = ("TransformMatrix = " + " ".join(repr(float(x)) for x in direction.T.ravel())).encode()
    expect(b"TransformMatrix = 1 0 0 0 1 0 0 0 1" in data, data[:300])
    with open(paths["mha"], "wb") as f:
        f.write(data.replace(b"TransformMatrix = 1 0 0 0 1 0 0 0 1", matrix, 1))
    # NIfTI-1 by hand (VTK's writer would round-trip its own reading): the
    # sform's rows map (i, j, k) to the world, pixdim the spacing.
    hdr = bytearray(352)
    struct.pack_into("<i", hdr, 0, 348)
    struct.pack_into("<8h", hdr, 40, 3, *dims, 1, 1, 1, 1)
    struct.pack_into("<hh", hdr, 70, 16, 32)  # float32
    struct.pack_into("<8f", hdr, 76, 1.0, *spacing, 1.0, 1.0, 1.0, 1.0)
    struct.pack_into("<fff", hdr, 108, 352.0, 1.0, 0.0)  # vox_offset, scl_slope, scl_inter
    struct.pack_into("<hh", hdr, 252, 0, 1)  # qform_code 0, sform_code 1
    for r in range(3):
        struct.pack_into("<4f", hdr, 280 + 16 * r, *(direction[r] * spacing), origin[r])
    hdr[344:348] = b"n+1\0"
    paths["nii"] = os.path.join(d, "frame.nii")
    with open(paths["nii"], "wb") as f:
        f.write(bytes(hdr) + v.astype("<f4").tobytes())
    surfaces = {}
    for label, path in paths.items():
        out = os.path.join(d, label + ".vtp")
        ok(path, "-v", "40", "-q", "-o", out)
        pts = vtk_to_numpy(read_surface(out).GetPoints().GetData()).astype(np.float64)
        surfaces[label] = pts[np.lexsort(pts.T[::-1])]
    want = surfaces["vti"]
    # Not the frame of an identity matrix, nor of one that ignores the
    # origin: the reference lies where the frame puts it.
    index_box = np.array(dims) * spacing
    expect(want[:, 2].max() < origin[2] + 1e-9 and want[:, 2].min() > origin[2] - index_box[2],
           "reference not mirrored along z")
    for label in ("nrrd", "mha", "nii"):
        got = surfaces[label]
        if label != "nii":
            # The same samples in the same frame: the same points (float32).
            expect(got.shape == want.shape, f"{label}: {got.shape} points, want {want.shape}")
            err = np.abs(got - want).max()
        else:
            # VTK's NIfTI reader turns a mirroring frame into one that is
            # not, reversing the slices: another triangulation of the same
            # surface. Each one's points lie on the other (within the
            # refinement's epsilon, 0.01 cells, twice).
            from vtkmodules.vtkFiltersCore import vtkImplicitPolyDataDistance
            err = 0.0
            for a, b in (("nii", "vti"), ("vti", "nii")):
                distance = vtkImplicitPolyDataDistance()
                distance.SetInput(read_surface(os.path.join(d, b + ".vtp")))
                err = max(err, max(abs(distance.EvaluateFunction(p)) for p in surfaces[a]))
            err = err if err > 0.03 else 0.0
        expect(err < 1e-4, f"{label}: points {err} away from the .vti's")
    # A 4D NIfTI (3 time points): refused.
    struct.pack_into("<8h", hdr, 40, 4, *dims, 3, 1, 1, 1)
    four = os.path.join(d, "four.nii")
    with open(four, "wb") as f:
        f.write(bytes(hdr) + np.concatenate([v.ravel()] * 3).astype("<f4").tobytes())
    out = os.path.join(d, "four.vtp")
    expect_error([four, "-o", out], "3 time points", outputs=[out], status=1)


@check
def nrrd_headers_vtk_misreads_are_refused():
    """Data VTK's NRRD reader would read as garbage (ASCII after an attached
    header) or crash on (a detached header declaring more than the machine
    holds) is refused with a reason: a data file too small for the samples
    declared as cut short, one as large (sparse) as beyond the memory."""
    d = fresh_dir("nrrd-refused")
    ascii_path = os.path.join(d, "ascii.nrrd")
    with open(ascii_path, "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n"
                "1 2 3 4 5 6 7 8\n")
    out = os.path.join(d, "o.vtp")
    expect_error([ascii_path, "-o", out], "ascii", outputs=[out])
    raw = os.path.join(d, "small.raw")
    with open(raw, "wb") as f:
        f.write(bytes(64))
    huge = os.path.join(d, "huge.nhdr")
    with open(huge, "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 100000 100000 100000\n"
                "encoding: raw\nendian: little\ndata file: small.raw\n\n")
    expect_error([huge, "-o", out], "holds 64 bytes, fewer than the 4000000000000000",
                 outputs=[out])
    # 4 TB of floats, a sparse file that takes no room.
    with open(os.path.join(d, "huge.raw"), "wb") as f:
        f.truncate(4 * 10 ** 12)
    with open(huge, "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 10000 10000 10000\n"
                "encoding: raw\nendian: little\ndata file: huge.raw\n\n")
    expect_error([huge, "-o", out], "more than this machine's memory", outputs=[out])


@check
def nrrd_headers_vtk_hangs_on_or_misreads_are_refused():
    """An attached header that no blank line ends (VTK 9.1's reader never
    returns), sizes that are not positive, a first axis the reader takes
    for vector components, and a MetaImage header with a negative size:
    each refused with its reason, in time."""
    d = fresh_dir("nrrd-hang")
    out = os.path.join(d, "o.vtp")
    data = np.arange(12 ** 3, dtype="<f4").tobytes()
    head = "NRRD0004\ntype: float\ndimension: 3\nsizes: %s\nendian: little\nencoding: raw\n"
    cases = [
        ("noblank.nrrd", (head % "12 12 12").encode() + data, "no blank line ends the header"),
        ("negative.nrrd", (head % "-12 12 12").encode() + b"\n" + data, "positive integers"),
        ("zero.nrrd", (head % "12 0 12").encode() + b"\n" + data, "positive integers"),
        ("short.nrrd", (head % "4 4 4").encode() + b"\n" + np.zeros(64, "<f4").tobytes(),
         "4x4x1 samples of 4 components"),
        ("negative.mhd", b"ObjectType = Image\nNDims = 3\nDimSize = -12 12 12\n"
         b"ElementType = MET_FLOAT\nElementDataFile = LOCAL\n" + data, "no samples along axis 0"),
    ]
    for name, content, fragment in cases:
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(content)
        start = time.monotonic()
        expect_error([path, "-o", out], fragment, outputs=[out])
        expect(time.monotonic() - start < 60, f"{name}: took {time.monotonic() - start:.0f} s")


@check
def metaimage_header_field_longer_than_metaio_holds_is_refused():
    """MetaIO copies a header line's key and value into buffers of 255
    bytes: a Name or Comment of 255 characters or more (or a key as long)
    aborted the tool inside VTK's reader ("buffer overflow detected").
    Refused naming the line; 254 characters still read."""
    d = fresh_dir("metaimage-long-field")
    out = os.path.join(d, "o.vtp")
    data = np.zeros(4 ** 3, dtype="u1")
    data[21] = 9
    head = b"ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\n"
    for name, line, fragment in (
            ("name.mha", b"Name = " + b"a" * 300, "line 5 of its header has a value of 300 "
             "characters ('Name')"),
            ("comment.mha", b"Comment = " + b"b" * 255, "a value of 255 characters ('Comment')"),
            ("key.mha", b"c" * 255 + b" = 1", "line 5 of its header has a key of 255")):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(head + line + b"\nElementDataFile = LOCAL\n" + data.tobytes())
        try:
            expect_error([path, "-o", out], fragment, outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{name}: {e}")
    path = os.path.join(d, "254.mha")
    with open(path, "wb") as f:
        f.write(head + b"Name = " + b"a" * 254 + b"\nElementDataFile = LOCAL\n" + data.tobytes())
    ok(path, "-q", "-o", out)


@check
def metaimage_slice_file_pattern_that_misses_slices_is_refused():
    """ElementDataFile = "s%d.raw min max step" names one file per slice:
    a step of 0 (given, or (max - min) / slices in integers, as "1 2" on 2
    slices) made VTK 9.1's reader divide by zero (SIGFPE), a negative one
    names no file, and a range naming fewer files than slices left the
    others zeros, exit status 0. Refused with the pattern; a pattern
    naming every slice still reads."""
    d = fresh_dir("metaimage-pattern")
    out = os.path.join(d, "o.vtp")
    for k in range(1, 5):
        with open(os.path.join(d, f"s{k}.raw"), "wb") as f:
            f.write(bytes([k, 0, 0, 9]))
    for label, pattern, fragment in (
            ("step0", "s%d.raw 1 2 0", "steps by 0: VTK's MetaImage reader would divide by zero"),
            ("derived-step0", "s%d.raw 1 2", "steps by 0 ((max - min) / slices"),
            ("negative", "s%d.raw 2 1 -1", "steps by -1"),
            ("one-file", "s%d.raw 1 1 1", "names 1 file (1 to 1 by 1) for 2 slices"),
            ("wide-step", "s%d.raw 1 2 5", "names 1 file (1 to 2 by 5) for 2 slices")):
        path = os.path.join(d, label + ".mhd")
        with open(path, "w") as f:
            f.write("ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                    f"ElementDataFile = {pattern}\n")
        try:
            expect_error([path, "-o", out], fragment, outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{label}: {e}")
    for pattern in ("s%d.raw 1 2 1", "s%d.raw 2 4 2", "s%d.raw 3", "s%d.raw"):
        path = os.path.join(d, "good.mhd")
        with open(path, "w") as f:
            f.write("ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                    f"ElementDataFile = {pattern}\n")
        ok(path, "-q", "-v", "4", "-o", out)


@check
def metaimage_file_list_that_misses_slices_is_refused():
    """ElementDataFile = LIST names one slice file a line after it: with
    fewer lines than slices (or a last name without its newline, which
    VTK 9.1's reader skips) the missing slices were read as zeros, exit
    status 0. Refused, and so are a listed file that is missing or
    shorter than a slice, and an empty line among them; a complete list
    (CRLF line ends, LIST 2D) still reads."""
    d = fresh_dir("metaimage-list")
    out = os.path.join(d, "o.vtp")
    for k in range(1, 3):
        with open(os.path.join(d, f"s{k}.raw"), "wb") as f:
            f.write(bytes([k, 0, 0, 9]))
    with open(os.path.join(d, "short.raw"), "wb") as f:
        f.write(b"\1\2")
    head = "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
    for label, listing, fragment in (
            ("one", "LIST 2D\ns1.raw\n", "its file list names 1 file (one a line, each line "
             "ended by a newline) for 2 slices"),
            ("no-newline", "LIST\ns1.raw\ns2.raw", "names 1 file"),
            ("missing", "LIST\ns1.raw\nnone.raw\n", "line 2 of its file list names "
             "'none.raw', which is not a readable file"),
            ("short", "LIST\ns1.raw\nshort.raw\n", "holds 2 bytes, fewer than a slice's 4"),
            ("empty-line", "LIST\ns1.raw\n\n", "line 2 of its file list is empty")):
        path = os.path.join(d, label + ".mhd")
        with open(path, "w", newline="") as f:
            f.write(head + "ElementDataFile = " + listing)
        try:
            expect_error([path, "-o", out], fragment, outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{label}: {e}")
    for listing in ("LIST\ns1.raw\ns2.raw\n", "LIST 2D\r\ns1.raw \r\ns2.raw\r\n"):
        path = os.path.join(d, "good.mhd")
        with open(path, "w", newline="") as f:
            f.write(head + "ElementDataFile = " + listing)
        ok(path, "-q", "-v", "4", "-o", out)


@check
def header_errors_stop_the_read():
    """A reader that rejects a header (VTK's MetaImage reader takes at most
    3 dimensions) must not be asked for the data anyway: it allocated an
    empty image and read the samples past its end (heap overflow, abort)."""
    d = fresh_dir("header-errors")
    out = os.path.join(d, "o.vtp")
    data = np.zeros(4 ** 3, dtype="u1")
    data[21] = 9
    for name, dims in (("4d.mha", "4 4 4 1"), ("4d-long.mha", "4 4 4 2"),
                       ("9d.mha", "4 4 4 1 1 1 1 1 1")):
        ndims = len(dims.split())
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(b"ObjectType = Image\nNDims = %d\nDimSize = %s\nElementType = MET_UCHAR\n"
                    b"ElementDataFile = LOCAL\n" % (ndims, dims.encode()))
            f.write(np.tile(data, 2).tobytes())
        try:
            expect_error([path, "-o", out], "dimensions", outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{name}: {e}")


def refuse_nrrd_headers(d, head, data, cases):
    """Each (name, fields, fragment) of `cases`: the NRRD file `d/name` of
    header `head % fields` and samples `data` is refused, the error
    containing `fragment`."""
    out = os.path.join(d, "o.vtp")
    for name, fields, fragment in cases:
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write((head % fields).encode() + data.tobytes())
        try:
            expect_error([path, "-o", out], fragment, outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{name}: {e}")


def expect_refused_in_time(path, fragment, out):
    """expect_error() for the input `path`, within 60 s (the cases hung)."""
    start = time.monotonic()
    try:
        expect_error([path, "-o", out], fragment, outputs=[out], status=1)
    except Failure as e:
        raise Failure(f"{os.path.basename(path)}: {e}")
    took = time.monotonic() - start
    expect(took < 60, f"{os.path.basename(path)}: took {took:.0f} s")


@check
def nrrd_raw_data_cut_short_is_refused_with_its_byte_counts():
    """Raw NRRD samples cut short, after an attached header (no samples at
    all, or 100 bytes missing) or in a detached data file: refused with the
    bytes there and the bytes the samples take, where VTK's reader failed
    in its own words ("File operation failed. row = 9, Tried to Read = 48,
    Read = 44, ..."); the whole files still read."""
    d = fresh_dir("nrrd-cut")
    out = os.path.join(d, "o.vtp")
    data = np.arange(12 ** 3, dtype="<f4").tobytes()
    head = "NRRD0004\ntype: float\ndimension: 3\nsizes: 12 12 12\nendian: little\nencoding: raw\n"
    for name, content in (("cut.raw", data[:-100]), ("whole.raw", data)):
        with open(os.path.join(d, name), "wb") as f:
            f.write(content)
    for name, content, fragment in (
            ("empty.nrrd", head + "\n", "data after the header holds 0 bytes, fewer than the 6912"),
            ("cut.nrrd", (head + "\n").encode() + data[:-100],
             "data after the header holds 6812 bytes, fewer than the 6912"),
            ("cut.nhdr", head + "data file: cut.raw\n\n",
             "data file 'cut.raw' holds 6812 bytes, fewer than the 6912")):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(content.encode() if isinstance(content, str) else content)
        expect_refused_in_time(path, fragment, out)
    for name, content in (("whole.nrrd", (head + "\n").encode() + data),
                          ("whole.nhdr", (head + "data file: whole.raw\n\n").encode())):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(content)
        ok(path, "-q", "-v", "100.5", "-o", os.path.join(d, "good.vtp"))
        expect(read_surface(os.path.join(d, "good.vtp")).GetNumberOfPolys() > 0, f"{name}: empty")


@check
def slice_file_names_vtk_crashes_or_hangs_on_are_refused():
    """A review under AddressSanitizer (fifty-second session): a slice file
    pattern's printf conversion reached snprintf in VTK's readers ("%s":
    SIGSEGV; "%n": abort), a NRRD pattern stepping by 0 named files without
    end (memory grew by 250 MB/s) and one over 10^9 numbers built as many
    names, a detached NRRD header whose last line has no newline never
    finished reading, a MetaImage NDims of -1 or 2^31 - 1 looped, and a
    FIFO named as a data file (or in a DICOM directory) waited for a
    writer while a device was read as samples. Each refused with its
    reason, in time; integer patterns and regular files still read."""
    d = fresh_dir("slice-file-names")
    out = os.path.join(d, "o.vtp")
    data = bytes(range(256)) * 10
    for k in range(1, 11):
        with open(os.path.join(d, f"s{k:03d}.raw"), "wb") as f:
            f.write(data[:256])
    with open(os.path.join(d, "all.raw"), "wb") as f:
        f.write(data)
    os.mkfifo(os.path.join(d, "fifo.raw"))
    for k in range(1, 11):
        # q010.raw, the last slice, a FIFO; p%NNN.raw, names with a percent sign.
        if k < 10:
            shutil.copy(os.path.join(d, f"s{k:03d}.raw"), os.path.join(d, f"q{k:03d}.raw"))
        shutil.copy(os.path.join(d, f"s{k:03d}.raw"), os.path.join(d, f"p%{k:03d}.raw"))
    os.mkfifo(os.path.join(d, "q010.raw"))
    mhd = ("ObjectType = Image\nNDims = 3\nDimSize = 16 16 10\nElementType = MET_UCHAR\n"
           "ElementDataFile = %s\n")
    nhdr = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 16 16 10\nencoding: raw\ndata file: %s"
    cases = [
        ("conv-s.mhd", mhd % "s%s.raw 1 10 1", "holds '%s', not an integer conversion"),
        ("conv-n.mhd", mhd % "s%n.raw 1 10 1", "holds '%n', not an integer conversion"),
        ("conv-long.mhd", mhd % "s%03ld.raw 1 10 1", "holds '%03l'"),
        ("two.mhd", mhd % "s%d%d.raw 1 10 1", "holds 2 integer conversions"),
        ("wide.mhd", mhd % "s%999999999d.raw 1 10 1", "holds '%999999999d'"),
        ("ndims-negative.mhd", mhd.replace("NDims = 3", "NDims = -1") % "all.raw",
         "NDims = -1, not a number of dimensions"),
        ("ndims-huge.mhd", mhd.replace("NDims = 3", "NDims = 2147483647") % "all.raw",
         "NDims = 2147483647"),
        ("fifo.mhd", mhd % "fifo.raw", "'fifo.raw', which is not a regular file"),
        ("device.mhd", mhd % "/dev/zero", "'/dev/zero', which is not a regular file"),
        ("fifo-slice.mhd", mhd % "q%03d.raw 1 10 1", "'q010.raw', which is not a regular file"),
        ("missing-slice.mhd", mhd % "s%03d.raw 0 9 1", "names 's000.raw': no such file"),
        ("conv-s.nhdr", nhdr % "s%s.raw 1 10 1\n\n", "holds '%s', not an integer conversion"),
        ("step0.nhdr", nhdr % "s%03d.raw 1 10 0\n\n", "steps by 0"),
        ("range.nhdr", nhdr % "s%03d.raw 1 1000000000 1\n\n", "names 1000000000 files"),
        ("few.nhdr", nhdr % "s%03d.raw 1 9 1\n\n", "names 9 files (1 to 9 by 1) for 10 slices"),
        ("unended.nhdr", nhdr % "all.raw", "last line ends without a newline"),
        ("fifo.nhdr", nhdr % "fifo.raw\n", "'fifo.raw', which is not a regular file"),
        ("device.nhdr", nhdr % "/dev/urandom\n", "'/dev/urandom', which is not a regular"),
        ("fifo-list.nhdr", nhdr % "LIST\nall.raw\nfifo.raw\n", "'fifo.raw', which is not"),
    ]
    for name, text, fragment in cases:
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write(text)
        expect_refused_in_time(path, fragment, out)
    dicom = os.path.join(d, "series")
    os.mkdir(dicom)
    os.mkfifo(os.path.join(dicom, "x.dcm"))
    expect_refused_in_time(dicom, "holds 'x.dcm', which is not a regular file", out)
    for name, text in (("good.mhd", mhd % "s%03d.raw 1 10 1"), ("good-one.mhd", mhd % "all.raw"),
                       ("good.nhdr", nhdr % "s%03d.raw 1 10 1\n"),
                       ("good-one.nhdr", nhdr % "all.raw\n"),
                       ("percent.nhdr", nhdr % "p%%%03d.raw 1 10 1\n"),
                       ("percent.mhd", mhd % "p%%%03d.raw 1 10 1")):
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write(text)
        ok(path, "-q", "-v", "100", "-o", out)


def compressed_vti(path, inline):
    """The blob written by VTK's XML writer with zlib compression to `path`
    (appended raw data, or inline base64 with `inline`): its bytes, and
    where the first array's block header starts and how long its words
    are (bytes; in base64 characters for inline data)."""
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(blob_image())
    w.SetCompressorTypeToZLib()
    if inline:
        w.SetDataModeToBinary()
    else:
        w.SetDataModeToAppended()
        w.EncodeAppendedDataOff()
    w.Write()
    with open(path, "rb") as f:
        data = f.read()
    word = 8 if b'header_type="UInt64"' in data else 4
    if inline:
        at = data.index(b">", data.index(b"<DataArray")) + 1
        while data[at:at + 1].isspace():
            at += 1
    else:
        at = data.index(b"_", data.index(b"<AppendedData")) + 1
    return data, at, word


@check
def headers_vtk_crashes_on_past_the_first_checks_are_refused():
    """A second review under AddressSanitizer (fifty-second session): a
    compressed .vti whose block header gives 0 blocks or blocks of 0 bytes
    (SIGSEGV, SIGFPE in VTK's XML reader), NRRD fields spelled so that VTK's
    reader does not know them ("SIZES:", "dimension:3") or sizes before
    the dimension (SIGSEGV: it read into an image it never allocated), a
    MetaImage header or a detached NRRD header too long for the checks'
    window (the checks were skipped: a %s pattern crashed), and a
    MetaImage of 0 channels (memory never written read as samples, exit
    0). Each refused with its reason; compressed data VTK wrote still
    reads, a MetaImage marked compressed as "TRUE" is checked as one
    marked "True", and its CompressedDataSize bytes are the ones checked."""
    import base64
    import zlib
    d = fresh_dir("past-the-checks")
    out = os.path.join(d, "o.vtp")
    for inline in (False, True):
        good = os.path.join(d, f"good-{'inline' if inline else 'appended'}.vti")
        data, at, word = compressed_vti(good, inline)
        ok(good, "-q", "-o", os.path.join(d, "good.vtp"))
        for label, index in (("blocks0", 0), ("blocksize0", 1)):
            if inline:
                header = bytearray(base64.b64decode(data[at:at + 4 * 3 * word]))
                header[index * word:(index + 1) * word] = bytes(word)
                patched = data[:at] + base64.b64encode(bytes(header)) + data[at + 4 * 3 * word:]
            else:
                patched = data[:at + index * word] + bytes(word) + data[at + (index + 1) * word:]
            path = good.replace("good", label)
            with open(path, "wb") as f:
                f.write(patched)
            expect_refused_in_time(path, "which VTK's XML reader crashes on", out)
    samples = np.arange(16 ** 3, dtype="<f4").tobytes()
    for name, head, fragment in (
            ("upper.nrrd", "NRRD0004\ntype: float\ndimension: 3\nSIZES: 16 16 16\n",
             "declares dimension 3 but 0 sizes"),
            ("tight.nrrd", "NRRD0004\ntype: float\ndimension:3\nsizes: 16 16 16\n",
             "no dimension field"),
            ("order.nrrd", "NRRD0004\ntype: float\nsizes: 16 16 16\ndimension: 3\n",
             "sizes field comes before its dimension field")):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(head.encode() + b"endian: little\nencoding: raw\n\n" + samples)
        expect_refused_in_time(path, fragment, out)
    with open(os.path.join(d, "s.raw"), "wb") as f:
        f.write(samples)
    comments = "".join(f"Comment{k} = x\n" for k in range(6000))
    path = os.path.join(d, "long.mhd")
    with open(path, "w") as f:
        f.write("ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n"
                + comments + "ElementDataFile = s%s.raw 1 16 1\n")
    expect_refused_in_time(path, "no ElementDataFile line ends its header within its first 64 KiB",
                           out)
    path = os.path.join(d, "long.nhdr")
    with open(path, "w") as f:
        f.write("NRRD0004\ntype: float\ndimension: 3\nsizes: 16 16 16\nencoding: raw\n"
                "data file: s.raw\n" + "# x\n" * 400000 + "data file: s%s.raw 1 16 1\n")
    expect_refused_in_time(path, "its header does not end within its first 1 MiB", out)
    path = os.path.join(d, "channels0.mhd")
    with open(path, "w") as f:
        f.write("ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n"
                "ElementNumberOfChannels = 0\nElementDataFile = s.raw\n")
    expect_refused_in_time(path, "0 channels (ElementNumberOfChannels)", out)
    whole = zlib.compress(samples)
    half = whole[:len(whole) // 2]
    meta = ("ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n"
            "CompressedData = True\nCompressedDataSize = %d\nElementDataFile = LOCAL\n")
    # The reader reads CompressedDataSize bytes of the stream: half of it
    # read as half the samples and zeros, exit status 0.
    path = os.path.join(d, "size-half.mha")
    with open(path, "wb") as f:
        f.write((meta % len(half)).encode() + whole)
    expect_refused_in_time(path, "its compressed data holds", out)
    path = os.path.join(d, "size-whole.mha")
    with open(path, "wb") as f:
        f.write((meta % len(whole)).encode() + whole)
    ok(path, "-q", "-o", os.path.join(d, "good.vtp"))
    for flag in ("TRUE", "1"):
        path = os.path.join(d, f"zhalf-{flag}.mha")
        with open(path, "wb") as f:
            f.write(("ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\nElementType = MET_FLOAT\n"
                     f"CompressedData = {flag}\nElementDataFile = LOCAL\n").encode() + half)
        expect_refused_in_time(path, "its compressed data holds", out)


@check
def vti_tags_hidden_from_the_checks_are_found():
    """The .vti checks searched the text: an inline binary array cut short
    but written format='binary' (or format = "binary"), a comment holding
    an <ImageData Origin="0 0 0"> before the real element with a NaN
    origin, or an <AppendedData> in a comment before a cut block, passed
    them, and the file was read with zeros, garbage or the default origin,
    exit status 0 (a second review under AddressSanitizer, fifty-second
    session). Each refused; the files they came from still read."""
    from vtkmodules.vtkIOXML import vtkXMLImageDataWriter
    d = fresh_dir("vti-hidden-tags")
    out = os.path.join(d, "o.vtp")
    files = {}
    for mode in ("binary", "appended"):
        path = os.path.join(d, f"{mode}.vti")
        w = vtkXMLImageDataWriter()
        w.SetFileName(path)
        w.SetInputData(blob_image())
        w.SetCompressorTypeToNone()
        if mode == "binary":
            w.SetDataModeToBinary()
        else:
            w.SetDataModeToAppended()
            w.EncodeAppendedDataOff()
        w.Write()
        ok(path, "-q", "-o", os.path.join(d, "good.vtp"))
        with open(path, "rb") as f:
            files[mode] = f.read()

    def inside_root(data, comment):
        end = data.index(b">", data.index(b"<VTKFile")) + 1
        return data[:end] + b"\n" + comment + data[end:]

    b = files["binary"]
    start = b.index(b">", b.index(b'format="binary"')) + 1
    stop = b.index(b"<", start)
    short = b[:start] + b[start:stop][:(stop - start) // 2] + b"\n" + b[stop:]
    a = files["appended"]
    block = a.index(b"_", a.index(b"<AppendedData")) + 1
    cut = a[:block + 4000] + a[block + 12000:]
    origin = re.search(rb'Origin="[^"]*"', a).group(0)
    cases = [
        ("quote.vti", short.replace(b'format="binary"', b"format='binary'"),
         "fewer than the"),
        ("space.vti", short.replace(b'format="binary"', b'format = "binary"'),
         "fewer than the"),
        ("origin.vti", inside_root(a.replace(origin, b'Origin="nan 0 0"'),
                                   b'<!-- <ImageData Origin="0 0 0"> -->'),
         'its Origin "nan 0 0" is not 3 finite numbers'),
        ("appended-comment.vti", inside_root(cut, b"<!-- <AppendedData> -->"),
         "ends past the end of the file"),
    ]
    for name, content, fragment in cases:
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(content)
        expect_refused_in_time(path, fragment, out)


@check
def detached_nrrd_data_and_legacy_fields_vtk_misreads_are_refused():
    """A third review under AddressSanitizer (fifty-second session): a NRRD
    LIST naming fewer files than slices (SIGSEGV), gzip slice files (the
    first inflated, the other slices unwritten memory), a detached file
    holding more bytes than its samples take (VTK's reader skipped the
    excess as a header: gzip of noise read as garbage), ASCII data in a
    detached file (characters read as samples), and a legacy FIELD block
    that does not hold the arrays it declares (SIGSEGV): each refused with
    its reason, exit status 0 before; exact raw and gzip files still read."""
    import gzip
    d = fresh_dir("detached-nrrd")
    out = os.path.join(d, "o.vtp")
    rng = np.random.default_rng(7)
    noise = rng.integers(0, 256, 16 * 16 * 10, dtype=np.uint8).tobytes()
    smooth = bytes((k * 7) % 256 for k in range(16 * 16 * 10))
    files = {"noise.raw": noise, "noise.raw.gz": gzip.compress(noise, 9),
             "smooth.raw.gz": gzip.compress(smooth), "more.raw": smooth + bytes(100),
             "text.txt": " ".join(str(b) for b in smooth).encode()}
    for k in range(10):
        files[f"s{k}.raw"] = smooth[k * 256:(k + 1) * 256]
        files[f"s{k}.raw.gz"] = gzip.compress(files[f"s{k}.raw"])
    for name, content in files.items():
        with open(os.path.join(d, name), "wb") as f:
            f.write(content)
    head = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 16 16 10\nencoding: %s\ndata file: %s\n"
    for name, enc, data, fragment in (
            ("few.nhdr", "raw", "LIST\ns0.raw\ns1.raw", "lists 2 files for 10 slices"),
            ("list-gz.nhdr", "gzip", "LIST\n" + "\n".join(f"s{k}.raw.gz" for k in range(10)),
             "its gzip slice files"),
            ("pattern-gz.nhdr", "gzip", "s%d.raw.gz 0 9 1", "its gzip slice files"),
            ("noise-gz.nhdr", "gzip", "noise.raw.gz", "more than the 2560 its samples take"),
            ("more.nhdr", "raw", "more.raw", "holds 2660 bytes, more than the 2560"),
            ("text.nhdr", "ascii", "text.txt", "ASCII-encoded NRRD data")):
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write(head % (enc, data) + "\n")
        expect_refused_in_time(path, fragment, out)
    for name, enc, data in (("raw.nhdr", "raw", "noise.raw"), ("gz.nhdr", "gzip", "smooth.raw.gz"),
                            ("list.nhdr", "raw",
                             "LIST\n" + "\n".join(f"s{k}.raw" for k in range(10)))):
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write(head % (enc, data) + "\n")
        ok(path, "-q", "-v", "100", "-o", os.path.join(d, "good.vtp"))
    samples = " ".join(str(b) for b in smooth[:12 * 11 * 10])
    for label, field in (("declared-two", "FIELD FieldData 2\nTIME 1 1 double\n0\n"),
                         ("bad-type", "FIELD FieldData 1\nTIME 1 1 quaternion\n0\n")):
        path = os.path.join(d, f"field-{label}.vtk")
        with open(path, "w") as f:
            f.write("# vtk DataFile Version 3.0\nvtk output\nASCII\nDATASET STRUCTURED_POINTS\n"
                    + field + "DIMENSIONS 12 11 10\nSPACING 1 1 1\nORIGIN 0 0 0\n"
                    "POINT_DATA 1320\nSCALARS s float\nLOOKUP_TABLE default\n" + samples + "\n")
        expect_refused_in_time(path, "its FIELD block 'FieldData' declares", out)


@check
def nifti_headers_vtk_crashes_on_or_misreads_are_refused():
    """0 vector components (dim[5]) made VTK 9.1's NIfTI reader divide by
    zero (SIGFPE), and a single-file .nii whose vox_offset lies inside the
    header (below 352) had the header's bytes read as samples, exit status
    0; a dimension count beyond 7, a used dimension of 0 and a spacing of
    0 (pixdim, which the reader took for 1) are refused too, and so are
    dimensions 6 or 7 above 1 (dim = {7, x, y, z, 1, 1, 1, 32767}: the
    reader ignores them and gave the first 3D volume, exit status 0). .nii
    and .nii.gz alike; the file they were made from still reads, and so
    do vector components (dim[5]) and sizes beyond dim[0]."""
    import gzip
    d = fresh_dir("nifti-header")
    out = os.path.join(d, "o.vtp")
    good, data = written_nifti(d)
    expect(struct.unpack("<f", data[108:112])[0] >= 352, "vox_offset of the written file")

    def patched(fmt, at, *values):
        b = bytearray(data)
        struct.pack_into(fmt, b, at, *values)
        return bytes(b)

    dims = list(struct.unpack("<8h", data[40:56]))
    cases = [
        ("components0", patched("<8h", 40, 5, *dims[1:4], 1, 0, 1, 1),
         "0 vector components (dim[5])"),
        ("time0", patched("<8h", 40, 4, *dims[1:4], 0, 1, 1, 1), "0 time points (dim[4])"),
        ("x0", patched("<8h", 40, 3, 0, *dims[2:8]), "0 x (dim[1])"),
        ("eight", patched("<8h", 40, 8, *dims[1:8]), "8 dimensions (dim[0])"),
        ("dim6", patched("<8h", 40, 6, *dims[1:4], 1, 1, 4, 1), "4 along dimension 6 (dim[6])"),
        ("dim7", patched("<8h", 40, 7, *dims[1:4], 1, 1, 1, 32767),
         "32767 along dimension 7 (dim[7])"),
        ("offset0", patched("<f", 108, 0.0), "data at byte 0 (vox_offset)"),
        ("offset348", patched("<f", 108, 348.0), "data at byte 348 (vox_offset)"),
        ("spacing0", patched("<f", 84, 0.0), "spacing of 0 along axis 1 (pixdim[2])"),
    ]
    for label, content, fragment in cases:
        for ext in ("nii", "nii.gz"):
            path = os.path.join(d, f"{label}.{ext}")
            with (gzip.open if ext == "nii.gz" else open)(path, "wb") as f:
                f.write(content)
            expect_refused_in_time(path, fragment, out)
    ok(good, "-q", "-o", out)
    # Still read: 3 vector components (dim[5], the samples three times;
    # component 0 contoured), and sizes beyond the dimension count, which
    # NIfTI ignores.
    offset = int(struct.unpack("<f", data[108:112])[0])
    vector = os.path.join(d, "vector.nii")
    with open(vector, "wb") as f:
        f.write(patched("<8h", 40, 5, *dims[1:4], 1, 3, 1, 1) + data[offset:] * 2)
    r = ok(vector, "-o", out)
    expect("(component 0 of 3)" in r.stdout, f"table header:\n{r.stdout}")
    beyond = os.path.join(d, "beyond.nii")
    with open(beyond, "wb") as f:
        f.write(patched("<8h", 40, 5, *dims[1:4], 1, 1, 9, 9))
    ok(beyond, "-q", "-o", out)


@check
def nrrd_header_with_a_control_byte_is_refused():
    """A NUL byte in a NRRD header (at the end of a line, or at the start
    of the next) made VTK 9.1's reader hang for ever or crash; so may other
    control bytes. A header holding one (but tab, CR and LF) is refused,
    in time, with the byte's place; a header with CRLF line ends reads."""
    d = fresh_dir("nrrd-control")
    out = os.path.join(d, "o.vtp")
    data = np.zeros((2, 2, 12), dtype="u1")
    data[1, 1, 5] = 9
    head = b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 12 2 2\nencoding: raw\n\n"
    for name, at, byte in (("end-of-line.nrrd", 20, b"\0"), ("start-of-line.nrrd", 9, b"\0"),
                           ("escape.nrrd", 30, b"\x1b"), ("delete.nrrd", 40, b"\x7f")):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write(head[:at] + byte + head[at:] + data.tobytes())
        start = time.monotonic()
        try:
            expect_error([path, "-o", out], f"control byte (0x{byte[0]:02x}) at byte {at}",
                         outputs=[out], status=1)
        except (Failure, subprocess.TimeoutExpired) as e:
            raise Failure(f"{name}: {e}")
        expect(time.monotonic() - start < 60, f"{name}: took {time.monotonic() - start:.0f} s")
    crlf = os.path.join(d, "crlf.nrrd")
    with open(crlf, "wb") as f:
        f.write(head.replace(b"\n", b"\r\n") + data.tobytes())
    ok(crlf, "-q", "-v", "4", "-o", out)


@check
def nrrd_dimensions_vtk_crashes_on_are_refused():
    """VTK 9.1's NRRD reader reads volumes of dimension 3 (or 4, the first
    axis being vector components): a header without a dimension, with
    another one, or whose sizes do not match it made it read past its
    image (segmentation fault) or read a volume the header does not
    describe. Each is refused with its reason."""
    d = fresh_dir("nrrd-dimension")
    out = os.path.join(d, "o.vtp")
    data = np.zeros(1000, dtype="u1")
    data[555] = 9
    data[554] = 9  # component 0 of the vector reads too (not a constant)
    head = "NRRD0004\ntype: uchar\n%sencoding: raw\n\n"
    cases = [
        ("none.nrrd", "sizes: 10 10 10\n", "no dimension"),
        ("one.nrrd", "dimension: 1\nsizes: 1000\n", "dimension 1"),
        ("two.nrrd", "dimension: 2\nsizes: 4 250\n", "dimension 2"),
        ("five.nrrd", "dimension: 5\nsizes: 10 10 10 1 1\n", "dimension 5"),
        ("zero.nrrd", "dimension: 0\nsizes: 10 10 10\n", "dimension 0"),
        ("word.nrrd", "dimension: x\nsizes: 10 10 10\n", "dimension"),
        ("more-sizes.nrrd", "dimension: 3\nsizes: 10 10 5 2\n", "4 sizes"),
        ("fewer-sizes.nrrd", "dimension: 4\nsizes: 10 10 10\n", "3 sizes"),
    ]
    refuse_nrrd_headers(d, head, data, cases)
    # Dimension 4 with a first axis of vector components reads.
    path = os.path.join(d, "vector.nrrd")
    with open(path, "wb") as f:
        f.write((head % "dimension: 4\nsizes: 2 10 10 5\nkinds: vector domain domain domain\n")
                .encode() + data.tobytes())
    r = ok(path, "-o", out)
    expect("10x10x5, unsigned char (component 0 of 2)" in r.stdout, r.stdout)


@check
def nrrd_4d_with_a_spatial_first_axis_is_refused():
    """VTK 9.1's NRRD reader takes the first of 4 axes for vector
    components: a time series (kinds domain domain domain time) of
    10x10x10 samples was read as 10x10x2 samples of 10 components and
    contoured without a word. A first axis the header calls spatial is
    refused."""
    d = fresh_dir("nrrd-4d")
    out = os.path.join(d, "o.vtp")
    data = np.zeros(2000, dtype="u1")
    data[555] = 9
    data[554] = 9  # component 0 of the vector reads too (not a constant)
    head = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 10 10 10 2\n%sencoding: raw\n\n"
    cases = [
        ("time.nrrd", "kinds: domain domain domain time\n", "'domain'"),
        ("list.nrrd", "kinds: space space space list\n", "'space'"),
        ("directions.nrrd", "space: 3D-right-handed\n"
         "space directions: (1,0,0) (0,1,0) (0,0,1) none\n", "space direction"),
    ]
    refuse_nrrd_headers(d, head, data, cases)
    # A first axis of vectors, however it is said, reads.
    for name, fields in (("vector.nrrd", "kinds: vector domain domain domain\n"),
                         ("none.nrrd", "space: 3D-right-handed\n"
                          "space directions: none (1,0,0) (0,1,0) (0,0,1)\n")):
        path = os.path.join(d, name)
        with open(path, "wb") as f:
            f.write((head.replace("10 10 10 2", "2 10 10 10") % fields).encode()
                    + data.tobytes())
        r = ok(path, "-o", out)
        expect("10x10x10, unsigned char (component 0 of 2)" in r.stdout, f"{name}: {r.stdout}")


@check
def vti_pieces_must_cover_the_whole_extent():
    """VTK's XML reader allocates the whole extent and fills what the
    pieces hold: a .vti whose pieces leave samples out (a piece lost, a
    whole extent larger than its piece, an inverted piece extent) was
    contoured with those samples zero or uninitialised, exit status 0.
    Such files are refused; a file of several pieces that cover the whole
    extent reads as one piece."""
    d = fresh_dir("vti-pieces")
    whole = os.path.join(d, "whole.vti")
    pieces = os.path.join(d, "pieces.vti")
    for path, count in ((whole, 1), (pieces, 3)):
        write_wavelet_vti(path, (0, 15, 0, 13, 0, 11), count)
    a = ok(whole, "-v", "150", "-o", os.path.join(d, "whole.vtp"))
    b = ok(pieces, "-v", "150", "-o", os.path.join(d, "pieces.vtp"))
    expect(table_value(a.stdout, "output triangles") == table_value(b.stdout, "output triangles"),
           f"pieces read differently:\n{a.stdout}\n{b.stdout}")
    with open(pieces) as f:
        text = f.read()
    blocks = re.findall(r"<Piece .*?</Piece>\s*", text, re.S)
    expect(len(blocks) == 3, f"{len(blocks)} pieces written")
    m = re.search(r'WholeExtent="([^"]*)"', text)
    ext = [int(v) for v in m.group(1).split()]
    first = re.search(r'<Piece Extent="([^"]*)"', text).group(1)
    lo = first.split()
    inverted = " ".join([lo[1], lo[0]] + lo[2:])
    cases = {
        "lost.vti": text.replace(blocks[1], ""),
        "larger.vti": text.replace(m.group(0), 'WholeExtent="%d %d %d %d %d %d"' % (
            ext[0], ext[1] + 4, ext[2], ext[3], ext[4], ext[5])),
        "inverted.vti": text.replace('<Piece Extent="%s"' % first,
                                     '<Piece Extent="%s"' % inverted),
    }
    out = os.path.join(d, "o.vtp")
    for name, content in cases.items():
        path = os.path.join(d, name)
        with open(path, "w") as f:
            f.write(content)
        try:
            expect_error([path, "-v", "150", "-o", out], "pieces", outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{name}: {e}")


def write_wavelet_vti(path, extent, pieces=1):
    """VTK's wavelet source (scalars "RTData") over `extent`, written as an
    ASCII .vti of `pieces` pieces; returns the file's text."""
    from vtkmodules.vtkImagingCore import vtkRTAnalyticSource
    source = vtkRTAnalyticSource()
    source.SetWholeExtent(*extent)
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputConnection(source.GetOutputPort())
    w.SetNumberOfPieces(pieces)
    w.SetDataModeToAscii()
    w.Write()
    with open(path) as f:
        return f.read()


@check
def a_reader_failing_inside_names_the_file():
    """A header that makes VTK's XML reader throw (a negative number of
    components: std::length_error from its arrays) gave the bare library
    message 'precisemc: error: vector::_M_default_append', without the
    file or what happened; it is reported as a failure to read that file."""
    d = fresh_dir("reader-throws")
    text = write_wavelet_vti(os.path.join(d, "good.vti"), (0, 5, 0, 5, 0, 5))
    bad = os.path.join(d, "bad.vti")
    with open(bad, "w") as f:
        f.write(re.sub(r'(<DataArray type="Float32" Name="RTData")',
                       r'\1 NumberOfComponents="-3"', text, count=1))
    out = os.path.join(d, "o.vtp")
    expect_error([bad, "-v", "150", "-o", out], "bad.vti", outputs=[out], status=1)


@check
def vti_geometry_that_is_not_finite_is_refused():
    """VTK's XML reader drops an Origin, Spacing or Direction it cannot
    parse ('NaN', 'Infinity', a word) and uses the default: a .vti with
    Spacing="NaN 1 1" was contoured at spacing 1, exit status 0. Such files
    are refused; the file with finite values still reads."""
    d = fresh_dir("vti-geometry")
    good = os.path.join(d, "good.vti")
    text = write_wavelet_vti(good, (0, 9, 0, 8, 0, 7))
    ok(good, "-v", "150", "-o", os.path.join(d, "good.vtp"))
    out = os.path.join(d, "o.vtp")
    for attr, value in (("Spacing", "NaN 1 1"), ("Origin", "0 Infinity 0"),
                        ("Spacing", "1 one 1"), ("Direction", "1 0 0 0 1 0 0 0 nan")):
        m = re.search(attr + r'="[^"]*"', text)
        expect(m, f"no {attr} in the written file")
        bad = os.path.join(d, "bad.vti")
        with open(bad, "w") as f:
            f.write(text.replace(m.group(0), f'{attr}="{value}"', 1))
        try:
            expect_error([bad, "-v", "150", "-o", out], attr, outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{attr}={value!r}: {e}")


@check
def vti_geometry_of_the_wrong_count_or_quoting_is_refused():
    """VTK's XML reader also drops an Origin or Spacing of fewer than 3
    numbers, an empty one, or a Direction of 8, and uses the default; the
    tool's check looked for name="..." only, so Spacing='NaN 2 2' or
    Spacing = "NaN 2 2" slipped past it too. All refused; the same
    attributes written with single quotes or spaces around '=' still read,
    at their own spacing."""
    d = fresh_dir("vti-geometry-count")
    good = os.path.join(d, "good.vti")
    text = write_wavelet_vti(good, (0, 9, 0, 8, 0, 7))
    out = os.path.join(d, "o.vtp")
    for attr, written in (("Spacing", 'Spacing="2 3"'), ("Origin", 'Origin="100 200"'),
                          ("Spacing", 'Spacing=""'), ("Direction", 'Direction="1 0 0 0 1 0 0 0"'),
                          ("Spacing", "Spacing='NaN 2 2'"), ("Spacing", 'Spacing = "NaN 2 2"'),
                          ("Origin", 'Origin="1 2 3 4"')):
        m = re.search(attr + r'="[^"]*"', text)
        expect(m, f"no {attr} in the written file")
        bad = os.path.join(d, "bad.vti")
        with open(bad, "w") as f:
            f.write(text.replace(m.group(0), written, 1))
        try:
            expect_error([bad, "-v", "150", "-o", out], f"its {attr} ", outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{written}: {e}")
    m = re.search(r'Spacing="[^"]*"', text)
    quoted = os.path.join(d, "quoted.vti")
    with open(quoted, "w") as f:
        f.write(text.replace(m.group(0), "Spacing = '2 2 2'", 1))
    ok(good, "-q", "-v", "150", "-o", out)
    unit = read_surface(out).GetBounds()
    ok(quoted, "-q", "-v", "150", "-o", out)
    bounds = read_surface(out).GetBounds()
    expect(all(abs(b - 2 * u) < 1e-4 for b, u in zip(bounds, unit)),
           f"spacing 2 not applied: bounds {bounds}, at spacing 1 {unit}")


@check
def vti_arrays_that_are_not_numbers_are_refused():
    """VTK's XML reader crashed (segmentation fault) on a String array whose
    values it could not parse (words, or numbers that do not make one
    string per sample), scalars or not; it could not make a String array
    named as the point scalars the scalars, and the tool contoured another
    array of the file instead (exit status 0). A .vti whose point scalars
    are Strings, or whose point data holds no numbers, is refused, and so
    is ASCII data with a word among the numbers, saying so; String arrays
    beside numeric scalars are left unread, and the file reads."""
    d = fresh_dir("vti-not-numbers")
    good = os.path.join(d, "good.vti")
    text = write_wavelet_vti(good, (0, 7, 0, 6, 0, 5))
    m = re.search(r'(<DataArray type="Float32" Name="RTData"[^>]*>)(.*?)(</DataArray>)', text, re.S)
    expect(m, "no RTData array in the written file")
    tag, values, end = m.groups()
    numbers = values.split()
    words = " ".join(["abc"] * len(numbers))
    as_string = tag.replace("Float32", "String")
    # The scalars, then a String array "s" holding `body`.
    beside = lambda body: m.group(0) + as_string.replace('"RTData"', '"s"') + body + end
    cases = {
        "string-words": (as_string + words + end, "String"),
        "string-numbers": (as_string + values + end, "String"),
        "float-word": (tag + " ".join(numbers[:5] + ["abc"] + numbers[6:]) + end, "Float32"),
        "float-few": (tag + " ".join(numbers[:len(numbers) // 2]) + end, "Float32"),
        # The scalars "RTData" are (valid) Strings, the numbers are in "f".
        "string-scalars-beside-numbers": (tag.replace('"RTData"', '"f"') + values + end
                                          + as_string + " 97 0" * len(numbers) + end, "String"),
    }
    out = os.path.join(d, "o.vtp")
    for name, (array, fragment) in cases.items():
        path = os.path.join(d, name + ".vti")
        with open(path, "w") as f:
            f.write(text.replace(m.group(0), array, 1))
        try:
            line = expect_error([path, "-v", "150", "-o", out], name + ".vti", outputs=[out],
                                status=1)
            expect(fragment in line, f"{fragment!r} not in {line!r}")
        except Failure as e:
            raise Failure(f"{name}: {e}")
    # The same in binary and appended encodings, as VTK writes them.
    image = blob_image()
    names = vtkStringArray()
    names.SetName("s")
    names.SetNumberOfValues(image.GetNumberOfPoints())
    for i in range(image.GetNumberOfPoints()):
        names.SetValue(i, f"sample {i}")
    image.GetPointData().AddArray(names)
    for mode in ("binary", "appended"):
        path = os.path.join(d, f"string-scalars-{mode}.vti")
        w = vtkXMLImageDataWriter()
        w.SetFileName(path)
        w.SetInputData(image)
        if mode == "binary":
            w.SetDataModeToBinary()
        else:
            w.SetDataModeToAppended()
        w.Write()
        ok(path, "-v", "50", "-q")  # the scalars "density" are numbers
        with open(path, "rb") as f:
            data = f.read()
        expect(b'<PointData Scalars="density">' in data, f"{mode}: no PointData Scalars")
        with open(path, "wb") as f:
            f.write(data.replace(b'<PointData Scalars="density">', b'<PointData Scalars="s">', 1))
        expect_error([path, "-v", "50", "-o", out], "String", outputs=[out], status=1)
    # Strings only, not named as the scalars: no numbers to contour.
    only = os.path.join(d, "strings-only.vti")
    with open(only, "w") as f:
        f.write(text.replace(m.group(0), as_string + words + end, 1)
                .replace('<PointData Scalars="RTData">', "<PointData>"))
    expect_error([only, "-v", "150", "-o", out], "no numbers", outputs=[out], status=1)
    # A String array beside the scalars, unparsable or not: the file reads.
    expected = table_value(ok(good, "-v", "150", "-o", out).stdout, "output triangles")
    for name, body in (("beside-words", words), ("beside-bytes", " 97 0" * len(numbers))):
        path = os.path.join(d, name + ".vti")
        with open(path, "w") as f:
            f.write(text.replace(m.group(0), beside(body), 1))
        r = ok(path, "-v", "150", "-o", out)
        expect(table_value(r.stdout, "output triangles") == expected, f"{name}:\n{r.stdout}")


@check
def scalars_of_a_type_the_filter_cannot_contour_are_refused():
    """A legacy .vtk whose scalars are bits: the filter refused them after
    the tool had printed the default isovalue's line on stdout. The tool
    refuses them with its other checks, nothing on stdout; the same file
    with bytes reads."""
    d = fresh_dir("bit-scalars")
    out = os.path.join(d, "o.vtp")
    head = ("# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n"
            "DIMENSIONS 2 2 2\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 8\n")
    for kind, fails in (("bit", True), ("unsigned_char", False)):
        path = os.path.join(d, kind + ".vtk")
        with open(path, "w") as f:
            f.write(head + f"SCALARS s {kind} 1\nLOOKUP_TABLE default\n0 1 0 1 0 1 0 1\n")
        if fails:
            line = expect_error([path, "-o", out], "type bit", outputs=[out], status=1)
            expect(kind + ".vtk" in line, line)
        else:
            ok(path, "-o", out, "-q")
            expect(os.path.exists(out), "no output for bytes")


@check
def another_format_under_a_nrrd_name_is_refused_as_not_nrrd():
    """A MetaImage header renamed .nrrd (or any file without the NRRD magic)
    was refused for a header with no blank line: now for not being NRRD."""
    d = fresh_dir("not-nrrd")
    out = os.path.join(d, "o.vtp")
    for name, text in (("metaimage", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\n"
                                     "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n"
                                     "\x00\x01\x00\x01\x00\x01\x00\x01"),
                       ("short", "NRR")):
        for ext in (".nrrd", ".nhdr"):
            path = os.path.join(d, name + ext)
            with open(path, "w") as f:
                f.write(text)
            line = expect_error([path, "-o", out], "not a NRRD file", outputs=[out], status=1)
            expect(name + ext in line, line)


@check
def legacy_ascii_with_non_finite_values_names_them():
    """VTK's legacy writer writes NaN and infinities as words in ASCII files,
    which its reader cannot read back ("Unsupported point attribute type:
    nan"): the tool refuses such a file saying why; in binary it reads,
    the non-finite samples skipped."""
    d = fresh_dir("legacy-nan")
    out = os.path.join(d, "o.vtp")
    for value, word in ((float("nan"), "nan"), (float("inf"), "inf"), (-float("inf"), "inf")):
        image = blob_image()
        scalars = image.GetPointData().GetScalars()
        scalars.SetValue(image.GetNumberOfPoints() // 3, value)
        for binary in (False, True):
            path = os.path.join(d, f"{word}-{'binary' if binary else 'ascii'}.vtk")
            w = vtkStructuredPointsWriter()
            w.SetFileName(path)
            w.SetInputData(image)
            if binary:
                w.SetFileTypeToBinary()
            else:
                w.SetFileTypeToASCII()
            w.Write()
            if binary:
                ok(path, "-v", "50", "-o", out, "-q")
            else:
                refused = os.path.join(d, f"{word}-refused.vtp")
                line = expect_error([path, "-v", "50", "-o", refused], "non-finite value",
                                    outputs=[refused], status=1)
                expect(f"'{word}'" in line, line)


@check
def far_from_the_origin_the_refinement_is_kept():
    """Single-precision points round the surface by 0.25 cells at 4e6 with
    unit spacing: the tool stores points in double precision there (and
    where float overflows), so --measure shows what refinement achieved."""
    d = fresh_dir("far-origin")
    dims, _, _, v = blob_volume()
    results = {}
    # Beyond float at a spacing doubles still resolve (a unit spacing
    # there is refused: see far_origins_that_collapse_the_cells_are_refused).
    for label, origin, spacing in (("near", (0.0, 0.0, 0.0), 1.0), ("far", (5e5, 4e6, 0.0), 1.0),
                                   ("beyond float", (1e39, 0.0, 0.0), 1e28)):
        path = os.path.join(d, label.replace(" ", "-") + ".vti")
        write_vti(density_image(v, dims, (spacing,) * 3, origin), path)
        vtp = os.path.join(d, label.replace(" ", "-") + ".vtp")
        r = ok(path, "-v", "40", "--epsilon", "0.001", "--measure", "-o", vtp)
        (out_max, out_mean, _), = measured(r.stdout, "S_K distance out")
        results[label] = (out_max, out_mean)
        pts = vtk_to_numpy(read_surface(vtp).GetPoints().GetData())
        expect(np.isfinite(pts).all(), f"{label}: non-finite points written")
        expect(out_max <= 0.0015, f"{label}: max distance {out_max} (refined to 0.001)")
        # PLY and STL hold float coordinates: beyond float's range the
        # write is refused (it wrote infinite points); far from the origin
        # it warns that the points are rounded. Near it, nothing is said.
        for ext in (".ply", ".stl"):
            out = os.path.join(d, label.replace(" ", "-") + ext)
            args = [path, "-v", "40", "--epsilon", "0.001", "-q", "-o", out]
            if label == "beyond float":
                expect_error(args, "beyond float's range", outputs=[out])
                continue
            # -q prints nothing but errors: the warning is for runs without.
            ok(*args)
            r = run(*args[:-3], "-o", out)
            expect(r.returncode == 0, f"{label} {ext}: exit status {r.returncode}: {r.stderr!r}")
            warned = "stores float coordinates" in r.stderr
            expect(warned == (label == "far"), f"{label} {ext}: stderr {r.stderr!r}")
            expect(os.path.getsize(out) > 0, f"{label} {ext}: nothing written")
    expect(abs(results["far"][1] - results["near"][1]) <= 0.2 * results["near"][1] + 1e-5,
           f"mean distance far from the origin {results['far']} vs near it {results['near']}")


@check
def far_origins_that_collapse_the_cells_are_refused():
    """An origin so far from 0 that double precision cannot resolve the
    spacing there (1e30 or 1e17 at spacing 1: coordinates 16 or more cells
    apart) collapsed the surface's points onto each other, exit status 0,
    and --distance printed "mean nan". Refused when the spacing along an
    index axis is below 2^-40 times the coordinates along it (a rounding of
    1e-4 of a cell); above it the volume reads."""
    d = fresh_dir("far-collapse")
    dims, _, _, v = blob_volume()
    out = os.path.join(d, "o.vtp")
    for label, origin, spacing in (("1e30", (1e30, 1e30, 1e30), 1.0), ("1e17", (1e17, 0, 0), 1.0),
                                   ("negative", (0, -1e13, 0), 1.0)):
        path = os.path.join(d, label + ".vti")
        write_vti(density_image(v, dims, (spacing,) * 3, origin), path)
        try:
            expect_error([path, "-v", "40", "-o", out, "--distance", os.path.join(d, "d.png")],
                         "are too large for its spacing", outputs=[out], status=1)
        except Failure as e:
            raise Failure(f"{label}: {e}")
    # Per index axis: a turned grid whose axis 1 runs along x, far out in x.
    turned = density_image(v, dims, (1.0, 1.0, 1.0), (1e17, 0, 0))
    turned.SetDirectionMatrix(0, 1, 0, 1, 0, 0, 0, 0, 1)
    path = os.path.join(d, "turned.vti")
    write_vti(turned, path)
    expect_error([path, "-v", "40", "-o", out], "along axis 1", outputs=[out], status=1)
    # Anisotropic: the coarse axis far out, the fine ones near 0, reads.
    path = os.path.join(d, "anisotropic.vti")
    write_vti(density_image(v, dims, (1e6, 1.0, 1.0), (1e17, 0, 0)), path)
    ok(path, "-q", "-v", "40", "-o", out)
    path = os.path.join(d, "resolved.vti")
    write_vti(density_image(v, dims, (1.0, 1.0, 1.0), (1e11, 0, 0)), path)
    r = ok(path, "-v", "40", "-o", out, "--distance", os.path.join(d, "d.png"))
    expect("nan" not in r.stdout, r.stdout)


@check
def infinite_samples_drop_the_same_cells_on_both_sides():
    """A sample set to +inf: vtkMarchingCubes's triangles around it have
    finite points (pulled to a corner); they are dropped like PreciseMC's
    skipped cells, so its measured distance stays that of the other cells."""
    d = fresh_dir("inf-sample")
    dims, spacing, origin, v = blob_volume()
    rows = {}
    for label in ("finite", "inf"):
        w = v.copy()
        if label == "inf":
            # The sample nearest the isovalue: cells around it are crossed.
            w.flat[np.argmin(np.abs(w - 40.0))] = np.inf
        path = os.path.join(d, label + ".vti")
        write_vti(density_image(w, dims, spacing, origin), path)
        r = ok(path, "-v", "40", "--measure")
        rows[label] = r.stdout
    (mc_max, _, _), = measured(rows["finite"], "S_K distance MC")
    (mc_max_inf, _, _), = measured(rows["inf"], "S_K distance MC")
    expect("NaN or infinite" in rows["inf"], rows["inf"])
    expect(mc_max_inf <= mc_max + 1e-4, f"MC max {mc_max_inf} with an inf sample vs {mc_max}")


@check
def output_piped_into_an_early_quitter_leaves_nothing_behind():
    """`precisemc ... | head -1`: the tool dies of SIGPIPE once the reader
    is gone, and removes its temporary files as on SIGINT."""
    d = fresh_dir("sigpipe")
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    p = subprocess.Popen([TOOL, "--sample", "all", "-o", os.path.join(d, "s.ply"), "--measure"],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=environment, cwd=d)
    p.stdout.close()  # the reader quits before the tool writes
    p.wait(timeout=TIMEOUT)
    expect(p.returncode != 0, f"exit status {p.returncode} with nobody reading its output")
    leftovers = [f for f in os.listdir(d) if ".tmp" in f]
    expect(not leftovers, f"temporary files left: {leftovers}")


@check
def a_limit_on_threads_runs_on_the_threads_that_start():
    """Under a limit on threads (RLIMIT_NPROC of an unprivileged user, as a
    container's pids limit) the default thread count used to fail the
    extraction ("out of memory: cannot start worker threads"): it now runs
    on the threads that start, with the same surface and measure."""
    runuser, prlimit = shutil.which("runuser"), shutil.which("prlimit")
    if os.geteuid() != 0 or not runuser or not prlimit:
        raise Skipped("needs root, runuser and prlimit")
    probe = subprocess.run([runuser, "-u", "nobody", "--", TOOL, "--version"],
                           capture_output=True, text=True, timeout=TIMEOUT)
    if probe.returncode != 0:
        raise Skipped(f"user nobody cannot run {TOOL}")
    args = ["--sample", "atoms", "--epsilon", "0.01", "--measure"]
    free = ok(*args)
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    # Two tasks for nobody: the tool and one more thread at most.
    limited = subprocess.run([runuser, "-u", "nobody", "--", prlimit, "--nproc=2:2", TOOL, *args],
                             capture_output=True, text=True, env=environment, timeout=TIMEOUT)
    expect(limited.returncode == 0,
           f"exit status {limited.returncode}, stderr: {limited.stderr.strip()!r}")
    for key in ("MC triangles", "output triangles"):
        expect(table_value(limited.stdout, key) == table_value(free.stdout, key),
               f"{key} differ under the limit")
    expect(measured(limited.stdout, "S_K distance out") == measured(free.stdout, "S_K distance out"),
           "the measured max distance differs under the limit")


@check
def measure_runs_on_the_threads_asked_for():
    """--threads bounds --measure too (it measured on all cores whatever
    --threads said): the process's threads, polled while it runs, stay at
    one with --threads 1; with --threads 2 the poll sees the second."""
    if (os.cpu_count() or 1) < 2:
        raise Skipped("one core: all cores is one thread")

    def most_threads(threads):
        p = subprocess.Popen([TOOL, "--sample", "atoms", "--threads", threads, "--measure",
                              "--measure-density", "4"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        most, start = 0, time.monotonic()
        while p.poll() is None and time.monotonic() - start < TIMEOUT:
            try:
                most = max(most, len(os.listdir(f"/proc/{p.pid}/task")))
            except FileNotFoundError:
                break
            time.sleep(0.002)
        out, err = p.communicate(timeout=TIMEOUT)
        expect(p.returncode == 0, f"--threads {threads}: exit status {p.returncode}: {err!r}")
        measured(out, "S_K distance out")  # the measure ran
        return most

    expect(most_threads("1") == 1, "--threads 1 --measure ran on more than one thread")
    expect(most_threads("2") >= 2, "--threads 2: the poll saw no second thread")


@check
def no_progress_bar_when_not_a_terminal():
    r = ok("--sample", "ml")
    expect(r.stderr == "", "stderr written")


@check
def numbers_are_decimal_and_do_not_underflow_to_0():
    """A number below the least subnormal double (1e-330) was read as 0:
    --epsilon 1e-330 ran plain Marching Cubes, exit status 0. Refused, as
    are hexadecimal numbers and leading blanks (as for the counts)."""
    d = fresh_dir("numbers")
    out = os.path.join(d, "o.vtp")
    for args, fragment in (
            (["--epsilon", "1e-330"], "--epsilon: '1e-330' underflows to 0"),
            (["--epsilon", "-1e-400"], "--epsilon: '-1e-400' underflows to 0"),
            (["-v", "1e-400"], "-v: '1e-400' underflows to 0"),
            (["--epsilon", " 0.1"], "--epsilon: ' 0.1' is not a finite number"),
            (["-v", "\t50"], "is not a finite number"),
            (["--epsilon", "0x10"], "--epsilon: '0x10' is not a decimal number"),
            (["-v", "0x32"], "-v: '0x32' is not a decimal number"),
            (["-v", "-0X1p5"], "is not a decimal number")):
        try:
            expect_error(["--sample", "tube", "-o", out, *args], fragment, outputs=[out],
                         status=2)
        except Failure as e:
            raise Failure(f"{args}: {e}")
    # Zero however written, and a subnormal, are numbers.
    ok("--sample", "tube", "-q", "--epsilon", "0e-400")
    ok("--sample", "tube", "-q", "--epsilon", "5e-324")


def tmp_files(d):
    return [f for f in os.listdir(d) if ".tmp" in f]


def make_node(path, kind, device=None):
    """A FIFO, or a character device node with the numbers of `device`
    (major, minor), in the scratch directory; Skipped where mknod is not
    permitted."""
    try:
        if kind == "fifo":
            os.mkfifo(path)
        else:
            os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(*device))
    except (PermissionError, OSError) as e:
        raise Skipped(f"cannot make a {kind} node in the scratch directory: {e}")


@check
def messages_name_what_is_wrong():
    """A FIFO or device as input was 'no such file or directory'; an output
    in a 'directory' that is a file said it does not exist; a name that is
    only an extension ('.png') was said not to end in it; the STL writer's
    full-disk message named the tool's temporary file."""
    d = fresh_dir("messages")
    fifo = os.path.join(d, "f.vti")
    make_node(fifo, "fifo")
    expect_error([fifo], f"cannot read '{fifo}': not a regular file")
    afile = os.path.join(d, "afile")
    open(afile, "w").close()
    target = os.path.join(afile, "x.vtp")
    expect_error(["--sample", "tube", "-o", target], f"'{afile}' is not a directory")
    for args, fragment in (
            (["--compare", os.path.join(d, ".png")], f"'{d}/.png' has no base name"),
            (["--distance", os.path.join(d, ".PNG")], "no base name, only the extension .png"),
            (["--write-volume", os.path.join(d, ".vti")], f"'{d}/.vti' has no base name"),
            (["-o", os.path.join(d, ".vtp")], f"'{d}/.vtp' has no base name"),
            (["-o", os.path.join(d, ".stl")], "only the extension .stl")):
        try:
            expect_error(["--sample", "tube", *args], fragment, status=2)
        except Failure as e:
            raise Failure(f"{args}: {e}")
    stl = os.path.join(d, "o.stl")
    r = limited_run(8, "--sample", "tube", "--epsilon", "0", "-q", "-o", stl)
    lines = r.stderr.splitlines()
    expect(r.returncode == 1 and len(lines) == 1 and
           lines[0].startswith(f"precisemc: error: cannot write '{stl}'") and
           ".tmp" not in lines[0], f"full STL: exit status {r.returncode}, stderr {r.stderr!r}")
    device = os.path.join(d, "zero")
    make_node(device, "char", (1, 5))
    os.symlink(device, os.path.join(d, "z.vti"))
    expect_error([os.path.join(d, "z.vti")], "not a regular file")
    expect(sorted(os.listdir(d)) == ["afile", "f.vti", "z.vti", "zero"], os.listdir(d))


def shell_run(script, *args, stdout=subprocess.PIPE):
    """The tool run by `exec "$0" "$@"` at the end of a shell script (its
    redirections and traps apply to it)."""
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    return subprocess.run(["/bin/sh", "-c", script, TOOL, *map(str, args)], stdout=stdout,
                          stderr=subprocess.PIPE, text=True, env=environment, timeout=TIMEOUT)


@check
def file_size_limit_and_other_signals_leave_no_temporaries():
    """Past a file size limit (ulimit -f, SIGXFSZ not ignored, as in any
    shell) the tool died half-way through the file, its partial temporary
    left behind: now the write fails (EFBIG) and is reported, the old file
    kept. The other signals whose default action kills the tool (a CPU time
    limit, timers, SIGUSR1/2) remove the temporaries first, as SIGTERM."""
    d = fresh_dir("signals")
    out = os.path.join(d, "t.vtp")
    with open(out, "w") as f:
        f.write("OLD\n")
    r = shell_run('ulimit -f 8; exec "$0" "$@"', "--sample", "tube", "--epsilon", "0", "-q",
                  "-o", out)
    lines = r.stderr.splitlines()
    expect(r.returncode == 1 and len(lines) == 1 and
           lines[0].startswith(f"precisemc: error: cannot write '{out}'"),
           f"ulimit -f: exit status {r.returncode}, stderr {r.stderr!r}")
    with open(out) as f:
        expect(f.read() == "OLD\n", "the old file was changed")
    expect(not tmp_files(d), f"ulimit -f: temporary files left: {tmp_files(d)}")
    os.remove(out)
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    for sig in (signal.SIGXCPU, signal.SIGALRM, signal.SIGVTALRM, signal.SIGPROF,
                signal.SIGUSR1, signal.SIGUSR2):
        p = subprocess.Popen([TOOL, "--sample", "all", "--measure", "-o",
                              os.path.join(d, "run.vtp")], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, env=environment)
        # Once a temporary holds data (the probe of the directory, empty,
        # may be gone between the listing and the size).
        def holds_data(name):
            try:
                return os.path.getsize(os.path.join(d, name)) > 0
            except FileNotFoundError:
                return False
        try:
            seen = []
            for _ in range(6000):
                seen = [f for f in tmp_files(d) if holds_data(f)]
                if seen or p.poll() is not None:
                    break
                time.sleep(0.01)
            expect(seen, f"{sig.name}: no temporary file seen while the run went on")
            p.send_signal(sig)
            p.wait(timeout=TIMEOUT)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
        expect(p.returncode == -sig, f"{sig.name}: exit status {p.returncode}")
        expect(not os.listdir(d), f"{sig.name}: left behind: {os.listdir(d)}")


@check
def outputs_that_are_not_regular_files_are_refused():
    """An output that is a FIFO or a device node (or a link to one) was
    replaced by a regular file at the commit, exit status 0: a link to
    /dev/null as -o, run as root, replaced /dev/null for the whole system.
    Refused before any work, the node left as it was (a copy of the null
    device, made in the scratch directory)."""
    d = fresh_dir("special-outputs")
    fifo = os.path.join(d, "pipe.vtp")
    make_node(fifo, "fifo")
    for args in (["-o", fifo], ["--write-volume", os.path.join(d, "pipe.vti")],
                 ["--compare", os.path.join(d, "pipe.png")]):
        if args[1] != fifo:
            os.symlink(fifo, args[1])
        line = expect_error(["--sample", "tube", "-q", *args], status=1)
        expect(f"'{args[1]}' is not a regular file" in line, line)
        expect(stat.S_ISFIFO(os.stat(fifo).st_mode), f"{args}: the FIFO was replaced")
    null = os.path.join(d, "mynull")
    make_node(null, "char", (1, 3))
    link = os.path.join(d, "discard.stl")
    os.symlink(null, link)
    line = expect_error(["--sample", "tube", "-q", "-o", link], status=1)
    expect(f"'{link}' is not a regular file" in line, line)
    expect(stat.S_ISCHR(os.stat(null).st_mode), "the device node was replaced")
    expect(not tmp_files(d), f"temporary files left: {tmp_files(d)}")


@check
def another_users_file_in_a_sticky_directory_is_refused_up_front():
    """In a sticky directory (as /tmp) a file of another user that the user
    may write cannot be replaced (rename() fails with EPERM): the run failed
    at the commit, after the volume it wrote before was already in place.
    Now refused before any work; root (CAP_FOWNER) replaces it."""
    runuser = shutil.which("runuser")
    if os.geteuid() != 0 or not runuser:
        raise Skipped("needs root and runuser")
    # A directory user nobody can reach (the scratch directory is private).
    d = tempfile.mkdtemp(prefix="precisemc-sticky-")
    try:
        os.chmod(d, 0o1777)
        probe = subprocess.run([runuser, "-u", "nobody", "--", TOOL, "--version"],
                               capture_output=True, text=True, cwd=d, timeout=TIMEOUT)
        if probe.returncode != 0:
            raise Skipped(f"user nobody cannot run {TOOL}")
        surface, volume = os.path.join(d, "a.vtp"), os.path.join(d, "v.vti")
        with open(surface, "w") as f:
            f.write("OLDSURF\n")
        os.chmod(surface, 0o666)  # root's, writable by everyone
        with open(volume, "w") as f:
            f.write("OLDVOL\n")
        shutil.chown(volume, "nobody")
        r = subprocess.run([runuser, "-u", "nobody", "--", TOOL, "--sample", "tube", "-q",
                            "--write-volume", volume, "-o", surface],
                           capture_output=True, text=True, timeout=TIMEOUT)
        lines = r.stderr.splitlines()
        expect(r.returncode == 1 and len(lines) == 1 and
               lines[0].startswith(f"precisemc: error: cannot write surface '{surface}'") and
               "sticky" in lines[0], f"exit status {r.returncode}, stderr {r.stderr!r}")
        for path, old in ((surface, "OLDSURF\n"), (volume, "OLDVOL\n")):
            with open(path) as f:
                expect(f.read() == old, f"{path} was replaced")
        expect(not tmp_files(d), f"temporary files left: {tmp_files(d)}")
        ok("--sample", "tube", "-q", "--write-volume", volume, "-o", surface)
        expect(read_surface(surface).GetNumberOfPolys() > 1000, "root did not replace it")
    finally:
        shutil.rmtree(d, ignore_errors=True)


@check
def a_rename_failing_at_the_commit_undoes_the_others():
    """A rename that fails at the commit, unforeseeable before the work (a
    file bind-mounted over the output: EBUSY), left the outputs renamed
    before it in place, the files they replaced lost. The commit is all or
    nothing: the file replaced is put back, the new ones removed."""
    d = fresh_dir("commit-undo")
    source, busy = os.path.join(d, "src"), os.path.join(d, "s-ml.vtp")
    for path in (source, busy):
        with open(path, "w") as f:
            f.write("MOUNTED\n")
    vol = os.path.join(d, "v-tube.vti")
    with open(vol, "w") as f:
        f.write("OLDVOL\n")
    mounted = subprocess.run(["mount", "--bind", source, busy], capture_output=True, text=True)
    if mounted.returncode != 0:
        raise Skipped(f"mount --bind is not permitted: {mounted.stderr.strip()}")
    try:
        # Committed in turn: v-tube.vti (replaced), s-tube.vtp, v-atoms.vti,
        # s-atoms.vtp, v-ml.vti (new), then s-ml.vtp fails.
        line = expect_error(["--sample", "all", "--epsilon", "0", "-q", "-o",
                             os.path.join(d, "s.vtp"), "--write-volume",
                             os.path.join(d, "v.vti")], f"cannot write '{busy}'", status=1)
        expect("busy" in line, line)
    finally:
        subprocess.run(["umount", busy], capture_output=True)
    with open(vol, "rb") as f:
        expect(f.read() == b"OLDVOL\n", "the volume replaced was not put back")
    expect(sorted(os.listdir(d)) == ["s-ml.vtp", "src", "v-tube.vti"],
           f"left behind: {sorted(os.listdir(d))}")


def expect_stdout_error(r, reason, label):
    lines = r.stderr.splitlines()
    expect(r.returncode == 1 and len(lines) == 1 and
           lines[0] == f"precisemc: error: cannot write to standard output: {reason}",
           f"{label}: exit status {r.returncode}, stderr {r.stderr!r}")


@check
def write_errors_on_standard_output_are_reported():
    """A report that cannot be written (stdout closed, a full disk, a reader
    gone while SIGPIPE is ignored) was lost with exit status 0: now one
    error line and status 1, and a run whose report is lost commits none of
    its files."""
    d = fresh_dir("stdout-errors")
    out, vol = os.path.join(d, "t.vtp"), os.path.join(d, "t.vti")
    closed = 'exec "$0" "$@" >&-'
    for args in (["--version"], ["--help"], ["--sample", "tube", "-o", out, "--write-volume", vol]):
        expect_stdout_error(shell_run(closed, *args), "Bad file descriptor", args)
    expect(os.listdir(d) == [], f"written with stdout closed: {os.listdir(d)}")
    # A reader that is gone, SIGPIPE ignored by the caller: EPIPE.
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    p = subprocess.Popen(["/bin/sh", "-c", "trap '' PIPE; exec \"$0\" \"$@\"", TOOL,
                          "--sample", "tube", "-o", out], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=environment)
    p.stdout.close()
    err = p.stderr.read()
    p.wait(timeout=TIMEOUT)
    expect_stdout_error(subprocess.CompletedProcess(p.args, p.returncode, "", err), "Broken pipe",
                        "EPIPE")
    expect(os.listdir(d) == [], f"written with the reader gone: {os.listdir(d)}")
    # A full disk: a copy of /dev/full, made in the scratch directory.
    full = os.path.join(d, "full")
    make_node(full, "char", (1, 7))
    with open(full, "w") as sink:
        for args in (["--version"], ["--sample", "atoms", "--measure", "--measure-density", "1"],
                     ["--sample", "tube", "-o", out]):
            expect_stdout_error(shell_run('exec "$0" "$@"', *args, stdout=sink),
                                "No space left on device", args)
    expect(os.listdir(d) == ["full"], f"written with stdout full: {os.listdir(d)}")


@check
def a_reader_that_stops_early_never_leaves_a_finished_run_killed():
    """The picture lines were printed after the commit: a reader of stdout
    that stopped after the table made the run die of SIGPIPE (status 141)
    with every output in place. Everything is printed before the commit:
    the run dies before committing, leaving nothing."""
    d = fresh_dir("sigpipe-late")
    out, png = os.path.join(d, "t.vtp"), os.path.join(d, "t.png")
    environment = dict(os.environ)
    environment.pop("DISPLAY", None)
    p = subprocess.Popen([TOOL, "--sample", "tube", "-o", out, "--compare", png],
                         stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                         env=environment)
    for line in p.stdout:
        if line.startswith("  output file"):
            break  # the table's last row: the reader quits (| head -n 9)
    p.stdout.close()
    p.wait(timeout=TIMEOUT)
    written = sorted(os.listdir(d))
    expect((p.returncode == 0 and written == ["t.png", "t.vtp"]) or
           (p.returncode != 0 and written == []),
           f"exit status {p.returncode} with {written} written")


@check
def an_empty_surface_inside_the_range_is_warned_about():
    """An isovalue inside the scalar range whose surface is empty (the low
    sample's neighbours all NaN: no cell with finite samples is crossed)
    wrote an empty file, exit status 0, without a word under -q. Now a
    warning, also under -q; the status stays 0."""
    d = fresh_dir("empty-surface")
    a = np.full((6, 6, 6), 10.0)
    a[3, 3, 3] = 0.0
    for dz, dy, dx in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
        a[3 + dz, 3 + dy, 3 + dx] = np.nan
    vti = os.path.join(d, "nanlow.vti")
    write_vti(density_image(a, (6, 6, 6), (1, 1, 1), (0, 0, 0)), vti)
    out = os.path.join(d, "empty.stl")
    for quiet in (["-q"], []):
        r = ok(vti, *quiet, "-o", out, warns="nanlow.vti: the surface is empty")
        expect("holds no triangles" in r.stderr, r.stderr)
        expect(read_surface(out).GetNumberOfPolys() == 0, "triangles written")



@check
def an_empty_surface_of_finite_data_is_not_blamed_on_non_finite_samples():
    """An isovalue met only at samples equal to it (a single peak at the
    data's maximum, a ridge plane between lower samples) gives no
    triangles: the warning said "no cell with only finite samples is
    crossed" of data without a NaN, where the cells are crossed and no
    sample is non-finite. It now names the cause."""
    d = fresh_dir("empty-surface-finite")
    peak = np.zeros((7, 6, 6), dtype=np.float32)
    peak[3, 3, 3] = 5.0
    ridge = np.zeros((7, 6, 6), dtype=np.float32)
    ridge[3, :, :] = 5.0
    for name, values in (("peak.vti", peak), ("ridge.vti", ridge)):
        vti = write_vti(density_image(values, (6, 6, 7), (1, 1, 1), (0, 0, 0)),
                        os.path.join(d, name))
        out = os.path.join(d, name + ".stl")
        r = ok(vti, "-q", "-v", "5", "-o", out, warns=f"{name}: the surface is empty")
        expect("finite" not in r.stderr, r.stderr)
        expect("meet it only at samples equal to it" in r.stderr, r.stderr)
        expect("holds no triangles" in r.stderr, r.stderr)
        expect(read_surface(out).GetNumberOfPolys() == 0, "triangles written")

def main():
    if not os.access(TOOL, os.X_OK):
        print(f"cli: the tool {TOOL} is not built")
        print("cli: 0 passed, 1 failed")
        return 1
    passed = failed = skipped = 0
    for fn in CHECKS:
        try:
            fn()
        except Skipped as e:
            skipped += 1
            print(f"skip {fn.__name__}: {e}", flush=True)
        except Failure as e:
            failed += 1
            print(f"FAIL {fn.__name__}: {e}", flush=True)
        except subprocess.TimeoutExpired as e:
            failed += 1
            print(f"FAIL {fn.__name__}: timed out after {TIMEOUT} s: {e.cmd}", flush=True)
        except Exception:  # a bug of the test itself counts as a failure
            failed += 1
            print(f"FAIL {fn.__name__}: {traceback.format_exc()}", flush=True)
        else:
            passed += 1
            print(f"ok   {fn.__name__}", flush=True)
    print(f"cli: {passed} passed, {failed} failed, {skipped} skipped")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
