#!/usr/bin/env python3
"""A measured-BRDF file made from a closed form, and a scene that uses it.

    scripts/measured-scene.py scenes

writes scenes/measured-ggx.bsdf, a tensor file in the layout of Dupuy and
Jakob's measured BRDFs (what pbrt-v4's `measured` material reads), its
anisotropic sibling scenes/measured-ggx-aniso.bsdf, and
scenes/measured.pbrt, spheres of them in a lit room: the CPU/GPU
comparison scene of scripts/gpu-check for measured materials.

The BRDF is isotropic GGX with alpha ALPHA and a reflectance F(lambda) that
rises from 0.2 at 400 nm to 0.9 at 700 nm, tabulated as such files are:

    f(wo, wi) = F * D(wm) / (4 sigma(wo) cos(theta_i)),
    sigma(wo) = cos(theta_o) (1 + Lambda(wo))   (projected microfacet area),

so f = F D G1(wo) / (4 cos(theta_o) cos(theta_i)), which atoll's tests
compute in closed form. The anisotropic file holds GGX with alphas
ANISO_ALPHAS (x, y) and a constant reflectance 0.7, tabulated for
incident azimuths over the whole circle, its normals in absolute azimuth. The visible-normal table is D_wo(m) in the unit
square of the normal (with its Jacobian 2 pi^2 u sin(theta_m)); the
luminance table, 1 + x, is deliberately not uniform so that sampling warps
through both tables. Deterministic: no randomness.
"""
import math
import os
import struct
import sys

ALPHA = 0.3
ANISO_ALPHAS = (0.15, 0.45)
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


def ggx_d(cos_m, phi=0.0, alphas=None):
    """Anisotropic GGX's D at elevation cosine cos_m and azimuth phi."""
    ax, ay = alphas or (ALPHA, ALPHA)
    if cos_m <= 0:
        return 0.0
    c2 = cos_m * cos_m
    tan2 = (1 - c2) / c2
    e = tan2 * (math.cos(phi) ** 2 / (ax * ax) + math.sin(phi) ** 2 / (ay * ay))
    return 1.0 / (math.pi * ax * ay * c2 * c2 * (1 + e) ** 2)


def ggx_lambda(cos_t, phi=0.0, alphas=None):
    ax, ay = alphas or (ALPHA, ALPHA)
    c2 = cos_t * cos_t
    if c2 >= 1:
        return 0.0
    tan2 = (1 - c2) / max(c2, 1e-12)
    a2 = (math.cos(phi) * ax) ** 2 + (math.sin(phi) * ay) ** 2
    return (-1 + math.sqrt(1 + a2 * tan2)) / 2


def grid(ny, nx, f):
    return [f(x / (nx - 1), y / (ny - 1)) for y in range(ny) for x in range(nx)]


def ndf(alphas=None):
    return lambda ux, uy: ggx_d(math.cos(u2theta(ux)), u2phi(uy), alphas)


def sigma(alphas=None):
    def value(ux, uy):
        c = math.cos(u2theta(ux))
        return c * (1 + ggx_lambda(c, u2phi(uy), alphas))

    return value


def vndf(theta_o, phi_o=0.0, alphas=None):
    """D_wo over the normal's square; the normal's azimuth is relative to
    phi_o for isotropic tables (phi_o 0), absolute for anisotropic ones."""
    st = math.sin(theta_o)
    wo = (st * math.cos(phi_o), st * math.sin(phi_o), math.cos(theta_o))

    def value(ux, uy):
        tm, pm = u2theta(ux), u2phi(uy)
        m = (math.sin(tm) * math.cos(pm), math.sin(tm) * math.sin(pm), math.cos(tm))
        dot = wo[0] * m[0] + wo[1] * m[1] + wo[2] * m[2]
        if dot <= 0:
            return 0.0
        g1 = 1 / (1 + ggx_lambda(wo[2], phi_o, alphas))
        return g1 * dot * ggx_d(m[2], pm, alphas) / wo[2] * 2 * math.pi ** 2 * ux * math.sin(tm)

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


def brdf_file(description, phi_i, theta_i, wavelengths, reflectance, alphas, sizes):
    """The tensor file of GGX with `alphas` (None: isotropic ALPHA) whose
    reflectance at wavelength l is reflectance(l)."""
    u8, f32 = 1, 10
    ndf_size, vndf_size, sample_size = sizes
    n_phi, n_theta = len(phi_i), len(theta_i)
    vndf_values, lum_values, spectra_values = [], [], []
    for phi in phi_i:
        for theta in theta_i:
            # A normal incidence of exactly 0 has no azimuth: tabulate just off it.
            vndf_values += grid(*vndf_size, vndf(max(theta, 1e-3), phi, alphas))
            lum_values += grid(*sample_size, lambda x, y: 1 + x)
            for lam in wavelengths:
                spectra_values += grid(*sample_size, lambda x, y: reflectance(lam))
    fields = [
        ("description", u8, [len(description)], description),
        ("jacobian", u8, [1], bytes([1])),
        ("phi_i", f32, [n_phi], floats(phi_i)),
        ("theta_i", f32, [n_theta], floats(theta_i)),
        ("wavelengths", f32, [len(wavelengths)], floats(wavelengths)),
        ("ndf", f32, list(ndf_size), floats(grid(*ndf_size, ndf(alphas)))),
        ("sigma", f32, list(ndf_size), floats(grid(*ndf_size, sigma(alphas)))),
        ("vndf", f32, [n_phi, n_theta, *vndf_size], floats(vndf_values)),
        ("luminance", f32, [n_phi, n_theta, *sample_size], floats(lum_values)),
        ("spectra", f32, [n_phi, n_theta, len(wavelengths), *sample_size], floats(spectra_values)),
    ]
    return tensor_file(fields)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "scenes"
    description = b"GGX alpha 0.3, reflectance rising from 0.2 to 0.9 (scripts/measured-scene.py)"
    sizes = (NDF_SIZE, VNDF_SIZE, SAMPLE_SIZE)
    with open(os.path.join(out, "measured-ggx.bsdf"), "wb") as f:
        f.write(brdf_file(description, PHI_I, THETA_I, WAVELENGTHS, reflectance, None, sizes))
    description = b"GGX alphas 0.15, 0.45, reflectance 0.7 (scripts/measured-scene.py)"
    phi_i = [math.pi * (i / 4 - 1) for i in range(9)]
    theta_i = [math.radians(d) for d in (0, 15, 30, 45, 60, 75)]
    sizes = ((64, 64), (24, 24), (8, 8))
    with open(os.path.join(out, "measured-ggx-aniso.bsdf"), "wb") as f:
        f.write(brdf_file(description, phi_i, theta_i, [500.0], lambda l: 0.7, ANISO_ALPHAS, sizes))
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
Material "measured" "string filename" "measured-ggx-aniso.bsdf"
Translate 0.55 0.35 -0.2
Rotate 60 0 1 0
Shape "sphere" "float radius" 0.35
AttributeEnd
""")


if __name__ == "__main__":
    main()
