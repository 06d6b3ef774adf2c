"""A minimal DICOM series writer for the command-line tests: VTK 9.1 can read
DICOM (vtkDICOMImageReader) but not write it, and pydicom is not a
dependency. Explicit VR little endian (or implicit VR, or RLE-compressed),
one CT slice per file, signed 16-bit samples (or unsigned 8-bit), with the
tags vtkDICOMImageReader needs to place and sort slices.
"""
import os
import struct

EXPLICIT = "1.2.840.10008.1.2.1"
IMPLICIT = "1.2.840.10008.1.2"
RLE = "1.2.840.10008.1.2.5"


def elem(group, element, vr, value, implicit=False):
    """One data element; values are padded to an even length as DICOM wants."""
    if isinstance(value, str):
        value = value.encode()
        if len(value) % 2:
            value += b"\0" if vr == "UI" else b" "
    if len(value) % 2:
        value += b"\0"
    if implicit:
        return struct.pack("<HHI", group, element, len(value)) + value
    head = struct.pack("<HH", group, element) + vr.encode()
    if vr in ("OB", "OW", "SQ", "UN", "UT"):
        return head + b"\0\0" + struct.pack("<I", len(value)) + value
    return head + struct.pack("<H", len(value)) + value


def rle_pixel_data(samples):
    """The pixel data element of RLE Lossless: encapsulated (undefined
    length), one fragment of one segment per byte of the samples, most
    significant first, written as literal runs."""
    raw = samples.astype(samples.dtype.newbyteorder(">")).tobytes()
    size = samples.dtype.itemsize
    segments = []
    for b in range(size):
        plane = raw[b::size]
        seg = b"".join(bytes([len(plane[i:i + 128]) - 1]) + plane[i:i + 128]
                       for i in range(0, len(plane), 128))
        segments.append(seg + (b"\x80" if len(seg) % 2 else b""))  # 0x80: a no-op run
    offsets = [64]
    for seg in segments[:-1]:
        offsets.append(offsets[-1] + len(seg))
    frame = struct.pack("<16I", size, *offsets, *([0] * (15 - size))) + b"".join(segments)
    item = lambda v: struct.pack("<HHI", 0xFFFE, 0xE000, len(v)) + v
    return (struct.pack("<HH", 0x7FE0, 0x10) + b"OB\0\0" + struct.pack("<I", 0xFFFFFFFF)
            + item(b"") + item(frame) + struct.pack("<HHI", 0xFFFE, 0xE0DD, 0))


def us(v):
    return struct.pack("<H", v)


def write_series(d, vol, spacing, series="1.2.826.0.1.3680043.9.7777.1", prefix="slice",
                 suffix=".dcm", syntax=EXPLICIT):
    """Writes vol (int16, or uint8, z-y-x order) as d/slice001.dcm, ...
    (`prefix` and `suffix` instead of "slice" and ".dcm"), series instance
    UID `series`, transfer syntax `syntax` (EXPLICIT, IMPLICIT or RLE);
    spacing is (x, y, z)."""
    nz, ny, nx = vol.shape
    bits = 8 * vol.dtype.itemsize
    signed = int(vol.dtype.kind == "i")
    os.makedirs(d, exist_ok=True)
    for k in range(nz):
        inst = f"{series}.{k + 1}"
        meta_body = (elem(2, 1, "OB", b"\0\1") + elem(2, 2, "UI", "1.2.840.10008.5.1.4.1.1.2")
                     + elem(2, 3, "UI", inst) + elem(2, 0x10, "UI", syntax))
        meta = elem(2, 0, "UL", struct.pack("<I", len(meta_body))) + meta_body
        implicit = syntax == IMPLICIT
        e = lambda *args: elem(*args, implicit=implicit)  # the data set's elements
        samples = vol[k].astype(vol.dtype.newbyteorder("<"))
        pixels = (rle_pixel_data(samples) if syntax == RLE else
                  e(0x7FE0, 0x10, "OW" if bits == 16 else "OB", samples.tobytes()))
        ds = b"".join([
            e(8, 0x16, "UI", "1.2.840.10008.5.1.4.1.1.2"), e(8, 0x18, "UI", inst),
            e(8, 0x60, "CS", "CT"), e(0x18, 0x50, "DS", f"{spacing[2]:g}"),
            e(0x20, 0xD, "UI", series + ".0"), e(0x20, 0xE, "UI", series),
            e(0x20, 0x13, "IS", str(k + 1)),
            e(0x20, 0x32, "DS", f"0\\0\\{k * spacing[2]:g}"),
            e(0x20, 0x37, "DS", "1\\0\\0\\0\\1\\0"),
            e(0x28, 2, "US", us(1)), e(0x28, 4, "CS", "MONOCHROME2"),
            e(0x28, 0x10, "US", us(ny)), e(0x28, 0x11, "US", us(nx)),
            e(0x28, 0x30, "DS", f"{spacing[1]:g}\\{spacing[0]:g}"),
            e(0x28, 0x100, "US", us(bits)), e(0x28, 0x101, "US", us(bits)),
            e(0x28, 0x102, "US", us(bits - 1)), e(0x28, 0x103, "US", us(signed)),
        ]) + pixels
        with open(os.path.join(d, f"{prefix}{k + 1:03d}{suffix}"), "wb") as f:
            f.write(b"\0" * 128 + b"DICM" + meta + ds)
