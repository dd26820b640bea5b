#!/usr/bin/env python3
"""Writes scenes/hair.pbrt: three tufts of hair strands (seeded, so the file is reproducible)."""
import math, random
random.seed(7)
out = []
out.append('''# Hair: tufts of cylinder curves under pbrt-v4's "hair" material (its
# HairBxDF) in three colours, lit by a distant light and a sky: rendered on
# the CPU and the GPU by scripts/gpu-check and compared. Strands are made
# by scripts/hair-scene.py.
LookAt 0 1.2 -4  0 0.7 0  0 1 0
Camera "perspective" "float fov" [ 35 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "hair.exr"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 12 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.3 0.35 0.45 ]
LightSource "distant" "point3 from" [ -1 3 -2 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material "diffuse" "rgb reflectance" [ 0.4 0.4 0.4 ]
Shape "trianglemesh" "point3 P" [ -3 0 -3  3 0 -3  3 0 3  -3 0 3 ] "integer indices" [ 0 1 2 0 2 3 ]''')
tufts = [(-0.9, '"float eumelanin" [ 1.3 ]'), (0.0, '"float eumelanin" [ 0.3 ] "float pheomelanin" [ 0.2 ] "float beta_m" [ 0.2 ]'), (0.9, '"rgb reflectance" [ 0.8 0.25 0.1 ] "float alpha" [ 3 ]')]
for cx, mat in tufts:
    out.append(f'Material "hair" {mat}')
    for s in range(70):
        a = random.uniform(0, 2 * math.pi); r = 0.25 * math.sqrt(random.random())
        x, z = cx + r * math.cos(a), r * math.sin(a)
        lean = random.uniform(-0.35, 0.35); lean2 = random.uniform(-0.35, 0.35)
        h = random.uniform(1.0, 1.5)
        pts = [(x, 0, z), (x + 0.1 * lean, h / 3, z + 0.1 * lean2), (x + 0.5 * lean, 2 * h / 3, z + 0.4 * lean2), (x + lean, h, z + lean2)]
        p = "  ".join(f"{px:.4f} {py:.4f} {pz:.4f}" for px, py, pz in pts)
        out.append(f'Shape "curve" "string type" "cylinder" "point3 P" [ {p} ] "float width0" [ 0.02 ] "float width1" [ 0.006 ]')
print("\n".join(out))
