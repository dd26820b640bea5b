#!/usr/bin/env python3
"""Hair scenes in pbrt-v4 form, seeded so that they are reproducible.

    scripts/hair-scene.py > scenes/hair.pbrt
        three tufts of 70 strands, one Bézier segment each (the CPU/GPU
        comparison scene of scripts/gpu-check);
    scripts/hair-scene.py --strands 200000 --segments 4 > field.pbrt
        a square metre of fur: STRANDS strands of SEGMENTS segments each,
        for measuring hair at scale.
"""
import argparse
import math
import random

HEADER = '''# {what}: cylinder curves under pbrt-v4's "hair" material (its HairBxDF),
# lit by a distant light and a sky. Made by scripts/hair-scene.py{args}.
LookAt 0 {eye_y} {eye_z}  0 {look_y} 0  0 1 0
Camera "perspective" "float fov" [ 35 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "hair.exr"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 12 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.3 0.35 0.45 ]
LightSource "distant" "point3 from" [ -1 3 -2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material "diffuse" "rgb reflectance" [ 0.4 0.4 0.4 ]
Shape "trianglemesh" "point3 P" [ -3 0 -3  3 0 -3  3 0 3  -3 0 3 ] "integer indices" [ 0 1 2 0 2 3 ]'''

# The left tuft's eumelanin is a texture (darker bands along each strand,
# its u); the middle tuft's absorption and roughness are textures
# (evaluated per hit): bands, and a constant; the right one's colour is a
# texture too (lighter towards the tips), turned into an absorption per hit.
TUFT_TEXTURES = '''Texture "melanin" "float" "checkerboard" "float uscale" [ 4 ] "float vscale" [ 1 ]
  "float tex1" [ 0.9 ] "float tex2" [ 2.2 ]
Texture "bands" "spectrum" "checkerboard" "float uscale" [ 6 ] "float vscale" [ 1 ]
  "rgb tex1" [ 0.35 0.6 1.2 ] "rgb tex2" [ 1.6 0.9 0.3 ]
Texture "roughness" "float" "constant" "float value" [ 0.2 ]
Texture "tips" "spectrum" "checkerboard" "float uscale" [ 2 ] "float vscale" [ 1 ]
  "rgb tex1" [ 0.8 0.25 0.1 ] "rgb tex2" [ 0.9 0.75 0.4 ]'''

TUFT_MATERIALS = [
    (-0.9, '"texture eumelanin" "melanin" "float pheomelanin" [ 0.2 ]'),
    (0.0, '"texture sigma_a" "bands" "texture beta_m" "roughness"'),
    (0.9, '"texture reflectance" "tips" "float alpha" [ 3 ]'),
]


def strand(rng, root, height, segments):
    """Control points of a strand rising from `root`, bending as it goes."""
    lean_x, lean_z = rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35)
    points = []
    for k in range(3 * segments + 1):
        f = k / (3 * segments)
        bend = f * f
        points.append((root[0] + lean_x * bend, height * f, root[1] + lean_z * bend))
    return points


def curve(points, width0, width1):
    p = "  ".join(f"{x:.4f} {y:.4f} {z:.4f}" for x, y, z in points)
    return (f'Shape "curve" "string type" "cylinder" "point3 P" [ {p} ] '
            f'"float width0" [ {width0} ] "float width1" [ {width1} ]')


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--strands", type=int, default=0, help="a fur field of this many strands (0: the tufts)")
    ap.add_argument("--segments", type=int, default=1, help="Bézier segments per strand")
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    if a.strands == 0:
        print(HEADER.format(what="Hair tufts", args="", eye_y=1.2, eye_z=-4, look_y=0.7))
        print(TUFT_TEXTURES)
        for cx, material in TUFT_MATERIALS:
            print(f'Material "hair" {material}')
            for _ in range(70):
                angle, r = rng.uniform(0, 2 * math.pi), 0.25 * math.sqrt(rng.random())
                root = (cx + r * math.cos(angle), r * math.sin(angle))
                print(curve(strand(rng, root, rng.uniform(1.0, 1.5), a.segments), 0.02, 0.006))
        return
    args = f" --strands {a.strands} --segments {a.segments} --seed {a.seed}"
    print(HEADER.format(what="A fur field", args=args, eye_y=0.5, eye_z=-1.2, look_y=0.05))
    print('Material "hair" "float eumelanin" [ 0.8 ] "float pheomelanin" [ 0.3 ]')
    for _ in range(a.strands):
        root = (rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5))
        print(curve(strand(rng, root, rng.uniform(0.15, 0.3), a.segments), 0.004, 0.001))


if __name__ == "__main__":
    main()
