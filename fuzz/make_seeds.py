#!/usr/bin/env python3
"""Writes the small seed corpora of the fuzz targets into fuzz/seeds/<target>/.

Run from the repository root: python3 fuzz/make_seeds.py. The seeds are
tiny valid (and a few nearly valid) files of each format, so libFuzzer
starts past the header checks. The .vseq seeds are written by
`vol_app pack` (built with cargo) from a small 4-D NRRD.
"""
import gzip
import os
import struct
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SEEDS = os.path.join(ROOT, "fuzz", "seeds")


def put(target, name, data):
    d = os.path.join(SEEDS, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def ramp(n, mul=37, mod=251):
    return bytes((i * mul) % mod for i in range(n))


# .vol: linear, bricked (B = 3), UC Davis.
def vol_header(dims, spacing, layout, b):
    return struct.pack("<3I3fBB", *dims, *spacing, layout, b)


put("vol", "linear.vol", vol_header((6, 5, 4), (1, 1.5, 2), 1, 0) + ramp(120))
# 5^3 with B = 3: ceil(4/2) = 2 bricks per axis, 8 bricks of 27 samples.
put("vol", "bricked.vol", vol_header((5, 5, 5), (1, 1, 1), 2, 3) + ramp(8 * 27))
put("vol", "davis.vol", struct.pack(">4I3f", 4, 3, 2, 0, 1, 1, 1) + ramp(24))

# NRRD, attached.
def nrrd(fields, data=b""):
    head = "NRRD0004\n" + "".join(f"{k}: {v}\n" for k, v in fields) + "\n"
    return head.encode() + data


put("nrrd", "uchar_raw.nrrd", nrrd([("type", "uchar"), ("dimension", 3), ("sizes", "4 3 2"),
                                   ("spacings", "0.5 1 2"), ("encoding", "raw")], ramp(24)))
put("nrrd", "short_be.nrrd", nrrd([("type", "short"), ("dimension", 3), ("sizes", "3 2 2"),
                                  ("endian", "big"), ("encoding", "raw"),
                                  ("space directions", "(1,0,0) (0,1,0) (0,0,2)")],
                                 ramp(24)))
put("nrrd", "float_gzip.nrrd", nrrd([("type", "float"), ("dimension", 3), ("sizes", "3 2 2"),
                                    ("encoding", "gzip"), ("endian", "little")],
                                   gzip.compress(struct.pack("<12f", *[i * 0.5 for i in range(12)]))))
put("nrrd", "4d.nrrd", nrrd([("type", "uchar"), ("dimension", 4), ("sizes", "3 2 2 2"),
                            ("encoding", "raw"), ("byte skip", "-1")], ramp(24)))

# NRRD, detached: header, blank line, then the data file's bytes.
put("nhdr", "raw.nhdr", nrrd([("type", "uchar"), ("dimension", 3), ("sizes", "4 3 2"),
                             ("encoding", "raw"), ("data file", "d.raw")], ramp(24)))
put("nhdr", "lineskip.nhdr", nrrd([("type", "uchar"), ("dimension", 3), ("sizes", "2 2 2"),
                                  ("encoding", "raw"), ("line skip", 1), ("byte skip", 2),
                                  ("data file", "d.raw")], b"# comment\nxx" + ramp(8)))


# NIfTI-1 single file.
def nifti(dims, datatype, bitpix, pixdim, data, slope=0.0, inter=0.0):
    h = bytearray(352)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, len(dims), *dims, *([1] * (7 - len(dims))))
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1.0, *pixdim, *([1.0] * (7 - len(pixdim))))
    struct.pack_into("<f", h, 108, 352.0)
    struct.pack_into("<ff", h, 112, slope, inter)
    h[344:348] = b"n+1\0"
    return bytes(h) + data


n_u8 = nifti((4, 3, 2), 2, 8, (1, 1, 2), ramp(24))
n_i16 = nifti((3, 2, 2), 4, 16, (0.5, 0.5, 1), struct.pack("<12h", *range(-6, 6)), 2.0, -1.0)
n_4d = nifti((3, 2, 2, 2), 2, 8, (1, 1, 1, 2), ramp(24))
put("nifti", "u8.nii", n_u8)
put("nifti", "i16_scaled.nii", n_i16)
put("nifti", "4d.nii", n_4d)
put("nifti_gz", "u8.nii.gz", gzip.compress(n_u8))
put("nifti_gz", "4d.nii.gz", gzip.compress(n_4d))


# DICOM: explicit VR little endian (and implicit), 4 columns x 3 rows, 16 bits.
def element(group, elem, vr, value, explicit=True):
    if len(value) % 2:
        value += b"\0" if vr in ("UI", "OB") else b" "
    tag = struct.pack("<HH", group, elem)
    if not explicit:
        return tag + struct.pack("<I", len(value)) + value
    if vr in ("OB", "OW", "SQ", "UN", "UT", "OF"):
        return tag + vr.encode() + b"\0\0" + struct.pack("<I", len(value)) + value
    return tag + vr.encode() + struct.pack("<H", len(value)) + value


