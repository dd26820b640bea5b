#!/usr/bin/env python3
"""A scene of glowing grid media in pbrt-v4 form (deterministic).

    scripts/glowing-media-scene.py > scenes/glowing-media.pbrt

A dim room holding a fireball (an `rgbgrid`: σa, σs and Le per colour,
hot and yellow at the core, red and smoky outside) and a glowing column
of mist (a `uniformgrid` whose emission is its `Le` times an `Lescale`
grid) standing just above the floor (a boundary in the floor's plane
would make which surface is hit a matter of rounding). The CPU/GPU
comparison scene of scripts/gpu-check for grid media
that emit.
"""
import math

N = 8  # samples per axis of the fireball


def fireball():
    sigma_a, sigma_s, le = [], [], []
    for z in range(N):
        for y in range(N):
            for x in range(N):
                # Distance from the centre in [0, 1] at the box's faces,
                # with a lumpy edge.
                p = [(c + 0.5) / N * 2 - 1 for c in (x, y, z)]
                r = math.sqrt(sum(c * c for c in p)) + 0.15 * math.sin(5 * p[0] + 3 * p[1]) * math.cos(4 * p[2])
                d = max(0.0, 1.0 - r)
                heat = max(0.0, 1.0 - 1.8 * r)
                sigma_a.append((2.0 * d, 2.5 * d, 3.0 * d))
                sigma_s.append((1.5 * d, 1.2 * d, 1.0 * d))
                le.append((6.0 * heat, 3.5 * heat * heat, 0.8 * heat ** 3))
    return sigma_a, sigma_s, le


def column():
    density, lescale = [], []
    for z in range(4):
        for y in range(6):
            for x in range(4):
                density.append(0.6 + 0.4 * math.cos(1.3 * x + 0.7 * z) * math.sin(0.9 * y + 0.5))
                lescale.append(max(0.0, 1.0 - y / 5.0) ** 2)
    return density, lescale


def box(lo, hi):
    """A trianglemesh box whose normals point out (pbrt's normal is
    cross(p0 - p2, p1 - p2); the inside medium lies behind it)."""
    corner = lambda i: [hi[a] if i >> a & 1 else lo[a] for a in range(3)]
    sub = lambda a, b: [a[k] - b[k] for k in range(3)]
    cross = lambda a, b: [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    centre = [(lo[a] + hi[a]) / 2 for a in range(3)]
    indices = []
    for f in [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]:
        for a, b, c in [(f[0], f[1], f[2]), (f[0], f[2], f[3])]:
            p0, p1, p2 = corner(a), corner(b), corner(c)
            n = cross(sub(p0, p2), sub(p1, p2))
            mid = [(p0[k] + p1[k] + p2[k]) / 3 - centre[k] for k in range(3)]
            indices += [a, b, c] if sum(n[k] * mid[k] for k in range(3)) > 0 else [a, c, b]
    points = "  ".join(" ".join(f"{v:g}" for v in corner(i)) for i in range(8))
    return f'Shape "trianglemesh" "point3 P" [ {points} ] "integer indices" [ {numbers(indices)} ]'


def triples(values):
    return "  ".join(" ".join(f"{v:.4g}" for v in t) for t in values)


def numbers(values):
    return " ".join(f"{v:.4g}" for v in values)


def main():
    sigma_a, sigma_s, le = fireball()
    density, lescale = column()
    print(f'''# Glowing grid media: a fireball (pbrt-v4's rgbgrid with Le) and a column
# of mist that glows at its foot (a uniformgrid with an Lescale grid), in
# a dim room. Made by scripts/glowing-media-scene.py.
LookAt 0 1 -3.2  0 0.8 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "glowing-media.exr"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "volpath" "integer maxdepth" [ 8 ]
WorldBegin
LightSource "distant" "point3 from" [ 1 3 -2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 0.3 0.3 0.35 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -3 0 -4  3 0 -4  3 0 3  -3 0 3 ] "integer indices" [ 0 2 1 0 3 2 ]
Shape "trianglemesh" "point3 P" [ -3 0 2  3 0 2  3 3 2  -3 3 2 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeBegin
Translate -0.4 0.9 0.2
Rotate 25 0.2 1 0.1
MakeNamedMedium "fireball" "string type" "rgbgrid" "float g" [ 0.3 ] "float scale" [ 4 ] "float Lescale" [ 1.5 ]
  "integer nx" [ {N} ] "integer ny" [ {N} ] "integer nz" [ {N} ]
  "point3 p0" [ -0.6 -0.6 -0.6 ] "point3 p1" [ 0.6 0.6 0.6 ]
  "rgb sigma_a" [ {triples(sigma_a)} ]
  "rgb sigma_s" [ {triples(sigma_s)} ]
  "rgb Le" [ {triples(le)} ]
Material "interface"
MediumInterface "fireball" ""
Shape "sphere" "float radius" [ 0.6 ]
AttributeEnd
AttributeBegin
Translate 0.8 0 0.4
MakeNamedMedium "mist" "string type" "uniformgrid" "rgb sigma_a" [ 0.8 0.8 0.8 ] "rgb sigma_s" [ 0.6 0.8 1.2 ]
  "rgb Le" [ 0.4 1.2 2.0 ] "integer nx" [ 4 ] "integer ny" [ 6 ] "integer nz" [ 4 ]
  "point3 p0" [ -0.3 0.02 -0.3 ] "point3 p1" [ 0.3 1.8 0.3 ]
  "float density" [ {numbers(density)} ]
  "float Lescale" [ {numbers(lescale)} ]
Material "interface"
MediumInterface "mist" ""
{box([-0.3, 0.02, -0.3], [0.3, 1.8, 0.3])}
AttributeEnd''')


main()
