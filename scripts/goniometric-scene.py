#!/usr/bin/env python3
"""A room lit by a goniometric light (deterministic).

    scripts/goniometric-scene.py scenes

writes scenes/goniometric.pbrt and its map, scenes/goniometric-map.png: a
32x32 greyscale checkerboard over pbrt-v4's equal-area square of
directions, so the light throws a pattern of bright and dim patches on
the floor, the walls and a ball. The CPU/GPU comparison scene of
scripts/gpu-check for goniometric lights.
"""
import os
import struct
import sys
import zlib

N = 32


def png(width, height, rows):
    """An 8-bit greyscale PNG of `rows` (lists of bytes)."""
    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)
    raw = b"".join(b"\x00" + bytes(r) for r in rows)
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes"
    rows = [[255 if (x // 4 + y // 4) % 2 == 0 else 60 for x in range(N)] for y in range(N)]
    with open(os.path.join(out, "goniometric-map.png"), "wb") as f:
        f.write(png(N, N, rows))
    with open(os.path.join(out, "goniometric.pbrt"), "w") as f:
        f.write("""# A room lit by a goniometric light whose map is a checkerboard.
# Made by scripts/goniometric-scene.py.
LookAt 0 1 -3.2  0 0.7 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "goniometric.exr"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 5 ]
WorldBegin
AttributeBegin
Translate 0 1.6 0
Rotate 30 1 0 0.3
LightSource "goniometric" "string filename" "goniometric-map.png" "rgb I" [ 1 0.9 0.8 ] "float power" 40
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "trianglemesh" "point3 P" [ -2 0 -4  2 0 -4  2 0 2  -2 0 2 ] "integer indices" [ 0 2 1 0 3 2 ]
Shape "trianglemesh" "point3 P" [ -2 0 2  2 0 2  2 2.5 2  -2 2.5 2 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -2 0 -4  -2 0 2  -2 2.5 2  -2 2.5 -4 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeBegin
Material "diffuse" "rgb reflectance" [ 0.7 0.3 0.2 ]
Translate 0.4 0.4 0.3
Shape "sphere" "float radius" 0.4
AttributeEnd
""")


if __name__ == "__main__":
    main()
