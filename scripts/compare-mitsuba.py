#!/usr/bin/env python3
"""atoll's noise against Mitsuba 3's on the same scene, at equal samples per pixel.

The scene ("small light over sky-lit ground"): a 100 x 100 diffuse ground
(reflectance 0.5) in the y = 0 plane, a constant sky (radiance 0.3), a
1 x 1 one-sided area light facing down 1.5 above the ground (radiance 10), a
diffuse block beside the light's footprint for a shadow, seen from above at
an angle. The sky holds nearly all of the scene's power, so a light sampler
that picks lights by power alone almost never picks the small light, and
the pool of light under it is noisy; Mitsuba picks its two emitters
uniformly. The script writes the scene as pbrt-v4 (for atoll) and builds the
same scene for Mitsuba (`mi.load_dict`, variant scalar_rgb, on the CPU) from
the same triangles, then:

1. renders atoll's reference at --ref-spp and Mitsuba at --mitsuba-ref-spp,
   and prints both means (whole image and the light's pool) to show the
   scenes match;
2. renders each renderer --runs times (different seeds) at every --spp and
   prints the RMSE against atoll's reference over the light's pool (pixels
   whose reference luminance exceeds --pool-factor x the image's median) and
   over the whole image, with the render seconds;
3. prints atoll/Mitsuba of the pool RMSE per spp and exits 1 when any
   exceeds --max-ratio (2 for a scene mismatch or a failed render).

`--cornell` instead renders the shared Cornell box with atoll alone (Mitsuba
does not read pbrt): RMSE of the whole image against atoll's own reference
at each spp, and at equal time (--seconds, spp from the measured samples/s).

Run from the repository root, after `cargo build --release -p atoll`:

    python3 -m pip install mitsuba      # also installs drjit; numpy needed
    scripts/compare-mitsuba.py                        # defaults below
    scripts/compare-mitsuba.py --spp 16,64 --runs 4 --ref-spp 4096 --res 128
    scripts/compare-mitsuba.py --cornell --seconds 1

Images (references, one noisy render of each, PNG previews) and the scene go
to --out (default /tmp/atoll-mitsuba).

Depth: pbrt's (and atoll's) `maxdepth` counts bounces: 0 shows emitters
seen directly, 1 adds direct lighting. Mitsuba's `max_depth` counts path
segments: 1 shows emitters only, 2 direct lighting. So Mitsuba gets
max_depth = maxdepth + 1. Russian roulette: atoll's starts after the first
bounce (pbrt-v4); Mitsuba's at rr_depth = 5 (its default), so at these
depths Mitsuba hardly applies it; both are unbiased.

Camera: pbrt's camera space is left-handed; `Scale -1 1 1` before `LookAt`
makes pbrt's image the same as Mitsuba's `look_at` with the same vectors
(as in the shared Cornell box). Both use the fov of the shorter image axis.
"""

import argparse
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

try:
    import mitsuba as mi
except ImportError:
    sys.exit("needs Mitsuba 3: python3 -m pip install mitsuba")

mi.set_variant("scalar_rgb")

# ---- the scene -------------------------------------------------------------

SKY = 0.3
LIGHT_L = 10.0
GROUND_R = 0.5
BLOCK_R = 0.5
LIGHT_Y = 1.5
EYE = (1.8, 3.0, 3.4)
TARGET = (0.0, 0.0, 0.0)
UP = (0.0, 1.0, 0.0)
FOV = 40.0
MAX_DEPTH = 5  # pbrt's maxdepth; Mitsuba's max_depth is this + 1 (see above)


def quad(corners):
    """Two triangles; the normal (right-handed, (p1-p0) x (p2-p0)) is the
    side a one-sided light emits to, in pbrt and in Mitsuba alike."""
    return np.array(corners, float), np.array([[0, 1, 2], [0, 2, 3]])


