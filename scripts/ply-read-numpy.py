#!/usr/bin/env python3
"""A plain PLY reader to compare atoll's loading with: reads every binary
little-endian PLY (or .ply.gz) file named on the command line into numpy
arrays (vertex rows as one structured array, faces as (count, i0, i1, i2)
rows, so all-triangle files only), on one thread, and prints the bytes
read (unpacked), the triangles and the seconds taken.

Usage: ply-read-numpy.py FILE...
"""
import gzip
import sys
import time

import numpy as np

TYPES = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4", "uint": "<u4",
         "float": "<f4", "double": "<f8", "int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2",
         "int32": "<i4", "uint32": "<u4", "float32": "<f4", "float64": "<f8"}


def read(path):
    opener = gzip.open if path.endswith(".gz") else open
    with opener(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    elements = []
    for line in data[:end].decode("ascii").splitlines():
        words = line.split()
        if words[:1] == ["element"]:
            elements.append([words[1], int(words[2]), []])
        elif words[:1] == ["property"]:
            elements[-1][2].append(words[1:])
        elif words[:1] == ["format"] and words[1] != "binary_little_endian":
            sys.exit(f"{path}: only binary_little_endian is read here")
    at, triangles = end, 0
    for name, count, props in elements:
        fields = []
        for p in props:
            if p[0] == "list":
                # Triangles only: the count and three indices.
                fields += [("n", TYPES[p[1]]), (p[3], TYPES[p[2]], (3,))]
            else:
                fields.append((p[1], TYPES[p[0]]))
        rows = np.frombuffer(data, dtype=np.dtype(fields), count=count, offset=at)
        if name == "face":
            if not (rows["n"] == 3).all():
                sys.exit(f"{path}: faces other than triangles")
            triangles += count
        at += rows.nbytes
    return len(data), triangles


def main():
    start = time.perf_counter()
    total, triangles = 0, 0
    for path in sys.argv[1:]:
        n, t = read(path)
        total += n
        triangles += t
    seconds = time.perf_counter() - start
    print(f"numpy: {len(sys.argv) - 1} files, {total / 1e9:.2f} GB, {triangles / 1e6:.1f} M triangles "
          f"in {seconds:.2f} s ({total / 1e9 / seconds:.2f} GB/s, one thread)")


if __name__ == "__main__":
    main()
