"""A minimal DICOM series writer for the command-line tests: VTK 9.1 can read
DICOM (vtkDICOMImageReader) but not write it, and pydicom is not a
dependency. Explicit VR little endian, one CT slice per file, signed 16-bit
samples, with the tags vtkDICOMImageReader needs to place and sort slices.
"""
import os
import struct



def elem(group, element, vr, value):
    """One data element; values are padded to an even length as DICOM wants."""
    if isinstance(value, str):
        value = value.encode()
        if len(value) % 2:
            value += b"\0" if vr == "UI" else b" "
    if len(value) % 2:
        value += b"\0"
    head = struct.pack("<HH", group, element) + vr.encode()
    if vr in ("OB", "OW", "SQ", "UN", "UT"):
        return head + b"\0\0" + struct.pack("<I", len(value)) + value
    return head + struct.pack("<H", len(value)) + value


def us(v):
    return struct.pack("<H", v)


def write_series(d, vol, spacing, series="1.2.826.0.1.3680043.9.7777.1", prefix="slice",
                 suffix=".dcm"):
    """Writes vol (int16, z-y-x order) as d/slice001.dcm, ... (`prefix` and
    `suffix` instead of "slice" and ".dcm"), series instance UID `series`;
    spacing is (x, y, z)."""
    nz, ny, nx = vol.shape
    os.makedirs(d, exist_ok=True)
    for k in range(nz):
        inst = f"{series}.{k + 1}"
        meta_body = (elem(2, 1, "OB", b"\0\1") + elem(2, 2, "UI", "1.2.840.10008.5.1.4.1.1.2")
                     + elem(2, 3, "UI", inst) + elem(2, 0x10, "UI", "1.2.840.10008.1.2.1"))
        meta = elem(2, 0, "UL", struct.pack("<I", len(meta_body))) + meta_body
        ds = b"".join([
            elem(8, 0x16, "UI", "1.2.840.10008.5.1.4.1.1.2"), elem(8, 0x18, "UI", inst),
            elem(8, 0x60, "CS", "CT"), elem(0x18, 0x50, "DS", f"{spacing[2]:g}"),
            elem(0x20, 0xD, "UI", series + ".0"), elem(0x20, 0xE, "UI", series),
            elem(0x20, 0x13, "IS", str(k + 1)),
            elem(0x20, 0x32, "DS", f"0\\0\\{k * spacing[2]:g}"),
            elem(0x20, 0x37, "DS", "1\\0\\0\\0\\1\\0"),
            elem(0x28, 2, "US", us(1)), elem(0x28, 4, "CS", "MONOCHROME2"),
            elem(0x28, 0x10, "US", us(ny)), elem(0x28, 0x11, "US", us(nx)),
            elem(0x28, 0x30, "DS", f"{spacing[1]:g}\\{spacing[0]:g}"),
            elem(0x28, 0x100, "US", us(16)), elem(0x28, 0x101, "US", us(16)),
            elem(0x28, 0x102, "US", us(15)), elem(0x28, 0x103, "US", us(1)),
            elem(0x7FE0, 0x10, "OW", vol[k].astype("<i2").tobytes()),
        ])
        with open(os.path.join(d, f"{prefix}{k + 1:03d}{suffix}"), "wb") as f:
            f.write(b"\0" * 128 + b"DICM" + meta + ds)