def box(lo, hi):
    """A closed box, each face with its own vertices (flat normals), outward."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],  # +y
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],  # -y
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],  # +x
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],  # -x
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],  # +z
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],  # -z
    ]
    p = np.array([v for f in faces for v in f], float)
    i = np.array([[4 * k, 4 * k + 1, 4 * k + 2] for k in range(6)] + [[4 * k, 4 * k + 2, 4 * k + 3] for k in range(6)])
    return p, i


def scene_meshes():
    """name -> (points, triangles, reflectance, emitted radiance or None)."""
    s = 50.0
    h = 0.5
    ground = quad([(-s, 0, -s), (-s, 0, s), (s, 0, s), (s, 0, -s)])  # normal +y
    light = quad([(-h, LIGHT_Y, -h), (h, LIGHT_Y, -h), (h, LIGHT_Y, h), (-h, LIGHT_Y, h)])  # normal -y
    block = box((0.55, 0.0, -0.45), (0.95, 0.6, -0.05))  # off-centre: a mirrored image would show
    for (p, i), n in ((ground, (0, 1, 0)), (light, (0, -1, 0))):
        e1, e2 = p[i[0, 1]] - p[i[0, 0]], p[i[0, 2]] - p[i[0, 0]]
        assert np.allclose(np.cross(e1, e2) / np.linalg.norm(np.cross(e1, e2)), n)
    return {
        "ground": (*ground, GROUND_R, None),
        "light": (*light, 0.0, LIGHT_L),
        "block": (*block, BLOCK_R, None),
    }


def fmt(values):
    return " ".join(f"{v:g}" for v in np.asarray(values).ravel())


def write_pbrt(path, res, spp):
    lines = [
        "# Written by scripts/compare-mitsuba.py: a small light over sky-lit ground.",
        "Scale -1 1 1  # pbrt's left-handed camera space, as Mitsuba's look_at",
        f"LookAt {fmt(EYE)}  {fmt(TARGET)}  {fmt(UP)}",
        f'Camera "perspective" "float fov" [ {FOV:g} ]',
        f'Film "rgb" "integer xresolution" [ {res} ] "integer yresolution" [ {res} ] "string filename" [ "scene.exr" ]',
        'PixelFilter "box"',
        f'Sampler "independent" "integer pixelsamples" [ {spp} ]',
        f'Integrator "path" "integer maxdepth" [ {MAX_DEPTH} ]',
        "WorldBegin",
        f'LightSource "infinite" "rgb L" [ {SKY:g} {SKY:g} {SKY:g} ]',
    ]
    for name, (p, i, refl, le) in scene_meshes().items():
        lines.append(f"AttributeBegin  # {name}")
        if le is not None:
            lines.append(f' AreaLightSource "diffuse" "rgb L" [ {le:g} {le:g} {le:g} ]')
        lines.append(f' Material "diffuse" "rgb reflectance" [ {refl:g} {refl:g} {refl:g} ]')
        lines.append(f' Shape "trianglemesh" "point3 P" [ {fmt(p)} ] "integer indices" [ {fmt(i)} ]')
        lines.append("AttributeEnd")
    path.write_text("\n".join(lines) + "\n")


def write_obj(path, p, i):
    with open(path, "w") as f:
        f.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in p)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in i)


def mitsuba_scene(out, res):
    def gray(v):
        return {"type": "rgb", "value": [v, v, v]}

    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH + 1},  # pbrt maxdepth + 1: equal depth
        "sensor": {
            "type": "perspective",
            "fov": FOV,
            "fov_axis": "smaller",  # pbrt's fov spans the shorter axis
            "to_world": mi.ScalarTransform4f().look_at(origin=EYE, target=TARGET, up=UP),
            "sampler": {"type": "independent", "sample_count": 16},
            "film": {
                "type": "hdrfilm",
                "width": res,
                "height": res,
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
        },
        "sky": {"type": "constant", "radiance": gray(SKY)},
    }
    for name, (p, i, refl, le) in scene_meshes().items():
        obj = out / f"{name}.obj"
        write_obj(obj, p, i)
        shape = {"type": "obj", "filename": str(obj), "face_normals": True, "bsdf": {"type": "diffuse", "reflectance": gray(refl)}}
        if le is not None:
            shape["emitter"] = {"type": "area", "radiance": gray(le)}
        d[name] = shape
    return mi.load_dict(d)


# ---- rendering -------------------------------------------------------------


def read_exr(path):
    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[..., :3]


def write_png(path, img):
    mi.Bitmap(np.ascontiguousarray(img, dtype=np.float32)).convert(
        mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True
    ).write(str(path))


def render_atoll(args, scene, spp, seed, out, res=None):
    cmd = [args.atoll, "render", str(scene), "--spp", str(spp), "--seed", str(seed), "-o", str(out), "--device", args.device]
    if res:
        cmd += ["--res", f"{res}x{res}"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.stderr.write(r.stdout + r.stderr)
        sys.exit(f"atoll failed: {' '.join(cmd)}")
    # "... in 0.23 s (load ...": the render alone, without loading; else the process's wall time.
    m = re.search(r" in ([0-9.]+) s \(load", r.stderr + r.stdout)
    return read_exr(out), float(m.group(1)) if m else wall


def render_mitsuba(scene, spp, seed):
    t0 = time.perf_counter()
    img = mi.render(scene, seed=seed, spp=spp)
    secs = time.perf_counter() - t0
    return np.array(img, dtype=np.float64)[..., :3], secs


def luminance(img):
    return img @ np.array([0.2126, 0.7152, 0.0722])


def rmse(img, ref, mask=None):
    d2 = ((img - ref) ** 2).mean(axis=-1)
    return math.sqrt(d2[mask].mean() if mask is not None else d2.mean())


def spp_list(s):
    return [int(x) for x in s.split(",") if x]


def box_blur(img, r):
    """Mean over (2r+1)^2 pixels, edges clamped."""
    p = np.pad(img, r, mode="edge")
    c = np.pad(p.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    k = 2 * r + 1
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)


def light_pool(ref, factor):
    """Pixels whose luminance, blurred over 7x7 pixels, exceeds factor x the
    median: blurred, so that the reference's own noise does not pick the
    pixels (which would bias the pool's mean upwards)."""
    lum = box_blur(luminance(ref), 3)
    return lum > factor * np.median(lum)


def block_means(img, k=8):
    h, w = img.shape[0] // k * k, img.shape[1] // k * k
    return luminance(img[:h, :w]).reshape(h // k, k, w // k, k).mean(axis=(1, 3))


def compare(args):
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pbrt = out / "light-over-ground.pbrt"
    write_pbrt(pbrt, args.res, args.ref_spp)
    mscene = mitsuba_scene(out, args.res)
    st = os.stat(args.atoll)
    print(f"atoll: {args.atoll} (built {time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(st.st_mtime))}); Mitsuba {mi.__version__} scalar_rgb")
    print(f"scene: {pbrt} ({args.res}x{args.res}, maxdepth {MAX_DEPTH}; Mitsuba max_depth {MAX_DEPTH + 1})")

    ref, ref_s = render_atoll(args, pbrt, args.ref_spp, 1_000_000, out / "ref-atoll.exr")
    write_png(out / "ref-atoll.png", ref)
    mref, mref_s = render_mitsuba(mscene, args.mitsuba_ref_spp, 1_000_000)
    mi.Bitmap(mref.astype(np.float32)).write(str(out / "ref-mitsuba.exr"))
    write_png(out / "ref-mitsuba.png", mref)
    pool = light_pool(ref, args.pool_factor)

    print(f"reference: atoll {args.ref_spp} spp ({ref_s:.1f} s), Mitsuba {args.mitsuba_ref_spp} spp ({mref_s:.1f} s); "
          f"light pool: {pool.sum()} of {pool.size} pixels (luminance > {args.pool_factor:g} x median)")
    mismatch = False
    for what, m in (("whole image", None), ("light pool", pool)):
        a = luminance(ref)[m].mean() if m is not None else luminance(ref).mean()
        b = luminance(mref)[m].mean() if m is not None else luminance(mref).mean()
        rel = b / a - 1
        mismatch |= abs(rel) > args.max_mean_diff
        print(f"  mean luminance, {what:11}: atoll {a:.5f}  Mitsuba {b:.5f}  ({100 * rel:+.2f}%)")
    # 8x8-pixel blocks: a mirrored or shifted image shows here, not in the means.
    ba, bb = block_means(ref), block_means(mref)
    lit = (ba > 0.01) & (bb > 0.01)  # not the black top of the light
    worst = np.abs(bb[lit] / ba[lit] - 1).max()
    mismatch |= worst > 4 * args.max_mean_diff
    print(f"  8x8-block means: largest relative difference {100 * worst:.2f}%")
    print(f"  RMSE Mitsuba {args.mitsuba_ref_spp} spp vs atoll's reference: pool {rmse(mref, ref, pool):.5f}, whole {rmse(mref, ref):.5f}")
    if mismatch:
        print(f"SCENE MISMATCH: a mean differs by more than {100 * args.max_mean_diff:g}% "
              f"(or a block by more than {400 * args.max_mean_diff:g}%)")

    rows = []
    for spp in args.spp:
        for name in ("atoll", "Mitsuba"):
            e_pool, e_all, secs = [], [], []
            for run in range(args.runs):
                seed = 1 + run
                if name == "atoll":
                    img, s = render_atoll(args, pbrt, spp, seed, out / f"atoll-{spp}.exr")
                else:
                    img, s = render_mitsuba(mscene, spp, seed)
                if run == 0:
                    write_png(out / f"{name.lower()}-{spp}.png", img)
                e_pool.append(rmse(img, ref, pool))
                e_all.append(rmse(img, ref))
                secs.append(s)
            rows.append((name, spp, np.mean(e_pool), np.std(e_pool), np.mean(e_all), np.mean(secs)))

    print(f"\n{args.runs} runs each; RMSE against atoll's {args.ref_spp}-spp reference (mean over runs +- std), seconds per render")
    print(f"{'renderer':8} {'spp':>5} {'RMSE light pool':>20} {'RMSE whole':>11} {'seconds':>8}")
    for name, spp, ep, sp, ea, s in rows:
        print(f"{name:8} {spp:5d} {ep:11.5f} +- {sp:.5f} {ea:11.5f} {s:8.2f}")
    worst = 0.0
    print()
    for spp in args.spp:
        a = next(r for r in rows if r[0] == "atoll" and r[1] == spp)
        m = next(r for r in rows if r[0] == "Mitsuba" and r[1] == spp)
        ratio = a[2] / m[2]
        worst = max(worst, ratio)
        print(f"spp {spp:5d}: light-pool RMSE atoll/Mitsuba = {ratio:.2f} (whole image {a[4] / m[4]:.2f}; "
              f"time atoll/Mitsuba {a[5] / m[5]:.2f})")
    print(f"images in {out}")
    if mismatch:
        return 2
    if worst > args.max_ratio:
        print(f"FAIL: ratio {worst:.2f} > --max-ratio {args.max_ratio:g}")
        return 1
    print(f"ok: ratio {worst:.2f} <= --max-ratio {args.max_ratio:g}")
    return 0


def cornell(args):
    """atoll alone on the shared Cornell box: equal spp and equal time against its own reference."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    scene = Path(args.cornell_scene)
    res = args.res
    if args.reference:
        # A reference shared between runs (e.g. two builds compared on one image).
        ref = read_exr(args.reference)
        print(f"Cornell box {scene} at {res}x{res}; reference {args.reference}")
    else:
        ref, ref_s = render_atoll(args, scene, args.ref_spp, 1_000_000, out / "cornell-ref.exr", res)
        write_png(out / "cornell-ref.png", ref)
        print(f"Cornell box {scene} at {res}x{res}; atoll reference {args.ref_spp} spp ({ref_s:.1f} s)")
    print(f"{'spp':>6} {'RMSE whole':>11} {'seconds':>8} {'Msamples/s':>11}")
    rates = []
    for spp in args.spp:
        e, secs = [], []
        for run in range(args.runs):
            img, s = render_atoll(args, scene, spp, 1 + run, out / f"cornell-{spp}.exr", res)
            e.append(rmse(img, ref))
            secs.append(s)
        rate = spp * res * res / np.mean(secs)
        rates.append(rate)
        print(f"{spp:6d} {np.mean(e):11.5f} {np.mean(secs):8.2f} {rate / 1e6:11.2f}")
    # Equal time: the spp that fills --seconds at the best measured rate.
    spp = max(1, round(args.seconds * max(rates) / (res * res)))
    e, secs = [], []
    for run in range(args.runs):
        img, s = render_atoll(args, scene, spp, 101 + run, out / "cornell-equal-time.exr", res)
        e.append(rmse(img, ref))
        secs.append(s)
    print(f"equal time {args.seconds:g} s: {spp} spp, RMSE whole {np.mean(e):.5f}, {np.mean(secs):.2f} s "
          "(Mitsuba does not read pbrt; no Mitsuba column)")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--atoll", default="target/release/atoll", help="atoll binary (default %(default)s)")
    ap.add_argument("--out", default="/tmp/atoll-mitsuba", help="output folder (default %(default)s)")
    ap.add_argument("--spp", type=spp_list, default=[16, 64], help="comma-separated spp (default 16,64)")
    ap.add_argument("--ref-spp", type=int, default=4096, help="atoll's reference spp (default %(default)s)")
    ap.add_argument("--mitsuba-ref-spp", type=int, default=1024, help="Mitsuba's high-spp render, to check the scenes match (default %(default)s)")
    ap.add_argument("--runs", type=int, default=4, help="renders per renderer and spp, each its own seed (default %(default)s)")
    ap.add_argument("--res", type=int, default=128, help="square image size (default %(default)s)")
    ap.add_argument("--device", default="cpu", help="atoll's --device (default %(default)s)")
    ap.add_argument("--max-ratio", type=float, default=1.2, help="fail when atoll/Mitsuba light-pool RMSE exceeds this (default %(default)s)")
    ap.add_argument("--max-mean-diff", type=float, default=0.01, help="scene-match tolerance on the means (default %(default)s)")
    ap.add_argument("--pool-factor", type=float, default=2.0, help="light pool: reference luminance above this x the median (default %(default)s)")
    ap.add_argument("--cornell", action="store_true", help="atoll alone on the shared Cornell box, equal spp and equal time")
    ap.add_argument("--cornell-scene", default="../shared/scenes/cbox/diffuse/scene.pbrt")
    ap.add_argument("--reference", help="--cornell: an EXR to use as the reference instead of rendering one")
    ap.add_argument("--seconds", type=float, default=1.0, help="--cornell: the equal-time budget (default %(default)s)")
    args = ap.parse_args()
    if not os.access(args.atoll, os.X_OK):
        sys.exit(f"no atoll binary at {args.atoll}: cargo build --release -p atoll")
    return cornell(args) if args.cornell else compare(args)


if __name__ == "__main__":
    sys.exit(main())
