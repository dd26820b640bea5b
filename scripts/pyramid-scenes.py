#!/usr/bin/env python3
"""Writes two one-texture scenes for timing MIP pyramid construction
(`atoll info DIR/pow2.pbrt`, `atoll info DIR/odd.pbrt`): a plane with a
trilinear `imagemap` of a 2048x2048 8-bit PNG (power-of-two sides), or of
a 1500x1000 one (resized up first). The PNGs are patterns written with
zlib alone, so nothing needs installing."""
import struct
import sys
import zlib
from pathlib import Path


def png(path, w, h):
    raw = bytearray()
    for y in range(h):
        raw.append(0)  # no row filter
        for x in range(w):
            raw += bytes(((x ^ y) & 255, (x * 3 + y) & 255, (y * 7) & 255))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(raw), 1)) + chunk(b"IEND", b"")
    )


SCENE = """LookAt 0 0 -3 0 0 0 0 1 0
Camera "perspective"
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Texture "t" "spectrum" "imagemap" "string filename" "{name}.png" "string filter" "trilinear"
Material "diffuse" "texture reflectance" "t"
Shape "trianglemesh" "point3 P" [-1 -1 0 1 -1 0 1 1 0 -1 1 0] "integer indices" [0 1 2 0 2 3] "point2 uv" [0 0 1 0 1 1 0 1]
"""

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)
for name, (w, h) in {"pow2": (2048, 2048), "odd": (1500, 1000)}.items():
    png(out / f"{name}.png", w, h)
    (out / f"{name}.pbrt").write_text(SCENE.format(name=name))