def dicom(ts, instance, z, explicit=True):
    us = lambda v: struct.pack("<H", v)
    meta_body = (element(2, 1, "OB", b"\0\1")
                 + element(2, 2, "UI", b"1.2.840.10008.5.1.4.1.1.4")
                 + element(2, 3, "UI", f"1.2.3.{instance}".encode())
                 + element(2, 0x10, "UI", ts.encode()))
    meta = element(2, 0, "UL", struct.pack("<I", len(meta_body))) + meta_body
    e = lambda g, el, vr, v: element(g, el, vr, v, explicit)
    body = (e(8, 0x16, "UI", b"1.2.840.10008.5.1.4.1.1.4")
            + e(8, 0x18, "UI", f"1.2.3.{instance}".encode())
            + e(0x18, 0x50, "DS", b"2")
            + e(0x20, 0x0E, "UI", b"1.2.3")
            + e(0x20, 0x13, "IS", str(instance).encode())
            + e(0x20, 0x32, "DS", f"0\\0\\{z}".encode())
            + e(0x20, 0x37, "DS", b"1\\0\\0\\0\\1\\0")
            + e(0x28, 0x02, "US", us(1))
            + e(0x28, 0x04, "CS", b"MONOCHROME2")
            + e(0x28, 0x10, "US", us(3))
            + e(0x28, 0x11, "US", us(4))
            + e(0x28, 0x30, "DS", b"0.5\\0.75")
            + e(0x28, 0x100, "US", us(16))
            + e(0x28, 0x101, "US", us(12))
            + e(0x28, 0x102, "US", us(11))
            + e(0x28, 0x103, "US", us(0))
            + e(0x7FE0, 0x10, "OW", struct.pack("<12H", *[instance * 100 + i for i in range(12)])))
    return b"\0" * 128 + b"DICM" + meta + body


EXPLICIT, IMPLICIT = "1.2.840.10008.1.2.1", "1.2.840.10008.1.2"
put("dicom", "explicit.dcm", dicom(EXPLICIT, 1, 0))
put("dicom", "implicit.dcm", dicom(IMPLICIT, 1, 0, explicit=False))


def parts(*files):
    return b"".join(struct.pack("<H", len(f)) + f for f in files)


put("dicom_series", "two.bin", parts(dicom(EXPLICIT, 1, 0), dicom(EXPLICIT, 2, 2)))
put("dicom_series", "three_implicit.bin",
    parts(*(dicom(IMPLICIT, k, 2 * k, explicit=False) for k in (1, 2, 3))))

# Raw: dims-1 per axis, sample type index, endian, order, offset, padding.
put("raw", "u8.bin", bytes([3, 2, 1, 0, 0, 0, 0, 0]) + ramp(24))
put("raw", "i16_be_offset.bin", bytes([2, 1, 1, 3, 1, 1, 4, 0]) + ramp(4 + 24))
put("raw", "f32.bin", bytes([1, 1, 1, 4, 0, 0, 0, 0]) + struct.pack("<8f", *range(8)))

# Transfer functions.
put("tf_json", "linear.json", b'{"interpolation": "linear", "points": ['
    b'{"value": 0, "color": [0, 0, 0], "opacity": 0},'
    b'{"value": 128, "color": [1, 0.5, 0], "opacity": 0.3},'
    b'{"value": 255, "color": [1, 1, 1], "opacity": 1}]}')
put("tf_json", "step.json", b'{"interpolation": "step", "points": ['
    b'{"value": 85.001, "color": [1, 0, 0], "opacity": 0.1},'
    b'{"value": 100.001, "color": [0, 0, 1], "opacity": 0.5}]}')

# Points files.
put("points", "xyz.csv", b"x,y,z,radius,value\n0,0,0,1,5\n1,0,0,1,7\n0,1.5,0,0.8,9\n")
put("points", "plain.csv", b"# three balls\n0 0 0\n1 1 1\n2 0 1\n")

# .vseq: packed by vol_app from a 3-frame 4-D NRRD, LZ4 and zstd with difference frames.
tmp = os.path.join(SEEDS, "..", "target-seeds")
os.makedirs(tmp, exist_ok=True)
src = os.path.join(tmp, "frames.nrrd")
with open(src, "wb") as f:
    f.write(nrrd([("type", "uchar"), ("dimension", 4), ("sizes", "4 3 2 3"), ("encoding", "raw")],
                 ramp(72, 7, 256)))
vol_app = os.path.join(ROOT, "target", "release", "vol_app")
if os.path.exists(vol_app):
    for name, extra in [("lz4.vseq", ["--codec", "lz4"]),
                        ("zstd_delta.vseq", ["--codec", "zstd", "--delta", "--key-interval", "2"]),
                        ("none.vseq", ["--codec", "none"])]:
        out = os.path.join(SEEDS, "vseq", name)
        os.makedirs(os.path.dirname(out), exist_ok=True)
        subprocess.run([vol_app, "pack", src, "-o", out, "--force", *extra], check=True,
                       stdout=subprocess.DEVNULL)
else:
    print("no target/release/vol_app: build it to write the .vseq seeds", file=sys.stderr)
