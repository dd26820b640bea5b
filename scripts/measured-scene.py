#!/usr/bin/env python3
"""A measured-BRDF file made from a closed form, and a scene that uses it.

    scripts/measured-scene.py scenes

writes scenes/measured-ggx.bsdf, a tensor file in the layout of Dupuy and
Jakob's measured BRDFs (what pbrt-v4's `measured` material reads), and
scenes/measured.pbrt, spheres of it in a lit room: the CPU/GPU comparison
scene of scripts/gpu-check for measured materials.

The BRDF is isotropic GGX with alpha ALPHA and a reflectance F(lambda) that
rises from 0.2 at 400 nm to 0.9 at 700 nm, tabulated as such files are:

    f(wo, wi) = F * D(wm) / (4 sigma(wo) cos(theta_i)),
    sigma(wo) = cos(theta_o) (1 + Lambda(wo))   (projected microfacet area),

so f = F D G1(wo) / (4 cos(theta_o) cos(theta_i)), which atoll's tests
compute in closed form. The visible-normal table is D_wo(m) in the unit
square of the normal (with its Jacobian 2 pi^2 u sin(theta_m)); the
luminance table, 1 + x, is deliberately not uniform so that sampling warps
through both tables. Deterministic: no randomness.
"""
import math
import os
import struct
import sys

ALPHA = 0.3
WAVELENGTHS = [400.0 + 50.0 * i for i in range(8)]
THETA_I = [math.radians(d) for d in (0, 10, 20, 30, 40, 50, 60, 70, 80)]
PHI_I = [0.0]
NDF_SIZE = (16, 64)  # (phi, theta) points
VNDF_SIZE = (32, 32)
SAMPLE_SIZE = (16, 16)


def reflectance(lam):
    return min(max(0.2 + 0.7 * (lam - 400.0) / 300.0, 0.2), 0.9)


def u2theta(u):
    return u * u * math.pi / 2


def u2phi(u):
    return (2 * u - 1) * math.pi


def ggx_d(cos_m):
    if cos_m <= 0:
        return 0.0
    c2 = cos_m * cos_m
    tan2 = (1 - c2) / c2
    return 1.0 / (math.pi * ALPHA * ALPHA * c2 * c2 * (1 + tan2 / (ALPHA * ALPHA)) ** 2)


def ggx_lambda(cos_t):
    c2 = cos_t * cos_t
    if c2 >= 1:
        return 0.0
    tan2 = (1 - c2) / max(c2, 1e-12)
    return (-1 + math.sqrt(1 + ALPHA * ALPHA * tan2)) / 2


def grid(ny, nx, f):
    return [f(x / (nx - 1), y / (ny - 1)) for y in range(ny) for x in range(nx)]


def ndf(ux, uy):
    return ggx_d(math.cos(u2theta(ux)))


def sigma(ux, uy):
    c = math.cos(u2theta(ux))
    return c * (1 + ggx_lambda(c))


def vndf(theta_o):
    wo = (math.sin(theta_o), 0.0, math.cos(theta_o))

    def value(ux, uy):
        tm, pm = u2theta(ux), u2phi(uy)
        m = (math.sin(tm) * math.cos(pm), math.sin(tm) * math.sin(pm), math.cos(tm))
        dot = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2]
        if dot <= 0:
            return 0.0
        g1 = 1 / (1 + ggx_lambda(wo[2]))
        return g1 * dot * ggx_d(m[2]) / wo[2] * 2 * math.pi ** 2 * ux * math.sin(tm)

    return value


def tensor_file(fields):
    """Mitsuba's tensor format: magic, version 1.0, field headers, data."""
    header_len = 12 + 2 + 4 + sum(2 + len(n) + 2 + 1 + 8 + 8 * len(s) for n, _, s, _ in fields)
    out = bytearray(b"tensor_file\0" + bytes([1, 0]) + struct.pack("<I", len(fields)))
    offset = header_len
    for name, code, shape, data in fields:
        out += struct.pack("<H", len(name)) + name.encode() + struct.pack("<HBQ", len(shape), code, offset)
        out += b"".join(struct.pack("<Q", s) for s in shape)
        offset += len(data)
    for _, _, _, data in fields:
        out += data
    return bytes(out)


def floats(values):
    return struct.pack("<%df" % len(values), *values)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes"
    u8, f32 = 1, 10
    n_phi, n_theta = len(PHI_I), len(THETA_I)
    vndf_values, lum_values, spectra_values = [], [], []
    for _ in PHI_I:
        for theta in THETA_I:
            # A normal incidence of exactly 0 has no azimuth: tabulate just off it.
            vndf_values += grid(*VNDF_SIZE, vndf(max(theta, 1e-3)))
            lum_values += grid(*SAMPLE_SIZE, lambda x, y: 1 + x)
            for lam in WAVELENGTHS:
                spectra_values += grid(*SAMPLE_SIZE, lambda x, y: reflectance(lam))
    description = b"GGX alpha 0.3, reflectance rising from 0.2 to 0.9 (scripts/measured-scene.py)"
    fields = [
        ("description", u8, [len(description)], description),
        ("jacobian", u8, [1], bytes([1])),
        ("phi_i", f32, [n_phi], floats(PHI_I)),
        ("theta_i", f32, [n_theta], floats(THETA_I)),
        ("wavelengths", f32, [len(WAVELENGTHS)], floats(WAVELENGTHS)),
        ("ndf", f32, list(NDF_SIZE), floats(grid(*NDF_SIZE, ndf))),
        ("sigma", f32, list(NDF_SIZE), floats(grid(*NDF_SIZE, sigma))),
        ("vndf", f32, [n_phi, n_theta, *VNDF_SIZE], floats(vndf_values)),
        ("luminance", f32, [n_phi, n_theta, *SAMPLE_SIZE], floats(lum_values)),
        ("spectra", f32, [n_phi, n_theta, len(WAVELENGTHS), *SAMPLE_SIZE], floats(spectra_values)),
    ]
    with open(os.path.join(out, "measured-ggx.bsdf"), "wb") as f:
        f.write(tensor_file(fields))
    with open(os.path.join(out, "measured.pbrt"), "w") as f:
        f.write("""# Spheres of a measured BRDF (measured-ggx.bsdf) in a lit room.
# Made by scripts/measured-scene.py.
LookAt 0 1 -3.2  0 0.7 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "measured.exr"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 5 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.2 0.25 0.3 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 8 7 6 ]
Shape "trianglemesh" "point3 P" [ -0.5 2.4 -0.5  0.5 2.4 -0.5  0.5 2.4 0.5  -0.5 2.4 0.5 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
Material "diffuse" "rgb reflectance" [ 0.6 0.6 0.6 ]
Shape "trianglemesh" "point3 P" [ -2 0 -4  2 0 -4  2 0 2  -2 0 2 ] "integer indices" [ 0 2 1 0 3 2 ]
Shape "trianglemesh" "point3 P" [ -2 0 2  2 0 2  2 2.5 2  -2 2.5 2 ] "integer indices" [ 0 1 2 0 2 3 ]
MakeNamedMaterial "ggx" "string type" "measured" "string filename" "measured-ggx.bsdf"
NamedMaterial "ggx"
AttributeBegin
Translate -0.5 0.45 0.3
Shape "sphere" "float radius" 0.45
AttributeEnd
AttributeBegin
Translate 0.55 0.35 -0.2
Shape "sphere" "float radius" 0.35
AttributeEnd
""")


if __name__ == "__main__":
    main()
