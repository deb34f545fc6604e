#!/usr/bin/env python3
"""Writes hand-made reproductions of the first libFuzzer probe's findings
(issue 17) into fuzz/regressions/<target>/; inputs that scripts/fuzz.sh
finds later are copied there by it. tests/fuzz_regressions.rs replays all.
Run from the repository root after fuzz/make_seeds.py."""
import os
import struct

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SEEDS = os.path.join(ROOT, "fuzz", "seeds")
OUT = os.path.join(ROOT, "fuzz", "regressions")


def put(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def seed(target, name):
    with open(os.path.join(SEEDS, target, name), "rb") as f:
        return bytearray(f.read())


# Spacings that hung every renderer (the default step took ~1e16 samples a ray).
for name, sp in [("spacing_tiny_z.vol", (1, 1.5, 1.8e-15)), ("spacing_huge_xy.vol", (1e17, 1e17, 1))]:
    v = seed("vol", "linear.vol")
    struct.pack_into("<3f", v, 12, *sp)
    put("vol", name, bytes(v))
n = seed("nifti", "u8.nii")
struct.pack_into("<3f", n, 80, 1.0, 1.5, 1.8e-15)
put("nifti", "pixdim_tiny_z.nii", bytes(n))
put("nrrd", "spacings_huge.nrrd",
    b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 2\nspacings: 1e17 1e17 1\nencoding: raw\n\n"
    + bytes(range(24)))

# line skip on an endless data file.
put("nhdr", "line_skip_dev_zero.nhdr",
    b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nline skip: 1\n"
    b"data file: /dev/zero\n\n")

# DICOM: the pixel data element claims 4 GB; Rows/Columns as UL 2^31 - 1.
d = seed("dicom", "explicit.dcm")
at = d.index(bytes.fromhex("e07f1000") + b"OW")
struct.pack_into("<I", d, at + 8, 0xF0000000)
put("dicom", "pixel_data_claims_4gb.dcm", bytes(d))
d = seed("dicom", "explicit.dcm")
for elem in (0x10, 0x11):
    tag = struct.pack("<HH", 0x28, elem) + b"US" + struct.pack("<H", 2)
    at = d.index(tag)
    d[at:at + 10] = struct.pack("<HH", 0x28, elem) + b"UL" + struct.pack("<HI", 4, 0x7FFFFFFF)
# The meta group's length is unchanged; the data set grew by 4 bytes.
put("dicom", "rows_columns_ul_max.dcm", bytes(d))
